"""Whether a result can be trusted: a model given data unlike its training data, a path that is
implausible for walking, a model that did not learn (issue 22, section 1).

Two halves. **Facts** (:func:`recording_facts`, :func:`data_facts`): what a model's training
data was like, recorded in the run's ``training.json`` under ``training_data`` when it is trained,
and the same facts of a recording it is given: per device the sampling rate (Hz) and the gravity
direction in the device's own frame per window (the unit vector of the mean acceleration over
``window_s``: where "down" is for the device, which tells how it is held or worn), and the
recordings' placements (``meta["placement"]``). **Checks**: pure functions, one per question,
each returning one finding (a sentence without advice, None when nothing is wrong); the command
that shows them (``wearnav track``, ``wearnav classify``) adds what to do.

A finding is a warning, never an error: the result is still written, with the finding beside it
(``track.json`` / ``classify.json`` ``warnings``, and one ``warning:`` line each on the console).
"""

from __future__ import annotations

import numpy as np

# ---- thresholds -------------------------------------------------------------------------------

# A rate is "the training data's" within this factor of the training recordings' range: phones
# asked for one rate deliver a few per cent either side of it (e.g. 98–102 Hz for 100 Hz).
RATE_TOLERANCE = 1.1
# An input window's gravity direction is "seen in training" when some training window's lies
# within this angle: wider than the tilt of a device held one way while walking, narrower than
# the 90° between a phone flat in the hand and one upright in a trouser pocket or waist holder.
GRAVITY_MATCH_DEG = 30.0
# The gravity check warns when at least this share of the input's windows are unseen in training.
GRAVITY_OUTSIDE_SHARE = 0.5
# Training gravity directions kept per device (evenly spaced over the training windows).
MAX_DIRECTIONS = 256
# Input windows compared per device (evenly spaced), to bound the check's time on long walks.
MAX_INPUT_WINDOWS = 2000

# Walking (issue 22): a walking person's median speed lies in this range (m/s).
WALK_SPEED_RANGE_M_S = (0.5, 2.5)
# A typical step: PDR's step length (Suite-IN++ Sec. V-B; wearnav.models.pdr), m.
STEP_LENGTH_M = 0.67
# The path length may differ from steps × STEP_LENGTH_M by this factor either way (0.34–1.34 m per
# step, wider than adults' walking step lengths) before it is called implausible.
PATH_TO_STEPS_RANGE = (0.5, 2.0)
# A window is "walking" when PDR's step detector finds at least this many steps per second in it
# (normal walking cadence is about 1.6–2.0 steps/s; half of it allows for slow walking and stops).
WALKING_STEP_RATE_HZ = 0.8
# The walking checks apply when at least this share of the windows are walking.
MIN_WALKING_SHARE = 0.25

# Placement names of the importers and the simulator, mapped onto shared words (the simulator's
# recording-level codes are Suite-IN++ Table IV's; "MP" changes between hand and pocket).
PLACEMENT_WORDS: dict[str, tuple[str, ...]] = {
    "HD": ("handheld",),
    "texting": ("handheld",),
    "swinging": ("handheld",),
    "call": ("handheld",),
    "PK": ("pocket",),
    "front_pocket": ("pocket",),
    "back_pocket": ("pocket",),
    "BG": ("bag",),
    "MP": ("handheld", "pocket"),
}


# ---- facts ------------------------------------------------------------------------------------


def window_gravity(acc: np.ndarray, n_per_window: int) -> np.ndarray:
    """Gravity direction per non-overlapping window: the unit mean of ``acc`` ((N, 3) m/s², device
    frame, gravity included) over each ``n_per_window`` samples → (W, 3); W = N // n_per_window
    (one window of all samples when N is shorter). Windows whose mean is ~0 are dropped."""
    acc = np.asarray(acc, np.float64)
    n = max(1, int(n_per_window))
    w = len(acc) // n
    means = acc[: w * n].reshape(w, n, 3).mean(axis=1) if w else acc.mean(axis=0, keepdims=True)
    norm = np.linalg.norm(means, axis=1)
    ok = norm > 1e-6
    return means[ok] / norm[ok, None]


