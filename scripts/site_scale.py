"""Would one speed scale per building, fitted on its training walks, fix a path's length (issue 34)?

For each path of a `wearnav bench real-odometry` suite folder (every run in ``SUITE/runs``, a
heading-frame run also as its speed along where the phone points): the *site scale*, the truth's
length over the path's between consecutive surveyed points inside the path's span on the site's
training traces (as the site yaw is fitted there, with the same preprocessing), then the held-out
traces scored as the user-protocol rows score a path (:func:`wearnav.bench.user_protocol.score_path`:
errors at the surveyed points from the second on, the median per-trace length ratio) as evaluated
and scaled about its start.

    PYTHONPATH=src python scripts/site_scale.py SUITE [SUITE ...] [--site main]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import runs
from wearnav.bench.real_sites import TRUTH_MAX_GAP_S
from wearnav.bench.user_protocol import score_path
from wearnav.dataset import Dataset
from wearnav.evaluate import load_sequences, predict_sequence
from wearnav.train.odometry import TrainConfig, load_model
from wearnav.trajectory import integrate_velocity


def _length(xy: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())


def site_scale(run: Path, data: Path, speed: str) -> float:
    """Σ truth length / Σ path length over the training traces' segments inside the path's span."""
    model, tcfg = load_model(run, speed=speed)
    cfg: TrainConfig = dataclasses.replace(
        tcfg, data=str(data), frame_align="none", truth_max_gap=TRUTH_MAX_GAP_S, yaw_deg=0.0
    )
    est = true = 0.0
    for seq in load_sequences(Dataset.open(data).split("train"), cfg, False):
        t_c, vel, _ = predict_sequence(model, seq, cfg.window, cfg.stride)
        rec = seq.recording
        if t_c.size < 2 or rec is None or rec.truth is None:
            continue
        k = (rec.truth.t >= t_c[0]) & (rec.truth.t <= t_c[-1])
        if k.sum() >= 2:
            est += _length(integrate_velocity(t_c, vel, rec.truth.t[k], np.zeros(2)))
            true += _length(rec.truth.pos[k, :2])
    return true / est


def scored(eval_dir: Path, data: Path, scale: float) -> dict:
    """Median / p75 / p95 error (m) and median length ratio of the evaluation's held-out paths,
    each scaled by ``scale`` about its position at the trace's first surveyed point."""
    ds, errors, ratios = Dataset.open(data), [], []
    for f in sorted((eval_dir / "trajectories" / "test").glob("*.csv")):
        df = pd.read_csv(f)
        if f.stem not in ds.names or len(df) < 2:
            continue
        truth = ds.load(f.stem).truth
        assert truth is not None  # a scored test recording has truth
        t, xy = df["t"].to_numpy(), df[["x", "y"]].to_numpy()
        start = np.array([np.interp(truth.t[0], t, xy[:, j]) for j in range(2)])
        err, ratio = score_path(t, start + scale * (xy - start), truth.t, truth.pos[:, :2])
        errors.append(err)
        ratios.append(ratio)
    e = np.concatenate(errors)
    e = e[np.isfinite(e)]
    p50, p75, p95 = np.percentile(e, [50, 75, 95])
    return {"median": p50, "p75": p75, "p95": p95, "length": float(np.nanmedian(ratios))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("suites", nargs="+", type=Path)
    ap.add_argument("--site", default="main", help="the suite's site to score (main or other)")
    args = ap.parse_args()
    rows = []
    for suite in args.suites:
        data = suite / "data" / args.site
        for run in sorted((suite / "runs").iterdir()):
            heading = bool(runs.read_config(run)["config"]["train"].get("heading_frame"))
            for speed, suffix in (("model", ""), ("pointing", "_pointing"))[: 2 if heading else 1]:
                ev = run / f"eval_{args.site}{suffix}"
                if not runs.is_complete(ev):
                    continue
                scale = site_scale(run, data, speed)
                before, after = scored(ev, data, 1.0), scored(ev, data, scale)
                rows.append(
                    {
                        "suite": suite.name,
                        "path": run.name + ("" if speed == "model" else " · pointing"),
                        "site scale": scale,
                        **{f"{k}, as scored": v for k, v in before.items()},
                        **{f"{k}, scaled": v for k, v in after.items()},
                    }
                )
                print(pd.DataFrame(rows[-1:]).to_string(index=False, float_format="%.2f"), flush=True)
    print(pd.DataFrame(rows).to_markdown(index=False, floatfmt=".2f"))


if __name__ == "__main__":
    main()
