"""The smoother's calibration for a model and a recording (:mod:`wearnav.fuse`): the odometry's random
walk, the σ scale and the fixes' lag measured on walks with truth, stored in a run folder (``CALIBRATION_JSON``), and
the heading prior a recording's north-referenced frame gives; :func:`config_for` puts them together.

Decisions: docs/decisions/0020-fused-path-smoother.md, docs/decisions/0023-smoother-point-sigma.md,
docs/decisions/0036-fix-lag.md."""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np

from wearnav.core.textio import read_json
from wearnav.errors import FormatError
from wearnav.export.header import is_exported, read_header
from wearnav.fuse.config import CALIBRATION_JSON, MAX_FIX_LAG_S, RAYLEIGH_MEDIAN, FuseConfig
from wearnav.recording import ANDROID_ENU_FRAME
from wearnav.runs import run_folder

log = logging.getLogger(__name__)


def odometry_walk_sigma(walks) -> dict:
    """Calibrate ``odometry_walk_m_per_sqrt_s`` on walks with truth (a model's validation walks).

    ``walks`` yields (t (N,) s, odometry xy (N, 2) m, truth_t (M,) s, truth_xy (M, 2) m). Each path
    is fitted to its truth points by rotation, scale and translation (the unknowns the smoother
    estimates otherwise); the residual's increments between consecutive truth points, over √Δt,
    give the random walk's σ per axis, robustly: their median / √(2 ln 2) (the median length of a
    2-D Gaussian with σ per axis is σ √(2 ln 2))."""
    rates, n = [], 0
    for t, xy, tt, tp in walks:
        k = (tt >= t[0]) & (tt <= t[-1])
        if k.sum() < 3:
            continue
        p = np.stack([np.interp(tt[k], t, xy[:, j]) for j in range(2)], axis=1)
        zp = (p[:, 0] + 1j * p[:, 1]) - np.mean(p[:, 0] + 1j * p[:, 1])
        zq = (tp[k, 0] + 1j * tp[k, 1]) - np.mean(tp[k, 0] + 1j * tp[k, 1])
        a = np.sum(np.conj(zp) * zq) / max(float(np.sum(np.abs(zp) ** 2)), 1e-12)  # scale · e^{iθ}
        dt = np.diff(tt[k])
        rates.append(np.abs(np.diff(a * zp - zq))[dt > 0] / np.sqrt(dt[dt > 0]))
        n += 1
    if n == 0:
        return {"odometry_walk_m_per_sqrt_s": None, "walks": 0}
    sigma = float(np.median(np.concatenate(rates)) / RAYLEIGH_MEDIAN)
    return {"odometry_walk_m_per_sqrt_s": round(sigma, 4), "walks": n}


def sigma_scale_of(error_over_sigma) -> dict:
    """Calibrate ``sigma_scale`` on walks with truth: ``error_over_sigma`` holds, at their truth
    points, the smoothed path's error over its σ (run with ``sigma_scale`` 1). Where σ is right
    their median is :data:`RAYLEIGH_MEDIAN`; the scale is their median over it, so that the 68 %
    radius (:data:`RADIUS_68` σ) holds about 68 % of the errors."""
    z = np.asarray(error_over_sigma, np.float64)
    z = z[np.isfinite(z)]
    if z.size == 0:
        return {"sigma_scale": None, "sigma_points": 0}
    return {"sigma_scale": round(float(np.median(z)) / RAYLEIGH_MEDIAN, 3), "sigma_points": int(z.size)}


# the lags fix_lag_of tries, s: fixes that lag by more than MAX_FIX_LAG_S are not a position source
FIX_LAGS_S = np.arange(0.0, MAX_FIX_LAG_S + 0.01, 0.5)


def fix_lag_of(walks, lags_s=FIX_LAGS_S) -> dict:
    """Calibrate ``fix_lag_s`` (a fix stamped t shows where the walker was at t − lag) on walks with
    truth and fixes: the lag of ``lags_s`` at which the fixes, read at each truth point's time plus
    the lag (linearly between fixes), lie closest to the truth, by the median over every walk's
    points (the same points at every lag: those whose time plus the largest lag is still inside
    the fixes). ``walks`` yields (fix_t (M,) s, fix_xy (M, 2) m, truth_t (K,) s, truth_xy (K, 2) m).
    On IPIN 2023's training trials the phone's indoor fixes lag by 4 s (median 6.49 m at 0 s, 5.57 at
    4 s; docs/decisions/0036-fix-lag.md)."""
    lags_s = np.asarray(lags_s, np.float64)
    err, n = [], 0
    for ft, fz, tt, tp in walks:
        ft, fz, tt, tp = (np.asarray(a, np.float64) for a in (ft, fz, tt, tp))
        k = (tt >= ft[0] - lags_s.min()) & (tt <= ft[-1] - lags_s.max()) if ft.size >= 2 else np.zeros(tt.size, bool)
        if not k.any():
            continue
        q = tt[k][None, :] + lags_s[:, None]
        at = np.stack([np.interp(q, ft, fz[:, j]) for j in range(2)], axis=-1)
        err.append(np.linalg.norm(at - tp[k][None, :, :2], axis=-1))
        n += 1
    if n == 0:
        return {"fix_lag_s": None, "fix_lag_walks": 0}
    med = np.median(np.concatenate(err, axis=1), axis=1)
    best = int(np.argmin(med))
    return {
        "fix_lag_s": float(lags_s[best]),
        "fix_lag_walks": n,
        "fix_median_m_at_lag": round(float(med[best]), 3),
        "fix_median_m_at_0": round(float(np.interp(0.0, lags_s, med)), 3),
    }


