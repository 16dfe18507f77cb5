"""From a Recording's per-device streams to one aligned multi-device array on a common clock.

Order of operations per device (why): rotate to the world frame at the device's own rate (the
orientation is best matched sample by sample), optionally subtract gravity, low-pass below the
new Nyquist rate (so 100 Hz → 25 Hz does not alias the step harmonics), then interpolate onto the
common clock. Devices that are absent, not yet started, stopped, or not worn are kept as zeros
with ``mask`` False; they are never dropped, so a model always sees a fixed device layout.

Suite-IN++ (paper 000, Sec. III-B/C) resamples phone, watch and earbuds to 25 Hz and rotates
each IMU into the world frame with the device's orientation; these are the defaults.
"""

from __future__ import annotations

import functools
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
from scipy import signal
from scipy.interpolate import CubicSpline

from wearnav.core.progress import progress as report_progress
from wearnav.core.rotations import from_wxyz
from wearnav.core.timeseries import interp_onto, periods, rate
from wearnav.errors import ConfigError, ValidationError
from wearnav.preprocess.frames import FRAME_ALIGN_MODES, frame_yaws, rotate_stacked, turn_devices
from wearnav.recording import STANDARD_GRAVITY, DeviceStream, Recording
from wearnav.runs import OMIT_AT_DEFAULT

# Gap rules (wearnav.core.timeseries): a device stream is trusted across a hole of up to this many of
# its own sample periods (its rate is 25–200 Hz, so a fixed time would be wrong for some: one
# or two dropped samples are jitter, more is a hole); truth is interpolated across at most
# TRUTH_MAX_GAP_S, so dense truth gives targets and sparse waypoints (seconds apart) do not.
STREAM_MAX_GAP_PERIODS = 3.0
TRUTH_MAX_GAP_S = 1.0
# A real building's surveyed points (ILC2 waypoints, IPIN's POSI points, seconds to a minute apart)
# are joined by straight lines across gaps up to this (the competitions' own assumption).
SURVEYED_TRUTH_MAX_GAP_S = 60.0
SPARSE_TRUTH_HZ = 1.0  # truth points per second below which a dataset's truth counts as surveyed points

CHANNELS = ("ax", "ay", "az", "gx", "gy", "gz")


# The model clock's rate bounds (Hz). Walking's step band reaches 5 Hz and the frame alignment
# low-passes turns at 0.5 Hz (wearnav.preprocess.frames): below 10 Hz the clock's Nyquist cuts into the steps.
# Above 1 kHz no wearable IMU samples (a rate typed in ms, or a damaged config.yaml).
MIN_RATE_HZ, MAX_RATE_HZ = 10.0, 1000.0


@dataclass(frozen=True)
class PreprocessConfig:
    """How streams become model input. Defaults follow Suite-IN++ (25 Hz, world frame)."""

    rate: float = 25.0
    devices: tuple[str, ...] = ("phone", "watch", "earbuds")
    frame: str = "world"  # "world": rotate with each device's quat; "device": raw axes
    remove_gravity: bool = False
    lowpass: bool = True
    # Streams whose start/end lie within this many seconds of the others' are treated as
    # clock offsets (the clock is cut to their overlap); a stream starting or ending further
    # inside is a device put on / taken off mid-walk and is masked instead of cutting the clock.
    edge_tolerance: float = 2.0
    # One horizontal frame for all devices (wearnav.preprocess.frames): "none" keeps each device's own yaw;
    # "common" rotates every device into the reference device's frame (IMU only); "truth" also
    # rotates that frame onto the truth's where the recording has truth, else it is "common".
    # Only world-frame input is rotated (frame="device" has no common vertical).
    frame_align: str = "truth"
    # Truth is interpolated across gaps up to this many seconds. The default keeps sparse
    # waypoints sparse; a real building's waypoints (ILC2, IPIN's POSI points) are joined by
    # straight lines when this is raised (the competitions' own assumption between waypoints).
    truth_max_gap: float = TRUTH_MAX_GAP_S
    # A constant yaw (degrees) of the input's world frame relative to the truth frame, as a site
    # has between its magnetic-north rotation vector and its floor plan (wearnav.preprocess.frames sign
    # convention); world-frame input is rotated by −yaw_deg into the truth frame, after any
    # frame alignment. Estimated from a site's training traces (wearnav.bench.real).
    yaw_deg: float = 0.0
    # Issue 34: the odometry's windows in the heading frame of the device that carries them (the
    # first present device of the layout): each window of world-frame input, and its target, turned
    # by −ψ, ψ the device's heading over the window (:func:`device_heading`); the model's velocity is
    # turned back by +ψ (:func:`wearnav.evaluate.predict_sequence`). A phone held in the hand points
    # where its walker goes, so the direction of travel becomes nearly constant in the window's
    # frame, whatever the building's orientation: what a step counter's heading uses, given to the
    # model. Left out of configs while False (runs made before it keep their names).
    heading_frame: bool = field(default=False, metadata={OMIT_AT_DEFAULT: True})

    def __post_init__(self) -> None:
        if self.heading_frame and self.frame != "world":
            raise ConfigError("heading_frame turns world-frame input; it needs frame='world'")
        if not MIN_RATE_HZ <= self.rate <= MAX_RATE_HZ:
            raise ConfigError(f"rate must be {MIN_RATE_HZ:g}..{MAX_RATE_HZ:g} Hz, got {self.rate}")
        if self.frame not in ("world", "device"):
            raise ConfigError(f"frame must be 'world' or 'device', got {self.frame!r}")
        if not self.devices:
            raise ConfigError("at least one device must be named")
        if self.frame_align not in FRAME_ALIGN_MODES:
            raise ConfigError(f"frame_align must be one of {', '.join(FRAME_ALIGN_MODES)}, got {self.frame_align!r}")
        if not self.truth_max_gap > 0:
            raise ConfigError(f"truth_max_gap must be positive seconds, got {self.truth_max_gap}")
        if self.yaw_deg and self.frame != "world":
            raise ConfigError("yaw_deg rotates world-frame input; it needs frame='world'")


