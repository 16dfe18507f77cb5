"""Sampled time series: putting a stream onto another clock, its rate, and repeated timestamps.

The only implementations in wearnav of

* :func:`interp_onto`: a stream evaluated at other times by linear interpolation (quaternions
  sign-aligned and renormalised), with a mask saying where the result can be trusted. The
  **gap rule** is always explicit: ``max_gap`` seconds, and ``rule`` says what it bounds:

  - ``"hole"`` (default): a target time is valid when it lies inside the source's span and the
    two source samples around it are at most ``max_gap`` apart (interpolating across a longer
    hole would invent data). A target time equal to a source sample is always valid: nothing
    is interpolated there.
  - ``"nearest"``: a target time is valid when some source sample lies within ``max_gap`` of
    it, also just outside the span (where the end sample is held, never extrapolated). This
    scores sparse references against an estimate (:func:`wearnav.metrics.errors_at_reference`).

  :func:`periods` writes a gap rule relative to the source rate ("k sample periods").
* :func:`rate` / :func:`sampling`: the sampling rate is 1 / median interval (robust to the odd
  late sample); jitter is the interquartile range of the intervals.
* :func:`nearest`: the index of the nearest sample of a sorted clock (a fix, a scan, a beacon
  reading at another stream's times).
* :func:`drop_duplicate_times`: the one policy for repeated timestamps (keep the first of each
  run, count the rest; refuse time going backwards or too many repeats).

Callers choose ``max_gap`` for a reason and say it where they call; the values in use:

====================================  ============  ==============================================
call site                             max_gap       why
====================================  ============  ==============================================
importers (gyro/orientation onto acc) 0.25 s        a fixed time: merging sensors of one phone at
                                                    import; longer holes are lost samples
``preprocess.stream_to_clock``        3 periods     a device's own rate (25–200 Hz): a dropped
                                                    sample or two is jitter, more is a hole
``preprocess.interpolate_position``   1 s           dense truth only; sparse waypoints (seconds
                                                    apart) are not turned into dense targets
``metrics.errors_at_reference``       caller's      ``"nearest"``: fixes within 2.5 s of a truth
                                                    point (``metrics.FIX_MAX_GAP_S``)
``fixlabels.fix_frame_yaw``           2.5 s         fixes onto the IMU clock across one missed
                                                    1-Hz fix (``metrics.FIX_MAX_GAP_S``)
====================================  ============  ==============================================
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wearnav.errors import ConfigError, ValidationError

GAP_RULES = ("hole", "nearest")
# A few repeated timestamps happen when a sensor batches or caches events; beyond this share the
# clock is broken and silently thinning the stream would hide it.
MAX_DUPLICATE_SHARE = 0.05


# ---- rate --------------------------------------------------------------------------------


def rate(t) -> float:
    """Sampling rate in Hz: 1 / median interval (0 for fewer than two samples)."""
    t = np.asarray(t, dtype=np.float64)
    if t.size < 2:
        return 0.0
    med = float(np.median(np.diff(t)))
    return 1.0 / med if med > 0 else 0.0


def period(t) -> float:
    """Median interval between samples in seconds (0 for fewer than two samples)."""
    t = np.asarray(t, dtype=np.float64)
    return float(np.median(np.diff(t))) if t.size > 1 else 0.0


def periods(k: float, rate_hz: float) -> float:
    """A gap rule of ``k`` sample periods of a stream sampled at ``rate_hz``, in seconds."""
    return k / max(rate_hz, 1e-9)


@dataclass(frozen=True)
class Sampling:
    """How regularly a stream is sampled (from its intervals between consecutive samples)."""

    rate_hz: float  # 1 / median interval
    interval_median_s: float
    jitter_iqr_s: float  # interquartile range (75th − 25th percentile) of the intervals
    gap_share: float  # share of intervals longer than twice the median


def sampling(dt) -> Sampling:
    """:class:`Sampling` of the intervals ``dt`` (e.g. ``np.diff(t)``, or several streams'
    intervals pooled); NaN fields when there are none."""
    dt = np.asarray(dt, dtype=np.float64)
    if dt.size == 0:
        return Sampling(float("nan"), float("nan"), float("nan"), float("nan"))
    q25, med, q75 = np.percentile(dt, [25, 50, 75])
    return Sampling(
        rate_hz=1.0 / float(med) if med > 0 else float("nan"),
        interval_median_s=float(med),
        jitter_iqr_s=float(q75 - q25),
        gap_share=float(np.mean(dt > 2 * med)),
    )


# ---- one clock onto another ----------------------------------------------------------------


def nearest(t_src, t_dst) -> np.ndarray:
    """For each time of ``t_dst``, the index of the nearest time in ``t_src`` (sorted ascending; at a
    tie the earlier). ``t_src`` must not be empty."""
    t_src, t_dst = np.asarray(t_src, np.float64), np.asarray(t_dst, np.float64)
    if t_src.size < 2:
        return np.zeros(t_dst.shape, np.intp)
    k = np.clip(np.searchsorted(t_src, t_dst), 1, t_src.size - 1)
    return np.where(np.abs(t_src[k - 1] - t_dst) <= np.abs(t_src[k] - t_dst), k - 1, k)


def covered(t_dst, t_src, max_gap: float, rule: str = "hole") -> np.ndarray:
    """(len(t_dst),) bool: where values interpolated from samples at ``t_src`` are trustworthy
    under the gap rule (``max_gap`` seconds, ``rule`` "hole" or "nearest"; module docstring)."""
    t_dst = np.asarray(t_dst, dtype=np.float64)
    t_src = np.asarray(t_src, dtype=np.float64)
    if rule not in GAP_RULES:
        raise ConfigError(f"gap rule must be one of {GAP_RULES}, got {rule!r}")
    if not max_gap >= 0:
        raise ConfigError(f"max_gap must be >= 0 seconds, got {max_gap}")
    n = t_src.size
    if n == 0:
        return np.zeros(t_dst.shape, bool)
    j = np.searchsorted(t_src, t_dst)
    before = t_src[np.clip(j - 1, 0, n - 1)]
    after = t_src[np.clip(j, 0, n - 1)]
    if rule == "nearest":
        return np.minimum(np.abs(t_dst - before), np.abs(after - t_dst)) <= max_gap
    inside = (t_dst >= t_src[0]) & (t_dst <= t_src[-1])
    if n == 1:
        return inside
    # The hole holding each target: samples j-1 and j (the first interval for the first sample).
    k = np.clip(j, 1, n - 1)
    ok = (t_src[k] - t_src[k - 1]) <= max_gap
    return inside & (ok | (after == t_dst))


def interp_onto(
    t_dst, t_src, values, max_gap: float, rule: str = "hole", quaternion: bool = False, fill: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``values`` (N, C) sampled at ``t_src`` evaluated at ``t_dst``, and the (M,) mask of
    :func:`covered` (gap rule ``max_gap`` / ``rule``; see the module docstring).

    Linear per column; outside the source span the end values are held (np.interp), never
    extrapolated. ``quaternion``: (w, x, y, z) rows are first made sign-continuous (q and −q are
    the same rotation), interpolated linearly and renormalised. ``fill``: masked rows are set to
    this value (e.g. NaN, 0); None leaves the interpolated values (callers that drop rows).
    When the clocks are identical ``values`` come back as they are.
    """
    t_dst = np.asarray(t_dst, dtype=np.float64)
    t_src = np.asarray(t_src, dtype=np.float64)
    mask = covered(t_dst, t_src, max_gap, rule)
    if t_src.shape == t_dst.shape and np.array_equal(t_src, t_dst):
        return values, mask
    values = np.asarray(values, dtype=np.float64)
    if quaternion:
        from wearnav.core.rotations import sign_continuous

        values = sign_continuous(values)
    out = np.column_stack([np.interp(t_dst, t_src, values[:, k]) for k in range(values.shape[1])])
    if quaternion:
        out /= np.linalg.norm(out, axis=1, keepdims=True)
    if fill is not None:
        out[~mask] = fill
    return out, mask


