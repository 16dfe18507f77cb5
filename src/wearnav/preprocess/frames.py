"""One horizontal frame for all devices, and that frame's relation to the truth frame.

Why: a device's orientation is a game rotation vector — gravity-aligned, but with its own arbitrary
yaw that also drifts slowly (a yaw random walk of a few °/√min). Rotating each device's IMU with
its own orientation (:mod:`wearnav.preprocess`) therefore gives world frames that differ by an
unknown, slowly varying yaw per device, and none of them is the truth's frame.

Convention: a yaw ψ of frame A relative to frame B means the horizontal coordinates of any vector
satisfy ``v_A = Rz(ψ) · v_B``; bringing data from A into B rotates it by ``−ψ``. In complex notation
(z = x + i·y) ``z_A = e^{iψ} z_B``. For the simulator, device d's world frame has ψ_d = drawn offset
+ yaw walk relative to the truth frame (``simulate/imu.py``: R_out = Rz(ψ) · tilt · R_true).

Method (IMU only, per pair of devices a, b):

1. Horizontal world acceleration as complex signals z_a, z_b, split into frequency bands. Between
   0.05 and 0.3 Hz every device moves with the whole body (turns, starts, stops), so that band is
   common to all devices and anchors the estimate (below 0.05 Hz the gravity leaking through each
   orientation's slow tilt error dominates). Higher bands (stride and step frequency) are shared
   only by devices riding rigidly on the trunk and head (earbuds, a phone held in front of the
   body); for a watch they are dominated by arm swing, with a systematic phase (~20° at the step
   frequency, 180° at the stride frequency against a phone swinging in the other hand).
2. Per band, a time-local complex least-squares fit z_a ≈ A z_b (+ nuisance terms) with a Gaussian
   kernel in time (``kernel_s``), so the estimate follows the slow yaw walk; ψ = arg A (2-D
   Procrustes). In the anchor band a second regressor, the lever-arm term (iω' − ω²) e^{i∫ω} from
   the vertical gyro (:func:`lever_regressor`), absorbs the centripetal and tangential acceleration
   difference of two points on one turning body, which otherwise biases the angle during turns;
   and per device e^{iθ(t)} with θ its own integrated heading (:func:`heading_regressor`) absorbs
   its accelerometer bias, which turns with the device and so changes exactly during turns.
   The band's confidence is the phase variance of the fit, |residual|² / (2 |A|² N · power), with
   N ≈ 2 · bandwidth · duration independent samples (for one regressor this is the coherence-phase
   error (1 − γ²) / (2 N γ²) of Bendat & Piersol).
3. A band other than the anchor joins only where it is coherent (global γ ≥ ``min_coherence``)
   and agrees with the anchor band (|Δψ| ≤ ``max_band_disagreement_deg``); bands are fused by
   their information (1 / variance) as a weighted circular mean.
4. All device pairs are fused into one yaw per device and time (a small synchronisation problem
   on the circle solved by weighted fixed-point iteration with the reference's yaw fixed at 0), so
   a watch is also tied to the phone through the earbuds, and a device is still tied to the
   others while the reference is absent.

Masks are respected: samples of absent or not-worn devices carry no weight, and a margin at each
mask edge is dropped because band filters ring there. The truth alignment uses the same pair
estimator between each device (already in the common frame) and the truth's acceleration
(second difference of truth positions), fused over devices with a model-error floor; it uses truth
positions only, never model predictions.

Confidence figures (``YawTrack.info`` / ``std_deg``) are statistical; how they compare with the
errors on the simulator, and what was tried and dropped: Decision: docs/decisions/0002-one-frame-for-all-devices.md.
Errors per device and walking mode: ``scripts/frame_alignment_report.py``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import signal
from scipy.ndimage import binary_erosion

from wearnav.core.rotations import rotate_about_vertical
from wearnav.errors import ConfigError

# "initial": the common frame plus ONE constant yaw onto the truth, estimated from the truth's first
# ``FrameConfig.initial_s`` seconds only (Suite-IN++'s single initial rotation): the honest test input,
# whose heading drift stays in. "truth" follows the truth's yaw over time (a training frame and a
# diagnostic: it removes heading drift from the input using ground truth).
FRAME_ALIGN_MODES = ("none", "common", "initial", "truth")
MIN_POWER = 1e-4  # (m/s²)², band power of a 0.01 m/s² rms acceleration
MAX_INFO = 1e12  # rad⁻² (a micro-degree): exact copies stay finite when summed


@dataclass(frozen=True)
class FrameConfig:
    """Parameters of the yaw estimator (see module docstring); the first band is the anchor."""

    bands_hz: tuple[tuple[float, float], ...] = ((0.05, 0.3), (0.3, 0.7), (0.7, 1.3), (1.3, 2.6))
    kernel_s: float = 20.0  # Gaussian σ of the time-local estimate (tracks the yaw walk)
    min_coherence: float = 0.9  # global coherence a non-anchor band needs to join
    max_band_disagreement_deg: float = 25.0  # ... and its agreement with the anchor band
    edge_margin_s: float = 1.0  # dropped at each mask edge (filter ringing)
    # Fit each device's accelerometer bias turning with its heading (:func:`heading_regressor`);
    # on `small` this took the worst relative earbuds error from 7.8° to 4.2°.
    bias_regressors: bool = True
    # Added in quadrature to each device's statistical uncertainty against the truth: a device
    # never moves as an exact rotated copy of the chest, and without this floor one coherent step
    # band claims hundredth-of-a-degree precision and outvotes the other devices. 2° measured
    # best on the `small` preset (0°: worst phone error 7.4°, 1°: 5.1°, 2°: 4.2°).
    truth_model_error_deg: float = 2.0
    reference_order: tuple[str, ...] = ("phone",)
    # Mode "initial": the truth seconds, from the first truth sample, that the one constant yaw onto
    # the truth is estimated from (the rest of the truth is not looked at).
    initial_s: float = 10.0

    def __post_init__(self) -> None:
        if not self.bands_hz or any(not 0 <= lo < hi for lo, hi in self.bands_hz):
            raise ConfigError(f"bands_hz must be (low, high) pairs with 0 ≤ low < high, got {self.bands_hz}")
        if self.kernel_s <= 0:
            raise ConfigError(f"kernel_s must be positive, got {self.kernel_s}")


@dataclass
class YawTrack:
    """Yaw of one frame relative to another over time: ``yaw`` (T,) rad in the module's
    convention, ``info`` (T,) its information 1/variance in rad⁻² (0 where nothing is known),
    ``bands`` the bands that contributed, ``coherence`` the anchor band's global coherence."""

    yaw: np.ndarray
    info: np.ndarray
    bands: tuple[int, ...] = ()
    coherence: float = 0.0

    @property
    def std_deg(self) -> np.ndarray:
        """1-σ uncertainty in degrees (inf where nothing is known)."""
        with np.errstate(divide="ignore"):
            return np.rad2deg(1.0 / np.sqrt(self.info))

    def summary(self) -> dict:
        """Mean yaw, its range over time, median uncertainty and evidence (the anchor band's
        coherence, the bands used), as plain numbers for ``meta``."""
        known = self.info > 0
        span = np.rad2deg(np.ptp(np.unwrap(self.yaw[known]))) if known.any() else 0.0
        return {
            "yaw_deg": round(float(np.rad2deg(_circular_mean(self.yaw, self.info))), 3) if known.any() else None,
            "span_deg": round(float(span), 3),  # how far the time-varying yaw moves
            "std_deg": round(float(np.median(self.std_deg[known])), 3) if known.any() else None,
            "coherence": round(float(self.coherence), 3),
            "bands": list(self.bands),
            "known_share": round(float(known.mean()), 3) if known.size else 0.0,
        }


