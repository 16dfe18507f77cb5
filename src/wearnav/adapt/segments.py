"""A user's walks cut into segments between two good location fixes, and the odometry's
displacement over each (issue 18 §3; EasyTrack, paper 004, §III-A, eq. 4, with longer segments).

A segment runs between two of the phone's fixes about ``segment_s`` apart (the chain of
:func:`wearnav.fixlabels.label_recording`, its jump filter included); its label is the fixes'
displacement d̃ = P̃_j − P̃_i (eq. 4). EasyTrack's 1-s segments carry ~1 m of label noise on ~1 m
of walk; a 10-s segment carries the same noise on ~12 m, which a speed calibration can use
directly. A segment is kept when both fixes report an accuracy of at most ``max_accuracy_m`` and
the fixes moved at least ``min_length_m`` (a standing walker's ratio is noise over nothing).

The odometry's displacement over a segment is the integral of the model's window velocities,
linearly interpolated between window centres and held before the first and after the last, as
:func:`wearnav.trajectory.integrate_velocity` integrates a path: it is linear in the velocities,
d_odo = A · v with A (segments × windows) from :func:`integration_weights`, so the same matrix
serves measuring (numpy) and fine-tuning (torch).

The fixes are east/north, the odometry in the phone's own world frame (an arbitrary yaw that
drifts slowly): :func:`segment_yaw` fits the yaw between them per segment from the segments of
the same walk near it in time (a Procrustes fit, Gaussian weights, σ = ``YAW_KERNEL_S``). Only
the user's fixes and IMU are used; a recording's truth is never read.

Decision: docs/decisions/0017-adaptation-from-fixes.md.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from wearnav.errors import ConfigError
from wearnav.evaluate import predict_sequence
from wearnav.fixlabels import LabelConfig, label_recording
from wearnav.preprocess import Aligned, align
from wearnav.recording import Recording

# Fixes reporting a wider accuracy are left out (m): IPIN 2023's outdoor GNSS reports 3–10 m
# (median 4–6), its indoor fixes 13–30 m and more (docs: measured on the imported training trials).
MAX_ACCURACY_M = 20.0
# The yaw between the phone's world frame and east/north drifts slowly (a game rotation vector):
# segments within about this many seconds share it (as wearnav.fixlabels.fix_frame_yaw's kernel).
YAW_KERNEL_S = 60.0


@dataclass(frozen=True)
class SegmentConfig:
    """Which fix pairs make a segment (module docstring)."""

    segment_s: float = 10.0
    tolerance: float = 0.25  # allowed relative deviation of a fix pair's spacing from segment_s
    max_accuracy_m: float = MAX_ACCURACY_M
    min_length_m: float = 3.0
    max_speed: float = 5.0  # m/s: wearnav.fixlabels' jump filter

    def __post_init__(self) -> None:
        if not (self.segment_s > 0 and self.max_accuracy_m > 0 and self.min_length_m >= 0 and self.max_speed > 0):
            raise ConfigError(f"segment settings must be positive: {dataclasses.asdict(self)}")


@dataclass
class WalkSegments:
    """One recording's segments: ``seq`` the model's input (its preprocessing, frame "common" as
    `wearnav track` prepares it), ``t0``/``t1`` (n,) the fix times (s), ``d_fix`` (n, 2) the fixes'
    displacement (m, east/north), ``fixes`` how many distinct fixes they use."""

    name: str
    seq: Aligned
    t0: np.ndarray
    t1: np.ndarray
    d_fix: np.ndarray
    fixes: int

    def __len__(self) -> int:
        return int(self.t0.size)

    def subset(self, idx) -> WalkSegments:
        idx = np.asarray(idx)
        return WalkSegments(
            self.name,
            self.seq,
            self.t0[idx],
            self.t1[idx],
            self.d_fix[idx],
            int(np.unique(np.concatenate([self.t0[idx], self.t1[idx]])).size),
        )


def walk_segments(rec: Recording, tcfg, cfg: SegmentConfig = SegmentConfig()) -> WalkSegments | None:
    """The segments of ``rec`` for a model of training config ``tcfg`` (None: no usable fix pair)."""
    if rec.fixes is None or len(rec.fixes) < 2:
        return None
    lcfg = LabelConfig(
        segment_s=cfg.segment_s, rate=tcfg.rate, tolerance=cfg.tolerance, align_to_fixes=False, max_speed=cfg.max_speed
    )
    lab = label_recording(rec, lcfg, warn_drops=False)
    if lab is None:
        return None
    fx = rec.fixes
    acc = np.asarray(fx.accuracy, np.float64) if fx.accuracy is not None else np.full(len(fx), np.nan)
    i0 = np.clip(np.searchsorted(fx.t, lab.t0), 0, len(fx) - 1)
    i1 = np.clip(np.searchsorted(fx.t, lab.t1), 0, len(fx) - 1)
    good = ~(acc[i0] > cfg.max_accuracy_m) & ~(acc[i1] > cfg.max_accuracy_m)  # NaN (not reported) is kept
    good &= np.linalg.norm(lab.label, axis=1) >= cfg.min_length_m
    if not good.any():
        return None
    seq = align(rec, dataclasses.replace(tcfg.preprocess_config(), frame_align="common"))
    return WalkSegments(
        rec.name,
        seq,
        lab.t0[good],
        lab.t1[good],
        lab.label[good],
        int(np.unique(np.concatenate([i0[good], i1[good]])).size),
    )


def integration_weights(c: np.ndarray, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """A (n, K) with A · v = ∫_{t0}^{t1} v(t) dt for window velocities v (K, 2) at centres ``c``
    (K,), v(t) linear between centres and held outside them (module docstring)."""
    c = np.asarray(c, np.float64)
    return _cumulative(c, np.asarray(t1, np.float64)) - _cumulative(c, np.asarray(t0, np.float64))


def _cumulative(c: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """W (m, K) with W · v = ∫_{c_0}^{τ} v(t) dt (negative before c_0)."""
    K = c.size
    W = np.zeros((tau.size, K))
    if K == 1:
        W[:, 0] = tau - c[0]
        return W
    h = np.diff(c)
    # trapezoid weights of ∫_{c_0}^{c_j}: cum[j] (K,) built row by row only for the needed j
    j = np.clip(np.searchsorted(c, tau, side="right") - 1, -1, K - 1)
    for r, (tr, jr) in enumerate(zip(tau, j)):
        if jr < 0:
            W[r, 0] = tr - c[0]
            continue
        W[r, :jr] += 0.5 * h[:jr]
        W[r, 1 : jr + 1] += 0.5 * h[:jr]
        u = tr - c[jr]
        if jr == K - 1:
            W[r, jr] += u
        else:
            q = u * u / (2.0 * h[jr])
            W[r, jr] += u - q
            W[r, jr + 1] += q
    return W


def window_centres(seq: Aligned, window: int, stride: int) -> np.ndarray:
    """Centre times (K,) of the windows :func:`wearnav.evaluate.predict_sequence` cuts from ``seq``."""
    starts = np.arange(0, len(seq) - window + 1, stride)
    return 0.5 * (seq.t[starts] + seq.t[starts + window - 1])


def odometry_displacements(model, seg: WalkSegments, window: int, stride: int) -> np.ndarray:
    """The model's displacement (n, 2) over each segment, in the phone's own world frame (m)."""
    c, vel, _ = predict_sequence(model, seg.seq, window, stride)
    if c.size == 0:
        return np.full((len(seg), 2), np.nan)
    return integration_weights(c, seg.t0, seg.t1) @ vel


def segment_yaw(d_odo: np.ndarray, d_fix: np.ndarray, t_mid: np.ndarray, kernel_s: float = YAW_KERNEL_S) -> np.ndarray:
    """Per segment, the yaw ψ (rad) that turns the odometry's frame onto the fixes':
    ψ_i = arg Σ_j w_ij d̃_j · conj(d_odo,j), w_ij = exp(−½((t_i − t_j)/kernel_s)²) (module docstring)."""
    z = (d_fix[:, 0] + 1j * d_fix[:, 1]) * np.conj(d_odo[:, 0] + 1j * d_odo[:, 1])
    z = np.where(np.isfinite(z), z, 0.0)
    w = np.exp(-0.5 * ((t_mid[:, None] - t_mid[None, :]) / kernel_s) ** 2)
    return np.angle(w @ z)


def rotate(d: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """2-D vectors (n, 2) turned by ``yaw`` (n,) rad."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], axis=1)


