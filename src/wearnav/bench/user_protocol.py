"""The user protocol of `wearnav bench real-odometry` (issue 25 §2): the path a user gets.

A user has no truth at all: neither the start point nor the site's yaw between the phone's
magnetic-north frame and the map. So each held-out trace is run through a trained model with no
yaw applied, its velocities integrated from (0, 0), and the path placed on the recording's own
location fixes by each anchoring of :mod:`wearnav.fuse`:

``first-fixes``  today's `track`: a rigid fit to the first minute's fixes;
``rigid``        one rotation + translation fitted to every fix of the walk;
``smooth``       the smoother (heading offset, scale, drift, a slowly varying fix bias).

Each is scored at the trace's surveyed points, from the second on (as the known-start protocol and
the raw fixes are), with the path-length ratio per walk: the length of the path through its
positions at the surveyed times over the truth's through the same points (1 is right; learned
paths run short). The known-start protocol (true start, site yaw: a floor, not available to a
user) is the benchmark's main table, beside it.

Decisions: docs/decisions/0020-fused-path-smoother.md, docs/decisions/0036-fix-lag.md,
docs/decisions/0033-length-ratio-arc.md.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from wearnav import fuse, metrics, runs
from wearnav.core.textio import read_json
from wearnav.core.timeseries import interp_onto
from wearnav.dataset import Dataset
from wearnav.evaluate import predict_sequence
from wearnav.fuse.particles import MapConfig
from wearnav.fuse.placement import SiteModels, floors_over_time, place
from wearnav.preprocess import SURVEYED_TRUTH_MAX_GAP_S, load_sequences
from wearnav.stats import difference_cells, walk_bootstrap_difference
from wearnav.train.odometry import load_model
from wearnav.trajectory import integrate_velocity

RAW_FIXES = "raw phone fixes"
# The particle filter with every observation the walk has (wearnav.fuse.placement, issue 36): its key
# in user_protocol's result and its label in the table
PARTICLES = "particles"
PARTICLES_LABEL = "particle filter: fixes + beacons + barometer (+ plan)"


def _length(p: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))


def score_path(t: np.ndarray, xy: np.ndarray, truth_t: np.ndarray, truth_xy: np.ndarray) -> tuple[np.ndarray, float]:
    """Errors (m) at the surveyed points from the second on, and the path-length ratio through
    the points inside the path's span (NaN when the truth does not move)."""
    err = metrics.errors_at_reference(t, xy, truth_t[1:], truth_xy[1:], metrics.FIX_MAX_GAP_S)
    k = (truth_t >= t[0]) & (truth_t <= t[-1])
    at = np.stack([np.interp(truth_t[k], t, xy[:, j]) for j in range(2)], axis=1)
    true_len = _length(truth_xy[k])
    return err, (_length(at) / true_len if true_len > 0 else float("nan"))


def arc_ratio(t: np.ndarray, xy: np.ndarray, truth_t: np.ndarray, truth_xy: np.ndarray) -> float:
    """The path's own length (every sample) from the first to the last surveyed time inside its span,
    over the truth's polyline through those surveyed points (NaN when the truth does not move).
    The truth's polyline is a lower bound of the walked distance, so below 1 the path is slow,
    whatever its direction; :func:`score_path`'s ratio (through the path's positions at the
    surveyed times) also comes out short for a path that wanders between them (issue 34)."""
    k = (truth_t >= t[0]) & (truth_t <= t[-1])
    true_len = _length(truth_xy[k])
    if k.sum() < 2 or true_len <= 0:
        return float("nan")
    ta, tb = truth_t[k][0], truth_t[k][-1]
    inner = (t > ta) & (t < tb)
    ends = np.stack([np.interp([ta, tb], t, xy[:, j]) for j in range(2)], axis=1)
    return _length(np.vstack([ends[:1], xy[inner], ends[1:]])) / true_len


def fix_point_errors(rec) -> np.ndarray:
    """The raw fixes' error (m) at the recording's surveyed points from the second on: the latest
    fix within :data:`wearnav.metrics.FIX_MAX_GAP_S` (NaN where none is)."""
    return metrics.errors_at_reference(
        rec.fixes.t, rec.fixes.pos[:, :2], rec.truth.t[1:], rec.truth.pos[1:, :2], metrics.FIX_MAX_GAP_S
    )


