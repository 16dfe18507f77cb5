"""A dataset folder holding the recordings of another that match a filter, their splits kept: e.g.
the simulator's hand-held walks alone, which issue 34 measured as the phone recipe's training
(docs/design.md: steadier in ILC2, less steady in IPIN).

    PYTHONPATH=src python scripts/subset_dataset.py SRC OUT --placement HD [--mode STW,PVW]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from wearnav.dataset import Dataset, write_subset


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("src", type=Path)
    ap.add_argument("out", type=Path)
    for column in ("placement", "mode", "subject", "source"):
        ap.add_argument(f"--{column}", help=f"keep these {column} values (comma-separated)")
    args = ap.parse_args()
    want = {c: getattr(args, c).split(",") for c in ("placement", "mode", "subject", "source") if getattr(args, c)}
    src = Dataset.open(args.src)
    out = write_subset(src, args.out, {"made_by": "scripts/subset_dataset.py"}, **want)
    print(f"{len(out.names)} of {len(src.names)} recordings in {args.out}")


if __name__ == "__main__":
    main()