def _circular_mean(angle: np.ndarray, weight: np.ndarray) -> float:
    return float(np.angle(np.sum(weight * np.exp(1j * angle))))


def wrap(angle):
    """Angle(s) into (−π, π]."""
    return np.angle(np.exp(1j * np.asarray(angle)))


def horizontal(x: np.ndarray) -> np.ndarray:
    """The xy channels of (..., ≥2) vectors as complex numbers x + iy."""
    return x[..., 0].astype(np.float64) + 1j * x[..., 1].astype(np.float64)


def rotate_stacked(x: np.ndarray, yaw) -> np.ndarray:
    """Rotate (T, 3k) stacked 3-vectors (acc xyz, gyro xyz, ...) about z by ``yaw`` (scalar or (T,))
    rad: v' = Rz(yaw) v (:func:`wearnav.core.rotations.rotate_about_vertical`). Vertical channels are
    untouched."""
    x = np.asarray(x)
    yaw = np.broadcast_to(np.asarray(yaw, np.float64), x.shape[:1])[:, None]
    v = x.reshape(x.shape[0], -1, 3).astype(np.float64)
    return rotate_about_vertical(v, yaw).reshape(x.shape).astype(x.dtype)


def _bandpass(z: np.ndarray, band: tuple[float, float], rate: float) -> np.ndarray:
    lo, hi = band
    hi = min(hi, 0.45 * rate)
    if lo > 0:
        sos = signal.butter(2, [lo, hi], btype="band", fs=rate, output="sos")
    else:
        sos = signal.butter(4, hi, fs=rate, output="sos")
    if z.size < 2:
        return np.zeros_like(z)
    pad = min(3 * (2 * len(sos) + 1), z.size - 1)  # scipy's default, shortened for short inputs
    return signal.sosfiltfilt(sos, z.real, padlen=pad) + 1j * signal.sosfiltfilt(sos, z.imag, padlen=pad)


