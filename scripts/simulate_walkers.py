"""Phone-only simulated walks, one simulated person each (EasyTrack's plan,
:func:`wearnav.simulate.presets.plan_phone_only`), every fifth walk the validation split: a
training set with many walkers' gaits for issue 34's question whether walker variety carries the
learned speed into real buildings (measured: it did not; docs/design.md).

    PYTHONPATH=src python scripts/simulate_walkers.py OUT [--walks 40] [--seed 0]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from wearnav.simulate.presets import plan_phone_only, simulate_plan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", type=Path)
    ap.add_argument("--walks", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    plan = plan_phone_only("L1", km=0.0, seed=args.seed, n=args.walks)
    plan = [dataclasses.replace(p, split="val" if i % 5 == 4 else "train") for i, p in enumerate(plan)]
    made_by = {"generator": "wearnav.simulate", "dataset": "phone-only walkers", "n": args.walks, "seed": args.seed}
    ds = simulate_plan(plan, args.out, made_by, progress=True)
    print(f"{len(ds.names)} walks, {sum(p.config.duration_s for p in plan) / 3600:.2f} h, in {args.out}")


if __name__ == "__main__":
    main()
