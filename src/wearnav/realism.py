"""How real is the simulated walking? Gait and sensor statistics of simulated and real recordings.

Every source is compared on walking only, device by device and placement by placement, with the
same pipeline:

1. **Walking stretches.** Labels where a dataset has them (simulator: ``activity = walk``;
   MotionSense: the ``walking`` trials; UJI: ``WALKING`` and the ``TURNING`` between two walking
   intervals, a turn taken while walking; Oxford: runs of annotated true steps less than
   :data:`MAX_STEP_GAP_S` apart). Without labels (ILC2, IPIN) :func:`detect_walking` decides,
   2-s window by window (hop 0.5 s, the centre second marked): the |acc| standard deviation
   within :data:`WALK_STD_BAND`, the |acc| spectrum peaking in the step band
   :data:`STEP_BAND_HZ` with at least 40 % of the 0.5–5 Hz power there, and the mean |gyro|
   below :data:`MAX_WALK_GYRO`; gaps shorter than a window are closed.
   Every stretch loses :data:`TRIM_S` at both ends (gait initiation and termination) and is
   cut into segments of :data:`SEGMENT_S` (the remainder kept if at least
   :data:`MIN_SEGMENT_S`). One segment is one sample of every statistic.
2. **One rate.** acc, gyro and world-frame acc (where the stream has an orientation) are
   interpolated onto a uniform 100 Hz grid and decimated to :data:`RATE_HZ` = 25 Hz with
   scipy's polyphase FIR anti-alias filter, so the 25 Hz earbuds, the 50 Hz and the 100–220 Hz
   devices all end with the same 12.5 Hz band.
3. **Statistics per segment** (:func:`segment_stats`), on the magnitude |acc| (independent of
   how the device is mounted):

   - ``acc_std``: standard deviation of |acc| (m/s²); ``gyro_mean``: mean |gyro| (rad/s);
   - ``f_dom``: frequency of the highest peak of the |acc| periodogram in 0.5–4 Hz (Hann
     window, zero-padded to 0.003 Hz);
   - ``cadence``: steps per second from the stride period, the highest peak of the |acc|
     autocorrelation at lags 0.8–1.6 s (parabolic sub-sample refinement);
   - ``step_reg``: the autocorrelation one step apart, the peak near half the stride lag
     (Moe-Nilssen & Helbostad's step regularity: 1 = identical consecutive steps);
   - ``step_cv`` and ``amp_cv``: coefficients of variation of the step-to-step periods and
     peak-to-trough amplitudes of the steps found as peaks of the 4 Hz low-passed |acc|
     (parabolic refinement of the peak times, so a 25 Hz grid does not add 40 ms jitter);
   - ``band_*``: share of the |acc| power (Welch) in the bands of :data:`BANDS` up to 12.5 Hz;
   - ``hv_ratio``: RMS horizontal over RMS vertical dynamic world-frame acceleration, where the
     stream carries an orientation.

Location fixes (:func:`fix_stats`), against the points a surveyor marked (IPIN's POSI points;
in the simulator, its truth every :data:`SIM_REFERENCE_EVERY_S`): error distribution, reported
accuracy over the actual error, outage lengths (gaps longer than :data:`OUTAGE_GAP_S`) and
jumps (consecutive fixes further apart than a walker could go, :data:`JUMP_SPEED_MPS`).

:func:`realism_report` runs it all and writes the Markdown page, the PNGs and a JSON holding
the numbers behind every table and figure.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy.signal import butter, filtfilt, find_peaks, periodogram, resample_poly, welch
from scipy.spatial.transform import Rotation

from wearnav.errors import ConfigError, WearnavError
from wearnav.fileio import atomic_path, write_text_atomic
from wearnav.metrics import FIX_MAX_GAP_S, errors_at_reference
from wearnav.recording import Recording

RATE_HZ = 25.0
_GRID_HZ = 100.0  # the uniform grid everything is interpolated onto before decimating to 25 Hz
SEGMENT_S = 10.0
MIN_SEGMENT_S = 4.0
TRIM_S = 1.0
STEP_BAND_HZ = (1.2, 2.6)
WALK_STD_BAND = (0.5, 8.0)  # m/s², |acc| std of walking (still: < 0.2; running: > 8)
WALK_WINDOW_S = 2.0
MAX_WALK_GYRO = 3.0  # rad/s
MAX_STEP_GAP_S = 1.0
STRIDE_LAGS_S = (0.8, 1.6)
F_DOM_BAND_HZ = (0.5, 4.0)
BANDS = ((0.3, 1.2), (1.2, 2.6), (2.6, 5.0), (5.0, 8.0), (8.0, 12.5))
OUTAGE_GAP_S = 2.5
JUMP_SPEED_MPS = 4.0
SIM_REFERENCE_EVERY_S = 10.0
SIM_DURATION_S = 120.0  # per simulated walk; long enough for GNSS jumps to show per recording
IQR_MIN_SEGMENTS = 8  # fewer real samples than this: the band is ±15 % of the real median
SMALL_SET_TOLERANCE = 0.15

STATS = ("acc_std", "gyro_mean", "f_dom", "cadence", "step_reg", "step_cv", "amp_cv", "hv_ratio") + tuple(
    f"band_{lo:g}_{hi:g}" for lo, hi in BANDS)
STAT_LABELS = {
    "acc_std": "|acc| std (m/s²)", "gyro_mean": "|gyro| mean (rad/s)", "f_dom": "f_dom (Hz)",
    "cadence": "cadence (steps/s)", "step_reg": "autocorr 1 step", "step_cv": "step-period CV",
    "amp_cv": "step-amplitude CV", "hv_ratio": "horiz/vert acc",
    **{f"band_{lo:g}_{hi:g}": f"power {lo:g}–{hi:g} Hz" for lo, hi in BANDS},
}
FIX_STATS = ("error_m", "acc_over_error", "fix_speed", "outage_s", "outage_share", "jumps_per_100")


# ---- resampling and walking stretches ----------------------------------------------------------

def resample(t: np.ndarray, x: np.ndarray, t0: float, t1: float, rate: float = RATE_HZ) -> np.ndarray:
    """``x`` (N, k) sampled at times ``t`` → uniform ``rate`` samples over [t0, t1): linear
    interpolation onto a 100 Hz grid, then polyphase FIR decimation (its anti-alias filter)."""
    grid = np.arange(t0, t1, 1.0 / _GRID_HZ)
    if grid.size < 8:
        return np.empty((0, x.shape[1]))
    y = np.stack([np.interp(grid, t, x[:, k]) for k in range(x.shape[1])], 1)
    down = int(round(_GRID_HZ / rate))
    mean = y.mean(0)  # the filter's edge transients are smaller on a zero-mean signal
    return resample_poly(y - mean, 1, down, axis=0) + mean


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of the True runs of a boolean array."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def detect_walking(t: np.ndarray, acc: np.ndarray, gyro: np.ndarray | None = None) -> list[tuple[float, float]]:
    """Walking intervals (s) of an unlabelled stream, from |acc| (and |gyro|, where there is one:
    a phone turned faster than :data:`MAX_WALK_GYRO` on average is being handled, e.g. waved
    in a figure of eight to calibrate its compass, not carried)."""
    if t.size < 2 or t[-1] - t[0] < WALK_WINDOW_S:
        return []
    x = np.linalg.norm(resample(t, acc, t[0], t[-1]), axis=1)
    g = None if gyro is None else np.linalg.norm(resample(t, gyro, t[0], t[-1]), axis=1)
    n = int(WALK_WINDOW_S * RATE_HZ)
    hop = n // 4
    starts = np.arange(0, x.size - n + 1, hop)
    walk = np.zeros(x.size, bool)
    for s in starts:
        w = x[s:s + n]
        sd = w.std()
        if not WALK_STD_BAND[0] <= sd <= WALK_STD_BAND[1]:
            continue
        if g is not None and g[s:s + n].mean() > MAX_WALK_GYRO:
            continue
        f, p = periodogram(w - w.mean(), RATE_HZ, window="hann", nfft=256)
        band = (f >= 0.5) & (f <= 5.0)
        if not band.any() or p[band].sum() <= 0:
            continue
        fb, pb = f[band], p[band]
        peak = fb[np.argmax(pb)]
        step = (fb >= STEP_BAND_HZ[0]) & (fb <= STEP_BAND_HZ[1])
        if STEP_BAND_HZ[0] <= peak <= STEP_BAND_HZ[1] and pb[step].sum() >= 0.4 * pb.sum():
            walk[s + n // 4:s + n - n // 4] = True  # the window's centre: edges good to ±0.5 s
    # close gaps shorter than one window (a turn or a missed window inside a walk)
    gaps = _runs(~walk)
    for a, b in gaps:
        if a > 0 and b < walk.size and (b - a) < n:
            walk[a:b] = True
    t_grid = t[0] + np.arange(x.size) / RATE_HZ
    return [(float(t_grid[a]), float(t_grid[b - 1])) for a, b in _runs(walk)]


def labelled_walking(rec: Recording, device: str) -> list[tuple[float, float]] | None:
    """Walking intervals from a recording's labels, or None where it has no walking labels."""
    lb = rec.labels
    src = rec.meta.get("source", "")
    if lb is None or len(lb) == 0:
        return None
    if src == "oxford-steps":
        steps = np.sort(lb.loc[lb["kind"] == "step", "start"].to_numpy(float))
        if steps.size < 2:
            return []
        close = np.diff(steps) <= MAX_STEP_GAP_S
        return [(float(steps[a]), float(steps[b])) for a, b in _runs(close)]
    kind = "activity"
    if src == "uji-phone-watch" and device != "phone":
        kind = f"activity_{device}"
    rows = lb[lb["kind"] == kind].sort_values("start")
    if rows.empty:
        return None
    values = [str(v).lower() for v in rows["value"]]
    walkish = np.array([v in ("walk", "walking") for v in values])
    turning = np.array([v == "turning" for v in values])
    # a turn between two walking intervals is part of the walk (UJI: walk, turn, walk back)
    inner = turning & np.r_[False, walkish[:-1]] & np.r_[walkish[1:], False]
    keep = walkish | inner
    starts, ends = rows["start"].to_numpy(float), rows["end"].to_numpy(float)
    return [(float(starts[a]), float(ends[b - 1])) for a, b in _runs(keep)]