@dataclass
class Aligned:
    """A recording on a common clock: ``imu`` (devices × T × 6: acc xyz, gyro xyz), ``mask``
    (devices × T, True where the device delivers data and is worn), and where the recording has
    truth, ``pos`` (T × 2, horizontal truth position interpolated on the clock, NaN where the
    truth does not cover the time)."""

    name: str
    t: np.ndarray
    devices: tuple[str, ...]
    imu: np.ndarray
    mask: np.ndarray
    pos: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    recording: Recording | None = field(default=None, repr=False)
    # with ``heading_frame``: the carrying device's heading ψ (T,; rad, in the frame of ``imu``;
    # NaN where no device is present or its heading is undefined), else None
    yaw: np.ndarray | None = field(default=None, repr=False)
    # with ``heading_frame``: every device's heading (devices × T, as ``yaw``; NaN where that device
    # is absent), from which ``yaw`` takes the first present. A window can then be turned into
    # another device's frame when training leaves its carrier out (``augment.drop_devices``)
    yaws: np.ndarray | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def rate(self) -> float:
        return rate(self.t)


def common_span(rec: Recording, devices: tuple[str, ...], tol: float) -> tuple[float, float]:
    """The common clock's [start, end]: the overlap of the streams, except that a stream that
    starts or ends more than ``tol`` seconds inside the others' span (a device put on or taken
    off mid-walk) does not shorten the clock."""
    present = [rec.devices[d] for d in devices if d in rec.devices]
    if not present:
        raise ValidationError(
            f"{rec.name}: none of the devices {list(devices)} is in the recording (it has {list(rec.devices)})"
        )
    starts = np.array([s.t[0] for s in present])
    ends = np.array([s.t[-1] for s in present])
    t0 = float(starts[starts <= starts.min() + tol].max())
    t1 = float(ends[ends >= ends.max() - tol].min())
    if t1 <= t0:
        raise ValidationError(f"{rec.name}: device streams do not overlap in time")
    return t0, t1


def clock(t0: float, t1: float, rate: float) -> np.ndarray:
    n = int(np.floor((t1 - t0) * rate + 1e-9)) + 1
    return t0 + np.arange(n) / rate


def nominal_rate(fs: float) -> float:
    """A stream's rate (Hz) to two significant digits, which the low-pass is designed for (its
    cutoff then moves by at most 5 %: 0.4 × the clock's rate stays well below the clock's
    Nyquist). The median rate of a jittery clock moves in its third digit with the stretch it is
    taken over (a simulated 100 Hz watch: 99.83 to 100.56 Hz over 35-s pieces of one walk), and the
    filter, so the input of a window, would change with the piece of the stream at hand (the live
    receiver aligns pieces, :mod:`wearnav.live.tracker`)."""
    return float(f"{fs:.2g}") if fs > 0 else 0.0


