"""Whether to trust a tracked path (`wearnav track`, and the live receiver as a session arrives):
one line per reason not to, each with what to do, from :mod:`wearnav.trust`'s findings: devices
the recording lacks, a rate / placement / gravity direction unlike the model's training data, a
model that did not beat standing still (:func:`input_warnings`), a result implausible for
walking (:func:`walk_warnings`), and an odometry that walks far less than the fixes and the
activity model say (:func:`distance_warnings`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from wearnav import activity_labels, runs, trust
from wearnav.core.textio import read_json
from wearnav.errors import ConfigError, FormatError
from wearnav.evaluate import predict_sequence
from wearnav.export.header import is_exported, read_header
from wearnav.fixcheck import check_fixes, filled_accuracy
from wearnav.fuse.config import FuseConfig
from wearnav.models import registry
from wearnav.models.pdr import PDR
from wearnav.recording import Recording
from wearnav.train.odometry import TRAINING


def run_training_record(model_path: str | Path) -> dict:
    """The run's ``training.json`` for a run folder or its checkpoint, or the copy an exported model
    file carries in its header; ``{}`` where it has none or cannot be read (the warnings then say
    that the training data is unknown: tracking goes on)."""
    p = Path(model_path)
    if is_exported(p):
        record = read_header(p).get("training")
        return record if isinstance(record, dict) else {}
    run = runs.run_folder(p)
    try:
        record = read_json(run / TRAINING) if (run / TRAINING).is_file() else {}
    except FormatError:
        return {}
    return record if isinstance(record, dict) else {}


def input_warnings(model_path, cfg, rec: Recording) -> list[str]:
    """The reasons not to trust a path that the input alone gives (one line each, with what to do),
    for learned models only (an untrained baseline such as PDR has no training data, and uses the
    first device the recording has): devices the recording lacks, a rate / placement / gravity
    direction unlike the training data's (a rate only where the recording is slower than the
    model's, :func:`wearnav.trust.rate_outside`), or a model that did not beat standing still. The live receiver
    gives these as the session's first half minute arrives (:mod:`wearnav.live.tracker`)."""
    out: list[str] = []
    if not registry.get(cfg.model).learned:  # PDR: no training data, any one device will do
        return out
    if (m := trust.missing_devices(cfg.devices, rec.devices)) is not None:
        out.append(f"{m}: {trust.TRACK_DEVICES_ADVICE}")
    record = run_training_record(model_path)
    facts = trust.recording_facts(rec, cfg.devices, cfg.window / cfg.rate)
    known = record.get("training_data")
    known = known if isinstance(known, dict) else None
    out += [f"{f}: {trust.TRACK_DOMAIN_ADVICE}" for f in trust.domain_findings(facts, known, cfg.rate)]
    if (m := trust.did_not_learn(record)) is not None:
        out.append(f"{m}: {trust.LEARN_ADVICE}")
    return out


def walk_warnings(cfg, seq, vel: np.ndarray, length_m: float) -> list[str]:
    """A result implausible for walking: PDR's step detector on the same windows as the model's
    velocities ``vel`` over the whole walk of ``length_m`` (none where the window is too short for
    PDR)."""
    try:
        pdr = PDR(n_devices=len(cfg.devices), window=cfg.window, rate=cfg.rate)
    except ConfigError:  # a window too short for PDR's step detector: no walking check
        return []
    _, pdr_vel, _ = predict_sequence(pdr, seq, cfg.window, cfg.stride)
    step_rate_hz = np.linalg.norm(pdr_vel, axis=1) / pdr.step_length
    steps = float(np.sum(step_rate_hz) * cfg.stride / cfg.rate)  # windows tile time at the stride
    findings = trust.implausible_walk(np.linalg.norm(vel, axis=1), step_rate_hz, length_m, steps)
    return [f"{f}: {trust.TRACK_RESULT_ADVICE}" for f in findings]


# ---- does the odometry walk as far as the fixes and the activity say? (issue 56 §6) ----------

# A gentle walker's steps went undetected (band-passed peaks of 0.31 m/s² against PDR's 0.6): the
# odometry walked 5.2 m where the fixes moved ~135 m, the smoother's fix bias made up the rest, and
# the path was shown as inertial without a word. Warn where the odometry's path is shorter than the
# distance the fixes move, or than the activity model's walking time × WALK_SPEED_M_S, by more than
# DISTANCE_FACTOR and by more than DISTANCE_MIN_M (a short walk's fixes wander by metres). Only that
# way: indoors a phone's fixes stall while the walker goes on (IPIN 2023's 43 walks with fixes,
# tracked by the shipped phone model: the fixes move 0.27–1.36 times the odometry's length, median
# 0.54), so fixes shorter than the odometry are normal. The factor leaves room above the normal walks'
# ratios: fixes / odometry at most 1.36 there; walking time × 1 m/s / odometry at most 1.35 on IPIN's
# 44 walks and 1.21 on ILC2's first 58 traces (2.9 on one 0.8 s trace, below DISTANCE_MIN_M).
DISTANCE_FACTOR = 2.5
DISTANCE_MIN_M = 25.0
FIX_SMOOTH_S = 10.0  # s: the fixes averaged with a Gaussian of σ half this, sampled this often
WALK_SPEED_M_S = 1.0  # the activity model's walking seconds times this: the distance walked (m)
ON_FOOT = (activity_labels.WALKING, activity_labels.STAIRS_UP, activity_labels.STAIRS_DOWN)
DISTANCE_ADVICE = (
    "the path drawn is then mostly the fixes, not the motion sensors: compare `--model pdr`, or check "
    "that the phone was carried while walking"
)