def walking_stretches(rec: Recording, device: str) -> tuple[list[tuple[float, float]], str]:
    """(intervals, how): labels where the recording has them, else the detector."""
    s = rec.devices[device]
    lab = labelled_walking(rec, device)
    if lab is not None:
        return lab, "labels"
    return detect_walking(s.t, s.acc, s.gyro), "detector"


def segments(intervals: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Trim each walking interval and cut it into analysis segments (see the module doc)."""
    out = []
    for a, b in intervals:
        a, b = a + TRIM_S, b - TRIM_S
        if b - a < MIN_SEGMENT_S:
            continue
        k = int((b - a) // SEGMENT_S)
        edges = [a + i * SEGMENT_S for i in range(k + 1)]
        if k == 0 or b - edges[-1] >= MIN_SEGMENT_S:  # a long enough remainder is a segment too
            edges.append(b)
        out += list(zip(edges[:-1], edges[1:]))
    return out


# ---- statistics of one segment -------------------------------------------------------------

def _autocorr(x: np.ndarray) -> np.ndarray:
    x = x - x.mean()
    n = x.size
    f = np.fft.rfft(x, 2 * n)
    ac = np.fft.irfft(f * np.conj(f))[:n]
    return ac / ac[0] if ac[0] > 0 else np.zeros(n)


def _peak(y: np.ndarray, lo: int, hi: int) -> tuple[float, float]:
    """(index, value) of the maximum of y[lo:hi], refined by a parabola through its neighbours."""
    lo, hi = max(lo, 1), min(hi, y.size - 1)
    if hi <= lo:
        return float("nan"), float("nan")
    i = lo + int(np.argmax(y[lo:hi]))
    a, b, c = y[i - 1], y[i], y[min(i + 1, y.size - 1)]
    den = a - 2 * b + c
    d = 0.5 * (a - c) / den if den < 0 else 0.0
    d = float(np.clip(d, -0.5, 0.5))
    return i + d, float(b - 0.25 * (a - c) * d)


def segment_stats(acc: np.ndarray, gyro: np.ndarray | None = None, acc_world: np.ndarray | None = None,
                  rate: float = RATE_HZ) -> dict[str, float]:
    """The statistics of one walking segment sampled uniformly at ``rate`` (module doc, step 3)."""
    x = np.linalg.norm(acc, axis=1)
    n = x.size
    out = {k: float("nan") for k in STATS}
    out["acc_std"] = float(x.std())
    if gyro is not None:
        out["gyro_mean"] = float(np.linalg.norm(gyro, axis=1).mean())
    xc = x - x.mean()
    f, p = periodogram(xc, rate, window="hann", nfft=max(8192, n))
    band = (f >= F_DOM_BAND_HZ[0]) & (f <= F_DOM_BAND_HZ[1])
    out["f_dom"] = float(f[band][np.argmax(p[band])])

    ac = _autocorr(x)
    stride_lag, _ = _peak(ac, int(STRIDE_LAGS_S[0] * rate), int(np.ceil(STRIDE_LAGS_S[1] * rate)) + 1)
    if np.isfinite(stride_lag):
        out["cadence"] = float(2.0 * rate / stride_lag)
        step_lag, step_val = _peak(ac, int(0.4 * stride_lag), int(np.ceil(0.6 * stride_lag)) + 1)
        out["step_reg"] = step_val
        # steps: peaks of the low-passed |acc|, at least 60 % of a step apart
        b, a = butter(4, 4.0 / (0.5 * rate))
        y = filtfilt(b, a, x) if n > 30 else x
        pk, _ = find_peaks(y, distance=max(1, int(0.6 * stride_lag / 2)))
        if pk.size >= 4:
            times = np.array([_peak(y, i, i + 1)[0] for i in pk]) / rate
            per = np.diff(times)
            out["step_cv"] = float(per.std() / per.mean())
            amps = np.array([y[i] - y[i:j].min() for i, j in zip(pk[:-1], pk[1:])])
            out["amp_cv"] = float(amps.std() / amps.mean()) if amps.mean() > 0 else float("nan")

    fw, pw = welch(xc, rate, nperseg=min(n, 64))
    total = pw[(fw >= BANDS[0][0]) & (fw <= BANDS[-1][1])].sum()
    for lo, hi in BANDS:
        m = (fw >= lo) & (fw < hi) if hi < BANDS[-1][1] else (fw >= lo) & (fw <= hi)
        out[f"band_{lo:g}_{hi:g}"] = float(pw[m].sum() / total) if total > 0 else float("nan")
    if acc_world is not None:
        dyn = acc_world - acc_world.mean(0)
        h = np.sqrt(np.mean(np.sum(dyn[:, :2] ** 2, axis=1)))
        v = np.sqrt(np.mean(dyn[:, 2] ** 2))
        out["hv_ratio"] = float(h / v) if v > 0 else float("nan")
    return out


def spectrum(acc: np.ndarray, rate: float = RATE_HZ) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD of |acc| (detrended), 0.39 Hz bins at 25 Hz: the spectra the report overlays."""
    x = np.linalg.norm(acc, axis=1)
    return welch(x - x.mean(), rate, nperseg=64)


def recording_segments(rec: Recording, device: str) -> tuple[list[dict], list[np.ndarray], str]:
    """Statistics and PSDs of every walking segment of one device of a recording."""
    s = rec.devices[device]
    intervals, how = walking_stretches(rec, device)
    if s.quat is not None:
        R = Rotation.from_quat(np.asarray(s.quat, float)[:, [1, 2, 3, 0]])  # w,x,y,z → scipy's x,y,z,w
        acc_world = R.apply(np.asarray(s.acc, float))
    rows, psds = [], []
    for a, b in segments(intervals):
        a, b = max(a, float(s.t[0])), min(b, float(s.t[-1]))
        if b - a < MIN_SEGMENT_S:
            continue
        if s.worn is not None and not np.all(s.worn[(s.t >= a) & (s.t <= b)]):
            continue
        acc = resample(s.t, np.asarray(s.acc, float), a, b)
        gyro = None if s.gyro is None else resample(s.t, np.asarray(s.gyro, float), a, b)
        aw = None if s.quat is None else resample(s.t, acc_world, a, b)
        st = segment_stats(acc, gyro, aw)
        st.update(recording=rec.name, start=round(a, 3), end=round(b, 3))
        rows.append(st)
        psds.append(spectrum(acc)[1])
    return rows, psds, how


# ---- location fixes --------------------------------------------------------------------------

def fix_stats(rec: Recording) -> dict[str, list[float]]:
    """Fix error at the reference points, accuracy/error there, outage lengths and jump rate."""
    fx = rec.fixes
    out = {k: [] for k in FIX_STATS}
    if fx is None or len(fx.t) < 2 or rec.truth is None:
        return out
    if rec.meta.get("source") == "simulator":
        t_ref = np.arange(SIM_REFERENCE_EVERY_S, rec.truth.t[-1], SIM_REFERENCE_EVERY_S)
        p_ref = np.stack([np.interp(t_ref, rec.truth.t, rec.truth.pos[:, k]) for k in range(2)], 1)
    else:
        t_ref, p_ref = rec.truth.t, rec.truth.pos[:, :2]
    fpos = np.asarray(fx.pos, float)[:, :2]
    ok = np.isfinite(fpos).all(1)
    t_f, p_f = fx.t[ok], fpos[ok]
    err = errors_at_reference(t_f, p_f, t_ref, p_ref, FIX_MAX_GAP_S)
    out["error_m"] = err.tolist()
    if fx.accuracy is not None and err.size:
        i = np.searchsorted(t_f, t_ref)
        keep = []
        for k, t in enumerate(t_ref):
            j = [q for q in (i[k] - 1, i[k]) if 0 <= q < t_f.size]
            if j and min(abs(t_f[q] - t) for q in j) <= FIX_MAX_GAP_S:
                keep.append(min(j, key=lambda q: abs(t_f[q] - t)))
        accu = np.asarray(fx.accuracy, float)[ok][keep]
        good = np.isfinite(accu) & (err > 0)
        out["acc_over_error"] = (accu[good] / err[good]).tolist()
    dt = np.diff(t_f)
    out["outage_s"] = dt[dt > OUTAGE_GAP_S].tolist()
    span = t_f[-1] - t_f[0]
    out["outage_share"] = [float(dt[dt > OUTAGE_GAP_S].sum() / span) if span > 0 else 0.0]
    step = np.linalg.norm(np.diff(p_f, axis=0), axis=1)
    out["fix_speed"] = (step / np.maximum(dt, 1e-3)).tolist()
    out["jumps_per_100"] = [float(100.0 * np.mean(step > JUMP_SPEED_MPS * np.maximum(dt, 1.0)))]
    return out


# ---- sources ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class RealSource:
    """Real recordings: dataset format, the device to read, which recordings (name regex)."""

    label: str
    fmt: str
    folder: str  # under the data root; imported from there
    device: str
    names: str = ".*"


@dataclass(frozen=True)
class Group:
    """One device and placement: the simulated hold and its real counterparts."""

    key: str
    title: str
    sim_device: str
    sim_hold: str
    real: tuple[RealSource, ...] = ()


# Calibration data: ILC2 site 1 floor F1 only, IPIN 2023 training trials 01 and 02 only. The
# odometry benchmarks must not evaluate on these (they are the simulator's calibration set).
ILC2_CALIBRATION = "site1/F1"
IPIN_CALIBRATION = r"IPIN2023_T3_TrainingTrial0[12]_"
GROUPS: tuple[Group, ...] = (
    Group("phone_hand", "phone held in the hand in front of the body (texting)", "phone", "texting", (
        RealSource("ILC2 F1", "ilc2", f"ilc2_indoor_location/{ILC2_CALIBRATION}", "phone"),
        RealSource("IPIN T01-02", "ipin2023", "ipin2023_track3", "phone", IPIN_CALIBRATION),
        RealSource("Oxford hand", "oxford-steps", "oxford_step_counter", "phone", r"_hand_"),
    )),
    Group("phone_front_pocket", "phone in a front trouser pocket", "phone", "front_pocket", (
        RealSource("MotionSense", "motionsense", "motionsense", "phone", r"_wlk_"),
        RealSource("UJI phone", "uji-phone-watch", "uji_phone_watch_har", "phone"),
        RealSource("Oxford frontpocket", "oxford-steps", "oxford_step_counter", "phone", r"_frontpocket_"),
    )),
    Group("phone_back_pocket", "phone in a back trouser pocket", "phone", "back_pocket", (
        RealSource("Oxford backpocket", "oxford-steps", "oxford_step_counter", "phone", r"_backpocket_"),
    )),
    Group("phone_bag", "phone in a bag", "phone", "bag", (
        RealSource("Oxford bag", "oxford-steps", "oxford_step_counter", "phone", r"_bag_"),
    )),
    Group("watch", "watch on the wrist", "watch", "texting", (
        RealSource("UJI watch", "uji-phone-watch", "uji_phone_watch_har", "watch"),
    )),
    Group("phone_swinging", "phone in the swinging hand", "phone", "swinging"),
    Group("earbuds", "earbuds (25 Hz)", "earbuds", "texting"),
)
FIX_REAL = RealSource("IPIN T01-02", "ipin2023", "ipin2023_track3", "phone", IPIN_CALIBRATION)

# Statistics the calibrated simulator claims to match: in band in this report and, re-checked by
# tests/test_realism.py, in band for fresh simulations (12 walkers × 40 s) over four seeds. The
# others marked "yes" in the tables are in band here but too close to an edge to promise.
CLAIMED = {
    "phone_hand": ("acc_std", "gyro_mean", "f_dom", "step_cv", "amp_cv", "hv_ratio", "band_0.3_1.2", "band_2.6_5"),
    "phone_front_pocket": ("acc_std", "gyro_mean", "f_dom", "cadence", "amp_cv", "band_5_8",
                           "band_8_12.5"),
    # step_cv and band_0.3_1.2 were claimed too until the pelvis' fore-aft ripple got the inverted
    # pendulum's phase (forward acceleration leading the vertical, as ILC2's phones show); since
    # then they fall below the band in 2 of 4 seeds: recalibrating the arm swing is open work.
    "watch": ("acc_std", "f_dom", "cadence", "amp_cv"),
    "phone_bag": ("f_dom", "cadence", "step_reg", "step_cv"),
    "phone_back_pocket": ("f_dom", "cadence"),
}

# What the calibration (simulator version 2) set, against which statistics and recordings.
CALIBRATION_NOTES = """\
| simulator parameter (src/wearnav/simulate/) | calibrated against | real recordings |
|---|---|---|
| walker population cadence N(1.76, 0.06) steps/s (`config.sample_subject`) | cadence, f_dom of every placement | all sources above (real walkers: 1.66–1.88 steps/s) |
| step-to-step timing variability `step_time_cv` (path: cadence wander over one step) | step-period CV | ILC2 F1, IPIN T01-02, Oxford hand; UJI watch |
| step-to-step amplitude variability `step_amp_cv`, left/right asymmetry `step_asymmetry` | step-amplitude CV, autocorr 1 step, power 0.3–1.2 Hz | same |
| hand-held phone: step bob `hand_bob_deg`, forearm bounce and stride rise `hand_bounce_m`, heel-strike shock `hand_impact` (peak m/s², a 20 ms spike train, `body.impact_train`) | \\|gyro\\|, \\|acc\\| std, horiz/vert, power by band | ILC2 F1, IPIN T01-02, Oxford hand |
| watch: forearm roll at step frequency `wrist_wobble_deg`, arm swing 10–20°, the same heel-strike shock | \\|gyro\\|, f_dom, autocorr 1 step, power by band | UJI watch |
| front pocket: thigh heel-strike spike `leg_impact` (peak m/s², 16 ms, right heel only), irregular soft-tissue wobble `thigh_wobble_mm`, pocket 18 cm down the thigh, hip swing 22–30° | \\|acc\\| std, \\|gyro\\|, autocorr 1 step, horiz/vert, power by band | MotionSense, UJI phone, Oxford frontpocket |
| bag knocks on each heel strike (`BAG_JOLT_GAIN` × the hands' shock) | \\|acc\\| std, power by band | Oxford bag |
| GNSS multipath jumps (rate, size, hold), outages, accuracy growing with the offset (`fixes.FixNoise`) | jumps per 100 fixes, outage lengths, reported accuracy / error | IPIN T01-02 phone GNSS at POSI points |

Not calibrated here:

- **Earbuds**: no real earbud (or head-worn IMU) walking data is in ../shared/data. Assumed: the head
  motion of the body model as it was, and the IMU's own digital low-pass before its 25 Hz output, a
  zero-phase 15-tap FIR with an 8 Hz cut-off on the 100 Hz motion (`imu.antialiased`; about ODR/3, as
  MEMS IMUs configure their filter), so nothing above 12.5 Hz folds into the stream.
- **Phone swinging in the hand**: no real set here (Oxford's validation part has none).
- **Fix error size**: the simulator's fix error follows EasyTrack's three label-noise levels (median
  1-s displacement noise 21.6 / 27.6 / 33.5 cm, an Ornstein-Uhlenbeck error with τ = 120 s), open-sky
  phone GNSS; IPIN's indoor museum GNSS is larger. Keeping EasyTrack's levels wins: the error at the
  reference points is reported, not fitted.
- **Frozen fixes**: IPIN's indoor phone fixes often repeat the previous position or creep (see the
  fix-to-fix speed row: a quarter of its consecutive fixes do not move, while the walker does).
  Simulating that would put the walker's whole 1-s displacement into EasyTrack's label noise and break
  its calibrated levels, so the simulator's fixes keep following the walker.
- **Outages**: IPIN trials 01–02 hold no gap longer than 2.5 s in about 27 min, so the outage rate
  (one per 30 min, median 4 s) is an upper bound chosen to be consistent with that, not a fit.
- **Back pocket and bag** rest on Oxford's two recordings each (two walkers); their spectra are
  reported but not fitted beyond |acc| std.
"""


def simulate_realism_walks(hold: str, n: int, seed: int = 0, duration_s: float = 60.0) -> list[Recording]:
    """``n`` straight-walking (STW) recordings of ``n`` different walkers with the phone in
    ``hold``: the simulated side of the comparison. Subjects come from the simulator's own
    population model (:func:`~wearnav.simulate.sample_subject`), so its cadence spread counts."""
    from wearnav.simulate import WalkConfig, sample_subject, simulate_recording
    from wearnav.simulate.config import HOLDS_OF_PLACEMENT

    placement = next(p for p, holds in HOLDS_OF_PLACEMENT.items() if hold in holds and p != "MP")
    rng = np.random.default_rng(np.random.SeedSequence([seed, 11]))
    recs = []
    for i in range(n):
        subject = sample_subject(rng, f"r{i + 1}")
        cfg = WalkConfig(name=f"realism_{hold}_{i:02d}", subject=subject, mode="STW", placement=placement,
                         phone_hold=hold, duration_s=duration_s, scene="medium",
                         noise_level=("L1", "L2", "L3")[i % 3])
        recs.append(simulate_recording(cfg, seed=int(rng.integers(0, 2**31))))
    return recs


def _open_real(src: RealSource, data: Path, work: Path, limit: int | None):
    from wearnav.dataset import Dataset
    from wearnav.importers import import_dataset

    dest = work / re.sub(r"[^A-Za-z0-9]+", "_", src.fmt + "_" + src.folder).strip("_")
    if (dest / "manifest.csv").exists():
        ds = Dataset.open(dest)
    else:
        folder = data / src.folder
        if not folder.exists():
            raise WearnavError(f"{folder}: real data for the realism report not found")
        ds = import_dataset(src.fmt, folder, dest, progress=False)
    names = [n for n in ds.names if re.search(src.names, n)]
    if limit is not None and len(names) > limit:
        # evenly spread over the list (subjects, floors, trials), not the first few
        names = [names[int(i)] for i in np.linspace(0, len(names) - 1, limit)]
    return ds, names


@dataclass
class SourceResult:
    label: str
    kind: str  # "sim" | "real"
    how: str  # how walking was picked
    rows: list[dict] = field(default_factory=list)
    psd: list[np.ndarray] = field(default_factory=list)
    recordings: int = 0

    def values(self, stat: str) -> np.ndarray:
        v = np.array([r[stat] for r in self.rows], float)
        return v[np.isfinite(v)]


def _summary(v: np.ndarray) -> dict:
    if v.size == 0:
        return {"n": 0}
    q25, q50, q75 = np.percentile(v, [25, 50, 75])
    return {"n": int(v.size), "median": round(float(q50), 4), "q25": round(float(q25), 4),
            "q75": round(float(q75), 4)}


def weighted_quantiles(samples: list[np.ndarray], q) -> np.ndarray:
    """Quantiles of several samples pooled with equal total weight per sample, so a large real
    set does not outvote a small one (ILC2's many short traces against IPIN's few long ones)."""
    samples = [np.asarray(v, float) for v in samples if np.size(v)]
    x = np.concatenate(samples)
    w = np.concatenate([np.full(v.size, 1.0 / v.size) for v in samples])
    order = np.argsort(x)
    x, w = x[order], w[order]
    cdf = (np.cumsum(w) - 0.5 * w) / w.sum()
    return np.interp(np.asarray(q, float), cdf, x)


def band_of(real: list[np.ndarray]) -> tuple[float, float, str] | None:
    """The calibration band of the real samples of a statistic: their pooled IQR (equal weight
    per source), or ±15 % of their pooled median where they hold few segments."""
    n = sum(np.size(v) for v in real)
    if n == 0:
        return None
    if n >= IQR_MIN_SEGMENTS:
        lo, hi = weighted_quantiles(real, [0.25, 0.75])
        return float(lo), float(hi), "IQR"
    m = float(weighted_quantiles(real, 0.5))
    return m - SMALL_SET_TOLERANCE * abs(m), m + SMALL_SET_TOLERANCE * abs(m), "±15 %"


def compare(sim: SourceResult, real: list[SourceResult]) -> dict:
    """Per statistic: sim median, pooled real median and band, and whether the sim is inside."""
    out = {}
    for stat in STATS:
        s = sim.values(stat)
        r = [x.values(stat) for x in real]
        entry = {"sim": _summary(s), "real": _summary(np.concatenate(r) if r else np.empty(0)),
                 "per_source": {x.label: _summary(x.values(stat)) for x in real}}
        band = band_of(r)
        if band is not None and s.size:
            lo, hi, kind = band
            med = float(np.median(s))
            entry.update(band=[round(lo, 4), round(hi, 4)], band_kind=kind, inside=bool(lo <= med <= hi))
        out[stat] = entry
    return out


# ---- the report ------------------------------------------------------------------------------

def _save(fig: Figure, out: Path) -> Path:
    FigureCanvasAgg(fig)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    return out


_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")


def _hist_data(results: list[SourceResult], stat: str, bins: int = 30) -> dict | None:
    vals = [r.values(stat) for r in results]
    allv = np.concatenate(vals) if vals else np.empty(0)
    if allv.size == 0:
        return None
    lo, hi = np.percentile(allv, [1, 99])
    if not hi > lo:
        lo, hi = lo - 0.5, hi + 0.5
    edges = np.linspace(lo, hi, bins + 1)
    return {"edges": np.round(edges, 5).tolist(),
            "density": {r.label: (np.round(np.histogram(np.clip(v, lo, hi), edges, density=True)[0], 5).tolist()
                                  if v.size else []) for r, v in zip(results, vals)}}


def _plot_group(group: Group, results: list[SourceResult], freqs: np.ndarray, out: Path) -> tuple[Path, dict]:
    stats = [s for s in STATS if any(r.values(s).size for r in results)]
    ncol = 4
    nrow = int(np.ceil((len(stats) + 1) / ncol))
    fig = Figure(figsize=(4.0 * ncol, 2.8 * nrow))
    data = {"statistics": {}, "spectrum": {"freq_hz": np.round(freqs, 4).tolist(), "psd": {}}}
    for k, stat in enumerate(stats):
        ax = fig.add_subplot(nrow, ncol, k + 1)
        h = _hist_data(results, stat)
        data["statistics"][stat] = h
        if h is None:
            continue
        for c, r in zip(_COLORS, results):
            d = h["density"][r.label]
            if d:
                ax.stairs(d, h["edges"], color=c, fill=r.kind == "sim", alpha=0.35 if r.kind == "sim" else 1.0,
                          label=f"{r.label} ({r.kind})")
        ax.set_title(STAT_LABELS[stat], fontsize=9)
        ax.tick_params(labelsize=7)
    ax = fig.add_subplot(nrow, ncol, len(stats) + 1)
    for c, r in zip(_COLORS, results):
        if r.psd:
            m = np.median(np.stack(r.psd), axis=0)
            data["spectrum"]["psd"][r.label] = np.round(m, 6).tolist()
            ax.semilogy(freqs, m, color=c, lw=2.0 if r.kind == "sim" else 1.2, label=r.label)
    ax.set_title("median |acc| PSD ((m/s²)²/Hz)", fontsize=9)
    ax.set_xlabel("Hz", fontsize=8)
    ax.tick_params(labelsize=7)
    handles, labels = fig.axes[0].get_legend_handles_labels()
    fig.suptitle(f"{group.title}: walking segments (histograms clipped to the 1st–99th percentile)",
                 y=0.995, fontsize=10)
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.965), ncol=len(results), fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    return _save(fig, out), data