def _lowpass(x: np.ndarray, fs: float, target_rate: float) -> np.ndarray:
    """Zero-phase Butterworth low-pass at 0.4 × the target rate (0.8 × its Nyquist)."""
    cutoff = 0.4 * target_rate
    if fs < 2.5 * cutoff or len(x) < 30:
        return x
    return signal.sosfiltfilt(_butter(cutoff, fs), x, axis=0)


@functools.lru_cache(maxsize=64)
def _butter(cutoff: float, fs: float) -> np.ndarray:
    """The 4th-order low-pass's sections, designed once per (cutoff, rate): rates are nominal
    (:func:`nominal_rate`), so there are few, and designing it was a third of the live tracker's
    aligning (an update aligns a few seconds, issue 37)."""
    return signal.butter(4, cutoff, fs=fs, output="sos")  # shared: scipy's filters only read it


def stream_to_clock(
    s: DeviceStream, t: np.ndarray, cfg: PreprocessConfig, name: str = ""
) -> tuple[np.ndarray, np.ndarray]:
    """One device's (T × 6) IMU on clock ``t`` and its (T,) mask."""
    acc = s.acc.astype(np.float64)
    gyro = s.gyro.astype(np.float64) if s.gyro is not None else np.zeros_like(acc)
    if cfg.frame == "world" or cfg.remove_gravity:
        if s.quat is None:
            raise ConfigError(f"{name}: device has no orientation; use frame='device' without gravity removal")
        rot = from_wxyz(s.quat)
    if cfg.frame == "world":
        acc = rot.apply(acc)
        gyro = rot.apply(gyro)
        if cfg.remove_gravity:
            acc[:, 2] -= STANDARD_GRAVITY
    elif cfg.remove_gravity:
        acc = acc - rot.inv().apply(np.array([0.0, 0.0, STANDARD_GRAVITY]))
    x = np.concatenate([acc, gyro], axis=1)
    if cfg.lowpass:
        x = _lowpass(x, nominal_rate(s.rate), cfg.rate)
    # Valid inside the stream's span, away from holes longer than STREAM_MAX_GAP_PERIODS of its
    # samples, and where the device is worn.
    out, mask = interp_onto(t, s.t, x, max_gap=periods(STREAM_MAX_GAP_PERIODS, s.rate))
    out = np.array(out, dtype=np.float64)  # identical clocks hand back x itself
    if s.worn is not None:
        nearest = np.clip(np.searchsorted(s.t, t), 0, len(s.t) - 1)
        mask &= s.worn[nearest]
    if s.gyro is None:
        out[:, 3:] = 0.0  # no gyro: zeros, and the model input says so only through the data
    out[~mask] = 0.0
    return out.astype(np.float32), mask


# The device axis whose horizontal direction is its heading: +y (the top edge) minus +z (out of
# the screen). A phone held flat in front points +y forward; held upright (screen to the face) it
# points −z forward; tilted between, y − z still points forward. It is vertical only when the phone
# lies tilted back by 45° (screen up and towards the walker), not a way phones are carried.
HEADING_AXIS = np.array([0.0, 1.0, -1.0])
MIN_HEADING_NORM = 0.2  # |horizontal part of HEADING_AXIS| (of √2) below which ψ is undefined


def device_heading(s: DeviceStream, t: np.ndarray) -> np.ndarray:
    """The device's heading on clock ``t`` as a unit complex number (east + i·north of its world
    frame): the horizontal direction of :data:`HEADING_AXIS` rotated by its orientation,
    interpolated (as a vector) inside its stream's span across holes up to
    ``STREAM_MAX_GAP_PERIODS`` samples; NaN elsewhere and where the axis is near vertical."""
    if s.quat is None:
        raise ConfigError("heading_frame needs each device's orientation")
    a = from_wxyz(s.quat).apply(HEADING_AXIS)
    h = a[:, 0] + 1j * a[:, 1]
    h = np.where(np.abs(h) >= MIN_HEADING_NORM, h, np.nan)
    out, ok = interp_onto(t, s.t, np.stack([h.real, h.imag], 1), max_gap=periods(STREAM_MAX_GAP_PERIODS, s.rate))
    v = np.asarray(out)[:, 0] + 1j * np.asarray(out)[:, 1]
    v = np.where(ok & (np.abs(v) > 0), v, np.nan)
    with np.errstate(invalid="ignore"):  # NaN where undefined, as said
        return v / np.abs(v)


