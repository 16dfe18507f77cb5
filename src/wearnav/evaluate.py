"""Windows → predictions → integrated trajectory → per-sequence metrics → tables and plots.

Every model is evaluated the same way: each test sequence is cut into windows (the training
window length, stride ``eval_stride``), the model's velocity of each window is placed at the
window's centre time, and the velocities are integrated from the true position at the first
centre (Suite-IN++ eq. 8, :func:`wearnav.trajectory.integrate_velocity`). With dense truth the
errors are ATE and RTE (DESIGN.md definitions, :mod:`wearnav.metrics`) over the span the windows
cover; with sparse truth (waypoints) they are errors at the truth times only, and the report says
so.

Decision: docs/decisions/0005-evaluation-integration.md.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch

from wearnav import metrics, runs
from wearnav.core.fileio import atomic_path
from wearnav.core.progress import progress as report_progress
from wearnav.core.textio import read_json
from wearnav.dataset import Dataset, scorable_split
from wearnav.errors import FormatError, ValidationError
from wearnav.models.registry import n_parameters
from wearnav.preprocess import Aligned, PreprocessConfig, align, load_sequences
from wearnav.preprocess.windows import WindowConfig, WindowDataset, turn
from wearnav.recording import Recording
from wearnav.train.odometry import TRAINING, load_model
from wearnav.trajectory import integrate_velocity

# Truth sampled at least this densely counts as dense (ATE/RTE); sparser truth is scored at its points.
DENSE_TRUTH_MAX_DT = 1.0
# A sparse truth point is scored when a trajectory sample lies within this many seconds of it.
SPARSE_MAX_GAP = 1.0
PERCENTILES = (50, 75, 90, 95)


@torch.no_grad()
def predict_sequence(
    model, seq: Aligned, window: int, stride: int, batch: int = 512, progress: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Window centre times (N,), predicted velocities (N, 2) and device presence (N, D)."""
    wds = WindowDataset([seq], WindowConfig(window=window, stride=stride, target=None))
    if len(wds) == 0:
        return np.empty(0), np.empty((0, 2)), np.empty((0, len(seq.devices)))
    device = next((p.device for p in model.parameters()), torch.device("cpu"))
    ts, vs, ms = [], [], []
    for b in report_progress(wds.loader(batch), desc="predict", unit="batch", enabled=progress, leave=False):
        v = model.predict(b["x"].to(device), b["mask"].to(device)).float().cpu().numpy()
        if "yaw" in b:  # the window's heading frame (PreprocessConfig.heading_frame) back to the world's
            v = turn(v, b["yaw"].numpy())
        vs.append(v)
        ts.append(b["t"].mean(dim=1).numpy())
        ms.append(b["mask"].numpy())
    return np.concatenate(ts), np.concatenate(vs), np.concatenate(ms)


def _is_dense(rec) -> bool:
    return rec.truth is not None and len(rec.truth) > 1 and float(np.median(np.diff(rec.truth.t))) <= DENSE_TRUTH_MAX_DT