def _plot_fixes(res: dict[str, dict], out: Path) -> tuple[Path, dict]:
    fig = Figure(figsize=(12, 3.2))
    data = {}
    for k, (stat, title, log) in enumerate((("error_m", "fix error at reference points (m)", False),
                                            ("acc_over_error", "reported accuracy / error", True),
                                            ("fix_speed", "fix-to-fix distance / time (m/s)", True))):
        ax = fig.add_subplot(1, 3, k + 1)
        data[stat] = {}
        for c, (label, r) in zip(_COLORS, res.items()):
            v = np.sort(np.asarray(r[stat], float))
            if v.size == 0:
                continue
            cdf = np.arange(1, v.size + 1) / v.size
            ax.step(v, cdf, where="post", color=c, label=f"{label} (n={v.size})")
            q = np.linspace(0, 1, 101)  # the CDF as 101 quantiles keeps the JSON small
            data[stat][label] = {"quantile": q.round(2).tolist(), "x": np.round(np.quantile(v, q), 3).tolist()}
        if log:
            ax.set_xscale("log")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, out), data


def _fmt(x: dict) -> str:
    if not x or x.get("n", 0) == 0:
        return "—"
    return f"{x['median']:.3g} [{x['q25']:.3g}, {x['q75']:.3g}]"