def usable(mask: np.ndarray, rate: float, margin_s: float) -> np.ndarray:
    """``mask`` without ``margin_s`` at each edge of its True stretches (filters ring there)."""
    n = int(round(margin_s * rate))
    if n <= 0 or not mask.any():
        return mask.astype(bool)
    return binary_erosion(mask.astype(bool), np.ones(2 * n + 1, bool), border_value=0)


def lever_regressor(yaw_rate: np.ndarray, rate: float, cutoff_hz: float = 0.5) -> np.ndarray:
    """The turn-dependent acceleration difference of two points fixed on one turning body.

    Two devices at horizontal positions differing by a lever arm r(t) = e^{iΘ(t)} r₀ on a body
    turning at ω = Θ' differ in acceleration by (iω' − ω²) e^{iΘ} r₀: centripetal and tangential
    terms perpendicular to the body's own turn acceleration, which bias a plain Procrustes angle by
    up to atan(ω|r₀|/v) during turns. With this regressor beside the reference's acceleration the
    unknown constant r₀ is fitted away. ``yaw_rate`` is the vertical world gyro (frame-independent),
    low-passed to the body's turns."""
    sos = signal.butter(4, cutoff_hz, fs=rate, output="sos")
    omega = signal.sosfiltfilt(sos, yaw_rate) if yaw_rate.size > 30 else yaw_rate
    theta = np.cumsum(omega) / rate
    return (1j * np.gradient(omega) * rate - omega**2) * np.exp(1j * theta)


def heading_regressor(yaw_rate: np.ndarray, rate: float) -> np.ndarray:
    """e^{iθ(t)} with θ the device's own heading (integrated vertical world gyro).

    A constant accelerometer bias b in the device frame appears in the world frame as R(t) b; its
    horizontal part turns with the device, e^{iθ(t)} b_h, so it changes exactly when the body
    turns — when the anchor band carries its signal — and would bias the angle. With this
    regressor its unknown b_h is fitted away."""
    return np.exp(1j * np.cumsum(yaw_rate) / rate)


