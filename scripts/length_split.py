"""Why a learned path comes out short (issue 34): slow, or wandering?

``arcs SUITE``: for each known-start path a `wearnav bench real-odometry` suite evaluated (the
learned run and PDR, each site), the pages' length ratio (chords) beside the arc ratio
(:func:`wearnav.bench.user_protocol.arc_ratio`: below 1 the path is slow, whatever its direction),
medians over walks, as the pages now show them; and, per segment between consecutive surveyed
points, the arc over the segment by how long the segment took.

``sensitivity DATA [DATA ...]``: the shipped phone model's speed on a dataset's windows, and how it
moves when one part of the input is scaled about the window's mean (vertical or horizontal
acceleration ×0.7 / ×1.4, gyroscope ×0 / ×1.5): what the model reads its speed from.

    PYTHONPATH=src python scripts/length_split.py arcs runs/sim-to-real
    PYTHONPATH=src python scripts/length_split.py sensitivity runs/sim-to-real/data/main runs/sim-to-real/data/other
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from wearnav import pretrained
from wearnav.bench.user_protocol import arc_ratio, score_path
from wearnav.dataset import Dataset
from wearnav.preprocess import SURVEYED_TRUTH_MAX_GAP_S, align
from wearnav.preprocess.windows import WindowConfig, WindowDataset
from wearnav.train.odometry import load_model

SEGMENT_BINS_S = ((0.0, 5.0), (5.0, 10.0), (10.0, 20.0), (20.0, np.inf))
SCALINGS = {
    "vertical ×0.7": {"vert": 0.7},
    "vertical ×1.4": {"vert": 1.4},
    "horizontal ×0.7": {"hor": 0.7},
    "horizontal ×1.4": {"hor": 1.4},
    "gyroscope ×0": {"gyro": 0.0},
    "gyroscope ×1.5": {"gyro": 1.5},
}


def _at(t: np.ndarray, p: np.ndarray, ts: float) -> np.ndarray:
    return np.array([np.interp(ts, t, p[:, 0]), np.interp(ts, t, p[:, 1])])


def segment_arcs(t: np.ndarray, p: np.ndarray, truth) -> list[tuple[float, float, float]]:
    """Per surveyed segment inside the path: its duration (s), the truth's length (m) and the
    path's arc over it (m)."""
    segs = []
    for a in range(len(truth.t) - 1):
        ta, tb = float(truth.t[a]), float(truth.t[a + 1])
        if ta < t[0] or tb > t[-1]:
            continue
        inner = (t > ta) & (t < tb)
        pts = np.vstack([_at(t, p, ta), p[inner], _at(t, p, tb)])
        arc = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        segs.append((tb - ta, float(np.linalg.norm(truth.pos[a + 1, :2] - truth.pos[a, :2])), arc))
    return segs


def arcs(suite: Path) -> None:
    for site in sorted(p.name for p in (suite / "data").iterdir() if p.is_dir()):
        ds = Dataset.open(suite / "data" / site)
        for ev in sorted(suite.glob(f"runs/*/eval_{site}")):
            chords, ratios, segs = [], [], []
            for f in sorted((ev / "trajectories" / "test").glob("*.csv")):
                if f.stem not in ds.names:
                    continue
                df = pd.read_csv(f)
                truth = ds.load(f.stem).truth
                t, p = df["t"].to_numpy(), df[["x", "y"]].to_numpy()
                chords.append(score_path(t, p, truth.t, truth.pos[:, :2])[1])
                ratios.append(arc_ratio(t, p, truth.t, truth.pos[:, :2]))
                segs += segment_arcs(t, p, truth)
            S = np.asarray(segs)
            print(
                f"{site} {ev.parent.name}: {len(ratios)} walks, {len(S)} segments; length ratio (chords) "
                f"{np.nanmedian(chords):.3f}, arc ratio {np.nanmedian(ratios):.3f}"
            )
            for lo, hi in SEGMENT_BINS_S:
                k = (S[:, 0] >= lo) & (S[:, 0] < hi)
                if k.any():
                    print(
                        f"    segments of {lo:g}–{hi:g} s: {k.sum()}, walked at {np.median(S[k, 1] / S[k, 0]):.2f} m/s "
                        f"(median), arc / segment {S[k, 2].sum() / S[k, 1].sum():.3f}"
                    )


def sensitivity(folders: list[Path]) -> None:
    torch.set_num_threads(1)
    model, tcfg = load_model(pretrained.model_path("phone", "odometry"))
    pcfg = dataclasses.replace(
        tcfg.preprocess_config(), frame_align="none", yaw_deg=0.0, truth_max_gap=SURVEYED_TRUTH_MAX_GAP_S
    )

    def speed(x: torch.Tensor, m: torch.Tensor) -> np.ndarray:
        with torch.no_grad():
            return np.hypot(*model.predict(x, m).numpy().T)

    for folder in folders:
        xs, ms, vs = [], [], []
        for rec in Dataset.open(folder):
            w = WindowDataset([align(rec, pcfg)], WindowConfig(window=tcfg.window, stride=tcfg.window // 2))
            if len(w):
                b = w[list(range(len(w)))]
                xs.append(b["x"])
                ms.append(b["mask"])
                vs.append(b["vel"])
        x, m, true = torch.cat(xs), torch.cat(ms), np.hypot(*torch.cat(vs).numpy().T)
        base, moving = speed(x, m), true > 0.5
        dyn = x[..., :3] - x[..., :3].mean(dim=2, keepdim=True)
        print(
            f"{folder}: {moving.sum()} windows over 0.5 m/s, true {np.median(true[moving]):.2f} m/s, "
            f"model {np.median(base[moving]):.2f} (median ratio {np.median(base[moving] / true[moving]):.2f}); "
            f"vertical std {dyn[..., 2].std(dim=2).median():.2f} m/s²"
        )
        mean = x.mean(dim=2, keepdim=True)
        for name, k in SCALINGS.items():
            y = x.clone()
            y[..., 2] = mean[..., 2] + k.get("vert", 1.0) * (x[..., 2] - mean[..., 2])
            y[..., :2] = mean[..., :2] + k.get("hor", 1.0) * (x[..., :2] - mean[..., :2])
            y[..., 3:6] = x[..., 3:6] * k.get("gyro", 1.0)
            print(f"    {name}: speed ×{np.median(speed(y, m)[moving] / base[moving]):.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    sub.add_parser("arcs").add_argument("suite", type=Path)
    sub.add_parser("sensitivity").add_argument("data", type=Path, nargs="+")
    a = ap.parse_args()
    arcs(a.suite) if a.cmd == "arcs" else sensitivity(a.data)


if __name__ == "__main__":
    main()