def _paths(run, data, split, speed: str = "model"):
    """(recording, t, path from (0, 0) in the phone's world frame, no yaw) per trace of ``split``;
    ``speed`` as :func:`wearnav.train.odometry.load_model`'s."""
    model, tcfg = load_model(run, speed=speed)
    tcfg = dataclasses.replace(tcfg, frame_align="none", yaw_deg=0.0, truth_max_gap=SURVEYED_TRUTH_MAX_GAP_S)
    for seq in load_sequences(Dataset.open(data).split(split), tcfg):
        rec = seq.recording
        if rec is None or rec.truth is None:
            continue
        t_c, vel, _ = predict_sequence(model, seq, tcfg.window, tcfg.stride)
        if t_c.size < 2:
            continue
        t = seq.t[(seq.t >= t_c[0]) & (seq.t <= t_c[-1])]
        yield rec, t, integrate_velocity(t_c, vel, t, np.zeros(2))


def calibrate(run: str | Path, data: str | Path, split: str = "val", speed: str = "model") -> dict:
    """The smoother's calibration for the run's model on the ``split`` walks of ``data``
    (:func:`calibration_of`)."""
    return calibration_of(_paths(run, data, split, speed))


def calibration_of(walks, every_s: float | None = None) -> dict:
    """The smoother's calibration from ``walks`` (recording, t, odometry xy from (0, 0)) with truth:
    the odometry's random walk (:func:`wearnav.fuse.odometry_walk_sigma`, at the truth points, or
    one every ``every_s`` seconds of a dense truth) and the fixes' lag (:func:`wearnav.fuse.fix_lag_of`),
    then, smoothing the walks that have fixes with them, the σ scale
    (:func:`wearnav.fuse.sigma_scale_of`; None without fixes)."""
    walks = list(walks)

    def points(truth):
        if not every_s:
            return truth.t, truth.pos[:, :2]
        k = np.unique(np.searchsorted(truth.t, np.arange(truth.t[0], truth.t[-1], every_s)))
        return truth.t[k], truth.pos[k, :2]

    cal = fuse.odometry_walk_sigma((t, xy, *points(rec.truth)) for rec, t, xy in walks)
    with_fixes = [rec for rec, _, _ in walks if rec.fixes is not None and len(rec.fixes) >= 2]
    cal.update(fuse.fix_lag_of((r.fixes.t, r.fixes.pos[:, :2], r.truth.t, r.truth.pos[:, :2]) for r in with_fixes))
    ratios = []
    for rec, t, xy in walks:
        if cal["odometry_walk_m_per_sqrt_s"] and rec.fixes is not None and len(rec.fixes) >= 2:
            c = fuse.calibrated(fuse.config_for(None, rec.meta, "phone")[0], cal)
            res = fuse.smooth(t, xy, rec.fixes.t, rec.fixes.pos[:, :2], rec.fixes.accuracy, c)
            ratios.extend(_error_over_sigma(t, res, rec.truth))
    return {**cal, **fuse.sigma_scale_of(ratios)}


