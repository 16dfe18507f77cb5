"""From a device's true motion to what its IMU reports.

Ideal measurements (:func:`true_imu`):

- specific force f = Rᵀ (a − g), g = (0, 0, −9.81) m/s² in the z-up world, so a device at rest
  reads +9.81 m/s² along its world-up axis;
- body angular rate ω from R(t − h)ᵀ R(t + h) = Exp(2h ω) (central difference on SO(3));
- a and v by central differences of the position with a small step h: the pose functions are
  smooth (C²) in time, so these are the derivatives up to round-off.

Sensor errors (:class:`ImuErrors`), drawn once per recording per device from its
:class:`ImuSpec`: constant bias + slow in-run bias drift, scale-factor and axis misalignment,
white noise, saturation and quantisation. The orientation output imitates a game rotation vector:
gravity-aligned with a small slowly varying tilt error, an arbitrary fixed yaw offset, and a yaw
drift that is a slow random walk.

Consumer grade throughout; earbuds are the noisiest. Rough figures behind the defaults:
smartphone accelerometer noise density ≈ 120–200 µg/√Hz and gyro ≈ 0.005–0.01 °/s/√Hz at 100 Hz
(ICM-4xxxx / LSM6DS class parts), residual biases after factory calibration of a few 10 mg and
0.1–0.5 °/s; hearables stream 25 Hz with coarser resolution.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from wearnav.core.rotations import matrix_to_wxyz
from wearnav.recording import STANDARD_GRAVITY as G  # sensor ranges and resolutions are in g
from wearnav.simulate.geometry import apply, apply_t, exp_so3, log_so3, rot_z
from wearnav.simulate.signals import smooth_noise

GRAVITY = 9.81  # the simulated world's local gravity (what the IMU measures), not the unit g
G_WORLD = np.array([0.0, 0.0, -GRAVITY])
DIFF_STEP_S = 1e-3


@dataclass(frozen=True)
class ImuSpec:
    """Error budget of one device type. Noise figures are per-sample standard deviations at
    ``rate_hz``; biases, scale and misalignment are standard deviations of per-recording draws."""

    rate_hz: float
    acc_noise: float  # m/s²
    gyro_noise: float  # rad/s
    acc_bias: float  # m/s²
    gyro_bias: float  # rad/s
    acc_bias_drift: float  # m/s², std of the slow in-run bias wander
    gyro_bias_drift: float  # rad/s
    acc_scale: float  # relative
    gyro_scale: float
    misalignment_deg: float
    acc_lsb: float  # m/s² per count
    gyro_lsb: float  # rad/s per count
    acc_range: float  # m/s², saturation
    gyro_range: float  # rad/s
    jitter_s: float  # timestamp jitter (std)
    start_delay_s: tuple[float, float]  # stream starts this long after the recording clock's zero
    yaw_walk_deg_per_sqrt_min: tuple[float, float]  # range of the orientation's yaw random walk
    tilt_error_deg: float  # std of the orientation's slow tilt error
    antialias_hz: float | None = None  # the sensor's own digital low-pass before its output rate


IMU_SPECS: dict[str, ImuSpec] = {
    "phone": ImuSpec(
        rate_hz=100.0,
        acc_noise=0.012,
        gyro_noise=0.0015,
        acc_bias=0.03,
        gyro_bias=0.002,
        acc_bias_drift=0.005,
        gyro_bias_drift=0.0003,
        acc_scale=0.005,
        gyro_scale=0.004,
        misalignment_deg=0.2,
        acc_lsb=16 * G / 32768,
        gyro_lsb=np.deg2rad(2000) / 32768,
        acc_range=16 * G,
        gyro_range=np.deg2rad(2000),
        jitter_s=0.0005,
        start_delay_s=(0.0, 0.2),
        yaw_walk_deg_per_sqrt_min=(1.0, 2.0),
        tilt_error_deg=0.3,
    ),
    "watch": ImuSpec(
        rate_hz=100.0,
        acc_noise=0.02,
        gyro_noise=0.003,
        acc_bias=0.05,
        gyro_bias=0.004,
        acc_bias_drift=0.008,
        gyro_bias_drift=0.0005,
        acc_scale=0.008,
        gyro_scale=0.006,
        misalignment_deg=0.4,
        acc_lsb=16 * G / 32768,
        gyro_lsb=np.deg2rad(2000) / 32768,
        acc_range=16 * G,
        gyro_range=np.deg2rad(2000),
        jitter_s=0.001,
        start_delay_s=(0.1, 0.8),
        yaw_walk_deg_per_sqrt_min=(1.5, 3.0),
        tilt_error_deg=0.5,
    ),
    "earbuds": ImuSpec(
        rate_hz=25.0,
        acc_noise=0.04,
        gyro_noise=0.006,
        acc_bias=0.08,
        gyro_bias=0.008,
        acc_bias_drift=0.015,
        gyro_bias_drift=0.001,
        acc_scale=0.01,
        gyro_scale=0.01,
        misalignment_deg=0.5,
        acc_lsb=G / 1024,
        gyro_lsb=np.deg2rad(2000) / 16384,
        acc_range=8 * G,
        gyro_range=np.deg2rad(2000),
        jitter_s=0.003,
        start_delay_s=(0.2, 1.2),
        yaw_walk_deg_per_sqrt_min=(2.0, 3.0),
        tilt_error_deg=0.8,
        # A MEMS IMU streaming 25 Hz samples its internal (kHz) data through a digital low-pass
        # of about ODR/3 before decimating. Assumed (no real earbud walking data here): 8 Hz.
        antialias_hz=8.0,
    ),
}


def sample_times(
    spec: ImuSpec, rng: np.random.Generator, t_start: float, t_end: float, jitter: bool = True
) -> np.ndarray:
    """Nominal ``rate_hz`` grid from ``t_start`` with small timestamp jitter, strictly increasing."""
    dt = 1.0 / spec.rate_hz
    n = int(np.floor((t_end - t_start) / dt)) + 1
    t = t_start + dt * np.arange(n)
    if jitter and spec.jitter_s > 0:
        t = t + np.clip(rng.normal(0.0, spec.jitter_s, n), -0.3 * dt, 0.3 * dt)
    return t


@dataclass
class TrueImu:
    """Exact kinematics of a device at its sample times (world frame; R maps device → world)."""

    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    R: np.ndarray
    omega: np.ndarray  # body-frame angular rate, rad/s
    specific_force: np.ndarray  # device frame, m/s², what an ideal accelerometer reads

    def take(self, idx) -> TrueImu:
        return TrueImu(*(getattr(self, k)[idx] for k in ("t", "pos", "vel", "acc", "R", "omega", "specific_force")))


def true_imu(pose, t: np.ndarray, h: float = DIFF_STEP_S) -> TrueImu:
    """Evaluate ``pose(t) -> (pos, R)`` at t ± h and t and form the ideal IMU quantities."""
    n = t.size
    p, R = pose(np.concatenate([t - h, t, t + h]))
    pm, p0, pp = p[:n], p[n : 2 * n], p[2 * n :]
    Rm, R0, Rp = R[:n], R[n : 2 * n], R[2 * n :]
    vel = (pp - pm) / (2 * h)
    acc = (pp - 2 * p0 + pm) / (h * h)
    omega = log_so3(np.swapaxes(Rm, -1, -2) @ Rp) / (2 * h)
    f = apply_t(R0, acc - G_WORLD)
    return TrueImu(t, p0, vel, acc, R0, omega, f)


ANTIALIAS_TAPS = 15
ANTIALIAS_STEP_S = 0.01  # the filter runs on the motion sampled at 100 Hz


def antialiased(pose, truth: TrueImu, spec: ImuSpec) -> TrueImu:
    """``truth`` with specific force and body rate passed through the device's low-pass: a
    zero-phase FIR (``ANTIALIAS_TAPS`` taps) over the motion sampled at 100 Hz around the
    stream, read off at the sample times (linear interpolation of the filtered, band-limited
    signal). Orientation, position and velocity stay exact. Unchanged when the spec has no filter."""
    if spec.antialias_hz is None or truth.t.size == 0:
        return truth
    from scipy.signal import firwin

    taps = firwin(ANTIALIAS_TAPS, spec.antialias_hz, fs=1.0 / ANTIALIAS_STEP_S)
    half = ANTIALIAS_TAPS // 2
    t = truth.t
    n = int(np.ceil((t[-1] - t[0]) / ANTIALIAS_STEP_S))
    grid = t[0] + ANTIALIAS_STEP_S * np.arange(-half - 1, n + half + 2)
    g = true_imu(pose, grid)
    inner = grid[half : grid.size - half]

    def filt(x):
        y = np.stack([np.convolve(x[:, k], taps, mode="valid") for k in range(3)], 1)
        return np.stack([np.interp(t, inner, y[:, k]) for k in range(3)], 1)

    return TrueImu(t, truth.pos, truth.vel, truth.acc, truth.R, filt(g.omega), filt(g.specific_force))


@dataclass
class ImuErrors:
    """One device's error realisation for one recording (see :class:`ImuSpec`)."""

    spec: ImuSpec
    acc_bias: np.ndarray
    gyro_bias: np.ndarray
    acc_matrix: np.ndarray  # (I + scale) · misalignment
    gyro_matrix: np.ndarray
    acc_drift: Callable[[np.ndarray], np.ndarray]  # t (s) → (T, 3); signals.smooth_noise
    gyro_drift: Callable[[np.ndarray], np.ndarray]
    yaw_offset: float
    yaw_walk: Callable[[np.ndarray], np.ndarray]
    tilt: Callable[[np.ndarray], np.ndarray]

    @classmethod
    def draw(cls, spec: ImuSpec, rng: np.random.Generator, t0: float, t1: float) -> ImuErrors:
        def matrix(scale_std):
            mis = exp_so3(rng.normal(0, np.deg2rad(spec.misalignment_deg), 3))
            return np.diag(1.0 + rng.normal(0, scale_std, 3)) @ mis

        walk = rng.uniform(*spec.yaw_walk_deg_per_sqrt_min) * np.pi / 180 / np.sqrt(60.0)
        return cls(
            spec=spec,
            acc_bias=rng.normal(0, spec.acc_bias, 3),
            gyro_bias=rng.normal(0, spec.gyro_bias, 3),
            acc_matrix=matrix(spec.acc_scale),
            gyro_matrix=matrix(spec.gyro_scale),
            acc_drift=smooth_noise(rng, t0 - 1, t1 + 1, 60.0, spec.acc_bias_drift, dims=3),
            gyro_drift=smooth_noise(rng, t0 - 1, t1 + 1, 60.0, spec.gyro_bias_drift, dims=3),
            yaw_offset=float(rng.uniform(-np.pi, np.pi)),
            yaw_walk=smooth_noise(rng, t0 - 1, t1 + 1, 5.0, walk, random_walk=True),
            tilt=smooth_noise(rng, t0 - 1, t1 + 1, 20.0, np.deg2rad(spec.tilt_error_deg), dims=2),
        )

    def measure(self, truth: TrueImu, rng: np.random.Generator):
        """(acc, gyro, quat_wxyz) as the device reports them."""
        s, t = self.spec, truth.t
        acc = apply(self.acc_matrix, truth.specific_force) + self.acc_bias + self.acc_drift(t)
        gyro = apply(self.gyro_matrix, truth.omega) + self.gyro_bias + self.gyro_drift(t)
        acc += rng.normal(0, s.acc_noise, acc.shape)
        gyro += rng.normal(0, s.gyro_noise, gyro.shape)
        acc = np.round(np.clip(acc, -s.acc_range, s.acc_range) / s.acc_lsb) * s.acc_lsb
        gyro = np.round(np.clip(gyro, -s.gyro_range, s.gyro_range) / s.gyro_lsb) * s.gyro_lsb
        tilt = self.tilt(t)
        err = exp_so3(np.stack([tilt[:, 0], tilt[:, 1], np.zeros_like(t)], 1))
        R_out = rot_z(self.yaw_offset + self.yaw_walk(t)) @ err @ truth.R
        return acc, gyro, matrix_to_wxyz(R_out)

    def summary(self) -> dict:
        return {
            "acc_bias": [round(float(b), 5) for b in self.acc_bias],
            "gyro_bias": [round(float(b), 6) for b in self.gyro_bias],
            "quat_yaw_offset_deg": round(float(np.rad2deg(self.yaw_offset)), 3),
        }