def interpolate_position(
    truth_t: np.ndarray, truth_pos: np.ndarray, t: np.ndarray, max_gap: float = TRUTH_MAX_GAP_S
) -> np.ndarray:
    """Horizontal truth at ``t`` by linear interpolation; NaN outside the truth or across gaps
    longer than ``max_gap`` s (sparse waypoints are not interpolated into dense truth)."""
    pos, _ = interp_onto(t, truth_t, np.asarray(truth_pos, dtype=np.float64)[:, :2], max_gap=max_gap, fill=np.nan)
    return np.array(pos, dtype=np.float64)


def align(rec: Recording, cfg: PreprocessConfig = PreprocessConfig(), t: np.ndarray | None = None) -> Aligned:
    """Resample every configured device of ``rec`` onto one clock (see module docstring): ``t``
    (s, increasing, at ``cfg.rate``) where given (the live receiver aligns a session piece by piece
    on the clock of its start, :mod:`wearnav.live.tracker`), else the common span's (:func:`clock`)."""
    if t is None:
        t0, t1 = common_span(rec, cfg.devices, cfg.edge_tolerance)
        t = clock(t0, t1, cfg.rate)
    if t.size < 2:
        span = float(t[-1] - t[0]) if t.size else 0.0
        raise ValidationError(
            f"{rec.name}: the devices' common span ({span:.3g} s) is shorter than one sample period at {cfg.rate:g} Hz"
        )
    imu = np.zeros((len(cfg.devices), t.size, 6), np.float32)
    mask = np.zeros((len(cfg.devices), t.size), bool)
    for i, dev in enumerate(cfg.devices):
        if dev in rec.devices:
            imu[i], mask[i] = stream_to_clock(rec.devices[dev], t, cfg, f"{rec.name}/{dev}")
    pos = None
    if rec.truth is not None:
        pos = interpolate_position(rec.truth.t, rec.truth.pos, t, cfg.truth_max_gap)
    meta = dict(rec.meta)
    turned = None  # each device's yaw, by whose negative it was turned (D, T)
    if cfg.frame == "world" and cfg.frame_align != "none":
        turned, meta["frame"] = frame_yaws(imu, mask, tuple(cfg.devices), cfg.rate, pos, cfg.frame_align)
        if turned is not None:
            imu = turn_devices(imu, mask, turned)
    if cfg.yaw_deg:
        imu = np.stack([rotate_stacked(x, -np.deg2rad(cfg.yaw_deg)) for x in imu]).astype(np.float32)
    yaws = _device_headings(rec, cfg, t, mask, turned) if cfg.heading_frame else None
    yaw = _carrier_heading(yaws) if yaws is not None else None
    return Aligned(rec.name, t, tuple(cfg.devices), imu, mask, pos, meta, rec, yaw, yaws)


def _device_headings(rec: Recording, cfg: PreprocessConfig, t, mask, turned) -> np.ndarray:
    """ψ (devices × T) of :attr:`Aligned.yaws`: each device's heading where it is present, in the
    frame the IMU was turned into (its frame alignment and ``yaw_deg``); NaN elsewhere."""
    yaws = np.full((len(cfg.devices), t.size), np.nan)
    for d, dev in enumerate(cfg.devices):
        if dev not in rec.devices or not mask[d].any():
            continue
        psi = np.angle(device_heading(rec.devices[dev], t))
        if turned is not None:
            psi = psi - turned[d]
        psi = psi - np.deg2rad(cfg.yaw_deg)
        here = mask[d] & np.isfinite(psi)
        yaws[d, here] = np.angle(np.exp(1j * psi[here]))
    return yaws


def _carrier_heading(yaws: np.ndarray) -> np.ndarray:
    """ψ (T,) of :attr:`Aligned.yaw`: at each sample the heading of the first device of the layout
    that has one there (NaN where none has)."""
    yaw = np.full(yaws.shape[1], np.nan)
    for row in yaws[::-1]:  # the first device with a heading wins
        yaw = np.where(np.isfinite(row), row, yaw)
    return yaw


class BoundedCache(OrderedDict):
    """A dict holding at most ``maxsize`` entries: storing one more drops the least recently
    used (read or stored). ``functools.lru_cache`` does not fit here: the value is computed from
    a Dataset view, which is not part of the key."""

    def __init__(self, maxsize: int):
        super().__init__()
        self.maxsize = maxsize

    def __getitem__(self, key):
        value = super().__getitem__(key)
        self.move_to_end(key)
        return value

    def __setitem__(self, key, value):
        super().__setitem__(key, value)
        self.move_to_end(key)
        while len(self) > self.maxsize:
            self.popitem(last=False)