def _spaced(a: np.ndarray, n: int) -> np.ndarray:
    return a if len(a) <= n else a[np.unique(np.linspace(0, len(a) - 1, n).astype(int))]


def recording_facts(rec, devices, window_s: float) -> dict:
    """The facts (module docstring) of one recording for the model ``devices``: ``placement``
    (str, "" unknown) and per device it has ``rate_hz`` (median) and ``gravity_directions``
    ((W, 3) unit vectors, one per ``window_s`` seconds)."""
    out: dict = {"placement": str(rec.meta.get("placement", "") or ""), "devices": {}}
    for dev in devices:
        s = rec.devices.get(dev)
        if s is None or len(s) < 2:
            continue
        rate = float(s.rate)
        dirs = window_gravity(s.acc, round(window_s * rate) if rate > 0 else len(s))
        out["devices"][dev] = {"rate_hz": rate, "gravity_directions": dirs}
    return out


def data_facts(recordings, devices, window_s: float) -> dict:
    """The facts of a model's training recordings, as ``training.json`` keeps them (JSON):
    ``recordings``, ``placements`` (sorted, known ones), and per device ``recordings``,
    ``rate_hz`` ([min, median, max] over the recordings) and ``gravity_directions`` (at most
    :data:`MAX_DIRECTIONS` of the windows' unit vectors, rounded to 3 decimals)."""
    placements: set[str] = set()
    rates: dict[str, list[float]] = {d: [] for d in devices}
    dirs: dict[str, list[np.ndarray]] = {d: [] for d in devices}
    n = 0
    for rec in recordings:
        f = recording_facts(rec, devices, window_s)
        n += 1
        if f["placement"]:
            placements.add(f["placement"])
        for dev, d in f["devices"].items():
            rates[dev].append(d["rate_hz"])
            dirs[dev].append(d["gravity_directions"])
    per_device = {}
    for dev in devices:
        if not rates[dev]:
            continue
        g = _spaced(np.concatenate(dirs[dev]), MAX_DIRECTIONS)
        r = np.asarray(rates[dev])
        per_device[dev] = {
            "recordings": len(r),
            "rate_hz": [round(float(v), 2) for v in (r.min(), np.median(r), r.max())],
            "gravity_directions": np.round(g, 3).tolist(),
        }
    return {"recordings": n, "placements": sorted(placements), "devices": per_device, "window_s": window_s}


# ---- checks: the input against the training data -----------------------------------------------


def _names(xs) -> str:
    xs = list(xs)
    return ", ".join(xs[:-1]) + " and " + xs[-1] if len(xs) > 1 else (xs[0] if xs else "none")


def missing_devices(model_devices, recording_devices) -> str | None:
    """The model's devices that the recording lacks."""
    lacks = [d for d in model_devices if d not in set(recording_devices)]
    if not lacks:
        return None
    return (
        f"the model was trained on {_names(model_devices)}; this recording has no {_names(lacks)} "
        f"(its input there is zeros the model never saw in training)"
    )


def rate_outside(device: str, rate_hz: float, training_rate_hz, model_rate_hz: float | None = None) -> str | None:
    """``rate_hz`` outside the training recordings' [min, median, max] range (± RATE_TOLERANCE).

    With the model's own rate ``model_rate_hz`` (Hz), a recording sampled at least that fast
    (within RATE_TOLERANCE) is never a finding: preprocessing low-passes it below the model
    clock's Nyquist and resamples it onto that clock (:mod:`wearnav.preprocess`), as it did the
    training recordings, so the model sees the same band whatever the rate it started at (a
    100 Hz Sensor Logger export for a 50 Hz model). Only a slower recording, interpolated up,
    lacks part of what the model saw in training."""
    if model_rate_hz is not None and rate_hz >= model_rate_hz / RATE_TOLERANCE:
        return None
    lo, med, hi = training_rate_hz
    if lo / RATE_TOLERANCE <= rate_hz <= hi * RATE_TOLERANCE:
        return None
    seen = f"{med:.0f} Hz" if round(lo) == round(hi) else f"{lo:.0f}–{hi:.0f} Hz"
    return f"{device} is sampled at {rate_hz:.0f} Hz; the model's training data at {seen}"


