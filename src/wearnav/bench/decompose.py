"""Why a path is wrong: its error split into speed and heading between surveyed points (issue 34 §1),
and at the surveyed points along the walk and across it (issue 36: what a floor plan corrects).

For every test trace an evaluation wrote (``eval_*/trajectories/test/*.csv``: the estimate from
the known start), each pair of consecutive surveyed points gives one segment
(:func:`wearnav.metrics.segment_speed_heading`): the estimate's length over the truth's (the
*speed ratio*: below 1 the path is short) and the angle between their directions (the *heading
error*). A model whose speed ratio sits below 1 at every walking speed errs in scale; one whose
ratio is right but whose heading error is wide errs in direction. Rows are kept per segment, with
the walk's device (the phone model, where the dataset names it) and the true speed, so the page
can split them by building, walking speed and device.

Decision: docs/decisions/0024-speed-heading-along-across.md.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.bench.map_eval import MAP_LABEL
from wearnav.dataset import Dataset
from wearnav.evaluate import SPARSE_MAX_GAP
from wearnav.metrics import along_cross_errors, segment_speed_heading
from wearnav.recording import Trajectory
from wearnav.stats import mean_sd_text

# Walking-speed bins of the page's split (m/s): slow, ordinary and brisk walkers (IPIN's walkers
# move at 0.92 m/s, ILC2's at 1.12: issue 34).
SPEED_BINS_M_S = (0.0, 0.8, 1.1, np.inf)


@dataclasses.dataclass
class ScoredWalk:
    """One test trace an evaluation wrote: its path (``t``, ``xy`` from the known start), its
    recording's truth and device."""

    name: str
    t: np.ndarray
    xy: np.ndarray
    truth: Trajectory
    device: str


def scored_walks(eval_dir: Path, data: str | Path, truths: dict | None = None) -> Iterator[ScoredWalk]:
    """Every test trace of ``eval_dir`` (``trajectories/test/*.csv``) of at least two samples whose
    recording in ``data`` has truth. ``truths``: a dict the recordings' (truth, device) are kept in,
    by (data, name), for the next evaluation of the same data (a page reads several)."""
    ds = Dataset.open(data)
    truths = {} if truths is None else truths
    for f in sorted((Path(eval_dir) / "trajectories" / "test").glob("*.csv")):
        if f.stem not in ds.names:
            continue
        est = pd.read_csv(f)
        if len(est) < 2:
            continue
        key = (str(data), f.stem)
        if key not in truths:
            rec = ds.load(f.stem)
            truths[key] = (rec.truth, str(rec.meta.get("device") or "unknown"))
        truth, device = truths[key]
        if truth is not None:
            yield ScoredWalk(f.stem, est["t"].to_numpy(), est[["x", "y"]].to_numpy(), truth, device)


def eval_segments(eval_dir: Path, data: str | Path) -> pd.DataFrame:
    """One row per segment of every test trace in ``eval_dir``: walk, device, t0_s, t1_s,
    true_speed_m_s, speed_ratio, heading_error_deg."""
    frames = []
    for w in scored_walks(eval_dir, data):
        seg = pd.DataFrame(segment_speed_heading(w.t, w.xy, w.truth.t, w.truth.pos[:, :2]))
        seg.insert(0, "device", w.device)
        seg.insert(0, "walk", w.name)
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


def along_across(eval_dir: Path, data: str | Path, truths: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """An evaluation's errors at the surveyed points split along the walk and across it
    (:func:`wearnav.metrics.along_cross_errors`: along positive ahead, across positive left; every
    test walk's points together, those where the truth stands still left out), scored as
    :func:`wearnav.bench.map_eval.map_aware_eval` scores them; ``truths`` as :func:`scored_walks`'."""
    along, across = [], []
    for w in scored_walks(eval_dir, data, truths):
        keep = (w.truth.t > w.t[0]) & (w.truth.t <= w.t[-1] + SPARSE_MAX_GAP)
        a, c = along_cross_errors(w.t, w.xy, w.truth.t[keep], w.truth.pos[keep, :2], SPARSE_MAX_GAP)
        ok = np.isfinite(a)
        along.append(a[ok])
        across.append(c[ok])
    cat = lambda v: np.concatenate(v) if v else np.empty(0)
    return cat(along), cat(across)


ALONG_TEXT = (
    "Where the error lies, map-aware rows beside their map-less ones: the error at each surveyed point "
    "split along the walk's direction there and across it (:func:`wearnav.metrics.along_cross_errors`; "
    "|·|, every walk's points together{seeds}; *along, signed*: the median with its sign, below 0 the path "
    "is behind the walker). A plan holds a path across a corridor everywhere, along it only where the "
    "corridor turns or ends:"
)


def along_across_table(evals: dict[str, list[tuple[Path, str | Path]]]) -> pd.DataFrame | None:
    """Per map-aware path and its map-less one (``evals``: label → its (evaluation folder, data) of
    each seed, in the page's order): the medians and 95th percentiles of :func:`along_across`'s
    absolute values and the median of its signed along, mean ± sd over the seeds where there are
    several."""
    rows: list[dict] = []
    truths: dict = {}
    for label in evals:
        if not label.endswith(MAP_LABEL) or label[: -len(MAP_LABEL)] not in evals:
            continue
        for name in (label[: -len(MAP_LABEL)], label):
            split = [along_across(ev, data, truths) for ev, data in evals[name]]
            rows.append(
                {
                    "path": name,
                    **{
                        f"{part}, {q_name} (m)": mean_sd_text(
                            [float(np.percentile(np.abs(x[k]), q)) for x in split if x[k].size]
                        )
                        for q, q_name in ((50, "median"), (95, "p95"))
                        for k, part in enumerate(("along", "across"))
                    },
                    "along, signed median (m)": mean_sd_text([float(np.median(x[0])) for x in split if x[0].size]),
                }
            )
    return pd.DataFrame(rows) if rows else None
