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
"""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path

import numpy as np

from wearnav import fuse, metrics, pretrained, runs
from wearnav.dataset import Dataset
from wearnav.errors import ConfigError
from wearnav.evaluate import predict_sequence
from wearnav.fileio import write_text_atomic
from wearnav.fuse.live import IncrementalFuser
from wearnav.models.registry import build
from wearnav.provenance import provenance
from wearnav.preprocess import SURVEYED_TRUTH_MAX_GAP_S, align, load_sequences
from wearnav.simulate.config import MODES, WalkConfig
from wearnav.simulate.walk import simulate_recording
from wearnav.stats import walk_bootstrap_difference
from wearnav.train.odometry import load_model
from wearnav.train.resolve import resolve_model
from wearnav.textio import read_json
from wearnav.timeseries import interp_onto
from wearnav.trajectory import integrate_velocity

log = logging.getLogger(__name__)

RAW_FIXES = "raw phone fixes"


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


def fix_point_errors(rec) -> np.ndarray:
    """The raw fixes' error (m) at the recording's surveyed points from the second on: the latest
    fix within :data:`wearnav.metrics.FIX_MAX_GAP_S` (NaN where none is)."""
    return metrics.errors_at_reference(rec.fixes.t, rec.fixes.pos[:, :2], rec.truth.t[1:], rec.truth.pos[1:, :2],
                                       metrics.FIX_MAX_GAP_S)


def _paths(run, data, split):
    """(recording, t, path from (0, 0) in the phone's world frame, no yaw) per trace of ``split``."""
    model, tcfg = load_model(run)
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


def calibrate(run: str | Path, data: str | Path, split: str = "val") -> dict:
    """The smoother's calibration for the run's model on the ``split`` walks of ``data``
    (:func:`calibration_of`)."""
    return calibration_of(_paths(run, data, split))


SIM_POINT_EVERY_S = 5.0  # the simulator's dense truth, thinned to a point this often to calibrate on


def calibration_of(walks, every_s: float | None = None) -> dict:
    """The smoother's calibration from ``walks`` (recording, t, odometry xy from (0, 0)) with truth:
    the odometry's random walk (:func:`wearnav.fuse.odometry_walk_sigma`, at the truth points, or
    one every ``every_s`` seconds of a dense truth), then, smoothing the walks that have fixes with
    it, the σ scale (:func:`wearnav.fuse.sigma_scale_of`; None without fixes)."""
    walks = list(walks)

    def points(truth):
        if not every_s:
            return truth.t, truth.pos[:, :2]
        k = np.unique(np.searchsorted(truth.t, np.arange(truth.t[0], truth.t[-1], every_s)))
        return truth.t[k], truth.pos[k, :2]

    cal = fuse.odometry_walk_sigma((t, xy, *points(rec.truth)) for rec, t, xy in walks)
    ratios = []
    for rec, t, xy in walks:
        if cal["odometry_walk_m_per_sqrt_s"] and rec.fixes is not None and len(rec.fixes) >= 2:
            c = fuse.calibrated(fuse.config_for(None, rec.meta, "phone")[0], cal)
            res = fuse.smooth(t, xy, rec.fixes.t, rec.fixes.pos[:, :2], rec.fixes.accuracy, c)
            ratios.extend(_error_over_sigma(t, res, rec.truth))
    return {**cal, **fuse.sigma_scale_of(ratios)}


def user_protocol(run: str | Path, data: str | Path, split: str = "test",
                  cfg: fuse.FuseConfig | None = None, calibration: dict | None = None) -> dict:
    """Per anchoring of :data:`wearnav.fuse.ANCHORS`: the errors at the surveyed points of
    ``split`` of ``data`` for the model of ``run`` (a run folder) under the user protocol, the
    path-length ratio per trace, what the smoother found per trace and its seconds per hour of walk.
    ``cfg``: the smoother's; default the run's own for each recording (:func:`wearnav.fuse.config_for`:
    its calibration, and a heading prior where the recording's frame is north-referenced); ``calibration``
    replaces its calibration (:func:`site_calibration`)."""
    out: dict = {a: {"errors": [], "length_ratio": [], "by_trace": {}} for a in fuse.ANCHORS}
    out["smooth"]["traces"] = {}
    out[RAW_FIXES] = {"by_trace": {}}
    smooth_s, walk_s = 0.0, 0.0
    for rec, t, xy in _paths(run, data, split):
        if rec.fixes is None or len(rec.fixes) == 0:
            continue
        fx = rec.fixes
        out[RAW_FIXES]["by_trace"][rec.name] = _rounded(fix_point_errors(rec))
        c = fuse.calibrated(cfg if cfg is not None else fuse.config_for(run, rec.meta, "phone")[0], calibration)
        for anchor, fn in fuse.ANCHORS.items():
            t0 = time.perf_counter()
            res = fn(t, xy, fx.t, fx.pos[:, :2], fx.accuracy) if anchor != "smooth" else \
                fuse.smooth(t, xy, fx.t, fx.pos[:, :2], fx.accuracy, c)
            if anchor == "smooth":
                smooth_s += time.perf_counter() - t0
                walk_s += float(t[-1] - t[0])
                out["smooth"].setdefault("inside_68", []).extend(
                    bool(z < fuse.RADIUS_68) for z in _error_over_sigma(t, res, rec.truth))
                out["smooth"]["traces"][rec.name] = {
                    "method": res.method, "warnings": res.warnings,
                    **{k: v for k, v in res.info.items() if k not in ("x", "config", "smoother")}}
            err, ratio = score_path(t, res.xy, rec.truth.t, rec.truth.pos[:, :2])
            out[anchor]["errors"].append(err)
            out[anchor]["by_trace"][rec.name] = _rounded(err)
            out[anchor]["length_ratio"].append(ratio)
    for a in fuse.ANCHORS:
        e = np.concatenate(out[a]["errors"]) if out[a]["errors"] else np.empty(0)
        out[a]["errors"] = _rounded(e)
    out["smooth_s_per_hour"] = round(smooth_s / walk_s * 3600.0, 3) if walk_s else None
    out["config"] = dataclasses.asdict(cfg if cfg is not None else fuse.config_for(run)[0])
    out["heading_prior"] = "where the recording's frame is north-referenced (wearnav.fuse.known_heading_deg)"
    return out


def ensure_calibration(run: str | Path, data: str | Path, split: str = "val", name: str = fuse.CALIBRATION_JSON,
                       method: str = "wearnav.fuse.odometry_walk_sigma on the model's validation walks") -> dict:
    """The run's smoother calibration (:func:`calibrate` on its ``split`` walks of ``data``), computed
    once and stored in the run folder as ``name`` (`track` reads :data:`wearnav.fuse.CALIBRATION_JSON`);
    recomputed when the stored one came from other walks or predates the σ scale."""
    f = Path(run) / name
    if f.is_file():
        cal = read_json(f)
        if cal.get("data") == str(data) and cal.get("split") == split and "sigma_scale" in cal:
            return cal
    cal = {**calibrate(run, data, split), "data": str(data), "split": split, "method": method}
    runs.write_json(f, cal)
    return cal


def site_calibration(run: str | Path, site: str, site_data: str | Path, trained_on: str | Path | None) -> dict:
    """The calibration a run's smoother uses on ``site`` (stored as ``fuse_calibration_<site>.json``):
    a learned model on the building it trained in, from its own validation walks; anywhere else
    (another building, PDR), from the site's training walks, which it never trained on and which
    are not the held-out routes. A model's validation walks overstate it elsewhere: the shipped
    recipe's model calibrates to 0.017 m/√s on its mix, 0.56 on IPIN's walks and 0.83 on ILC2's."""
    if trained_on is not None and Path(trained_on).resolve() == Path(site_data).resolve():
        return ensure_calibration(run, trained_on, "val", f"fuse_calibration_{site}.json")
    return ensure_calibration(run, site_data, "train", f"fuse_calibration_{site}.json",
                              "wearnav.fuse.odometry_walk_sigma on the site's training walks (not trained on)")


def user_table(folders: dict[str, Path], data: str | Path, fixes: dict | None, split: str = "test",
               cfg: fuse.FuseConfig | None = None, calibration: dict[str, dict] | None = None) -> tuple[list[dict], dict]:
    """The user-protocol rows (raw fixes, then each model × anchoring) and the raw per-run results;
    ``cfg`` None: each run's own calibrated config, or ``calibration[label]`` where given."""
    raw = {}
    rows = []
    if fixes:
        ratio = raw_fix_length_ratio(data, split)
        rows.append({"path": RAW_FIXES, "traces": fixes["sequences"], "points": fixes["points"],
                     **_stats(np.asarray(fixes["point_errors"])), "length ratio": _median(ratio), SIGMA_COLUMN: "—"})
    for label, run in folders.items():
        r = raw[label] = user_protocol(run, data, split, cfg, (calibration or {}).get(label))
        for anchor in fuse.ANCHORS:
            e = np.asarray(r[anchor]["errors"])
            inside = r[anchor].get("inside_68")
            rows.append({"path": f"{label} · {ANCHOR_LABEL[anchor]}", "traces": len(r[anchor]["length_ratio"]),
                         "points": int(e.size), **_stats(e), "length ratio": _median(r[anchor]["length_ratio"]),
                         SIGMA_COLUMN: round(float(np.mean(inside)), 2) if inside else "—"})
    return rows, raw


PAIRED_TEXT = (
    "The smoother against each other path on the same walks: the difference of its median, p75 and p95 "
    "error from theirs (m; below 0: the smoother is better), and in brackets a 90 % interval from "
    "resampling whole walks (:func:`wearnav.stats.walk_bootstrap_difference`). An interval across 0 "
    "means these walks cannot tell the two apart at that quantile. Against the raw fixes, each side "
    "keeps its own points (the table's *points*: a surveyed point with no fix near it in time has no "
    "raw-fix error).")


def paired_rows(raw: dict) -> list[dict]:
    """Per model of :func:`user_table`'s ``raw``: the smoother minus the raw fixes, the first-fix
    anchoring and the rigid fit, paired by walk (:func:`wearnav.stats.walk_bootstrap_difference`)."""
    rows = []
    for label, r in raw.items():
        names = [n for n in r["smooth"]["by_trace"] if n in r.get(RAW_FIXES, {}).get("by_trace", {})]
        if len(names) < 2:
            continue
        smooth = [r["smooth"]["by_trace"][n] for n in names]
        for other, name in ((RAW_FIXES, RAW_FIXES), ("first-fixes", ANCHOR_LABEL["first-fixes"]),
                            ("rigid", ANCHOR_LABEL["rigid"])):
            d = walk_bootstrap_difference(smooth, [r[other]["by_trace"][n] for n in names])
            rows.append({"model": label, "smoother minus": name, "walks": d["walks"],
                         **{f"{'median' if q == 50 else f'p{q}'} (m)": f"{p:+.2f} [{lo:+.2f}, {hi:+.2f}]"
                            for q, p, lo, hi in zip(d["quantiles"], d["difference"], d["low"], d["high"])}})
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

ANCHOR_LABEL = {"first-fixes": "first-fix anchoring (`track` before)", "rigid": "rigid fit to all fixes",
                "smooth": "smoother (`track` now)"}


def _median(x) -> float:
    x = np.asarray(x, float)
    return round(float(np.nanmedian(x)), 3) if np.isfinite(x).any() else float("nan")


def _stats(e: np.ndarray) -> dict:
    if e.size == 0:
        return {k: float("nan") for k in ("median (m)", "p75 (m)", "p95 (m)", "mean (m)")}
    return {"median (m)": float(np.median(e)), "p75 (m)": float(np.percentile(e, 75)),
            "p95 (m)": float(np.percentile(e, 95)), "mean (m)": float(e.mean())}


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


ODO_ORACLE = "odometry alone (oracle rigid fit to truth)"
ODO_FIRST = "odometry alone (first-fix anchoring)"
FIXES_ALONE = "fixes alone"
SMOOTHER = "smoother"
SIM_PATHS = (ODO_ORACLE, ODO_FIRST, FIXES_ALONE, SMOOTHER)


def _untrained(model: str):
    """The fusion benches' odometry by name, phone only, in the phone's own world frame, and its
    config: an untrained baseline (PDR), a shipped model (``phone``) or a phone-only run folder."""
    arg = pretrained.model_path(model, "odometry")
    net, tcfg = resolve_model(arg, "odometry")  # a learned model by name is refused: shipped or a folder only
    if not Path(str(arg)).exists():
        tcfg = dataclasses.replace(tcfg, devices=("phone",))
        net = build_untrained(model, tcfg)
    elif tuple(tcfg.devices) != ("phone",):
        raise ConfigError(f"the fusion bench runs the phone alone; {model} uses {', '.join(tcfg.devices)}")
    return net, dataclasses.replace(tcfg, frame_align="none", yaw_deg=0.0)


def _odometry_words(model: str) -> str:
    """How a page names the odometry of :func:`_untrained`."""
    arg = pretrained.model_path(model, "odometry")
    if not Path(str(arg)).exists():
        return f"untrained `{model}`"
    name = pretrained.shipped_name(arg)
    return f"the shipped model `{name}`" if name else f"the model of run `{arg}`"


def _odometry(rec, net, tcfg) -> tuple[np.ndarray, np.ndarray]:
    """``net``'s path of one recording (from (0, 0) in the phone's world frame) at its aligned times."""
    seq = align(rec, tcfg.preprocess_config())
    t_c, vel, _ = predict_sequence(net, seq, tcfg.window, tcfg.stride)
    t = seq.t[(seq.t >= t_c[0]) & (seq.t <= t_c[-1])]
    return t, integrate_velocity(t_c, vel, t, np.zeros(2))


def simulated_errors(rec, net, tcfg, cfg: fuse.FuseConfig = fuse.FuseConfig()) -> tuple[dict, float, float]:
    """For one simulated recording (dense truth and fixes): the errors (m) against truth at 1-s
    samples per path of :data:`SIM_PATHS`, the smoother's seconds and the walk's seconds. The
    odometry is ``net`` (phone only, from (0, 0) in the phone's world frame); ``odometry alone``
    is given its best rotation + translation onto the *truth* over the whole walk (an oracle no
    user has, so a generous bound for it) and, as a user gets it, first-fix anchoring; the fixes
    alone are linear between fixes."""

    t, xy = _odometry(rec, net, tcfg)
    tt = np.arange(t[0], t[-1], 1.0)
    truth = np.stack([np.interp(tt, rec.truth.t, rec.truth.pos[:, j]) for j in range(2)], axis=1)
    fx = rec.fixes
    odo = fuse.rigid_anchor(t, xy, tt, truth, np.full(tt.size, 1.0)).xy
    first = fuse.first_fix_anchor(t, xy, fx.t, fx.pos[:, :2], fx.accuracy).xy
    t0 = time.perf_counter()
    sm = fuse.smooth(t, xy, fx.t, fx.pos[:, :2], fx.accuracy, cfg).xy
    smooth_s = time.perf_counter() - t0
    fixes_at = np.stack([np.interp(tt, fx.t, fx.pos[:, j]) for j in range(2)], axis=1)
    errs = {}
    for label, path_t, path in ((ODO_ORACLE, t, odo), (ODO_FIRST, t, first), (SMOOTHER, t, sm),
                                (FIXES_ALONE, tt, fixes_at)):
        at = np.stack([np.interp(tt, path_t, path[:, j]) for j in range(2)], axis=1)
        errs[label] = np.linalg.norm(at - truth, axis=1)
    return errs, smooth_s, float(t[-1] - t[0])


def simulator_rows(model: str = "pdr", duration_s: float = 300.0, walks_per_mode: int = 2,
                   noise_level: str = "L3", seed: int = 0, cfg: fuse.FuseConfig = fuse.FuseConfig(),
                   modes: tuple[str, ...] | None = None) -> list[dict]:
    """:func:`simulated_errors` per walking mode on walks simulated here (``walks_per_mode`` of
    ``duration_s`` each; the simulator's correlated fix error with multipath jumps,
    :mod:`wearnav.simulate.fixes`); ``modes`` (default: all) the walking modes."""

    net, tcfg = _untrained(model)
    rows = []
    for mode in modes or MODES:
        errs: dict[str, list] = {p: [] for p in SIM_PATHS}
        for k in range(walks_per_mode):
            placement = "MP" if mode in ("PVW", "MVW") else "HD"
            rec = simulate_recording(WalkConfig(name=f"{mode}_{k}", mode=mode, placement=placement, duration_s=duration_s,
                                                noise_level=noise_level), seed=seed + 1000 * k + MODES.index(mode))
            for label, e in simulated_errors(rec, net, tcfg, cfg)[0].items():
                errs[label].append(e)
        for label in SIM_PATHS:
            rows.append({"mode": mode, "path": label, "walks": walks_per_mode, **_stats(np.concatenate(errs[label]))})
    return rows


def fusion_table(data: str | Path, model: str = "pdr", split: str | None = None,
                 cfg: fuse.FuseConfig | None = None) -> dict:
    """:func:`simulated_errors` over the recordings of a simulated dataset (``split``: one split, or
    all but the training walks), per walking mode (the manifest's ``mode``) and over all: rows of
    median / p75 / p95 / mean error (m) per path, and the smoother's seconds per hour of walk.
    ``cfg`` None: the smoother calibrated where it is used, as on a real site
    (:func:`calibration_of` on the dataset's training walks, never scored); the defaults where it
    has none. Recordings without truth or with fewer than two fixes are skipped and counted."""
    ds = Dataset.open(data)
    net, tcfg = _untrained(model)
    splits = sorted(set(ds.manifest["split"]))
    calibration = None
    if cfg is None:
        if "train" in splits and split != "train":
            train = ds.split("train")
            calibration = calibration_of(((rec, *_odometry(rec, net, tcfg)) for rec in map(train.load, train.names)
                                          if rec.truth is not None), SIM_POINT_EVERY_S)
            splits.remove("train")
        cfg = fuse.calibrated(fuse.FuseConfig(), calibration)
    view = ds.split(split) if split else ds.split(*splits)
    per_mode: dict[str, dict[str, list]] = {}
    smooth_s = walk_s = 0.0
    skipped = 0
    for name in view.names:
        rec = view.load(name)
        if rec.truth is None or rec.fixes is None or len(rec.fixes) < 2:
            skipped += 1
            continue
        errs, s, w = simulated_errors(rec, net, tcfg, cfg)
        smooth_s, walk_s = smooth_s + s, walk_s + w
        mode = str(rec.meta.get("mode", "?"))
        for label, e in errs.items():
            per_mode.setdefault(mode, {p: [] for p in SIM_PATHS})[label].append(e)
    rows = []
    for mode in sorted(per_mode) + (["all"] if per_mode else []):
        groups = [per_mode[mode]] if mode != "all" else list(per_mode.values())
        for label in SIM_PATHS:
            e = np.concatenate([x for g in groups for x in g[label]])
            rows.append({"mode": mode, "path": label, "walks": sum(len(g[label]) for g in groups),
                         "samples": int(e.size), **{k: round(v, 2) for k, v in _stats(e).items()}})
    prov = ds.provenance
    preset = prov.get("preset")
    return {"rows": rows, "model": model, "split": split or ", ".join(splits), "skipped": skipped, "calibration": calibration,
            "simulator": {"preset": preset.get("name") if isinstance(preset, dict) else preset, "seed": prov.get("seed")},
            "walk_s": round(walk_s, 1), "smooth_s": round(smooth_s, 3),
            "smooth_s_per_hour": round(smooth_s / walk_s * 3600.0, 3) if walk_s else None,
            "config": dataclasses.asdict(cfg)}


def _live_lines(live: dict) -> list[str]:
    return ["## The live receiver's smoother (fixed lag)", "",
            f"One simulated standard walk of {live['walk_min']} min (odometry at {live['odometry_hz']} Hz, "
            f"{live['fixes']} fixes), fed to `wearnav.fuse.live.IncrementalFuser` ({live['lag_s']:g}-s window) in time "
            f"order and solved every {live['every_s']:g} s: {live['updates']} updates, "
            f"**{live['ms_per_update_median']} ms per update** (median; p95 {live['ms_per_update_p95']} ms; "
            f"{live['ms_first_tenth_median']} ms in the walk's first tenth after the first window, "
            f"{live['ms_last_tenth_median']} ms in its last; solver evaluations per update "
            f"{live['solver_evaluations_first_tenth']} and {live['solver_evaluations_last_tenth']}), where the batch smoother over the whole walk took "
            f"{live['batch_s']} s. Its final path lies {live['gap_to_batch_median_m']} m (median; p95 "
            f"{live['gap_to_batch_p95_m']} m) from the batch smoother's; median error against truth "
            f"{live['live_error_median_m']} m (batch {live['batch_error_median_m']} m).", ""]


def fixed_lag_run(rec, net, tcfg, cfg: fuse.FuseConfig = fuse.FuseConfig(), lag_s: float = 300.0,
                  every_s: float = 10.0) -> dict:
    """The live receiver's smoother (:class:`wearnav.fuse.live.IncrementalFuser`) on one simulated
    recording: odometry and fixes fed in time order, the path asked for every ``every_s`` seconds.
    Returns the seconds per update (median, p95, and the medians over the first tenth after the
    first window and over the last tenth: equal when the cost does not grow with the walk), and
    the final path's median / p95 distance from the batch smoother's and both errors against truth."""

    t, xy = _odometry(rec, net, tcfg)
    fx = rec.fixes
    order = np.argsort(fx.t, kind="stable")
    ft, fp, acc = fx.t[order], fx.pos[order, :2], fx.accuracy[order]
    inc = IncrementalFuser(cfg, lag_s=lag_s)
    times, evals, fi, next_s = [], [], 0, t[0] + every_s
    for k in range(t.size):
        inc.add_odometry(t[k], xy[k])
        while fi < ft.size and ft[fi] <= t[k]:
            inc.add_fix(ft[fi], fp[fi, 0], fp[fi, 1], acc[fi])
            fi += 1
        if t[k] >= next_s or k == t.size - 1:
            next_s += every_s
            t0 = time.perf_counter()
            live = inc.result()
            times.append(time.perf_counter() - t0)
            evals.append(live.info.get("solver_evaluations", 0))
    t0 = time.perf_counter()
    batch = fuse.smooth(t, xy, ft, fp, acc, cfg)
    batch_s = time.perf_counter() - t0
    truth = np.stack([np.interp(t, rec.truth.t, rec.truth.pos[:, j]) for j in range(2)], axis=1)
    gap = np.linalg.norm(live.xy - batch.xy, axis=1)
    e_live, e_batch = np.linalg.norm(live.xy - truth, axis=1), np.linalg.norm(batch.xy - truth, axis=1)
    ms = np.asarray(times) * 1e3
    tenth = max(1, ms.size // 10)
    i0 = min(ms.size - 1, int(lag_s // every_s) + 1)
    first, ev = ms[i0:][:tenth], np.asarray(evals, float)
    return {"walk_min": round(float(t[-1] - t[0]) / 60.0, 1), "odometry_hz": round(float((t.size - 1) / (t[-1] - t[0])), 1),
            "fixes": int(ft.size), "lag_s": lag_s, "every_s": every_s, "updates": int(ms.size), "method": live.method,
            "ms_per_update_median": round(float(np.median(ms)), 1), "ms_per_update_p95": round(float(np.percentile(ms, 95)), 1),
            "ms_first_tenth_median": round(float(np.median(first)), 1), "ms_last_tenth_median": round(float(np.median(ms[-tenth:])), 1),
            "solver_evaluations_first_tenth": round(float(np.mean(ev[i0:][:tenth])), 1),
            "solver_evaluations_last_tenth": round(float(np.mean(ev[-tenth:])), 1),
            "batch_s": round(batch_s, 3),
            "gap_to_batch_median_m": round(float(np.median(gap)), 2), "gap_to_batch_p95_m": round(float(np.percentile(gap, 95)), 2),
            "live_error_median_m": round(float(np.median(e_live)), 2), "batch_error_median_m": round(float(np.median(e_batch)), 2)}


def live_walk(minutes: float, model: str = "pdr", seed: int = 0, cfg: fuse.FuseConfig = fuse.FuseConfig()) -> dict:
    """:func:`fixed_lag_run` on one simulated standard walk of ``minutes`` (the simulator's fixes)."""

    net, tcfg = _untrained(model)
    rec = simulate_recording(WalkConfig(name="live", mode="STW", placement="HD", duration_s=60.0 * minutes), seed=seed)
    return fixed_lag_run(rec, net, tcfg, cfg)


def write_fusion_page(table: dict, data: str | Path, out: str | Path, live: dict | None = None) -> Path:
    """results.md + results.json in ``out`` for :func:`fusion_table`'s ``table`` (and
    :func:`live_walk`'s result, where given)."""
    import os
    import platform

    import pandas as pd


    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runs.write_json(out / "results.json", {**table, "data": str(data), "live": live})
    p = provenance()
    df = pd.DataFrame(table["rows"])
    wide = df.pivot_table(index="mode", columns="path", values="median (m)", sort=False)[list(SIM_PATHS)]
    overall = df[df["mode"] == "all"].drop(columns=["mode"])
    cpu = platform.processor() or platform.machine()
    lines = ["# Fusion on the simulator: odometry, fixes and the smoother"
             + (f" (odometry `{table['model']}`)" if table["model"] != "pdr" else ""), "",
             f"Generated by `wearnav bench fusion` ({p['created']}, wearnav {p['wearnav']} {p['commit']}) on "
             f"`{Path(data).name}` ({table['split']} recordings; {table['walk_s'] / 60:.1f} min of walk"
             + (f", {table['skipped']} skipped: no truth or fewer than two fixes" if table["skipped"] else "")
             + (f"; simulator preset `{sim['preset']}`, seed {sim['seed']}" if (sim := table["simulator"])["seed"] is not None else "")
             + "); "
             f"{cpu}, {os.cpu_count()} CPUs, one process. "
             f"Odometry: {_odometry_words(table['model'])}, phone only, integrated from (0, 0) in the phone's world frame. "
             "Errors are against the simulator's dense truth at 1-s samples. "
             f"*{ODO_ORACLE}*: the odometry given its best rotation + translation onto the truth over the "
             "whole walk (an oracle no user has, so a generous bound); "
             f"*{ODO_FIRST}*: placed on the first minute's fixes, as `track --anchor first-fixes`; "
             f"*{FIXES_ALONE}*: the simulated phone fixes (correlated error, multipath jumps), linear between fixes; "
             f"*{SMOOTHER}*: `wearnav.fuse.smooth`, as `track` gives it (no truth used), "
             + (f"its odometry random walk ({cal['odometry_walk_m_per_sqrt_s']} m/√s) and σ scale "
                f"({cal['sigma_scale']}) calibrated on the dataset's training walks ({cal['walks']}), which are "
                "not scored (`wearnav.bench.user_protocol.calibration_of`)."
                if (cal := table.get("calibration")) else "with its default settings (no training walks to calibrate on)."),
             "",
             "## Every walk (m)", "",
             overall.to_markdown(index=False, floatfmt=".2f"), "",
             f"The smoother took {table['smooth_s']:.2f} s for {table['walk_s'] / 60:.1f} min of walk: "
             f"**{table['smooth_s_per_hour']} s per hour of walk** (one process; the machine is shared).", "",
             *(_live_lines(live) if live else []),
             "## Median error per walking mode (m)", "",
             wide.to_markdown(floatfmt=".2f"), "",
             "## Every statistic", "",
             df.to_markdown(index=False, floatfmt=".2f"), ""]
    return write_text_atomic("\n".join(lines), out / "results.md")


def build_untrained(model: str, tcfg):
    """An untrained baseline (PDR) for phone-only input at the config's window and rate."""

    return build(model, n_devices=len(tcfg.devices), window=tcfg.window, rate=tcfg.rate).eval()


__all__ = ["ensure_calibration", "site_calibration", "calibrate", "simulator_rows", "fusion_table", "write_fusion_page", "simulated_errors", "user_protocol", "user_table", "score_path", "raw_fix_length_ratio", "RAW_FIXES",
           "fix_point_errors", "paired_rows", "PAIRED_TEXT", "calibration_of"]