def placement_words(placement: str) -> set[str]:
    """The shared words of a placement name (:data:`PLACEMENT_WORDS`; else the name itself)."""
    return set(PLACEMENT_WORDS.get(placement, (placement,))) if placement else set()


def placement_outside(placement: str, training_placements) -> str | None:
    """A known placement that none of the training recordings had (by :func:`placement_words`)."""
    if not placement or not training_placements:
        return None
    seen = set().union(*(placement_words(p) for p in training_placements))
    if placement_words(placement) & seen:
        return None
    return f"the recording's placement is {placement!r}; the model's training data had {_names(sorted(training_placements))}"


def angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (degrees) between each unit vector of ``a`` (N, 3) and each of ``b`` (M, 3) → (N, M)."""
    return np.degrees(np.arccos(np.clip(np.asarray(a) @ np.asarray(b).T, -1.0, 1.0)))


def gravity_outside(device: str, directions: np.ndarray, training_directions) -> str | None:
    """The share of the input's gravity directions (W, 3) with no training direction within
    :data:`GRAVITY_MATCH_DEG`, when it is at least :data:`GRAVITY_OUTSIDE_SHARE`."""
    train = np.asarray(training_directions, np.float64).reshape(-1, 3)
    d = _spaced(np.asarray(directions, np.float64).reshape(-1, 3), MAX_INPUT_WINDOWS)
    if not len(d) or not len(train):
        return None
    share = float(np.mean(angles_deg(d, train).min(axis=1) > GRAVITY_MATCH_DEG))
    if share < GRAVITY_OUTSIDE_SHARE:
        return None
    return (
        f"{device} is held or worn differently from the model's training data: in {share:.0%} of the "
        f"recording its gravity direction is more than {GRAVITY_MATCH_DEG:g}° from any training window's"
    )


def domain_findings(facts: dict, training: dict | None, model_rate_hz: float | None = None) -> list[str]:
    """Rate, placement and gravity findings of a recording's ``facts`` (:func:`recording_facts`)
    against the ``training`` facts (:func:`data_facts`); None: the training data is unknown.
    ``model_rate_hz``: the rate the model's input is resampled to (:func:`rate_outside`)."""
    if not training:
        return [
            "training data unknown: the model's run does not record its training data's rates, "
            "placements and gravity directions (trained before wearnav kept them), so they cannot be "
            "compared with this recording"
        ]
    out = []
    if (p := placement_outside(facts.get("placement", ""), training.get("placements", ()))) is not None:
        out.append(p)
    for dev, f in facts.get("devices", {}).items():
        t = training.get("devices", {}).get(dev)
        if t is None:
            continue
        if (r := rate_outside(dev, f["rate_hz"], t["rate_hz"], model_rate_hz)) is not None:
            out.append(r)
        if (g := gravity_outside(dev, f["gravity_directions"], t["gravity_directions"])) is not None:
            out.append(g)
    return out


# ---- checks: the result ------------------------------------------------------------------------