def _band_count(g: dict | None) -> str:
    if g is None:
        return "—"
    e = [v for v in g["compare"].values() if "inside" in v]
    return f"{sum(v['inside'] for v in e)} of {len(e)}"


def _table(groups: dict, claimed: bool = False) -> list[str]:
    lines = []
    for key, g in groups.items():
        lines += [f"### {g['title']}", "",
                  f"Simulated: {g['sim']['label']} ({g['sim']['segments']} segments of "
                  f"{g['sim']['recordings']} recordings). Real: "
                  + (", ".join(f"{r['label']} ({r['segments']} segments of {r['recordings']} recordings, "
                               f"walking by {r['how']})" for r in g["real"]) or "none in the shipped data")
                  + ".", ""]
        reals = [r["label"] for r in g["real"]]
        head = ["statistic", "simulated"] + reals + (["band (pooled real)", "in band"] if reals else [])
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for stat, e in g["compare"].items():
            if e["sim"].get("n", 0) == 0 and e["real"].get("n", 0) == 0:
                continue
            row = [STAT_LABELS[stat].replace("|", "\\|"), _fmt(e["sim"])]
            row += [_fmt(e["per_source"][r]) for r in reals]
            if reals:
                if "band" in e:
                    row += [f"{e['band'][0]:.3g} … {e['band'][1]:.3g} ({e['band_kind']})",
                            "yes" if e["inside"] else "**no**"]
                else:
                    row += ["—", "—"]
            lines.append("| " + " | ".join(row) + " |")
        if claimed and g["real"] and key in CLAIMED:
            lines += ["", "Claimed (re-checked by tests/test_realism.py): "
                      + ", ".join(STAT_LABELS[k].replace("|", "\\|") for k in CLAIMED[key]) + "."]
        lines.append("")
    return lines


