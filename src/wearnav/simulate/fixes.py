"""Noisy phone location fixes ("phone labels") with a calibrated, correlated, heavy-tailed error.

EasyTrack (Sec. III-A/B) labels a 1-s IMU segment with the displacement between the phone's
reported positions at its ends, P̃(i+1) − P̃(i). The label noise is then (eqs. 5–7)

    d_e(i) = d(i) − d̃(i) = P_e(i+1) − P_e(i),

the increment of the position error P_e, so consecutive label noises are dependent (eq. 7) and
its size is set by how fast the position error changes, not by how large it is. Table I reports
median |d_e| of 21.6, 27.6 and 33.5 cm for DS_L1, DS_L2 and DS_L3; Fig. 1a shows noise over
200 cm; observation O2 says the noise is correlated along a trajectory.

Model, per horizontal axis, P_e = b + f + m:

* ``b``, the slow bias (satellite geometry, atmosphere): an Ornstein–Uhlenbeck process with
  correlation time ``correlation_s`` (120 s), wandering over minutes. Its 1-s increments are
  nearly independent (neighbour r = −(1 − e^(−Δ/τ))/2 ≈ 0).
* ``f``, the receiver filter's error. A phone does not report raw GNSS solutions: its Kalman
  filter carries a velocity state, and a velocity error persists for seconds before the
  measurements pull the position back. ``f`` is that error: a velocity error with correlation
  time T = ``filter_s`` (3 s) whose position is pulled back with the same time constant, the
  critically damped second-order Gauss–Markov process with autocovariance
  C(Δ) = σ_f² (1 + Δ/T) e^(−Δ/T), sampled exactly in its state (f, ḟ). Its 1-s increments keep
  their sign over seconds: neighbour r = (2 C(Δ) − C(2Δ) − C(0)) / (2 (C(0) − C(Δ))) = 0.62 at
  T = 3 s. ``filter_share`` of the Gaussian increment variance is f's, the rest b's.
* ``m``, multipath episodes (Poisson, ``jump_rate_hz``): an offset of log-normal size (median
  ``jump_median_m``) in a random direction that the receiver's filter does not take at once but
  ramps in over 0–``jump_ramp_s`` seconds (uniform), holds for an exponential time (mean
  ``jump_hold_s``) and ramps out the same way. A slow ramp spreads the offset over several labels
  of 1–3 m noise each (Fig. 1a's tail); a ramp under a second is the gross jump a plausibility
  filter drops. While an offset is on, the reported accuracy grows with it.
* outages: stretches without fixes (log-normal length, median ``outage_median_s``).

Calibration (:meth:`FixNoise.increment_std`): b and f are Gaussian, so outside multipath the
label noise is Rayleigh with per-axis increment std s; the ramps put a share p of the labels far
above the median (p = rate · 2 (E[ramp] / Δ + 1), each ramp touches ramp/Δ + 1 labels on
average), so the median of the mixture is the target when (1 − p)(1 − e^(−m²/2s²)) = ½, i.e.
s = m / √(−2 ln(1 − ½/(1 − p))). tests/test_simulate.py checks the medians after the labeller's
jump filter against Table I within ±1 cm, the neighbour correlation and the tail shares.
The rates and sizes of ``m`` and the outages are calibrated against IPIN 2023 trials 01–02
(docs/realism.md); the neighbour correlation is chosen inside the range IPIN's fixes allow
(Decision: docs/decisions/0008-label-noise-model.md).
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


def _gm2_increment_var(delta: float, T: float) -> float:
    """Variance of a Δ-increment of the unit critically damped Gauss–Markov process: 2 (C(0) − C(Δ))."""
    a = delta / T
    return 2.0 * (1.0 - (1.0 + a) * np.exp(-a))


@dataclass(frozen=True)
class FixNoise:
    """Position error model calibrated by its median label noise over ``segment_s`` seconds."""

    median_label_noise_m: float = LABEL_NOISE_MEDIAN_M["L1"]
    correlation_s: float = 120.0  # slow bias b
    segment_s: float = 1.0
    filter_s: float = 3.0  # receiver filter's velocity-error time constant T (f)
    filter_share: float = 0.25  # share of the Gaussian increment variance that is f's
    accuracy_jitter: float = 0.15
    jump_rate_hz: float = 0.006  # multipath episodes per second (IPIN T01-02: ~0.5 jumps per 100 fixes)
    jump_median_m: float = 6.0
    jump_hold_s: float = 15.0
    jump_ramp_s: float = 5.0  # ramp in / out lasts U(0, jump_ramp_s) seconds
    outage_rate_hz: float = 1.0 / 1800.0  # IPIN trials 01-02: no gap > 2.5 s in 27 min
    outage_median_s: float = 4.0

    def __post_init__(self):
        if (
            min(self.median_label_noise_m, self.correlation_s, self.segment_s, self.filter_s) <= 0
            or not 0 <= self.filter_share <= 1
        ):
            raise ConfigError("FixNoise parameters must be positive (filter_share in [0, 1])")
        if (
            min(self.jump_rate_hz, self.outage_rate_hz, self.jump_ramp_s) < 0
            or min(self.jump_median_m, self.jump_hold_s, self.outage_median_s) <= 0
        ):
            raise ConfigError("FixNoise jump and outage parameters must be positive (rates and ramp may be 0)")
        if self.multipath_share >= 0.5:
            raise ConfigError(
                f"multipath episodes touch {self.multipath_share:.0%} of the labels: no median left to calibrate"
            )

    @classmethod
    def from_level(cls, level: str, correlation_s: float = 120.0) -> FixNoise:
        if level not in LABEL_NOISE_MEDIAN_M:
            raise ConfigError(f"unknown noise level {level!r} (expected one of {', '.join(LABEL_NOISE_MEDIAN_M)})")
        return cls(LABEL_NOISE_MEDIAN_M[level], correlation_s)

    @property
    def multipath_share(self) -> float:
        """Expected share p of segments a multipath ramp touches (module docstring)."""
        return self.jump_rate_hz * self.segment_s * 2.0 * (0.5 * self.jump_ramp_s / self.segment_s + 1.0)

    @property
    def increment_std(self) -> float:
        """Per-axis std s of the Gaussian (b + f) increment over one segment, from the median."""
        q = 1.0 - 0.5 / (1.0 - self.multipath_share)
        return self.median_label_noise_m / float(np.sqrt(-2.0 * np.log(q)))

    @property
    def bias_sigma(self) -> float:
        """Stationary per-axis std of the slow bias b, m."""
        rho = np.exp(-self.segment_s / self.correlation_s)
        return float(self.increment_std * np.sqrt((1.0 - self.filter_share) / (2.0 * (1.0 - rho))))

    @property
    def filter_sigma(self) -> float:
        """Stationary per-axis std of the receiver-filter error f, m."""
        return float(
            self.increment_std * np.sqrt(self.filter_share / _gm2_increment_var(self.segment_s, self.filter_s))
        )

    @property
    def sigma(self) -> float:
        """Stationary per-axis std of the Gaussian position error b + f, m."""
        return float(np.hypot(self.bias_sigma, self.filter_sigma))

    def sample_error(self, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(N, 2) Gaussian error b + f at increasing times t: exact transitions, stationary start."""
        t = np.asarray(t, dtype=np.float64)
        dt = np.diff(t)
        sb, tau, sf, T = self.bias_sigma, self.correlation_s, self.filter_sigma, self.filter_s
        # state per axis: (b, f, ḟ); b is OU, (f, ḟ) critically damped: Φ = e^(−h/T)[[1+h/T, h], [−h/T², 1−h/T]]
        rho = np.exp(-dt / tau)
        e, a = np.exp(-dt / T), dt / T
        phi = np.zeros((dt.size, 3, 3))
        phi[:, 0, 0] = rho
        phi[:, 1, 1], phi[:, 1, 2] = e * (1 + a), e * dt
        phi[:, 2, 1], phi[:, 2, 2] = -e * a / T, e * (1 - a)
        P = np.diag([sb * sb, sf * sf, (sf / T) ** 2])  # stationary covariance
        Q = P[None] - phi @ P @ phi.transpose(0, 2, 1)
        L = np.linalg.cholesky(Q + 1e-15 * np.eye(3))
        z = rng.standard_normal((t.size, 3, 2))
        x = np.empty((t.size, 3, 2))
        x[0] = np.sqrt(np.diag(P))[:, None] * z[0]
        innov = L @ z[1:]
        for i in range(1, t.size):  # a 3×3 recursion; a few thousand steps per recording
            x[i] = phi[i - 1] @ x[i - 1] + innov[i - 1]
        return x[:, 0] + x[:, 1]

    def accuracy(self, n: int, rng: np.random.Generator, offset_m: np.ndarray | None = None) -> np.ndarray:
        base = RADIUS_68 * self.sigma if offset_m is None else np.hypot(RADIUS_68 * self.sigma, offset_m)
        acc = base * np.exp(rng.normal(0.0, self.accuracy_jitter, n))
        return np.round(acc, 1)

    def _episodes(self, t0: float, t1: float, rate: float, length, rng) -> list[tuple[float, float]]:
        """Poisson-started intervals over [t0, t1] with lengths drawn by ``length()``."""
        out: list[tuple[float, float]] = []
        t = t0
        while rate > 0:
            t += rng.exponential(1.0 / rate)
            if t >= t1:
                return out
            d = float(length())
            out.append((t, t + d))
            t += d
        return out

    def sample_multipath(self, t: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2) multipath offsets (ramped in and out) and a keep mask (False inside outages) at times t."""
        t = np.asarray(t, dtype=np.float64)
        offset = np.zeros((t.size, 2))
        keep = np.ones(t.size, bool)
        if t.size == 0:
            return offset, keep
        for a, b in self._episodes(t[0], t[-1], self.jump_rate_hz, lambda: rng.exponential(self.jump_hold_s), rng):
            size = self.jump_median_m * np.exp(rng.normal(0.0, 0.5))
            ang = rng.uniform(-np.pi, np.pi)
            r_in, r_out = rng.uniform(0.0, self.jump_ramp_s, 2) + 1e-9
            w = np.clip((t - a) / r_in, 0.0, 1.0) - np.clip((t - b - r_in) / r_out, 0.0, 1.0)  # full after a + r_in
            offset += (size * w)[:, None] * np.array([np.cos(ang), np.sin(ang)])
        for a, b in self._episodes(
            t[0], t[-1], self.outage_rate_hz, lambda: self.outage_median_s * np.exp(rng.normal(0.0, 0.6)), rng
        ):
            keep &= ~((t >= a) & (t < b))
        return offset, keep


def simulate_fixes(t: np.ndarray, true_xy: np.ndarray, noise: FixNoise, rng: np.random.Generator) -> Fixes:
    """Fixes at times ``t`` for a walker whose true horizontal position there is ``true_xy``."""
    true_xy = np.asarray(true_xy, dtype=np.float64)[:, :2]
    err = noise.sample_error(t, rng)
    offset, keep = noise.sample_multipath(t, rng)
    acc = noise.accuracy(len(t), rng, np.linalg.norm(offset, axis=1))
    return Fixes(t=t[keep], pos=(true_xy + err + offset)[keep], accuracy=acc[keep])
