"""One training set from several imported or simulated dataset folders, each recording's truth
turned into its own input's frame (:func:`wearnav.pretrained.mix.write_mix`): e.g. `mix-noipin`,
ILC2 and the simulator, on which the leave-one-building-out suites train
(docs/decisions/0019-pretrained-mix-lobo.md; `wearnav bench experiment --list`).

    PYTHONPATH=src python scripts/mix_dataset.py OUT ilc2=data/ilc2 sim=data/sim:recording
"""

from __future__ import annotations

import argparse
from pathlib import Path

from wearnav.pretrained.mix import Part, write_mix


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", type=Path)
    ap.add_argument("parts", nargs="+", help="NAME=FOLDER[:YAW], YAW axis (a real building, the default) or recording")
    args = ap.parse_args()
    parts = []
    for text in args.parts:
        name, _, rest = text.partition("=")
        folder, _, yaw = rest.partition(":")
        parts.append(Part(folder, name, yaw or "axis"))
    print(f"wrote {write_mix(parts, args.out)}")


if __name__ == "__main__":
    main()