def compute_realism(data: Path, work: Path, n_sim: int = 12, limit: int | None = None, seed: int = 0,
                    sim_duration_s: float = SIM_DURATION_S, groups: tuple[Group, ...] = GROUPS,
                    fix_source: RealSource | None = FIX_REAL, progress: bool = False) -> dict:
    """All the numbers of the report (no files but the imported datasets under ``work``)."""
    data, work = Path(data), Path(work)
    sims: dict[str, list[Recording]] = {}
    real_cache: dict[RealSource, SourceResult] = {}
    freqs = spectrum(np.zeros((int(SEGMENT_S * RATE_HZ), 3)))[0]
    results: dict[str, dict] = {}
    figs: dict[str, list[SourceResult]] = {}

    def collect(label, kind, recs_devices):
        res = SourceResult(label, kind, "")
        hows = set()
        for rec, dev in recs_devices:
            if dev not in rec.devices:
                continue
            rows, psds, how = recording_segments(rec, dev)
            hows.add(how)
            res.rows += rows
            res.psd += psds
            res.recordings += 1
        res.how = "/".join(sorted(hows))
        return res

    for g in groups:
        if g.sim_hold not in sims:
            sims[g.sim_hold] = simulate_realism_walks(g.sim_hold, n_sim, seed, sim_duration_s)
        sim = collect(f"sim {g.sim_device}" + (f" {g.sim_hold}" if g.sim_device == "phone" else ""), "sim",
                      [(r, g.sim_device) for r in sims[g.sim_hold]])
        reals = []
        for src in g.real:
            if src not in real_cache:
                ds, names = _open_real(src, data, work, limit)
                real_cache[src] = collect(src.label, "real", ((ds.load(n), src.device) for n in names))
                if progress:
                    print(f"realism: {src.label}: {len(real_cache[src].rows)} segments", flush=True)
            reals.append(real_cache[src])
        figs[g.key] = [sim] + reals
        results[g.key] = {
            "title": g.title,
            "sim": {"label": sim.label, "segments": len(sim.rows), "recordings": sim.recordings},
            "real": [{"label": r.label, "segments": len(r.rows), "recordings": r.recordings, "how": r.how}
                     for r in reals],
            "compare": compare(sim, reals),
        }

    # location fixes: IPIN's phone GNSS at its surveyed points vs the simulator's fixes
    fix = None
    if fix_source is not None:
        ds, names = _open_real(fix_source, data, work, limit)
        fix = {"sim fixes": {k: [] for k in FIX_STATS}, fix_source.label: {k: [] for k in FIX_STATS}}
        for rec in next(iter(sims.values())):
            for k, v in fix_stats(rec).items():
                fix["sim fixes"][k] += v
        for n in names:
            for k, v in fix_stats(ds.load(n)).items():
                fix[fix_source.label][k] += v
    return {"groups": results, "fixes": fix, "_figs": figs, "_freqs": freqs,
            "settings": {"rate_hz": RATE_HZ, "segment_s": SEGMENT_S, "min_segment_s": MIN_SEGMENT_S,
                         "trim_s": TRIM_S, "n_sim": n_sim, "sim_duration_s": sim_duration_s, "limit": limit,
                         "seed": seed, "ilc2_calibration": ILC2_CALIBRATION,
                         "ipin_calibration": IPIN_CALIBRATION}}