def fix_lags(calibrations) -> list[float]:
    """The distinct positive fixes' lags (:func:`fix_lag_of`) of these calibrations, ascending: what
    a page or card says the smoother read the fixes at (empty: as stamped, or calibrations from
    before the lag)."""
    return sorted({float(c["fix_lag_s"]) for c in calibrations if c.get("fix_lag_s")})


def calibrated(cfg: FuseConfig, cal: dict | None) -> FuseConfig:
    """``cfg`` with a calibration's odometry random walk, σ scale and fix lag (``CALIBRATION_JSON``'s
    ``odometry_walk_m_per_sqrt_s``, ``sigma_scale``, ``fix_lag_s``) where they are given and positive."""
    found = {}
    for key in ("odometry_walk_m_per_sqrt_s", "sigma_scale", "fix_lag_s"):
        try:
            v = float((cal or {}).get(key))  # type: ignore[arg-type]  # a missing key: the TypeError caught below
        except (TypeError, ValueError):
            continue
        if np.isfinite(v) and v > 0:
            found[key] = v
    return dataclasses.replace(cfg, **found)


def known_heading_deg(meta: dict, reference: str | None = "phone") -> float | None:
    """The yaw (deg) from a recording's world frame to east/north where its importer documents it,
    else None. ``reference``: the device whose frame the odometry ran in (``frame.reference`` of
    :func:`wearnav.preprocess.align`; None or "phone" for the phone's own). Android's rotation vector
    (ILC2, IPIN 2023: :data:`wearnav.recording.ANDROID_ENU_FRAME`) is east, magnetic north, up: 0.
    Unknown: the simulator (its orientation has an arbitrary yaw, as a game rotation vector has) and
    Sensor Logger (its docs give an x-north reference frame, unverified on a real walk with truth)."""
    if reference in (None, "phone") and meta.get("quat_frame") == ANDROID_ENU_FRAME:
        return 0.0
    return None


def config_for(run, meta: dict | None = None, reference: str | None = "phone") -> tuple[FuseConfig, dict | None]:
    """The smoother's config for a model's run folder (or a checkpoint inside it) and a recording's
    ``meta``: the defaults, with the odometry's random walk and the σ scale from ``CALIBRATION_JSON``
    where the run has one (:func:`calibrated`), and a prior on the heading offset where the recording's world frame is north-referenced
    (:func:`known_heading_deg`; on IPIN 2023's training walks it cut the p95 error of PDR from 25.8
    to 17.9 m and of a learned model from another building from 21.8 to 19.2 m). Returns the config
    and the calibration read (None: none). ``run`` may be a file of `wearnav export`: the
    calibration is then the one its header carries (``fuse_calibration``,
    :mod:`wearnav.export.header`), so that an exported model places the path as its run does."""
    cfg, cal = FuseConfig(), None
    p = Path(run) if run is not None else None
    if p is not None and is_exported(p):
        c = read_header(p).get("fuse_calibration")
        if isinstance(c, dict) and calibrated(cfg, c) != cfg:
            cfg, cal = calibrated(cfg, c), c
        p = None
    folder = run_folder(p) if p is not None else None
    f = folder / CALIBRATION_JSON if folder is not None else None
    if f is not None and f.is_file():
        try:
            c = read_json(f)
            if calibrated(cfg, c) != cfg:
                cfg, cal = calibrated(cfg, c), c
            else:
                log.warning("%s: no usable calibration in it, the smoother's defaults are used", f)
        except (FormatError, AttributeError):
            log.warning("%s: unreadable calibration, the smoother's defaults are used", f)
    heading = known_heading_deg(meta or {}, reference)
    if heading is not None:
        cfg = dataclasses.replace(cfg, heading_prior_deg=heading)
    return cfg, cal