def fixes_length_m(rec: Recording, t0: float, t1: float) -> float | None:
    """How far the recording's location fixes move between ``t0`` and ``t1`` s (m): the fixes that
    :func:`wearnav.fixcheck.check_fixes` keeps, averaged with a Gaussian kernel (σ half of
    :data:`FIX_SMOOTH_S`, weights 1/accuracy²) at every FIX_SMOOTH_S seconds, and the length of the
    polyline through those averages; None with fewer than 3 kept fixes or under 2 such points."""
    fx = rec.fixes
    if fx is None or len(fx.t) < 3:
        return None
    check = check_fixes(t0, t1, fx.t, fx.pos[:, :2], fx.accuracy, FuseConfig().wide_m)
    keep = check.kept
    if keep.sum() < 3:
        return None
    ft, fp = fx.t[keep], fx.pos[keep, :2].astype(np.float64)
    w_acc = 1.0 / filled_accuracy(fx.accuracy[keep]) ** 2
    grid = np.arange(ft[0], ft[-1] + 1e-9, FIX_SMOOTH_S)
    if len(grid) < 2:
        return None
    w = np.exp(-0.5 * ((grid[:, None] - ft[None, :]) / (FIX_SMOOTH_S / 2)) ** 2) * w_acc[None, :]
    mean = (w @ fp) / np.maximum(w.sum(axis=1, keepdims=True), 1e-300)
    return float(np.sum(np.linalg.norm(np.diff(mean, axis=0), axis=1)))


def walking_seconds(rows: list[dict] | None, t0: float, t1: float) -> float | None:
    """Seconds between ``t0`` and ``t1`` that the activity intervals ``rows`` label on foot
    (:data:`ON_FOOT`; the rows of :func:`wearnav.report.trajectory_page.activity_intervals`, as
    `wearnav classify` finds them); None where there are none (no model, no phone, too short)."""
    if rows is None:
        return None
    return float(sum(max(0.0, min(r["end_s"], t1) - max(r["start_s"], t0)) for r in rows if r["label"] in ON_FOOT))


def falls_short(odometry_m: float, other_m: float) -> bool:
    """The odometry's ``odometry_m`` is shorter than another measure's ``other_m`` (m) by more than
    :data:`DISTANCE_FACTOR` and by more than :data:`DISTANCE_MIN_M`."""
    return other_m - odometry_m > DISTANCE_MIN_M and other_m > DISTANCE_FACTOR * odometry_m


def distance_warnings(rec: Recording, t0: float, t1: float, length_m: float, activity: list[dict] | None) -> list[str]:
    """The odometry's path of ``length_m`` m over [``t0``, ``t1``] s against the distance the fixes
    move (:func:`fixes_length_m`) and the walking time × :data:`WALK_SPEED_M_S` of the recording's
    ``activity`` intervals (:func:`walking_seconds`): one line for each that it falls short of
    (:func:`falls_short`)."""
    out = []
    if (fix_m := fixes_length_m(rec, t0, t1)) is not None and falls_short(length_m, fix_m):
        out.append(
            f"the odometry walked far less than the fixes moved: the odometry's path is "
            f"{length_m:.1f} m long, the fixes move {fix_m:.0f} m; {DISTANCE_ADVICE}"
        )
    if (walk_s := walking_seconds(activity, t0, t1)) is not None and falls_short(length_m, walk_s * WALK_SPEED_M_S):
        out.append(
            f"the odometry walked far less than the activity model says: the odometry's path "
            f"is {length_m:.1f} m long, the activity model finds {walk_s:.0f} s of walking (≈ "
            f"{walk_s * WALK_SPEED_M_S:.0f} m at {WALK_SPEED_M_S:g} m/s); {DISTANCE_ADVICE}"
        )
    return out


def trust_warnings(
    model_path,
    cfg,
    rec: Recording,
    seq,
    t_c: np.ndarray,
    vel: np.ndarray,
    length_m: float,
    activity: list[dict] | None = None,
) -> list[str]:
    """One line per reason not to trust the path, each with what to do: :func:`input_warnings`
    (devices, domain, did the model learn), :func:`walk_warnings` (implausible for walking) and
    :func:`distance_warnings` (the odometry against the fixes and the ``activity`` intervals)."""
    return (
        input_warnings(model_path, cfg, rec)
        + walk_warnings(cfg, seq, vel, length_m)
        + distance_warnings(rec, float(t_c[0]), float(t_c[-1]), length_m, activity)
    )


__all__ = [
    "distance_warnings",
    "fixes_length_m",
    "input_warnings",
    "run_training_record",
    "trust_warnings",
    "walk_warnings",
    "walking_seconds",
]
