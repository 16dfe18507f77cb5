"""Walking stretches of a recording, resampled to one rate and cut into analysis segments.

Where a dataset labels walking, :func:`labelled_walking` reads the labels; otherwise
:func:`detect_walking` decides window by window from |acc| (and |gyro|). :func:`segments` trims
each stretch and cuts it into the segments that every statistic of :mod:`.stats` is computed on;
:func:`resample` brings any stream to :data:`RATE_HZ` so that devices of 25–220 Hz compare alike.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import periodogram, resample_poly

from wearnav.recording import Recording

RATE_HZ = 25.0  # the common rate: the slowest device in the comparison (earbuds) streams at 25 Hz
_GRID_HZ = 100.0  # the uniform grid everything is interpolated onto before decimating to 25 Hz
SEGMENT_S = 10.0
MIN_SEGMENT_S = 4.0
TRIM_S = 1.0
STEP_BAND_HZ = (1.2, 2.6)
WALK_STD_BAND = (0.5, 8.0)  # m/s², |acc| std of walking (still: < 0.2; running: > 8)
WALK_WINDOW_S = 2.0
MAX_WALK_GYRO = 3.0  # rad/s
MAX_STEP_GAP_S = 1.0
# The detector's spectral test (set by hand when the detector was written, not fitted): the |acc|
# power between 0.5 and 5 Hz holds walking's step frequency and its first harmonics (below: posture
# drift, above: impacts), and at least 40 % of that power must lie in STEP_BAND_HZ.
WALK_POWER_BAND_HZ = (0.5, 5.0)
MIN_STEP_POWER_SHARE = 0.4
_DETECT_NFFT = 256  # periodogram length of one 2-s window (50 samples at 25 Hz): 0.1 Hz bins


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
        w = x[s : s + n]
        sd = w.std()
        if not WALK_STD_BAND[0] <= sd <= WALK_STD_BAND[1]:
            continue
        if g is not None and g[s : s + n].mean() > MAX_WALK_GYRO:
            continue
        f, p = periodogram(w - w.mean(), RATE_HZ, window="hann", nfft=_DETECT_NFFT)
        band = (f >= WALK_POWER_BAND_HZ[0]) & (f <= WALK_POWER_BAND_HZ[1])
        if not band.any() or p[band].sum() <= 0:
            continue
        fb, pb = f[band], p[band]
        peak = fb[np.argmax(pb)]
        step = (fb >= STEP_BAND_HZ[0]) & (fb <= STEP_BAND_HZ[1])
        if STEP_BAND_HZ[0] <= peak <= STEP_BAND_HZ[1] and pb[step].sum() >= MIN_STEP_POWER_SHARE * pb.sum():
            walk[s + n // 4 : s + n - n // 4] = True  # the window's centre: edges good to ±0.5 s
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
