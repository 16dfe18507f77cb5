"""Pedestrian dead reckoning (PDR), the classic baseline of Suite-IN++ (Sec. V-B): detect the
steps, move 0.67 m per step along the device's heading. Not learned; per window, without state.

Input and output follow the odometry contract: x (B, D, L, 6) world-frame acc (incl. gravity) +
gyro at ``rate`` Hz → mean horizontal velocity (B, 2) over the window, in the input's world frame.
Like RoNIN it uses one device per sample: the first present one of the layout (the phone, else
the next present device).

Steps. The vertical world acceleration is band-passed around walking cadence (Butterworth, ``band``
Hz, zero phase); a step is a local maximum higher than a threshold with no higher sample within
``min_step_s`` s. The threshold is ``min_peak`` (0.6 m/s²), lowered for a gentle walker to
min(min_peak, max(``peak_floor``, ``peak_fraction`` · amplitude)), the amplitude being the 90th
percentile of |band-passed vertical acc|; the lowered threshold's peaks count only where they are
regular (at least 3, the coefficient of variation of their intervals at most ``max_interval_cv``)
and the window repeats itself at a step period (:func:`periodicity` at least ``min_periodicity``),
else the window counts the peaks above ``min_peak``. A window whose amplitude is at least
min_peak / peak_fraction (1.2 m/s²) counts exactly what the fixed threshold counted. Decision (the
constants, where they were chosen and what they measured):
docs/decisions/0044-adaptive-step-threshold.md.

A 4 s window holds 7–9 steps, so counting whole peaks would quantise the speed by ±1 step (±12 %);
the window's step count is instead the number of step intervals between its first and last peak
plus the edge gaps as fractions of the mean step period (each at most one step): for steady walking
this equals duration / period exactly, and a walk that stops mid-window counts only the steps
taken. Speed = steps · ``step_length`` / window duration ((L−1)/rate, the same span the velocity
targets use).

Heading. The input has no device orientation beyond the world frame (the yaw of the device
itself is not given), so the walking direction comes from the signal, as in gait-based PDR: the
band-passed horizontal acceleration at step frequency oscillates mostly along the walking
direction (the fore-aft surge of each step; lateral sway is at half that frequency), so its
principal axis gives the direction up to sign. The sign comes from the phase between fore-aft and
vertical acceleration: in the inverted-pendulum gait model the forward acceleration is in phase
with the time derivative of the vertical acceleration (it leads it by 90°: the body is slowest at
mid-stance, when it is highest). Measured on real data (ILC2 site 1, phone held flat in front,
so its +y axis points forward; 609 walking windows of 4 s in 40 traces): the forward acceleration
leads the vertical by a circular mean of 96° (per-trace medians mostly 55°–120°).
``phase_lead_deg`` sets that lead; the sign is right whenever the true lead is within ±90° of it.
With the default, PDR's direction is within 90° of the phone's forward axis in 89 % of the 9149
moving windows of ILC2 site 1 (per-trace median angle to it mostly 8°–30°).

The simulator's pelvis ripple first had the opposite phase (forward acceleration lagging the
vertical by 45–75°), which made this PDR walk backwards on simulated data; it now follows the
inverted pendulum (lead 73°–119°), found through this rule.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy import ndimage, signal
from torch import Tensor, nn

from wearnav.errors import ConfigError
from wearnav.models.base import OdometryModel, first_present
from wearnav.models.registry import register

# Below this learned speed (m/s) the hybrid's direction is taken as is, not blown up to unit length.
_MIN_SPEED_M_S = 1e-3

# The step length per unit cadence c (m per step/s) of a step length that grows with cadence,
# L = c·f (issue 34, "Hybrids"): measured on the simulator's training walks (the `default` preset,
# seed 0: train and val, 2,985 windows of 4 s; this detector's f and the truth's speed v,
# c = Σv / Σf²; `scripts/cadence_step.py`), so nothing real went into it. L ∝ f is the simulator's
# gait within one walker (cadence ∝ speed^0.5; windows' log-log slope of v/f on f: 0.8–1.1) and
# gives 0.66 m at 1.8 steps/s, the fixed step length's 0.67 m at about that cadence. On real walks
# with surveyed truth the fixed 0.67 m errs by building: PDR's paths are 1.19 long in IPIN's test
# walks (steps of about 0.56 m at a median 1.63 steps/s) and 1.01 in ILC2's (0.66 m at 1.83).
STEP_PER_CADENCE_M_S = 0.367

# The adaptive step threshold (module docstring; chosen on Oxford user 1, UCI HAPT 1–15, IPIN trials 1–5).
PEAK_FRACTION = 0.5  # of the window's amplitude (90th percentile of |band-passed vertical acc|, m/s²)
PEAK_FLOOR_M_S2 = 0.2  # never lower: a still phone's band-passed jitter stays under it
MAX_INTERVAL_CV = 0.3  # the lowered threshold's peaks count only as regular as a walk's steps
MIN_PERIODICITY = 0.4  # and where the window repeats itself at a step period (:func:`periodicity`)
STEP_RATE_RANGE_HZ = (1.2, 2.5)  # the step periods searched by :func:`periodicity`
AMPLITUDE_QUANTILE = 0.9


def interval_cv(peak: np.ndarray) -> np.ndarray:
    """(B,) coefficient of variation (std / mean) of the intervals between the peaks of each row of
    ``peak`` (B, L) bool; inf where a row has fewer than 3 peaks (fewer than 2 intervals)."""
    rows, cols = np.nonzero(peak)  # row-major: each row's peaks in time order
    same = rows[1:] == rows[:-1]
    d, r = np.diff(cols)[same].astype(np.float64), rows[1:][same]
    B = peak.shape[0]
    k = np.bincount(r, minlength=B).astype(np.float64)
    s1, s2 = np.bincount(r, d, minlength=B), np.bincount(r, d * d, minlength=B)
    mean = s1 / np.maximum(k, 1)
    var = np.maximum(s2 / np.maximum(k, 1) - mean**2, 0.0)
    return np.where(k >= 2, np.sqrt(var) / np.where(mean > 0, mean, 1.0), np.inf)


def periodicity(x: np.ndarray, rate: float) -> np.ndarray:
    """(B,) the highest normalised autocorrelation of each row of ``x`` (B, L) at a lag of one step
    period (``rate`` Hz samples; step rates :data:`STEP_RATE_RANGE_HZ`): near 1 for a walk, which
    repeats itself every step; 0.4 at the median for a still phone's band-passed jitter (UCI HAPT
    standing / sitting / lying windows whose amplitude is above 0.08 m/s²)."""
    lags = range(max(1, int(rate / STEP_RATE_RANGE_HZ[1])), int(rate / STEP_RATE_RANGE_HZ[0]) + 1)
    best = np.full(x.shape[0], -1.0)
    for lag in lags:
        if lag >= x.shape[1]:
            break
        a, b = x[:, :-lag], x[:, lag:]
        r = np.sum(a * b, axis=1) / np.sqrt(np.sum(a * a, axis=1) * np.sum(b * b, axis=1) + 1e-300)
        best = np.maximum(best, r)
    return best


class PDR(OdometryModel):
    """Step counting × step length along the acceleration-derived walking direction. The step
    length is ``step_length`` (m), or with ``step_per_cadence`` (m per step/s) that times the
    window's cadence f = steps / duration (L = c·f: speed c·f², :data:`STEP_PER_CADENCE_M_S`)."""

    learned = False

    def __init__(
        self,
        n_devices: int = 3,
        window: int = 100,
        rate: float = 25.0,
        step_length: float = 0.67,
        band: tuple[float, float] = (1.0, 3.0),
        min_step_s: float = 0.3,
        min_peak: float = 0.6,
        phase_lead_deg: float = 90.0,
        filter_order: int = 2,
        step_per_cadence: float | None = None,
        peak_fraction: float = PEAK_FRACTION,
        peak_floor: float = PEAK_FLOOR_M_S2,
        max_interval_cv: float = MAX_INTERVAL_CV,
        min_periodicity: float = MIN_PERIODICITY,
    ):
        super().__init__()
        if window < 32 or rate <= 0 or not 0 < band[0] < band[1] < rate / 2:
            raise ConfigError(f"PDR needs window ≥ 32, rate > 0 and 0 < band < rate/2, got {window}, {rate}, {band}")
        if step_per_cadence is not None and not step_per_cadence > 0:
            raise ConfigError(f"step_per_cadence must be a positive number of m per step/s, got {step_per_cadence}")
        self.n_devices, self.window, self.rate = n_devices, window, rate
        self.step_per_cadence = step_per_cadence
        if not 0 < peak_floor <= min_peak or peak_fraction < 0 or max_interval_cv < 0:
            raise ConfigError(
                f"PDR needs 0 < peak_floor ≤ min_peak, peak_fraction ≥ 0 and max_interval_cv ≥ 0, got "
                f"{peak_floor}, {min_peak}, {peak_fraction}, {max_interval_cv}"
            )
        self.step_length, self.min_peak, self.phase_lead = step_length, min_peak, np.deg2rad(phase_lead_deg)
        self.peak_fraction, self.peak_floor, self.max_interval_cv = peak_fraction, peak_floor, max_interval_cv
        self.min_periodicity = min_periodicity
        self.half_gap = max(1, int(round(min_step_s * rate)))
        self.sos = signal.butter(filter_order, band, btype="band", fs=rate, output="sos")

    def bandpass(self, acc: np.ndarray) -> np.ndarray:
        """Zero-phase band-pass of (B, L, 3) along time; removes gravity and slow drifts."""
        return signal.sosfiltfilt(self.sos, acc, axis=1)

    def threshold(self, acc_vert: np.ndarray) -> np.ndarray:
        """The lowered step threshold (B,) m/s² of each window of band-passed vertical acc (B, L):
        min(min_peak, max(peak_floor, peak_fraction · amplitude)) (module docstring)."""
        amplitude = np.quantile(np.abs(acc_vert), AMPLITUDE_QUANTILE, axis=1)
        return np.minimum(self.min_peak, np.maximum(self.peak_floor, self.peak_fraction * amplitude))

    def peaks(self, acc_vert: np.ndarray) -> np.ndarray:
        """(B, L) bool: the step peaks of band-passed vertical acc (B, L): above :meth:`threshold`
        where those peaks are regular (:func:`interval_cv`), else above ``min_peak``."""
        local_max = ndimage.maximum_filter1d(acc_vert, 2 * self.half_gap + 1, axis=1, mode="nearest")
        is_max = acc_vert >= local_max
        # A peak at the window's edge is not known to be a maximum: the next sample is outside.
        is_max[:, 0] = is_max[:, -1] = False
        fixed = is_max & (acc_vert > self.min_peak)
        low = is_max & (acc_vert > self.threshold(acc_vert)[:, None])
        regular = interval_cv(low) <= self.max_interval_cv
        regular &= periodicity(acc_vert, self.rate) >= self.min_periodicity
        return np.where(regular[:, None], low, fixed)

    def steps(self, acc_vert: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(peak count, fractional step count) per window of band-passed vertical acc (B, L)."""
        B, L = acc_vert.shape
        peak = self.peaks(acc_vert)
        n = peak.sum(axis=1)
        first = peak.argmax(axis=1)
        last = L - 1 - peak[:, ::-1].argmax(axis=1)
        period = (last - first) / np.maximum(n - 1, 1)
        gaps = np.minimum(first, period) + np.minimum(L - 1 - last, period)
        edge = gaps / np.where(period > 0, period, 1.0)
        frac = np.where(n >= 2, (n - 1) + edge, n).astype(np.float64)
        return n, frac

    def speed(self, steps: np.ndarray, length: int) -> np.ndarray:
        """Speed (m/s) of windows of ``length`` samples holding ``steps`` (fractional) steps."""
        duration = (length - 1) / self.rate
        if self.step_per_cadence is None:
            return steps * self.step_length / duration
        return self.step_per_cadence * (steps / duration) ** 2

    def heading(self, acc_bp: np.ndarray) -> np.ndarray:
        """Unit walking direction (B, 2) from band-passed world acc (B, L, 3) (module docstring)."""
        h, v = acc_bp[..., :2], acc_bp[..., 2]
        cov = np.einsum("bli,blj->bij", h, h)
        angle = 0.5 * np.arctan2(2 * cov[:, 0, 1], cov[:, 0, 0] - cov[:, 1, 1])
        axis = np.stack([np.cos(angle), np.sin(angle)], 1)
        fore = np.einsum("bli,bi->bl", h, axis)
        cross = np.sum(np.fft.rfft(fore, axis=1) * np.conj(np.fft.rfft(v, axis=1)), axis=1)
        sign = np.where(np.real(cross * np.exp(-1j * self.phase_lead)) >= 0, 1.0, -1.0)
        return axis * sign[:, None]

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        sel, _ = first_present(x, mask)
        acc = sel[..., :3].detach().to("cpu", torch.float64).numpy()
        L = acc.shape[1]
        acc_bp = self.bandpass(acc)
        _, steps = self.steps(acc_bp[..., 2])
        vel = self.heading(acc_bp) * self.speed(steps, L)[:, None]
        return torch.from_numpy(vel).to(device=x.device, dtype=x.dtype)


@register(
    "pdr",
    task="odometry",
    layout="single",
    learned=False,
    description="step detection × 0.67 m along the gait-derived walking direction (not learned)",
)
def pdr(n_devices: int = 3, window: int = 100, **kw) -> PDR:
    return PDR(n_devices, window, **kw)


class PDRPointing(PDR):
    """Step counting × fixed step length along where the phone points (issue 34 §2, "Hybrids"): its
    windows are in the device's heading frame (:attr:`wearnav.preprocess.PreprocessConfig.heading_frame`,
    the horizontal direction of the phone's y − z axis), so its velocity is (speed, 0) there and
    :func:`wearnav.evaluate.predict_sequence` turns it back. A phone held in the hand points where
    its walker goes: on the held-out ILC2 and IPIN walks that direction was 9.1° and 9.9° from the
    truth's per window (median; p90 29.8° and 29.2°), where PDR's gait axis was 15.1° (p90 86.6°,
    ILC2) and the heading-frame Suite-IN++ trained in the other building 10.7–21.0° (p90 36–129°)."""

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        sel, _ = first_present(x, mask)
        acc = sel[..., :3].detach().to("cpu", torch.float64).numpy()
        _, steps = self.steps(self.bandpass(acc)[..., 2])
        speed = torch.from_numpy(self.speed(steps, acc.shape[1]))
        return torch.stack([speed, torch.zeros_like(speed)], dim=1).to(device=x.device, dtype=x.dtype)


@register(
    "pdr-pointing",
    task="odometry",
    layout="single",
    learned=False,
    heading_frame=True,
    description="step detection × 0.67 m along where the phone points (its heading frame; not learned)",
)
def pdr_pointing(n_devices: int = 3, window: int = 100, **kw) -> PDRPointing:
    return PDRPointing(n_devices, window, **kw)


@register(
    "pdr-cadence",
    task="odometry",
    layout="single",
    learned=False,
    description="step detection × a step as long as the cadence makes it (0.367 m per step/s) along the "
    "gait-derived walking direction (not learned)",
)
def pdr_cadence(n_devices: int = 3, window: int = 100, **kw) -> PDR:
    return PDR(n_devices, window, **{"step_per_cadence": STEP_PER_CADENCE_M_S, **kw})


@register(
    "pdr-pointing-cadence",
    task="odometry",
    layout="single",
    learned=False,
    heading_frame=True,
    description="step detection × a step as long as the cadence makes it, along where the phone points "
    "(its heading frame; not learned)",
)
def pdr_pointing_cadence(n_devices: int = 3, window: int = 100, **kw) -> PDRPointing:
    return PDRPointing(n_devices, window, **{"step_per_cadence": STEP_PER_CADENCE_M_S, **kw})


class PDRSpeed(OdometryModel):
    """A hybrid (issue 34 §2, "Hybrids"): ``inner``'s walking direction at PDR's speed (detected
    steps × step length, :class:`PDR`) in the same window. The learned model keeps what it is good
    at (the direction, which PDR's gait axis gets only to ±14° median on IPIN's walks), PDR supplies
    what a step counter measures directly (the distance walked), which a learned model trained on
    other walkers regresses towards its training set's speeds. Where the learned velocity is
    (near) zero its direction is arbitrary, but PDR then counts no steps either."""

    def __init__(self, inner: nn.Module, pdr_model: PDR):
        super().__init__()
        self.inner = inner
        self.pdr = pdr_model

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        v = self.inner(x, mask)  # (B, 2) m/s
        speed = self.pdr(x, mask).norm(dim=1, keepdim=True)  # (B, 1) m/s
        return speed * v / v.norm(dim=1, keepdim=True).clamp_min(_MIN_SPEED_M_S)

    @torch.no_grad()
    def predict(self, x: Tensor, mask: Tensor) -> Tensor:
        return self(x, mask)