# ---- repeated timestamps -------------------------------------------------------------------


def drop_duplicate_times(
    t, what: str, path: str | Path | None = None, max_share: float = MAX_DUPLICATE_SHARE
) -> tuple[np.ndarray, int]:
    """The one policy for repeated timestamps: indices keeping the **first** sample of each run
    of equal timestamps, and how many were dropped (importers report the count in
    ``meta["dropped_duplicates"]``).

    Why the first: a repeat comes from a sensor batching or caching events (Sensor Logger's
    README: "the same value twice with identical timestamps"); the first delivery is the
    sample, and averaging would make up a value nobody measured. Raises
    :class:`~wearnav.errors.ValidationError` when time goes backwards, or when more than
    ``max_share`` of the timestamps repeat (one repeat is always tolerated, for short series
    such as waypoints): then the clock is broken, and thinning it would hide that.
    """
    t = np.asarray(t)
    dt = np.diff(t)
    if np.any(dt < 0):
        i = int(np.argmax(dt < 0)) + 1
        raise ValidationError(
            f"{what}: timestamps go backwards at row {i} of that type ({t[i - 1]!r} then {t[i]!r})", path
        )
    keep = np.concatenate([[True], dt > 0])
    n_dup = int(t.size - keep.sum())
    if n_dup > max(1.0, max_share * t.size):
        raise ValidationError(f"{what}: {n_dup} of {t.size} timestamps are duplicated (clock broken?)", path)
    return np.flatnonzero(keep), n_dup