def _smooth(x: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian-weighted local mean along the last axis (zero outside the signal), by FFT: the
    kernel spans thousands of samples, where direct convolution dominated the run time."""
    n = x.shape[-1]
    half = int(min(4 * sigma, n))
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma) ** 2)
    k = (k / k.sum()).reshape((1,) * (x.ndim - 1) + (-1,))
    return signal.fftconvolve(x, k, mode="same", axes=-1) if n else x


def _fit(y, X, w, n, smooth):
    """Weighted complex least squares y ≈ A X[0] + Σ c_k X[k] (k ≥ 1: nuisance regressors), with
    sums taken by ``smooth`` along time (a kernel, or a plain sum for the global fit). Returns the
    angle of A, its information 2|A|² N s₁₁' / r (s₁₁' the power of X[0] not explained by the
    nuisance regressors, r the residual power) and the plain coherence of y and X[0]."""
    K = len(X)
    iu = [(i, j) for i in range(K) for j in range(i, K)]
    prods = [w * np.conj(X[i]) * X[j] for i, j in iu] + [w * np.conj(x) * y for x in X]
    prods += [w * np.abs(y) ** 2, w.astype(complex)]
    P = np.moveaxis(np.atleast_2d(smooth(np.stack(prods))), 0, -1)  # (T or 1, products)
    S = np.zeros(P.shape[:-1] + (K, K), complex)
    for m, (i, j) in enumerate(iu):
        S[..., i, j] = P[..., m]
        S[..., j, i] = np.conj(P[..., m])
    r = P[..., len(iu) : len(iu) + K]
    syy, sw = P[..., -2].real, P[..., -1].real
    s11 = S[..., 0, 0].real
    # a tiny ridge keeps regressors that are all zero (no gyro) from making S singular
    diag = np.arange(K)
    S[..., diag, diag] += 1e-8 * S[..., diag, diag].real + 1e-10 * s11[..., None] + 1e-30
    c = np.linalg.solve(S, r[..., None])[..., 0]
    e0 = np.zeros(K)
    e0[0] = 1.0
    inv00 = np.linalg.solve(S, np.broadcast_to(e0, r.shape)[..., None])[..., 0, 0].real
    with np.errstate(divide="ignore"):
        # the power of X[0] left after the nuisance regressors: between 0 and its total power
        s11p = np.clip(np.where(inv00 > 0, 1.0 / inv00, 0.0), 0.0, s11)
    A = c[..., 0]
    fitted = np.real(np.sum(np.conj(c) * r, axis=-1))
    resid = np.maximum(syy - fitted, 1e-6 * syy)
    # Below MIN_POWER a signal is round-off or sensor noise, not motion: no information.
    floor = MIN_POWER * sw
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        info = np.where((syy > floor) & (s11 > floor), 2.0 * np.abs(A) ** 2 * n * s11p / resid, 0.0)
    info = np.clip(np.nan_to_num(info), 0.0, MAX_INFO)
    gamma = _coherence(r[..., 0], s11, syy)
    return np.angle(A), info, gamma


def relative_yaw(
    z_a: np.ndarray,
    z_b: np.ndarray,
    weight: np.ndarray,
    rate: float,
    cfg: FrameConfig = FrameConfig(),
    nuisance: Sequence[np.ndarray] = (),
) -> YawTrack:
    """Yaw of a's frame relative to b's (z_a ≈ e^{iψ} z_b) over time, from horizontal world
    accelerations ``z_a``, ``z_b`` (complex, T) and a per-sample ``weight`` (0 where either is
    absent; see :func:`usable`). ``nuisance`` regressors (:func:`lever_regressor`,
    :func:`heading_regressor`) join the anchor band's fit."""
    w = np.asarray(weight, np.float64)
    sigma = cfg.kernel_s * rate
    coverage = _smooth(w, sigma)  # share of the kernel with data
    coverage[coverage < 1e-6] = 0.0  # FFT round-off far from any data is not evidence
    per_band = []
    for k, band in enumerate(cfg.bands_hz):
        za, zb = _bandpass(z_a, band, rate), _bandpass(z_b, band, rate)
        X = [zb] + ([_bandpass(x, band, rate) for x in nuisance] if k == 0 else [])
        bandwidth = min(band[1], 0.45 * rate) - band[0]
        # independent complex samples: 2 × bandwidth × duration (a Gaussian window of σ spans 2√π σ)
        n_loc = 2.0 * bandwidth * 2.0 * np.sqrt(np.pi) * cfg.kernel_s * coverage
        n_glob = 2.0 * bandwidth * w.sum() / rate
        loc, info, _ = _fit(za, X, w, n_loc, lambda x: _smooth(x, sigma))
        glob, glob_info, gamma = _fit(za, X, w, n_glob, lambda x: x.sum(axis=-1, keepdims=True))
        per_band.append(
            dict(loc=loc, info=info, glob=float(glob[0]), gamma=float(gamma[0]), glob_info=float(glob_info[0]))
        )
    anchor = per_band[0]
    used = [0]
    for k, b in enumerate(per_band[1:], start=1):
        agree = abs(wrap(b["glob"] - anchor["glob"])) <= np.deg2rad(cfg.max_band_disagreement_deg)
        if b["gamma"] >= cfg.min_coherence and agree:
            used.append(k)
    acc = np.zeros(w.size, complex)
    info = np.zeros(w.size)
    for k in used:
        acc += per_band[k]["info"] * np.exp(1j * per_band[k]["loc"])
        info += per_band[k]["info"]
    yaw = np.where(info > 0, np.angle(acc), anchor["glob"])
    return YawTrack(yaw, info, tuple(used), anchor["gamma"])


