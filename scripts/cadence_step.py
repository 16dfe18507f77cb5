"""How long PDR's steps are at each cadence, on a dataset's walks with truth (issue 34): the
constant c of a step length that grows with the cadence, L = c·f (``wearnav.models.pdr``'s
``STEP_PER_CADENCE_M_S`` is this on the simulator's training walks), beside the fixed step
length that would keep the same distance.

Per 4-s window (stride 2 s, the phone, 25 Hz, world frame as PDR reads it): f = PDR's fractional
steps / duration, v = the truth's speed; c = Σv / Σf² and L = Σv / Σf keep the windows' total
distance.

    PYTHONPATH=src python scripts/cadence_step.py DATA [--splits train,val] [--truth-gap S]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from wearnav.dataset import Dataset
from wearnav.models.pdr import PDR
from wearnav.preprocess import PreprocessConfig, align
from wearnav.preprocess.windows import WindowConfig, WindowDataset

RATE, WINDOW = 25.0, 100


def cadence_and_speed(data: Path, splits: list[str], truth_gap: float) -> tuple[np.ndarray, np.ndarray]:
    """Every window's (cadence f in steps/s, true speed v in m/s) over the named splits' walks."""
    ds = Dataset.open(data)
    names = ds.manifest.loc[ds.manifest["split"].isin(splits), "name"].tolist()
    pcfg = PreprocessConfig(rate=RATE, devices=("phone",), frame_align="none", truth_max_gap=truth_gap)
    pdr = PDR(1, WINDOW, rate=RATE)
    fs, vs = [], []
    for name in names:
        rec = ds.load(name)
        if "phone" not in rec.devices:
            continue
        w = WindowDataset([align(rec, pcfg)], WindowConfig(window=WINDOW, stride=WINDOW // 2))
        if not len(w):
            continue
        b = w[list(range(len(w)))]
        _, steps = pdr.steps(pdr.bandpass(b["x"][:, 0, :, :3].numpy().astype(np.float64))[..., 2])
        fs.append(steps / ((WINDOW - 1) / RATE))
        vs.append(np.hypot(*b["vel"].numpy().T))
    if not fs:
        raise SystemExit(f"{data}: no phone walk with truth in splits {', '.join(splits)}")
    return np.concatenate(fs), np.concatenate(vs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", type=Path)
    ap.add_argument("--splits", default="train,val")
    ap.add_argument("--truth-gap", type=float, default=60.0, help="longest truth gap interpolated over (s)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    f, v = cadence_and_speed(args.data, args.splits.split(","), args.truth_gap)
    moving = f > 0.5
    print(
        f"{args.data} ({args.splits}): {len(f)} windows, {moving.sum()} with steps; median cadence "
        f"{np.median(f[moving]):.2f} steps/s, speed {np.median(v[moving]):.2f} m/s; fixed step "
        f"{v.sum() / f.sum():.3f} m; c = {v.sum() / (f**2).sum():.3f} m per step/s "
        f"(L = c·f: {v.sum() / (f**2).sum() * 1.8:.3f} m at 1.8 steps/s)"
    )


if __name__ == "__main__":
    main()