def user_protocol(
    run: str | Path,
    data: str | Path,
    split: str = "test",
    cfg: fuse.FuseConfig | None = None,
    calibration: dict | None = None,
    speed: str = "model",
    site: SiteModels | None = None,
) -> dict:
    """Per anchoring of :data:`wearnav.fuse.ANCHORS` (and, with ``site``, the particle filter of
    :func:`wearnav.fuse.placement.place` with the site's beacon and floor models and the smoother's
    fix lag, key :data:`PARTICLES`,
    its floor right at the surveyed points in ``floor_right``): the errors at the surveyed points of
    ``split`` of ``data`` for the model of ``run`` (a run folder) under the user protocol, the
    path-length ratio per trace, what the smoother found per trace and its seconds per hour of walk.
    ``cfg``: the smoother's; default the run's own for each recording (:func:`wearnav.fuse.config_for`:
    its calibration, and a heading prior where the recording's frame is north-referenced); ``calibration``
    replaces its calibration (:func:`site_calibration`); ``speed`` "pdr": the model's direction at
    PDR's speed (:func:`wearnav.train.odometry.load_model`)."""
    paths = (*fuse.ANCHORS, PARTICLES) if site is not None else tuple(fuse.ANCHORS)
    out: dict = {a: {"errors": [], "length_ratio": [], "by_trace": {}} for a in paths}
    out["smooth"]["traces"] = {}
    out[RAW_FIXES] = {"by_trace": {}}
    smooth_s, walk_s = 0.0, 0.0
    for rec, t, xy in _paths(run, data, split, speed):
        if rec.fixes is None or len(rec.fixes) == 0:
            continue
        fx = rec.fixes
        out[RAW_FIXES]["by_trace"][rec.name] = _rounded(fix_point_errors(rec))
        c = fuse.calibrated(cfg if cfg is not None else fuse.config_for(run, rec.meta, "phone")[0], calibration)
        for anchor, fn in fuse.ANCHORS.items():
            t0 = time.perf_counter()
            res = (
                fn(t, xy, fx.t, fx.pos[:, :2], fx.accuracy)
                if anchor != "smooth"
                else fuse.smooth(t, xy, fx.t, fx.pos[:, :2], fx.accuracy, c)
            )
            if anchor == "smooth":
                smooth_s += time.perf_counter() - t0
                walk_s += float(t[-1] - t[0])
                out["smooth"].setdefault("inside_68", []).extend(
                    bool(z < fuse.RADIUS_68) for z in _error_over_sigma(t, res, rec.truth)
                )
                out["smooth"]["traces"][rec.name] = {
                    "method": res.method,
                    "warnings": res.warnings,
                    **{k: v for k, v in res.info.items() if k not in ("x", "config", "smoother")},
                }
            err, ratio = score_path(t, res.xy, rec.truth.t, rec.truth.pos[:, :2])
            out[anchor]["errors"].append(err)
            out[anchor]["by_trace"][rec.name] = _rounded(err)
            out[anchor]["length_ratio"].append(ratio)
        if site is not None:
            placed, _ = place(rec, t, xy, site, cfg=MapConfig(fix_lag_s=c.fix_lag_s))  # the smoother's lag
            err, ratio = score_path(t, placed.xy, rec.truth.t, rec.truth.pos[:, :2])
            out[PARTICLES]["errors"].append(err)
            out[PARTICLES]["by_trace"][rec.name] = _rounded(err)
            out[PARTICLES]["length_ratio"].append(ratio)
            floor_at, _ = floors_over_time(rec, site)
            if floor_at is not None and rec.truth.floor is not None:
                out[PARTICLES].setdefault("floor_right", []).extend(
                    (floor_at(rec.truth.t) == rec.truth.floor).astype(int).tolist()
                )
    for a in paths:
        e = np.concatenate(out[a]["errors"]) if out[a]["errors"] else np.empty(0)
        out[a]["errors"] = _rounded(e)
    out["smooth_s_per_hour"] = round(smooth_s / walk_s * 3600.0, 3) if walk_s else None
    out["config"] = dataclasses.asdict(cfg if cfg is not None else fuse.config_for(run)[0])
    out["heading_prior"] = "where the recording's frame is north-referenced (wearnav.fuse.known_heading_deg)"
    return out


def ensure_calibration(
    run: str | Path,
    data: str | Path,
    split: str = "val",
    name: str = fuse.CALIBRATION_JSON,
    method: str = "wearnav.fuse.odometry_walk_sigma on the model's validation walks",
    speed: str = "model",
) -> dict:
    """The run's smoother calibration (:func:`calibrate` on its ``split`` walks of ``data``), computed
    once and stored in the run folder as ``name`` (`track` reads :data:`wearnav.fuse.CALIBRATION_JSON`);
    recomputed when the stored one came from other walks or predates the fixes' lag."""
    f = Path(run) / name
    if f.is_file():
        cal = read_json(f)
        if cal.get("data") == str(data) and cal.get("split") == split and "fix_lag_s" in cal:
            return cal
    cal = {**calibrate(run, data, split, speed), "data": str(data), "split": split, "method": method}
    runs.write_json(f, cal)
    return cal


