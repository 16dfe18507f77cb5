"""The smoother's constants and result (:mod:`wearnav.fuse`), and a fix's σ from its reported accuracy."""

from __future__ import annotations

import dataclasses

import numpy as np

from wearnav.errors import ValidationError
from wearnav.fixcheck import FixCheck

SURVEY_ODOMETRY = "pdr-pointing-cadence"  # where survey walks run between their surveyed points (fuse.survey)
RADIUS_68 = 1.515  # 68 % radius of a unit circular Gaussian (accuracy = RADIUS_68 · σ per axis)
RAYLEIGH_MEDIAN = float(np.sqrt(2 * np.log(2)))  # its median radius
MIN_SIGMA_M = 0.5  # no fix is trusted to better than this per axis (phones report 1–3 m at best)
ANCHOR_S = 60.0  # first-fix anchoring: fixes of the first minute (today's `track`)
MIN_SPREAD_M = 5.0  # below this weighted RMS spread the heading is not observable from fixes
DOWNWEIGHT = 0.2  # a fix whose robust weight falls below this (|r| > 2 c) counts as down-weighted
DISAGREE_SHARE = 0.5  # more than this share down-weighted: the fixes disagree, fall back
# The fix-error model measured on IPIN 2023's training walks (1-Hz fixes at the surveyed points):
# the error per axis is the reported accuracy / RADIUS_68 (median ratio 0.98) and almost all of it
# is correlated, falling to 0.83 / 0.57 / 0.32 / 0.08 at lags of 6 / 15 / 25 / 74 s (about 20 s).
# Opt-in: on those walks it helped Suite-IN++ (median 4.63 → 4.37 m) and not PDR (4.44 → 4.56 m).
MEASURED_FIX_BIAS = {"bias_share": 0.9, "bias_correlation_s": 20.0, "bias_knot_s": 10.0}
MAX_FIX_LAG_S = 10.0  # the largest lag of the fixes behind the walker calibrated or taken (s)
CALIBRATION_JSON = "fuse_calibration.json"  # in a run folder: the model's odometry_walk_sigma and sigma_scale_of


@dataclasses.dataclass(frozen=True)
class FuseConfig:
    """Every constant of the smoother (saved with its result)."""

    node_s: float = 1.0  # spacing of the path's nodes, s
    scale_prior: float = 1.0  # prior median of the odometry's scale
    scale_prior_log_sigma: float = 0.05  # σ of log(scale): ±5 % at 1 σ (looser let indoor fixes, which
    # move less than the walker, shrink the path: IPIN training walks, PDR, docs in the module)
    drift_sigma_rad_s: float = np.radians(10.0) / 600.0  # heading drift prior: 10° per 10 min at 1 σ
    bias_sigma_m: float = 3.0  # stationary σ per axis of the fixes' slowly varying error
    bias_correlation_s: float = 120.0  # its correlation time (GNSS errors wander over minutes)
    bias_knot_s: float = 30.0  # knot spacing of the bias, s
    robust_scale: float = 2.0  # Cauchy loss scale on the normalised fix residual (|r|/σ)
    wide_m: float = 100.0  # fixes reporting a wider accuracy are dropped (wearnav.fixcheck)
    fix_lag_s: float = 0.0  # a fix stamped t describes where the walker was at t − fix_lag_s
    heading_walk_deg_per_sqrt_min: float = 5.0  # random-walk heading error between bias knots (0: off)
    odometry_walk_m_per_sqrt_s: float = 0.3  # random-walk position error of the odometry at the knots (0: off)
    heading_prior_deg: float | None = None  # the odometry frame's known yaw to east/north (a north-referenced
    # orientation: 0), None: unknown (the fixes alone give the heading offset)
    heading_prior_sigma_deg: float = 15.0  # its 1-σ (magnetic disturbance indoors, declination, the model's bias)
    sigma_scale: float = 1.0  # each point's σ is the model's times this (calibrated where the model is used:
    # sigma_scale_of; the fit itself does not change)
    bias_share: float = 0.0  # 0: the bias has σ bias_sigma_m and each fix its full σ. In (0, 1): that share of
    # each fix's error variance is the bias (σ √share · the fixes' median σ), the rest white (module docs)

    def __post_init__(self):
        if not 0.0 <= self.bias_share < 1.0:
            raise ValidationError(f"bias_share must be in [0, 1); got {self.bias_share}")
        if not self.sigma_scale > 0:
            raise ValidationError(f"sigma_scale must be positive; got {self.sigma_scale}")


@dataclasses.dataclass
class FuseResult:
    """The fused path and what the fit found. ``xy`` (N, 2) m east/north at the input times;
    ``sigma_m`` (N,) its 1-σ per-axis uncertainty (m, NaN unknown) from the fit's covariance
    (:func:`wearnav.fuse.smoother.node_sigma`) times ``sigma_scale``: the model's alone is right
    where the fixes' and the odometry's errors follow the model and too small on IPIN 2023's indoor
    walks (their fix errors are more correlated), so the scale is calibrated where the model is
    used (:func:`wearnav.fuse.calibrate.sigma_scale_of`). ``fixes``: the status, reason and weight of every fix given (:class:`wearnav.fixcheck.FixCheck`)."""

    xy: np.ndarray
    sigma_m: np.ndarray
    method: str
    info: dict
    warnings: list[str]
    fixes: FixCheck | None = None


def fix_sigma_m(accuracy: np.ndarray) -> np.ndarray:
    """Per-axis σ (m) of each fix from its reported accuracy (a 68 % radius); NaN or non-positive
    accuracy takes the median of the others (1.0 m if none is known)."""
    acc = np.asarray(accuracy, np.float64)
    ok = np.isfinite(acc) & (acc > 0)
    fill = float(np.median(acc[ok])) if ok.any() else RADIUS_68
    return np.maximum(np.where(ok, acc, fill) / RADIUS_68, MIN_SIGMA_M)