# Aligned sequences kept per process (each holds its Recording): enough for every recording of one
# dataset and preprocessing (ILC2, the largest shipped set, has a few hundred traces), so a suite
# that evaluates several models on one split preprocesses it once, while a long benchmark over
# many datasets and preprocessing variants does not keep them all.
MAX_CACHED_SEQUENCES = 1024
_CACHE: BoundedCache = BoundedCache(MAX_CACHED_SEQUENCES)


SPEED_WARP_RANGE = (0.25, 4.0)  # the time-warp factors a training config accepts


def check_speed_warp(factors: tuple[float, ...]) -> None:
    lo, hi = SPEED_WARP_RANGE
    if any(not lo <= k <= hi for k in factors):
        raise ConfigError(f"speed-warp factors must lie in [{lo:g}, {hi:g}], got {', '.join(map(str, factors))}")


def time_warped(seq: Aligned, k: float) -> Aligned:
    """``seq`` played ``k`` times faster (issue 34's "speed time-warp" lead, a training expansion):
    at each time t' of a clock at ``seq``'s rate the input of time k·t' (a cubic spline for the IMU,
    which a straight line would smooth: −5 % of the vertical acceleration's swing at k = 1.25;
    linear for positions and heading). The
    walker then covers the same path k times faster: positions keep their places, so the velocity
    target scales by k; the gyroscope by k; the linear acceleration by k² (world-frame acc with
    gravity: k²(a − g ẑ) + g ẑ, g each device's median vertical reading). Cadence scales by k with
    the step length kept, an approximation of walking faster (which lengthens steps too)."""
    if not k > 0:
        raise ConfigError(f"a time warp needs a factor > 0, got {k}")
    t, dt = seq.t, float(np.median(np.diff(seq.t)))
    n = int(np.floor((t[-1] - t[0]) / (k * dt) + 1e-9)) + 1
    src = t[0] + k * dt * np.arange(n)
    i = np.clip(np.searchsorted(t, src, side="right") - 1, 0, len(t) - 2)
    w = np.clip((src - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)

    def lerp(a: np.ndarray, axis: int) -> np.ndarray:
        shape = [1] * a.ndim
        shape[axis] = n
        ww = w.reshape(shape)
        return np.take(a, i, axis=axis) * (1 - ww) + np.take(a, i + 1, axis=axis) * ww

    imu = CubicSpline(t, seq.imu.astype(np.float64), axis=1)(np.clip(src, t[0], t[-1]))
    mask = seq.mask[:, i] & seq.mask[:, i + 1]
    for d in range(imu.shape[0]):
        g = float(np.median(imu[d, mask[d], 2])) if mask[d].any() else 0.0
        imu[d, :, :2] *= k * k
        imu[d, :, 2] = k * k * (imu[d, :, 2] - g) + g
        imu[d, :, 3:] *= k
    imu[~mask] = 0.0

    def angles(a: np.ndarray) -> np.ndarray:  # unwrapped where finite, NaN where either neighbour is
        y = a.astype(np.float64).copy()
        fin = np.isfinite(y)
        y[fin] = np.unwrap(y[fin])
        return np.angle(np.exp(1j * lerp(y, 0)))

    yaw = angles(seq.yaw) if seq.yaw is not None else None
    yaws = np.stack([angles(row) for row in seq.yaws]) if seq.yaws is not None else None
    return Aligned(
        name=f"{seq.name}@x{k:g}",
        t=t[0] + dt * np.arange(n),
        devices=seq.devices,
        imu=imu.astype(seq.imu.dtype),
        mask=mask,
        pos=lerp(seq.pos, 0) if seq.pos is not None else None,
        meta={**seq.meta, "time_warp": k},
        recording=None,
        yaw=yaw,
        yaws=yaws,
    )


def load_sequences(view, cfg, progress: bool = False) -> list[Aligned]:
    """Align every recording of a Dataset view (:class:`wearnav.dataset.Dataset`) for ``cfg``, any
    config with a ``preprocess_config()`` (a TrainConfig, a ClassifyConfig). Aligned sequences are
    cached per process by (file, preprocess config), so a suite preprocesses each recording once."""
    pcfg = cfg.preprocess_config()
    out = []
    for name in report_progress(view.names, desc="preprocess", unit="rec", enabled=progress, leave=False):
        path = view.path(name)
        key = (str(path.resolve()), path.stat().st_mtime_ns, pcfg)
        if key not in _CACHE:
            _CACHE[key] = align(view.load(name), pcfg)
        out.append(_CACHE[key])
    return out