def fix_compare(fix: dict) -> dict:
    """Per fix statistic: simulated and real summaries, the real IQR and whether the simulated
    median is inside it (same rule as :func:`compare`)."""
    sim, real = fix["sim fixes"], next(v for k, v in fix.items() if k != "sim fixes")
    out = {}
    for k in FIX_STATS:
        s, r = np.asarray(sim.get(k, []), float), np.asarray(real.get(k, []), float)
        e = {"sim": _summary(s), "real": _summary(r)}
        band = band_of([r])
        if band is not None and s.size:
            e.update(band=[round(band[0], 4), round(band[1], 4)], band_kind=band[2],
                     inside=bool(band[0] <= float(np.median(s)) <= band[1]))
        out[k] = e
    return out


def _fix_table(fix: dict) -> list[str]:
    labels = list(fix)
    comp = fix_compare(fix)
    lines = ["| statistic | " + " | ".join(labels) + " | band (IPIN) | in band |",
             "|---|" + "---|" * (len(labels) + 2)]
    names = {"error_m": "error at reference points (m)", "acc_over_error": "reported accuracy / error",
             "fix_speed": "fix-to-fix distance / time (m/s; walking ≈ 1.3, jumps far above)",
             "outage_s": f"outage length (s, gaps > {OUTAGE_GAP_S:g} s)",
             "outage_share": "share of time in outages (per recording)",
             "jumps_per_100": f"jumps per 100 fixes (> {JUMP_SPEED_MPS:g} m/s apart, per recording)"}
    for k in FIX_STATS:
        row = [names[k]]
        for lab in labels:
            v = np.asarray(fix[lab].get(k, []), float)
            row.append(_fmt(_summary(v)) + (f" (n={v.size})" if v.size else ""))
        e = comp[k]
        if "band" in e:
            row += [f"{e['band'][0]:.3g} … {e['band'][1]:.3g} ({e['band_kind']})", "yes" if e["inside"] else "**no**"]
        else:
            row += ["—", "—"]
        lines.append("| " + " | ".join(row) + " |")
    return lines