def _coherence(p, ea, eb) -> np.ndarray:
    den = np.sqrt(np.maximum(ea * eb, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(den > 0, np.abs(p) / np.where(den > 0, den, 1.0), 0.0)
    return np.clip(g, 0.0, 0.999)


def reference_index(devices: tuple[str, ...], mask: np.ndarray, cfg: FrameConfig = FrameConfig()) -> int:
    """The reference device: the first of ``cfg.reference_order`` that is present, else the
    first present device (−1 if none is)."""
    present = [bool(m.any()) for m in mask]
    for name in cfg.reference_order:
        if name in devices and present[devices.index(name)]:
            return devices.index(name)
    return present.index(True) if any(present) else -1


@dataclass
class CommonFrame:
    """Each device's yaw relative to the reference device (``yaw`` (D, T) rad, ``info`` (D, T)
    rad⁻²), the reference's index, and the pairwise tracks it was built from."""

    reference: int
    yaw: np.ndarray
    info: np.ndarray
    pairs: dict[tuple[int, int], YawTrack] = field(default_factory=dict)


def common_frame(
    imu: np.ndarray,
    mask: np.ndarray,
    devices: tuple[str, ...],
    rate: float,
    cfg: FrameConfig = FrameConfig(),
    iterations: int = 10,
) -> CommonFrame:
    """Yaw of every present device relative to the reference device, from the IMU alone.

    ``imu`` (D, T, ≥2) world-frame acceleration first, ``mask`` (D, T). Pairwise tracks between
    all present devices are fused per time step: with ψ_ref = 0, each device's phasor is the
    information-weighted sum over its partners of (pair estimate · partner's phasor); a few
    fixed-point sweeps settle it (three devices: a 2-unknown problem)."""
    D, T = mask.shape
    ref = reference_index(devices, mask, cfg)
    yaw, info = np.zeros((D, T)), np.zeros((D, T))
    if ref < 0:
        return CommonFrame(ref, yaw, info)
    z = horizontal(imu)
    ok = np.stack([usable(m, rate, cfg.edge_margin_s) for m in mask])
    present = [d for d in range(D) if mask[d].any()]
    pairs: dict[tuple[int, int], YawTrack] = {}
    for i, a in enumerate(present):
        for b in present[i + 1 :]:
            w = (ok[a] & ok[b]).astype(np.float64)
            if w.sum() == 0:
                continue
            # the body's turn rate: both devices' vertical gyro (world z, the same in every yaw frame)
            nuisance = []
            if imu.shape[-1] >= 6:
                nuisance = [lever_regressor(0.5 * (imu[a, :, 5] + imu[b, :, 5]), rate)]
                if cfg.bias_regressors:
                    nuisance += [heading_regressor(imu[a, :, 5], rate), heading_regressor(imu[b, :, 5], rate)]
            pairs[(a, b)] = relative_yaw(z[a], z[b], w, rate, cfg, nuisance)
    # Initial phasors: direct edge to the reference where there is one, else 0.
    phasor = np.ones((D, T), complex)
    for d in present:
        if d == ref:
            continue
        tr = pairs.get((d, ref)) or pairs.get((ref, d))
        if tr is not None:
            phasor[d] = np.exp(1j * (tr.yaw if (d, ref) in pairs else -tr.yaw))
    for _ in range(iterations):
        for d in present:
            if d == ref:
                continue
            acc = np.zeros(T, complex)
            tot = np.zeros(T)
            for (a, b), tr in pairs.items():
                if d not in (a, b):
                    continue
                other, sign = (b, 1.0) if a == d else (a, -1.0)
                acc += tr.info * np.exp(1j * sign * tr.yaw) * phasor[other]
                tot += tr.info
            new = np.where(np.abs(acc) > 0, acc / np.where(np.abs(acc) > 0, np.abs(acc), 1.0), phasor[d])
            phasor[d] = new
            info[d] = tot
    yaw = np.angle(phasor)
    yaw[ref] = 0.0
    info[ref] = np.inf
    for d in range(D):
        if d not in present:
            yaw[d], info[d] = 0.0, 0.0
    return CommonFrame(ref, yaw, info, pairs)


def truth_acceleration(pos: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal truth acceleration (complex, T) from positions on the clock (T × 2, NaN where
    missing) and where it is valid: central second differences inside finite stretches."""
    finite = np.isfinite(pos).all(axis=1)
    z = np.where(finite, horizontal(np.nan_to_num(pos)), 0.0)
    acc = np.zeros_like(z)
    acc[1:-1] = (z[2:] - 2 * z[1:-1] + z[:-2]) * rate * rate
    ok = np.zeros_like(finite)
    ok[1:-1] = finite[2:] & finite[1:-1] & finite[:-2]
    acc[~ok] = 0.0
    return acc, ok


def truth_yaw(
    imu_common: np.ndarray, mask: np.ndarray, pos: np.ndarray, rate: float, cfg: FrameConfig = FrameConfig()
) -> YawTrack:
    """Yaw of the common frame relative to the truth frame over time, from devices already in the
    common frame (``imu_common`` (D, T, ≥2), ``mask`` (D, T)) and truth positions ``pos``
    (T × 2, NaN where missing): each device's track against the truth's acceleration, fused by
    information. Uses truth positions only, never predictions."""
    z_truth, ok_truth = truth_acceleration(pos, rate)
    ok_truth = usable(ok_truth, rate, cfg.edge_margin_s)
    z = horizontal(imu_common)
    T = z_truth.size
    acc = np.zeros(T, complex)
    info = np.zeros(T)
    bands: set[int] = set()
    coh = []
    for d in range(mask.shape[0]):
        w = (usable(mask[d], rate, cfg.edge_margin_s) & ok_truth).astype(np.float64)
        if w.sum() == 0:
            continue
        nuisance = []
        if imu_common.shape[-1] >= 6:
            nuisance = [lever_regressor(imu_common[d, :, 5], rate)]
            if cfg.bias_regressors:
                nuisance.append(heading_regressor(imu_common[d, :, 5], rate))
        tr = relative_yaw(z[d], z_truth, w, rate, cfg, nuisance)
        with np.errstate(divide="ignore"):
            tr_info = np.where(tr.info > 0, 1.0 / (1.0 / tr.info + np.deg2rad(cfg.truth_model_error_deg) ** 2), 0.0)
        acc += tr_info * np.exp(1j * tr.yaw)
        info += tr_info
        bands |= set(tr.bands)
        coh.append(tr.coherence)
    yaw = np.where(info > 0, np.angle(acc), 0.0)
    if info.any() and (info == 0).any():
        # Where no device overlaps the truth, hold the overall estimate rather than jump to 0.
        yaw[info == 0] = _circular_mean(yaw, info)
    return YawTrack(yaw, info, tuple(sorted(bands)), float(np.max(coh)) if coh else 0.0)


def initial_truth(pos: np.ndarray, rate: float, seconds: float) -> np.ndarray:
    """(T,) True at the samples within ``seconds`` of the first finite truth position of ``pos``
    (T × 2, NaN where missing); all False where there is none."""
    finite = np.isfinite(pos).all(axis=1)
    out = np.zeros(finite.size, bool)
    if finite.any():
        first = int(np.argmax(finite))
        out[first : first + int(round(seconds * rate)) + 1] = True
    return out & finite


def align_frames(
    imu: np.ndarray,
    mask: np.ndarray,
    devices: tuple[str, ...],
    rate: float,
    pos: np.ndarray | None,
    mode: str = "truth",
    cfg: FrameConfig = FrameConfig(),
) -> tuple[np.ndarray, dict]:
    """:func:`frame_yaws` applied: ``imu`` rotated by −yaw, device by device, and the record."""
    yaw, record = frame_yaws(imu, mask, devices, rate, pos, mode, cfg)
    return (imu if yaw is None else turn_devices(imu, mask, yaw)), record


def turn_devices(imu: np.ndarray, mask: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """``imu`` (D, T, 6) with each device rotated by −``yaw`` (D, T), absent samples zero."""
    out = np.stack([rotate_stacked(imu[d], -yaw[d]) for d in range(len(imu))])
    out[~mask] = 0.0
    return out.astype(imu.dtype)


def frame_yaws(
    imu: np.ndarray,
    mask: np.ndarray,
    devices: tuple[str, ...],
    rate: float,
    pos: np.ndarray | None,
    mode: str = "truth",
    cfg: FrameConfig = FrameConfig(),
) -> tuple[np.ndarray | None, dict]:
    """The yaw that turns world-frame ``imu`` (D, T, 6) of an aligned recording into one frame.

    ``mode`` "common": every device into the reference device's frame; "truth": then the common
    frame onto the truth's over time (only where ``pos`` gives usable truth, else it stays "common");
    "initial": the common frame turned by one constant yaw onto the truth, estimated from the first
    ``cfg.initial_s`` seconds of ``pos`` only (no truth after them is read).
    Returns each device's yaw (D, T; rad; None: nothing to turn), by whose negative
    :func:`align_frames` rotates it, and a plain-dict record of what was done (for ``Aligned.meta``):
    the frame reached, the reference, and per device its yaw relative to the reference with its
    uncertainty and coherence; for "truth" the common frame's yaw relative to the truth."""
    if mode not in FRAME_ALIGN_MODES:
        raise ConfigError(f"frame_align must be one of {', '.join(FRAME_ALIGN_MODES)}, got {mode!r}")
    record: dict = {"frame": "none"}
    if mode == "none":
        return None, record
    cf = common_frame(imu, mask, devices, rate, cfg)
    if cf.reference < 0:
        return None, record
    total = cf.yaw.copy()
    record = {"frame": "common", "reference": devices[cf.reference], "devices": {}, "truth": None}
    for d, name in enumerate(devices):
        if d != cf.reference and mask[d].any():
            pair = cf.pairs.get((d, cf.reference)) or cf.pairs.get((cf.reference, d))
            record["devices"][name] = YawTrack(
                cf.yaw[d], cf.info[d], pair.bands if pair else (), pair.coherence if pair else 0.0
            ).summary()
    if mode in ("truth", "initial") and pos is not None:
        common = np.stack([rotate_stacked(imu[d], -cf.yaw[d]) for d in range(len(devices))])
        if mode == "initial":
            initial = initial_truth(pos, rate, cfg.initial_s)
            tr = truth_yaw(common, mask, np.where(initial[:, None], pos, np.nan), rate, cfg)
            if (tr.info * initial).any():
                yaw0 = _circular_mean(tr.yaw, tr.info * initial)
                total = total + yaw0
                record["frame"] = "initial"
                record["truth"] = {
                    "yaw_deg": round(float(np.rad2deg(yaw0)), 3),
                    "from_s": cfg.initial_s,
                    "std_deg": round(float(np.rad2deg(1 / np.sqrt(np.sum(tr.info * initial)))), 3),
                }
        else:
            tr = truth_yaw(common, mask, pos, rate, cfg)
            if tr.info.any():
                total = total + tr.yaw[None, :]
                record["frame"] = "truth"
                record["truth"] = tr.summary()
    return total, record