def compare(d_odo: np.ndarray, d_fix: np.ndarray, t_mid: np.ndarray) -> dict:
    """How one walk's odometry agrees with its fixes, per segment: the length ratio |d_odo| / |d̃|,
    the speed factor |d̃| / |d_odo| (what the odometry's speed must be multiplied by) and the
    distance |R(ψ) d_odo − d̃| (m) after the walk's own yaw fit (:func:`segment_yaw`).

    Why lengths and not d̃ projected on the turned odometry: the projection also shrinks by the
    cosine of every heading disagreement, the fixes' own included. On IPIN's training trials (10-s
    segments, fixes against the POSI points joined by straight lines, the truth standing in for a
    perfect odometry) the fixes' length is 0.90 of the truth's (median, 220 segments) and their
    projection 0.82; on simulated walks the length ratio reads 1–4 % long (fix noise adds length)."""
    ok = np.isfinite(d_odo).all(axis=1) & (np.linalg.norm(d_odo, axis=1) > 1e-6)
    out = {
        "ratio": np.full(len(d_fix), np.nan),
        "factor": np.full(len(d_fix), np.nan),
        "error_m": np.full(len(d_fix), np.nan),
    }
    if not ok.any():
        return out
    yaw = segment_yaw(d_odo[ok], d_fix[ok], t_mid[ok])
    odo = rotate(d_odo[ok], yaw)
    length_odo, length_fix = np.linalg.norm(d_odo[ok], axis=1), np.linalg.norm(d_fix[ok], axis=1)
    out["ratio"][ok] = length_odo / length_fix
    out["factor"][ok] = length_fix / length_odo
    out["error_m"][ok] = np.linalg.norm(odo - d_fix[ok], axis=1)
    return out


def summary(parts: list[dict]) -> dict:
    """Medians (and p75 of the error) of :func:`compare`'s values pooled over walks."""

    def pooled(key):
        v = np.concatenate([p[key] for p in parts]) if parts else np.empty(0)
        return v[np.isfinite(v)]

    ratio, factor, err = pooled("ratio"), pooled("factor"), pooled("error_m")
    r = lambda x: round(float(x), 4)
    return {
        "segments": int(err.size),
        "length_ratio_median": r(np.median(ratio)) if ratio.size else None,
        "speed_factor_median": r(np.median(factor)) if factor.size else None,
        "segment_error_median_m": r(np.median(err)) if err.size else None,
        "segment_error_p75_m": r(np.percentile(err, 75)) if err.size else None,
    }


__all__ = [
    "SegmentConfig",
    "WalkSegments",
    "walk_segments",
    "integration_weights",
    "window_centres",
    "odometry_displacements",
    "segment_yaw",
    "rotate",
    "compare",
    "summary",
    "MAX_ACCURACY_M",
    "YAW_KERNEL_S",
]