def evaluate_sequence(
    model, seq: Aligned, window: int, stride: int, rte_delta: float = 60.0
) -> tuple[dict, pd.DataFrame]:
    """Metrics of one sequence and its trajectory table (t, estimate x/y, truth x/y)."""
    t_c, vel, present = predict_sequence(model, seq, window, stride)
    rec = seq.recording
    row = {
        "name": seq.name,
        "mode": str(seq.meta.get("mode", "")),
        "placement": str(seq.meta.get("placement", "")),  # the phone's (HD MP PK BG; Table IV)
        "subject": str(seq.meta.get("subject", "")),
        "devices_present": float(present.sum(axis=1).mean()) if len(present) else 0.0,
    }
    if t_c.size < 2 or rec is None or rec.truth is None:
        row["skipped"] = "too short for two windows or no truth"
        return row, pd.DataFrame()
    inside = (seq.t >= t_c[0]) & (seq.t <= t_c[-1])
    if _is_dense(rec):
        assert seq.pos is not None  # align interpolates dense truth onto the clock
        ok = inside & np.isfinite(seq.pos[:, 0])
        # the longest stretch of truth inside the predictions (truth gaps split a walk)
        idx = np.flatnonzero(ok)
        if idx.size < 2:
            row["skipped"] = "no truth under the predictions"
            return row, pd.DataFrame()
        breaks = np.flatnonzero(np.diff(idx) > 1)
        runs_ = np.split(idx, breaks + 1)
        idx = max(runs_, key=len)
        t = seq.t[idx]
        true = seq.pos[idx]
        est = integrate_velocity(t_c, vel, t, true[0])
        err = metrics.position_errors(t, est, true)
        row.update(
            truth="dense",
            duration=float(t[-1] - t[0]),
            length_m=float(np.sum(np.linalg.norm(np.diff(true, axis=0), axis=1))),
            ate=metrics.ate(t, est, true),
            rte=metrics.rte(t, est, true, rte_delta),
            rte_delta=rte_delta,
            final_error=float(err[-1]),
        )
        traj = pd.DataFrame(
            {"t": t, "x": est[:, 0], "y": est[:, 1], "x_true": true[:, 0], "y_true": true[:, 1], "error": err}
        )
        return row, traj
    # sparse truth: start at the first truth point on the clock (before the first window centre
    # the first window's velocity holds), score at the later truth points
    tt, tp = rec.truth.t, rec.truth.pos[:, :2]
    first = np.flatnonzero((tt >= seq.t[0]) & (tt <= seq.t[-1]))
    if first.size < 2:
        row["skipped"] = "fewer than two truth points on the clock"
        return row, pd.DataFrame()
    t = seq.t[(seq.t >= tt[first[0]]) & (seq.t <= tt[first[-1]] + SPARSE_MAX_GAP)]
    est = integrate_velocity(t_c, vel, t, tp[first[0]])
    keep = first[1:]
    err = metrics.errors_at_reference(t, est, tt[keep], tp[keep], SPARSE_MAX_GAP)
    row.update(
        truth="sparse",
        duration=float(t[-1] - t[0]),
        points=int(err.size),
        length_m=float(np.sum(np.linalg.norm(np.diff(tp[first], axis=0), axis=1))),
        mean_error=float(err.mean()) if err.size else float("nan"),
        median_error=float(np.median(err)) if err.size else float("nan"),
        point_errors=[round(float(e), 4) for e in err],
    )
    # the waypoints joined by straight lines, for plots only (errors are taken at the points)
    line = np.stack([np.interp(t, tt[first], tp[first, k]) for k in range(2)], axis=1)
    traj = pd.DataFrame({"t": t, "x": est[:, 0], "y": est[:, 1], "x_true": line[:, 0], "y_true": line[:, 1]})
    return row, traj


def summarise(rows: list[dict], errors: np.ndarray) -> dict:
    """Mean/median ATE and RTE over sequences (Suite-IN++ and RoNIN average over sequences) and
    percentiles of the per-timestamp error."""
    df = pd.DataFrame([r for r in rows if "skipped" not in r])
    out: dict = {"sequences": int(len(df)), "skipped": int(len(rows) - len(df))}
    if len(df) and "ate" in df:
        d = df.dropna(subset=["ate"])
        out.update(
            ate_mean=float(d.ate.mean()),
            ate_median=float(d.ate.median()),
            rte_mean=float(d.rte.mean()),
            rte_median=float(d.rte.median()),
            rte_delta=float(d.rte_delta.iloc[0]) if len(d) else None,
            hours=float(d.duration.sum() / 3600),
            km=float(d.length_m.sum() / 1000),
        )
    if len(df) and "mean_error" in df:
        d = df.dropna(subset=["mean_error"])
        out.update(
            points=int(d.points.sum()),
            truth="sparse: errors at truth points only",
            hours=float(d.duration.sum() / 3600),
            km=float(d.length_m.sum() / 1000),
        )
        if errors.size:
            out.update(error_mean=float(errors.mean()))
    if errors.size:
        out.update({f"error_p{p}": float(np.percentile(errors, p)) for p in PERCENTILES})
    return out


def evaluate_sequences(
    model, seqs: list[Aligned], window: int, stride: int, rte_delta: float = 60.0, progress: bool = False
) -> tuple[dict, dict[str, pd.DataFrame]]:
    """Per-sequence rows, the overall, per-walking-mode and per-phone-placement summaries, and the
    trajectories."""
    rows, trajs = [], {}
    for seq in report_progress(seqs, desc="evaluate", unit="seq", enabled=progress, leave=False):
        row, traj = evaluate_sequence(model, seq, window, stride, rte_delta)
        rows.append(row)
        if len(traj):
            trajs[seq.name] = traj
    by_name = {r["name"]: r for r in rows}

    def errs(names):
        """Per-timestamp errors (dense truth) or per-point errors (sparse truth), pooled."""
        e = [trajs[n]["error"].to_numpy() for n in names if n in trajs and "error" in trajs[n]]
        e += [np.asarray(by_name[n]["point_errors"]) for n in names if "point_errors" in by_name[n]]
        return np.concatenate(e) if e else np.empty(0)

    modes = sorted({r["mode"] for r in rows if r["mode"]})
    result = {
        "summary": summarise(rows, errs([r["name"] for r in rows])),
        "by_mode": {
            m: summarise([r for r in rows if r["mode"] == m], errs([r["name"] for r in rows if r["mode"] == m]))
            for m in modes
        },
        "by_placement": {
            p: summarise(
                [r for r in rows if r["placement"] == p], errs([r["name"] for r in rows if r["placement"] == p])
            )
            for p in sorted({r["placement"] for r in rows if r["placement"]})
        },
        "sequences": rows,
    }
    return result, trajs