def site_calibration(
    run: str | Path, site: str, site_data: str | Path, trained_on: str | Path | None, speed: str = "model"
) -> dict:
    """The calibration a run's smoother uses on ``site`` (stored as ``fuse_calibration_<site>.json``):
    a learned model on the building it trained in, from its own validation walks; anywhere else
    (another building, PDR), from the site's training walks, which it never trained on and which
    are not the held-out routes. A model's validation walks overstate it elsewhere: the shipped
    recipe's model calibrates to 0.017 m/√s on its mix, 0.56 on IPIN's walks and 0.83 on ILC2's.
    ``speed`` "pdr" (the PDR-speed hybrid) has its own calibration, ``..._pdr.json``."""
    name = f"fuse_calibration_{site}{'' if speed == 'model' else '_' + speed}.json"
    if trained_on is not None and Path(trained_on).resolve() == Path(site_data).resolve():
        return ensure_calibration(run, trained_on, "val", name, speed=speed)
    return ensure_calibration(
        run,
        site_data,
        "train",
        name,
        "wearnav.fuse.odometry_walk_sigma on the site's training walks (not trained on)",
        speed,
    )


def user_table(
    folders: dict[str, Path],
    data: str | Path,
    fixes: dict | None,
    split: str = "test",
    cfg: fuse.FuseConfig | None = None,
    calibration: dict[str, dict] | None = None,
    speeds: dict[str, str] | None = None,
    site: SiteModels | None = None,
) -> tuple[list[dict], dict]:
    """The user-protocol rows (raw fixes, then each model × anchoring) and the raw per-run results;
    ``cfg`` None: each run's own calibrated config, or ``calibration[label]`` where given;
    ``speeds[label]``: where that row's speed comes from (default the model's own)."""
    raw = {}
    rows = []
    if fixes:
        ratio = raw_fix_length_ratio(data, split)
        rows.append(
            {
                "path": RAW_FIXES,
                "traces": fixes["sequences"],
                "points": fixes["points"],
                **error_stats(np.asarray(fixes["point_errors"])),
                "length ratio": median_ratio(ratio),
                SIGMA_COLUMN: "—",
            }
        )
    for label, run in folders.items():
        speed = (speeds or {}).get(label, "model")
        r = raw[label] = user_protocol(run, data, split, cfg, (calibration or {}).get(label), speed, site)
        for anchor in (*fuse.ANCHORS, PARTICLES) if PARTICLES in r else fuse.ANCHORS:
            e = np.asarray(r[anchor]["errors"])
            inside = r[anchor].get("inside_68")
            floor = r[anchor].get("floor_right")
            rows.append(
                {
                    "path": f"{label} · {ANCHOR_LABEL[anchor]}",
                    **({FLOOR_COLUMN: round(float(np.mean(floor)), 3)} if floor else {}),
                    "traces": len(r[anchor]["length_ratio"]),
                    "points": int(e.size),
                    **error_stats(e),
                    "length ratio": median_ratio(r[anchor]["length_ratio"]),
                    SIGMA_COLUMN: round(float(np.mean(inside)), 2) if inside else "—",
                }
            )
    return rows, raw


PAIRED_TEXT = (
    "The smoother against each other path on the same walks: the difference of its median, p75 and p95 "
    "error from theirs (m; below 0: the smoother is better), and in brackets a 90 % interval from "
    "resampling whole walks (:func:`wearnav.stats.walk_bootstrap_difference`). An interval across 0 "
    "means these walks cannot tell the two apart at that quantile. Against the raw fixes, each side "
    "keeps its own points (the table's *points*: a surveyed point with no fix near it in time has no "
    "raw-fix error)."
)


def paired_rows(raw: dict) -> list[dict]:
    """Per model of :func:`user_table`'s ``raw``: the smoother minus the raw fixes, the first-fix
    anchoring and the rigid fit, paired by walk (:func:`wearnav.stats.walk_bootstrap_difference`)."""
    rows = []
    for label, r in raw.items():
        names = [n for n in r["smooth"]["by_trace"] if n in r.get(RAW_FIXES, {}).get("by_trace", {})]
        if len(names) < 2:
            continue
        smooth = [r["smooth"]["by_trace"][n] for n in names]
        for other, name in (
            (RAW_FIXES, RAW_FIXES),
            ("first-fixes", ANCHOR_LABEL["first-fixes"]),
            ("rigid", ANCHOR_LABEL["rigid"]),
        ):
            d = walk_bootstrap_difference(smooth, [r[other]["by_trace"][n] for n in names])
            rows.append(
                {
                    "model": label,
                    "smoother minus": name,
                    "walks": d["walks"],
                    **difference_cells(d),
                }
            )
    return rows


