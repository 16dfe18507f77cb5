"""Why a path is wrong: its error split into speed and heading between surveyed points (issue 34 §1).

For every test trace an evaluation wrote (``eval_*/trajectories/test/*.csv``: the estimate from
the known start), each pair of consecutive surveyed points gives one segment
(:func:`wearnav.metrics.segment_speed_heading`): the estimate's length over the truth's (the
*speed ratio*: below 1 the path is short) and the angle between their directions (the *heading
error*). A model whose speed ratio sits below 1 at every walking speed errs in scale; one whose
ratio is right but whose heading error is wide errs in direction. Rows are kept per segment, with
the walk's device (the phone model, where the dataset names it) and the true speed, so the page
can split them by building, walking speed and device.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.dataset import Dataset
from wearnav.metrics import segment_speed_heading

# Walking-speed bins of the page's split (m/s): slow, ordinary and brisk walkers (IPIN's walkers
# move at 0.92 m/s, ILC2's at 1.12: issue 34).
SPEED_BINS_M_S = (0.0, 0.8, 1.1, np.inf)


def eval_segments(eval_dir: Path, data: str | Path) -> pd.DataFrame:
    """One row per segment of every test trace in ``eval_dir``: walk, device, t0_s, t1_s,
    true_speed_m_s, speed_ratio, heading_error_deg."""
    ds, frames = Dataset.open(data), []
    for f in sorted((Path(eval_dir) / "trajectories" / "test").glob("*.csv")):
        if f.stem not in ds.names:
            continue
        est = pd.read_csv(f)
        if len(est) < 2:
            continue
        rec = ds.load(f.stem)
        if rec.truth is None:
            continue
        seg = pd.DataFrame(
            segment_speed_heading(est["t"].to_numpy(), est[["x", "y"]].to_numpy(), rec.truth.t, rec.truth.pos[:, :2])
        )
        seg.insert(0, "device", str(rec.meta.get("device") or "unknown"))
        seg.insert(0, "walk", f.stem)
        frames.append(seg)
    cols = ["walk", "device", "t0_s", "t1_s", "true_speed_m_s", "speed_ratio", "heading_error_deg"]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=cols)


def _describe(seg: pd.DataFrame) -> dict:
    r, h = seg["speed_ratio"].to_numpy(float), np.abs(seg["heading_error_deg"].to_numpy(float))
    if not len(r):
        return {"walks": 0, "segments": 0}
    per_walk = seg.groupby("walk")["speed_ratio"].median()
    return {
        "walks": int(seg["walk"].nunique()),
        "segments": len(r),
        "speed ratio median": round(float(np.median(r)), 3),
        "speed ratio p25–p75": f"{np.quantile(r, 0.25):.2f}–{np.quantile(r, 0.75):.2f}",
        "walks with ratio < 0.9": f"{float(np.mean(per_walk < 0.9)):.0%}",
        "|heading error| median (°)": round(float(np.median(h)), 1),
        "|heading error| p90 (°)": round(float(np.quantile(h, 0.9)), 1),
    }


def summary(segments: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Per source (the dict's labels): the speed ratio's and heading error's statistics."""
    return pd.DataFrame([{"source": label, **_describe(seg)} for label, seg in segments.items()])


def by_speed(segments: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """The median speed ratio per source and walking-speed bin (:data:`SPEED_BINS_M_S`)."""
    rows = []
    for label, seg in segments.items():
        bins = pd.cut(seg["true_speed_m_s"], SPEED_BINS_M_S)
        row: dict[str, object] = {"source": label}
        for b, part in seg.groupby(bins, observed=False):
            row[f"{b.left:g}–{b.right:g} m/s"] = (
                f"{part['speed_ratio'].median():.2f} ({len(part)})" if len(part) else "—"
            )
        rows.append(row)
    return pd.DataFrame(rows)


def by_device(segments: dict[str, pd.DataFrame], most: int = 6) -> pd.DataFrame:
    """The median speed ratio and |heading error| per source on the ``most`` devices with the
    most segments (a dataset that names no device has one row, "unknown")."""
    devices = pd.concat(segments.values())["device"].value_counts().index[:most] if segments else []
    rows = []
    for device in devices:
        row: dict[str, object] = {"device": device}
        for label, seg in segments.items():
            part = seg[seg["device"] == device]
            row[label] = (
                f"{part['speed_ratio'].median():.2f} / {part['heading_error_deg'].abs().median():.0f}°"
                if len(part)
                else "—"
            )
        rows.append(row)
    return pd.DataFrame(rows)
