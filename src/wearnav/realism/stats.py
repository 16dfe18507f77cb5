"""Gait and sensor statistics of one walking segment, and of every segment of a recording.

:func:`segment_stats` computes the statistics of :data:`STATS` on a segment sampled uniformly at
:data:`~.gait.RATE_HZ` (the method is spelt out in :mod:`.report`'s docstring, which the page
prints); :func:`spectrum` the |acc| PSD the report overlays; :func:`recording_segments` both for
every walking segment of one device of a recording.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.signal import butter, filtfilt, find_peaks, periodogram, welch

from wearnav.core import rotations
from wearnav.realism.gait import MIN_SEGMENT_S, RATE_HZ, resample, segments, walking_stretches
from wearnav.recording import Recording

STRIDE_LAGS_S = (0.8, 1.6)
F_DOM_BAND_HZ = (0.5, 4.0)
BANDS = ((0.3, 1.2), (1.2, 2.6), (2.6, 5.0), (5.0, 8.0), (8.0, 12.5))
_F_DOM_NFFT = 8192  # zero-padding of the f_dom periodogram: 25 Hz / 8192 = 0.003 Hz bins
_PSD_NPERSEG = 64  # Welch segment length: 25 Hz / 64 = 0.39 Hz bins
# Step search (set by hand with the statistics, not fitted): one step is half a stride, so the
# step peak of the autocorrelation is sought at 40–60 % of the stride lag, and the step peaks of
# |acc| at least 60 % of a step apart. |acc| is low-passed at 4 Hz (4th-order Butterworth, zero
# phase) before the peaks are picked: it keeps the step frequency (STEP_BAND_HZ, at most 2.6 Hz)
# and removes the heel-strike spikes above it.
STEP_LAG_SHARE = (0.4, 0.6)
MIN_STEP_SPACING = 0.6
STEP_LOWPASS_HZ = 4.0
STEP_LOWPASS_ORDER = 4

STATS = ("acc_std", "gyro_mean", "f_dom", "cadence", "step_reg", "step_cv", "amp_cv", "hv_ratio") + tuple(
    f"band_{lo:g}_{hi:g}" for lo, hi in BANDS
)
STAT_LABELS = {
    "acc_std": "|acc| std (m/s²)",
    "gyro_mean": "|gyro| mean (rad/s)",
    "f_dom": "f_dom (Hz)",
    "cadence": "cadence (steps/s)",
    "step_reg": "autocorr 1 step",
    "step_cv": "step-period CV",
    "amp_cv": "step-amplitude CV",
    "hv_ratio": "horiz/vert acc",
    **{f"band_{lo:g}_{hi:g}": f"power {lo:g}–{hi:g} Hz" for lo, hi in BANDS},
}


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


def segment_stats(
    acc: np.ndarray, gyro: np.ndarray | None = None, acc_world: np.ndarray | None = None, rate: float = RATE_HZ
) -> dict[str, float]:
    """The statistics of one walking segment sampled uniformly at ``rate`` (module doc, step 3)."""
    x = np.linalg.norm(acc, axis=1)
    n = x.size
    out = {k: float("nan") for k in STATS}
    out["acc_std"] = float(x.std())
    if gyro is not None:
        out["gyro_mean"] = float(np.linalg.norm(gyro, axis=1).mean())
    xc = x - x.mean()
    f, p = periodogram(xc, rate, window="hann", nfft=max(_F_DOM_NFFT, n))
    band = (f >= F_DOM_BAND_HZ[0]) & (f <= F_DOM_BAND_HZ[1])
    out["f_dom"] = float(f[band][np.argmax(p[band])])

    ac = _autocorr(x)
    stride_lag, _ = _peak(ac, int(STRIDE_LAGS_S[0] * rate), int(np.ceil(STRIDE_LAGS_S[1] * rate)) + 1)
    if np.isfinite(stride_lag):
        out["cadence"] = float(2.0 * rate / stride_lag)
        step_lag, step_val = _peak(
            ac, int(STEP_LAG_SHARE[0] * stride_lag), int(np.ceil(STEP_LAG_SHARE[1] * stride_lag)) + 1
        )
        out["step_reg"] = step_val
        # steps: peaks of the low-passed |acc|, at least MIN_STEP_SPACING of a step apart
        b, a = butter(STEP_LOWPASS_ORDER, STEP_LOWPASS_HZ / (0.5 * rate))
        y = filtfilt(b, a, x) if n > 30 else x
        pk, _ = find_peaks(y, distance=max(1, int(MIN_STEP_SPACING * stride_lag / 2)))
        if pk.size >= 4:
            times = np.array([_peak(y, i, i + 1)[0] for i in pk]) / rate
            per = np.diff(times)
            out["step_cv"] = float(per.std() / per.mean())
            amps = np.array([y[i] - y[i:j].min() for i, j in zip(pk[:-1], pk[1:])])
            out["amp_cv"] = float(amps.std() / amps.mean()) if amps.mean() > 0 else float("nan")

    fw, pw = welch(xc, rate, nperseg=min(n, _PSD_NPERSEG))
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
    return welch(x - x.mean(), rate, nperseg=_PSD_NPERSEG)


def recording_segments(rec: Recording, device: str) -> tuple[list[dict], list[np.ndarray], str]:
    """Statistics and PSDs of every walking segment of one device of a recording."""
    s = rec.devices[device]
    intervals, how = walking_stretches(rec, device)
    if s.quat is not None:
        acc_world = rotations.apply(s.quat, np.asarray(s.acc, float))
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
        st: dict[str, Any] = segment_stats(acc, gyro, aw)
        st.update(recording=rec.name, start=round(a, 3), end=round(b, 3))
        rows.append(st)
        psds.append(spectrum(acc)[1])
    return rows, psds, how
