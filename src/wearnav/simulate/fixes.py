"""Noisy phone location fixes ("phone labels") with a calibrated, correlated error.

EasyTrack (Sec. III-A/B) labels a 1-s IMU segment with the displacement between the phone's
reported positions at its ends, P̃(i+1) − P̃(i). The label noise is then (eq. 5–7)

    d_e(i) = d(i) − d̃(i) = P_e(i+1) − P_e(i),

the increment of the position error P_e, so consecutive label noises are dependent (eq. 7) and
its size is set by how fast the position error changes, not by how large it is. Table I reports
median |d_e| of 21.6, 27.6 and 33.5 cm for the datasets DS_L1, DS_L2 and DS_L3.

Model: each horizontal axis of P_e is an Ornstein–Uhlenbeck process with stationary std σ and
correlation time τ (GNSS errors wander over minutes), started from its stationary distribution
and sampled exactly. Over a segment of Δ seconds the increment of one axis is Gaussian with

    Var = 2 σ² (1 − e^(−Δ/τ)),

so |d_e| is Rayleigh with median s·√(2 ln 2), s² = that variance (the metric itself is
:func:`wearnav.metrics.label_noise`). :class:`FixNoise` inverts this:
given the median label noise (and τ), σ follows analytically. With τ = 120 s the three levels
give σ ≈ 1.4 / 1.8 / 2.2 m per axis (2.0 / 2.6 / 3.1 m RMS horizontal error), typical of phone
GNSS in open sky. The reported ``accuracy`` (like iOS ``horizontalAccuracy``, a ~68 % radius) is
1.515 σ (the 68 % radius of a circular Gaussian) with ±15 % log-normal jitter per fix.

On top of the OU error, :func:`simulate_fixes` adds what real phone GNSS does (calibrated against
IPIN 2023 trials 01–02, docs/realism.md): multipath episodes, a sudden offset of a few metres
(log-normal, median ``jump_median_m``) held for an exponential time (mean ``jump_hold_s``) and
then dropped, at ``jump_rate_hz``; and outages, stretches without fixes (log-normal length,
median ``outage_median_s``) at ``outage_rate_hz``. While an offset is on, the reported accuracy
grows with it (√((1.515 σ)² + |offset|²)), so the accuracy tracks the error as a phone's does.
The jumps touch two 1-s segments per episode, so the median label noise is unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wearnav.errors import ConfigError
from wearnav.recording import Fixes

# EasyTrack Table I: median phone-label noise per noise level, metres.
LABEL_NOISE_MEDIAN_M = {"L1": 0.216, "L2": 0.276, "L3": 0.335}
RAYLEIGH_MEDIAN = float(np.sqrt(2 * np.log(2)))  # median of |N(0, I₂)|
RADIUS_68 = 1.515  # radius holding 68 % of a unit circular Gaussian: sqrt(-2 ln 0.32)


@dataclass(frozen=True)
class FixNoise:
    """Position error model calibrated by its median label noise over ``segment_s`` seconds."""

    median_label_noise_m: float = LABEL_NOISE_MEDIAN_M["L1"]
    correlation_s: float = 120.0
    segment_s: float = 1.0
    accuracy_jitter: float = 0.15
    jump_rate_hz: float = 0.006  # multipath episodes per second (IPIN T01-02: ~0.8 jumps per 100 fixes)
    jump_median_m: float = 6.0
    jump_hold_s: float = 15.0
    outage_rate_hz: float = 1.0 / 1800.0  # IPIN trials 01-02: no gap > 2.5 s in 27 min
    outage_median_s: float = 4.0

    def __post_init__(self):
        if self.median_label_noise_m <= 0 or self.correlation_s <= 0 or self.segment_s <= 0:
            raise ConfigError("FixNoise parameters must be positive")
        if min(self.jump_rate_hz, self.outage_rate_hz) < 0 or min(self.jump_median_m, self.jump_hold_s,
                                                                  self.outage_median_s) <= 0:
            raise ConfigError("FixNoise jump and outage parameters must be positive (rates may be 0)")

    @classmethod
    def from_level(cls, level: str, correlation_s: float = 120.0) -> "FixNoise":
        if level not in LABEL_NOISE_MEDIAN_M:
            raise ConfigError(f"unknown noise level {level!r} (expected one of {', '.join(LABEL_NOISE_MEDIAN_M)})")
        return cls(LABEL_NOISE_MEDIAN_M[level], correlation_s)

    @property
    def increment_std(self) -> float:
        """Per-axis std s of the error increment over one segment (median |d_e| = s·√(2 ln 2))."""
        return self.median_label_noise_m / RAYLEIGH_MEDIAN

    @property
    def sigma(self) -> float:
        """Stationary per-axis std of the position error, m."""
        rho = np.exp(-self.segment_s / self.correlation_s)
        return float(self.increment_std / np.sqrt(2.0 * (1.0 - rho)))

    def sample_error(self, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(N, 2) error at increasing times t: exact OU transitions, stationary start."""
        t = np.asarray(t, dtype=np.float64)
        sigma, tau = self.sigma, self.correlation_s
        rho = np.exp(-np.diff(t) / tau)
        z = rng.standard_normal((t.size, 2))
        e = np.empty((t.size, 2))
        e[0] = sigma * z[0]
        innov = sigma * np.sqrt(1.0 - rho * rho)[:, None] * z[1:]
        for i in range(1, t.size):  # a scalar recursion; a few thousand steps per recording
            e[i] = rho[i - 1] * e[i - 1] + innov[i - 1]
        return e

    def accuracy(self, n: int, rng: np.random.Generator, offset_m: np.ndarray | None = None) -> np.ndarray:
        base = RADIUS_68 * self.sigma if offset_m is None else np.hypot(RADIUS_68 * self.sigma, offset_m)
        acc = base * np.exp(rng.normal(0.0, self.accuracy_jitter, n))
        return np.round(acc, 1)

    def _episodes(self, t0: float, t1: float, rate: float, length, rng) -> list[tuple[float, float]]:
        """Poisson-started intervals over [t0, t1] with lengths drawn by ``length()``."""
        out, t = [], t0
        while rate > 0:
            t += rng.exponential(1.0 / rate)
            if t >= t1:
                return out
            d = float(length())
            out.append((t, t + d))
            t += d
        return out

    def sample_multipath(self, t: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2) multipath offsets and a keep mask (False inside outages) at times t."""
        t = np.asarray(t, dtype=np.float64)
        offset = np.zeros((t.size, 2))
        keep = np.ones(t.size, bool)
        if t.size == 0:
            return offset, keep
        for a, b in self._episodes(t[0], t[-1], self.jump_rate_hz, lambda: rng.exponential(self.jump_hold_s), rng):
            size = self.jump_median_m * np.exp(rng.normal(0.0, 0.5))
            ang = rng.uniform(-np.pi, np.pi)
            offset[(t >= a) & (t < b)] = size * np.array([np.cos(ang), np.sin(ang)])
        for a, b in self._episodes(t[0], t[-1], self.outage_rate_hz,
                                   lambda: self.outage_median_s * np.exp(rng.normal(0.0, 0.6)), rng):
            keep &= ~((t >= a) & (t < b))
        return offset, keep


def simulate_fixes(t: np.ndarray, true_xy: np.ndarray, noise: FixNoise,
                   rng: np.random.Generator) -> Fixes:
    """Fixes at times ``t`` for a walker whose true horizontal position there is ``true_xy``."""
    true_xy = np.asarray(true_xy, dtype=np.float64)[:, :2]
    err = noise.sample_error(t, rng)
    offset, keep = noise.sample_multipath(t, rng)
    acc = noise.accuracy(len(t), rng, np.linalg.norm(offset, axis=1))
    return Fixes(t=t[keep], pos=(true_xy + err + offset)[keep], accuracy=acc[keep])