def implausible_walk(speed_m_s: np.ndarray, step_rate_hz: np.ndarray, length_m: float, steps: float) -> list[str]:
    """Findings on a tracked path: per window the model's speed (m/s) and PDR's step rate
    (steps/s); the path's length (m) and the steps counted over it. Applies only where at least
    :data:`MIN_WALKING_SHARE` of the windows are walking (:data:`WALKING_STEP_RATE_HZ`)."""
    speed = np.asarray(speed_m_s, np.float64)
    walking = np.asarray(step_rate_hz, np.float64) >= WALKING_STEP_RATE_HZ
    if not len(speed) or walking.mean() < MIN_WALKING_SHARE:
        return []
    out = []
    med = float(np.median(speed[walking]))
    lo, hi = WALK_SPEED_RANGE_M_S
    if not lo <= med <= hi:
        out.append(
            f"implausible for walking: the median speed is {med:.2f} m/s while steps are detected "
            f"(walking is {lo:g}–{hi:g} m/s)"
        )
    expected = steps * STEP_LENGTH_M
    if expected > 0 and not PATH_TO_STEPS_RANGE[0] <= length_m / expected <= PATH_TO_STEPS_RANGE[1]:
        out.append(
            f"implausible for walking: the path is {length_m:.1f} m long, but {steps:.0f} steps were "
            f"detected (≈ {expected:.0f} m at {STEP_LENGTH_M:g} m per step)"
        )
    return out


# ---- did the model learn? ---------------------------------------------------------------------


def odometry_baseline(best_val_mse: float | None, zero_val_mse: float) -> dict:
    """``beats_trivial`` of an odometry run: its best validation velocity MSE ((m/s)²) against
    standing still's (predicting zero velocity) on the same windows."""
    beats = best_val_mse is not None and bool(np.isfinite(best_val_mse)) and best_val_mse < zero_val_mse
    return {
        "beats_trivial": bool(beats),
        "trivial": "standing still (zero velocity)",
        "trivial_val_vel_mse": round(float(zero_val_mse), 6),
    }


def classify_baseline(accuracy: float, true: np.ndarray, majority: int, classes) -> dict:
    """``beats_trivial`` of a classifier: its accuracy against always answering the training
    windows' majority class ``majority`` (an index of ``classes``) on the same windows ``true``."""
    trivial = float(np.mean(np.asarray(true) == majority)) if len(true) else 0.0
    return {
        "beats_trivial": bool(accuracy > trivial),
        "trivial": f"always {classes[majority]} (majority class)",
        "trivial_accuracy": round(trivial, 4),
    }


def did_not_learn(record: dict | None) -> str | None:
    """The finding of a run's training record (``training.json`` / metrics' ``training``) that
    did not beat its trivial baseline; None when it did or when that is not recorded."""
    if not record or record.get("beats_trivial", True) is not False:
        return None

    def num(v) -> str:
        return f"{v:.4g}" if isinstance(v, (int, float)) else str(v)

    if "trivial_val_vel_mse" in record:
        return (
            f"the model did not learn: its best validation velocity MSE "
            f"({num(record.get('best_val_vel_mse'))} (m/s)²) is no better than {record['trivial']} "
            f"({num(record['trivial_val_vel_mse'])} (m/s)²)"
        )
    return (
        f"the model did not learn: its test accuracy ({num(record.get('accuracy'))}) is no better than "
        f"{record['trivial']} ({num(record.get('trivial_accuracy'))})"
    )


QUICK_NOTE = "pipeline check, not accuracy"


# ---- what to do -------------------------------------------------------------------------------

TRACK_DEVICES_ADVICE = (
    "track it with a model trained on the devices it has (e.g. `wearnav train ronin "
    "--devices phone`) or with `--model pdr`"
)
TRACK_DOMAIN_ADVICE = "the path may be wrong: use a model trained on recordings like this one, or `--model pdr`"
TRACK_RESULT_ADVICE = "do not trust this path: compare it with `--model pdr`"
LEARN_ADVICE = "train it longer (more --epochs / --max-time) or use `--model pdr`"
CLASSIFY_DOMAIN_ADVICE = "the labels may be wrong: use a classifier trained on recordings like this one"
CLASSIFY_LEARN_ADVICE = "its labels are no better than a constant guess: train it longer (more epochs)"


__all__ = [
    "recording_facts",
    "data_facts",
    "window_gravity",
    "missing_devices",
    "rate_outside",
    "placement_outside",
    "gravity_outside",
    "domain_findings",
    "implausible_walk",
    "odometry_baseline",
    "classify_baseline",
    "did_not_learn",
    "QUICK_NOTE",
]