def _error_over_sigma(t: np.ndarray, res: fuse.FuseResult, truth) -> list[float]:
    """Per surveyed point (scored as :func:`score_path` does): the path's error over its σ there.
    Empty where the path has no σ."""
    if not np.isfinite(res.sigma_m).any():
        return []
    est = np.stack([res.xy[:, 0], res.xy[:, 1], res.sigma_m], axis=1)
    at, keep = interp_onto(truth.t[1:], t, est, max_gap=metrics.FIX_MAX_GAP_S, rule="nearest")
    err = np.linalg.norm(at[keep, :2] - truth.pos[1:, :2][keep], axis=1)
    return [float(v) for v in err / at[keep, 2]]


def _rounded(e) -> list[float]:
    return [round(float(x), 3) for x in np.asarray(e, float)]


SIGMA_COLUMN = "inside σ's 68 % radius"  # the share of points whose error is inside it (0.68 if σ is right)

ANCHOR_LABEL = {
    "first-fixes": "first-fix anchoring (`track` before)",
    "rigid": "rigid fit to all fixes",
    "smooth": "smoother (`track` now)",
    PARTICLES: PARTICLES_LABEL,
}
FLOOR_COLUMN = "floor right"  # the particle filter's share of surveyed points on the right floor (barometer)


def particle_paired_rows(raw: dict) -> list[dict]:
    """Per model with a particle-filter path: it minus the raw fixes and minus the smoother, paired
    by walk (:func:`wearnav.stats.walk_bootstrap_difference`)."""
    rows = []
    for label, r in raw.items():
        if PARTICLES not in r:
            continue
        for other, name in ((RAW_FIXES, RAW_FIXES), ("smooth", ANCHOR_LABEL["smooth"])):
            names = [n for n in r[PARTICLES]["by_trace"] if n in r.get(other, {}).get("by_trace", {})]
            if len(names) < 2:
                continue
            d = walk_bootstrap_difference(
                [r[PARTICLES]["by_trace"][n] for n in names], [r[other]["by_trace"][n] for n in names]
            )
            rows.append(
                {
                    "model": label,
                    "particle filter minus": name,
                    "walks": d["walks"],
                    **difference_cells(d),
                }
            )
    return rows


def median_ratio(x) -> float:
    """The median of per-walk ratios, NaN ones left out (NaN if none is finite)."""
    x = np.asarray(x, float)
    return round(float(np.nanmedian(x)), 3) if np.isfinite(x).any() else float("nan")


def error_stats(e: np.ndarray) -> dict:
    """Median, p75, p95 and mean (m) of errors (NaN for none)."""
    if e.size == 0:
        return {k: float("nan") for k in ("median (m)", "p75 (m)", "p95 (m)", "mean (m)")}
    return {
        "median (m)": float(np.median(e)),
        "p75 (m)": float(np.percentile(e, 75)),
        "p95 (m)": float(np.percentile(e, 95)),
        "mean (m)": float(e.mean()),
    }


def raw_fix_length_ratio(data: str | Path, split: str = "test") -> list[float]:
    """The path-length ratio of the raw fixes (the latest fix at each surveyed point) per trace."""
    out = []
    view = Dataset.open(data).split(split)
    for name in view.names:
        rec = view.load(name)
        if rec.fixes is None or rec.truth is None or len(rec.fixes) < 2:
            continue
        _, ratio = score_path(rec.fixes.t, rec.fixes.pos[:, :2], rec.truth.t, rec.truth.pos[:, :2])
        out.append(ratio)
    return out


__all__ = [
    "ensure_calibration",
    "site_calibration",
    "calibrate",
    "calibration_of",
    "user_protocol",
    "user_table",
    "score_path",
    "raw_fix_length_ratio",
    "RAW_FIXES",
    "fix_point_errors",
    "paired_rows",
    "PAIRED_TEXT",
    "error_stats",
    "median_ratio",
]
