"""The map-aware row of `wearnav bench real-odometry` (issue 36 §3): an evaluation's paths placed on
the building's floor plans.

An evaluation folder (``eval_<site>``, :func:`wearnav.evaluate.evaluate_run`) holds each test trace's
known-start path (``trajectories/test/<name>.csv``: started at the trace's first surveyed point,
the input turned by the site's yaw from training traces). Where the trace's recording carries its
floor plan (ILC2: :mod:`wearnav.importers.ilc2`), :func:`map_aware_eval` runs the map-aware particle
filter (:func:`wearnav.fuse.particles.map_filter`) over that path from the same start (position: the
first surveyed point; heading offset: none, σ ``start_heading_sigma_deg``: the site yaw's own
uncertainty) and scores it at the same surveyed points. Nothing else is given: no later truth, no fix.
The result is an evaluation folder of the same shape beside the map-less one (``<eval>_map``), so
the page shows it as one more row (:data:`MAP_SUFFIX`).

The filter's constants (:class:`wearnav.fuse.particles.MapConfig`) were chosen on ILC2's training
floors (B1, F1, F3; PDR's paths), never on the test floors.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import metrics, runs
from wearnav.core.progress import progress as report_progress
from wearnav.dataset import Dataset
from wearnav.evaluate import SPARSE_MAX_GAP, summarise
from wearnav.fuse.particles import MapConfig, map_filter
from wearnav.plans import Walkable
from wearnav.recording import FloorPlan

MAP_SUFFIX = "_map"  # the map-aware evaluation of eval_<site>[_pdrspeed] is that folder + this suffix
MAP_LABEL = " · map-aware"  # ... and its row label is the map-less row's + this


def map_dir(eval_dir: Path) -> Path:
    return eval_dir.with_name(eval_dir.name + MAP_SUFFIX)


def has_plans(data: str | Path) -> bool:
    """Whether the first recording of ``data`` carries a floor plan (a site's recordings all do or
    none do: the importer attaches them)."""
    ds = Dataset.open(data)
    return bool(ds.names) and bool(ds.load(ds.names[0]).plans)


def map_aware_eval(
    eval_dir: Path, data: str | Path, cfg: MapConfig = MapConfig(), progress: bool = False
) -> Path | None:
    """Score ``eval_dir``'s paths placed on the floor plans (module docstring) into ``map_dir(eval_dir)``;
    None where the site has no plans. A complete folder is kept (the benchmark resumes)."""
    out = map_dir(eval_dir)
    if runs.is_complete(out):
        return out
    if not has_plans(data):
        return None
    t0 = time.perf_counter()
    ds = Dataset.open(data)
    base = runs.read_metrics(eval_dir)
    grids: dict[str, Walkable] = {}
    rows, errors, seconds = [], [], []
    (out / "trajectories" / "test").mkdir(parents=True, exist_ok=True)
    for row in report_progress(base["splits"]["test"]["sequences"], desc="map-aware", unit="seq", enabled=progress):
        f = eval_dir / "trajectories" / "test" / f"{row['name']}.csv"
        if "skipped" in row or not f.is_file():
            rows.append(dict(row))
            continue
        rec = ds.load(row["name"])
        assert rec.truth is not None  # a scored test recording has truth
        traj = pd.read_csv(f)
        t, xy = traj["t"].to_numpy(), traj[["x", "y"]].to_numpy()
        plan = _plan(rec.plans, rec.meta.get("floor_index"))
        if plan is None:
            rows.append(dict(row, skipped="no floor plan for the trace's floor"))
            continue
        if plan.name not in grids:
            grids[plan.name] = Walkable.of(plan)
        res = map_filter(t, xy, {None: grids[plan.name]}, xy[0], 0.0, cfg=cfg)
        seconds.append(res.info["seconds"])
        tt, tp = rec.truth.t, rec.truth.pos[:, :2]
        keep = np.flatnonzero((tt > t[0]) & (tt <= t[-1] + SPARSE_MAX_GAP))
        err = metrics.errors_at_reference(t, res.xy, tt[keep], tp[keep], SPARSE_MAX_GAP)
        if err.size != row.get("points"):  # the same surveyed points as the map-less score, or none
            rows.append(dict(row, skipped=f"scored at {err.size} points, the map-less path at {row.get('points')}"))
            continue
        errors.append(err)
        rows.append(
            dict(
                row,
                mean_error=float(err.mean()) if err.size else float("nan"),
                median_error=float(np.median(err)) if err.size else float("nan"),
                point_errors=[round(float(e), 4) for e in err],
                map_wall_share=res.info["wall_share"],
                map_scale=res.info["scale_median"],
                map_heading_offset_deg=res.info["heading_offset_deg"],
            )
        )
        traj = traj.assign(x=res.xy[:, 0], y=res.xy[:, 1])
        traj.to_csv(out / "trajectories" / "test" / f.name, index=False, float_format="%.4f")
    pooled = np.concatenate(errors) if errors else np.empty(0)
    metrics_out = {
        **{
            k: base[k] for k in ("model", "run", "data", "window", "eval_stride", "preprocess", "training") if k in base
        },
        "map_aware": {
            "of": eval_dir.name,
            "config": dataclasses.asdict(cfg),
            "filter_s_per_trace_median": float(np.median(seconds)) if seconds else None,
            "wall_s": round(time.perf_counter() - t0, 2),
        },
        "splits": {"test": {"summary": summarise(rows, pooled), "sequences": rows}},
    }
    runs.write_metrics(out, metrics_out)
    return out


def _plan(plans: list[FloorPlan], floor) -> FloorPlan | None:
    for p in plans:
        if floor is None or p.floor == floor:
            return p
    return None