def evaluate_run(
    run: str | Path,
    data: str | Path | None = None,
    splits: tuple[str, ...] = ("test",),
    stride: int | None = None,
    rte_delta: float = 60.0,
    progress: bool = True,
    training: dict | None = None,
    preprocess: dict | None = None,
    out_dir: str | Path | None = None,
    speed: str = "model",
) -> dict:
    """Evaluate a run folder's best model on ``splits`` of ``data`` (default: the training data);
    write metrics.json, trajectories/<split>/<name>.csv and plots/ into ``out_dir`` (default: the
    run folder). ``preprocess`` replaces preprocessing fields of the run's config for this data
    (e.g. another site's ``yaw_deg``); it is recorded in the metrics. ``speed`` "pdr": the model's
    direction at PDR's speed; "pointing": its speed along where the phone points
    (:func:`wearnav.train.odometry.load_model`). Returns the metrics."""
    run = Path(run)
    model, cfg = load_model(run, speed=speed)
    if preprocess:
        unknown = set(preprocess) - {"frame_align", "eval_frame_align", "truth_max_gap", "yaw_deg"}
        if unknown:
            raise ValidationError(f"not a preprocessing field: {sorted(unknown)}")
        cfg = dataclasses.replace(cfg, **preprocess)
    dest = Path(out_dir) if out_dir is not None else run
    ds = Dataset.open(data or cfg.data)
    old = runs.read_metrics(dest) if runs.is_complete(dest) else {}
    if not isinstance(old.get("splits", {}), dict):
        raise FormatError("'splits' is not a mapping of split names to results", dest / runs.METRICS)
    if training is None and (run / TRAINING).is_file():
        training = read_json(run / TRAINING)
    out: dict[str, Any] = {
        "model": cfg.model,
        "run": run.name,
        "data": str(data or cfg.data),
        "parameters": n_parameters(model),
        "window": cfg.window,
        "eval_stride": stride or cfg.stride,
        "preprocess": dict(preprocess or {}),
        "speed": speed,
        # the test recordings' frame (wearnav.preprocess.frames): "initial" = one constant yaw from the
        # truth's first 10 s; "truth" = the truth's yaw over time (a diagnostic)
        "test_frame": cfg.eval_config().frame_align,
        "training": training if training is not None else old.get("training", {}),
        # splits evaluated earlier on the same data are kept beside the new ones
        "splits": dict(old.get("splits", {})) if data is None or str(data) == old.get("data") else {},
    }
    if not splits:
        raise ValidationError("no split named to evaluate (e.g. --split test)")
    views = {split: scorable_split(ds, split) for split in splits}  # all checked before any write
    for split, view in views.items():
        seqs = load_sequences(view, cfg.eval_config(), progress)
        t0 = time.perf_counter()
        res, trajs = evaluate_sequences(model, seqs, cfg.window, stride or cfg.stride, rte_delta, progress)
        res["wall_s"] = round(time.perf_counter() - t0, 2)
        out["splits"][split] = res
        for name, traj in trajs.items():
            with atomic_path(dest / "trajectories" / split / f"{name}.csv", durable=True) as tmp:
                traj.to_csv(tmp, index=False, float_format="%.4f")
        from wearnav.report.odometry import plot_run_split

        plot_run_split(dest / "plots", split, res, trajs, cfg.model)
    runs.write_metrics(dest, out)
    return out


# ---- one way to window and run the odometry model (track and the live receiver) ----------------


def odometry_preprocess(cfg) -> PreprocessConfig:
    """The run's preprocessing for a user's recording: its devices in one common frame (mode
    "common", :mod:`wearnav.preprocess.frames`: a user's recording has no truth)."""
    return dataclasses.replace(cfg.preprocess_config(), frame_align="common")


def path_times(clock_t: np.ndarray, t_c: np.ndarray) -> np.ndarray:
    """The clock's times the path is given at: those between the first and last window centre."""
    return clock_t[(clock_t >= t_c[0]) & (clock_t <= t_c[-1])]


def odometry(model, cfg, rec: Recording, progress: bool = False):
    """The model's path of ``rec``: the aligned input (:func:`odometry_preprocess`), window centre
    times, velocities and device presence (:func:`wearnav.evaluate.predict_sequence`), and the
    path's times and positions, integrated from (0, 0) at the first centre (Suite-IN++ eq. 8,
    :func:`wearnav.trajectory.integrate_velocity`)."""
    seq = align(rec, odometry_preprocess(cfg))
    t_c, vel, present = predict_sequence(model, seq, cfg.window, cfg.stride, progress=progress)
    if t_c.size < 2:
        return seq, t_c, vel, present, np.empty(0), np.empty((0, 2))
    t = path_times(seq.t, t_c)
    return seq, t_c, vel, present, t, integrate_velocity(t_c, vel, t, np.zeros(2))