def realism_report(data: Path, out: Path, work: Path, n_sim: int = 12, limit: int | None = None,
                   seed: int = 0, before: Path | None = None, json_out: Path | None = None,
                   progress: bool = False, sim_duration_s: float = SIM_DURATION_S,
                   groups: tuple[Group, ...] = GROUPS, fix_source: RealSource | None = FIX_REAL) -> dict:
    """Compute everything, write ``out`` (Markdown), ``<out dir>/img/realism_*.png`` and the JSON
    (default: ``out`` with suffix .json). ``before``: an earlier JSON of this report (e.g. of the
    uncalibrated simulator) whose tables the page shows beside the current ones."""
    from wearnav import __version__
    from wearnav.provenance import git_commit

    if n_sim < 2:
        raise ConfigError("the realism report needs at least 2 simulated walks per placement")
    out = Path(out)
    json_out = Path(json_out) if json_out else out.with_suffix(".json")
    res = compute_realism(data, work, n_sim, limit, seed, sim_duration_s, groups, fix_source, progress)
    img = out.parent / "img"
    figures = {}
    for key, results in res.pop("_figs").items():
        g = next(g for g in groups if g.key == key)
        png, fdata = _plot_group(g, results, res["_freqs"], img / f"realism_{key}.png")
        figures[key] = {"png": os.path.relpath(png, out.parent), **fdata}
    if res["fixes"] is not None:
        png, fdata = _plot_fixes(res["fixes"], img / "realism_fixes.png")
        figures["fixes"] = {"png": os.path.relpath(png, out.parent), **fdata}
    res.pop("_freqs")
    commit = git_commit()
    from wearnav.simulate.walk import SIMULATOR_VERSION

    res["provenance"] = {"wearnav": __version__, "commit": commit, "simulator_version": SIMULATOR_VERSION}
    res["figures"] = figures
    res["fix_compare"] = fix_compare(res["fixes"]) if res["fixes"] is not None else None
    write_text_atomic(json.dumps(res, indent=1, default=float) + "\n", json_out)

    cmd = (f"wearnav realism --data {data} --out {out} --work {work} --n-sim {n_sim}"
           + (f" --limit {limit}" if limit else "") + (f" --before {before}" if before else ""))
    lines = [f"_Generated by `{cmd}` (wearnav {__version__}{', commit ' + commit if commit else ''}); "
             "do not edit by hand._", "", "# How real is the simulated walking?", "",
             re.sub(r":(?:data|func):`([^`]+)`", r"`\1`", (__doc__ or "").split("\n\n", 1)[1].strip()), "",
             f"Each cell: median [25th, 75th percentile] over walking segments. **Band**: the pooled real "
             f"segments' interquartile range (±15 % of their median when fewer than {IQR_MIN_SEGMENTS}); "
             "**in band**: the simulated median lies inside it.", "",
             "## Calibration data", "",
             f"- ILC2: only `{ILC2_CALIBRATION}` (site 1, floor F1). **Odometry benchmarks must not test on "
             "ILC2 floor F1.**",
             "- IPIN 2023: only training trials 01 and 02 (all repetitions). **Odometry and EasyTrack "
             "benchmarks must not evaluate on IPIN trials 01 and 02.**",
             "- MotionSense (`wlk` trials), UJI (phone and watch), Oxford validation (all placements): "
             "used whole; no benchmark evaluates odometry on them.", ""]
    lines += ["## What is calibrated against what", "", CALIBRATION_NOTES, ""]
    prev = json.loads(Path(before).read_text()) if before is not None else None
    lines += ["## Summary: statistics whose simulated median lies in the real band", "",
              "| device and placement | " + ("before calibration | " if prev else "") + "now |",
              "|---|" + ("---|" if prev else "") + "---|"]
    for key, g in res["groups"].items():
        if not g["real"]:
            continue
        cells = [_band_count(prev["groups"].get(key)) if prev else None, _band_count(g)]
        lines.append(f"| {g['title']} | " + " | ".join(c for c in cells if c is not None) + " |")
    was = f", {prev.get('provenance', {}).get('simulator_version', '?')} before (from `{before}`)" if prev else ""
    lines += ["", f"Simulator version {res['provenance']['simulator_version']} now{was}.", ""]
    lines += ["## Now", ""] + _table(res["groups"], claimed=True)
    if res["fixes"] is not None:
        lines += ["### Location fixes", "", f"IPIN: phone GNSS at the surveyed POSI points (trials 01–02); "
                  f"simulator: its fixes against its truth every {SIM_REFERENCE_EVERY_S:g} s.", ""]
        lines += _fix_table(res["fixes"]) + [""]
    for key, f in figures.items():
        lines += [f"![{key}]({f['png']})", ""]
    if prev is not None:
        pv = prev.get("provenance", {})
        lines += ["## Before calibration", "",
                  f"The same report on the simulator before calibration (from `{before}`: simulator version "
                  f"{pv.get('simulator_version', '?')}, wearnav {pv.get('wearnav', '?')}).", ""]
        lines += _table(prev["groups"])
        if prev.get("fixes"):
            lines += ["### Location fixes", ""] + _fix_table(prev["fixes"]) + [""]
    write_text_atomic("\n".join(lines).rstrip() + "\n", out)
    return res
