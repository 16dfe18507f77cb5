"""BLE ranging: a log-distance path-loss model of a beacon's RSSI, fitted on training walks (issue 36).

The model (log-distance path loss with a floor attenuation factor, Seidel & Rappaport 1992, eq. 4
and 6)::

    rssi_dbm = p0_dbm + offset_db[device] - 10 n log10(max(d, d_min_m)) - floor_loss_db · floors + ε
    d = sqrt(horizontal_m² + (floors · floor_height_m)²)

``floors`` is the number of floors between walker and beacon (|floor difference|), ``p0_dbm`` the
RSSI at 1 m of the average phone of the training walks and ``offset_db`` each named phone's gain
against it (the two phones of IPIN 2023 differ by ~10 dB). ε is Gaussian with σ ``sigma_db``, or
Student-t with ``nu`` degrees of freedom and scale ``sigma_db`` where the residuals' tails say so
(:func:`fit_path_loss` picks by AIC).

Fitting (:func:`fit_path_loss`) needs the walker's position at each reading: recordings carry
truth only at sparse surveyed points (IPIN's POSI, every 10–25 s). :func:`truth_at` interpolates it
linearly in time between two consecutive surveyed points on the same floor at most
``max_span_s`` apart, and holds a surveyed point's position for readings within ``margin_s`` of it
outside such a span (before the first point, after the last, next to a floor change); any other
reading is not used. The parameters are then linear given ``d_min_m`` and ``floor_height_m``:
ordinary least squares.

A particle filter calls :meth:`PathLoss.loglik` with one reading against N particles' distances
(and floor differences): every argument broadcasts.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from scipy import special, stats

from wearnav.core.timeseries import nearest
from wearnav.errors import ValidationError
from wearnav.recording import Recording, Trajectory

D_MIN_M = 1.0  # below 1 m the far-field model does not hold; distances are clipped there
# Height of one floor at the IPIN 2023 venue: 0.332 hPa per floor (wearnav.fuse.floors.
# fit_floor_levels on trials 51 and 52: floor -1 at +0.375 hPa, -2 at +0.664 hPa against floor 0)
# / 0.1158 hPa per m (hydrostatic at 977 hPa, 15 °C) = 2.86 m.
FLOOR_HEIGHT_M = 2.9
TRUTH_MARGIN_S = 2.0  # a reading this close to a surveyed point outside a span takes its position
TRUTH_MAX_SPAN_S = 40.0  # longer gaps between surveyed points are not interpolated across
# Student-t instead of Gaussian noise when it lowers the AIC by more than this (one more parameter).
T_NOISE_MIN_AIC_GAIN = 10.0
STUDENT_T_NU_GAUSS = 1000.0  # a fitted ν above this is reported as this


@dataclasses.dataclass(frozen=True)
class PathLoss:
    """A fitted path-loss model (module docstring); JSON with :meth:`to_dict` / :meth:`from_dict`."""

    p0_dbm: float  # RSSI at 1 m, average phone
    n: float  # path-loss exponent (2 in free space)
    sigma_db: float  # noise σ (Gaussian) or scale (Student-t), dB
    nu: float | None = None  # Student-t degrees of freedom; None: Gaussian
    d_min_m: float = D_MIN_M
    floor_height_m: float = FLOOR_HEIGHT_M
    floor_loss_db: float = 0.0  # extra loss per floor between walker and beacon
    offset_db: dict[str, float] = dataclasses.field(default_factory=dict)  # per phone (meta["device"])
    device: str = ""  # the phone whose offset expected_rssi applies ("" or unknown: none)
    fit: dict[str, Any] = dataclasses.field(default_factory=dict)  # how it was fitted (counts, residuals)

    def __post_init__(self) -> None:
        if not (self.sigma_db > 0 and self.d_min_m > 0 and self.floor_height_m >= 0):
            raise ValidationError(
                f"path loss: sigma_db {self.sigma_db}, d_min_m {self.d_min_m} must be > 0 and "
                f"floor_height_m {self.floor_height_m} >= 0"
            )
        if self.nu is not None and not self.nu > 0:
            raise ValidationError(f"path loss: Student-t nu {self.nu} must be > 0")

    def for_device(self, device: str) -> PathLoss:
        """This model for one phone (``meta["device"]``): its fitted offset, or none if unknown."""
        return dataclasses.replace(self, device=device)

    def distance_m(self, horizontal_m, floors=0) -> np.ndarray:
        """3-D distance (m) from a horizontal distance (m) and a number of floors between (broadcast)."""
        return np.hypot(horizontal_m, np.abs(floors) * self.floor_height_m)

    def expected_rssi(self, dist_m, floors=0) -> np.ndarray:
        """Mean RSSI (dBm) at 3-D distance ``dist_m`` with ``floors`` floors between (broadcast)."""
        d = np.maximum(np.asarray(dist_m, np.float64), self.d_min_m)
        return (
            self.p0_dbm
            + self.offset_db.get(self.device, 0.0)
            - 10.0 * self.n * np.log10(d)
            - self.floor_loss_db * np.abs(floors)
        )

    def range_m(self, rssi_dbm, floors=0) -> np.ndarray:
        """The distance (m) at which ``rssi_dbm`` is the mean: the model inverted (not clipped)."""
        excess = self.expected_rssi(1.0, floors) - np.asarray(rssi_dbm, np.float64)
        return np.power(10.0, excess / (10.0 * self.n))

    def loglik(self, rssi_dbm, dist_m, floors=0) -> np.ndarray:
        """Log-likelihood of readings ``rssi_dbm`` (dBm) at 3-D distances ``dist_m`` (m), with
        ``floors`` floors between; all broadcast (one reading against (N,) particle distances → (N,))."""
        z = (np.asarray(rssi_dbm, np.float64) - self.expected_rssi(dist_m, floors)) / self.sigma_db
        if self.nu is None:
            return -0.5 * z**2 - math.log(self.sigma_db * math.sqrt(2.0 * math.pi))
        nu = self.nu
        const = special.gammaln((nu + 1) / 2) - special.gammaln(nu / 2) - 0.5 * math.log(nu * math.pi)
        return const - math.log(self.sigma_db) - (nu + 1) / 2 * np.log1p(z**2 / nu)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PathLoss:
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValidationError(f"path loss: unknown fields {sorted(unknown)}")
        return cls(**d)


@dataclasses.dataclass(frozen=True)
class RangeSamples:
    """Beacon readings paired with the walker's (interpolated) true position, for fitting/scoring."""

    rssi_dbm: np.ndarray  # (N,)
    horizontal_m: np.ndarray  # (N,) horizontal distance walker–beacon
    floors: np.ndarray  # (N,) |walker floor − beacon floor|
    beacon: np.ndarray  # (N,) names
    device: np.ndarray  # (N,) the recording's meta["device"] ("" if unknown)
    recording: np.ndarray  # (N,) the recording's name

    def __len__(self) -> int:
        return int(self.rssi_dbm.size)

    def select(self, keep: np.ndarray) -> RangeSamples:
        return RangeSamples(*(getattr(self, f.name)[keep] for f in dataclasses.fields(self)))

    @classmethod
    def concat(cls, parts: list[RangeSamples]) -> RangeSamples:
        return cls(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in dataclasses.fields(cls)))


def truth_at(
    truth: Trajectory, t: np.ndarray, margin_s: float = TRUTH_MARGIN_S, max_span_s: float = TRUTH_MAX_SPAN_S
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The walker's position (N, 2) and floor (N,) at times ``t`` (N,) from sparse surveyed points,
    and which of them are known (N,) bool (module docstring: interpolated inside a span of one floor
    no longer than ``max_span_s``, else a surveyed point's own within ``margin_s``)."""
    t = np.asarray(t, np.float64)
    tt, pos = truth.t, truth.pos[:, :2]
    floor = truth.floor if truth.floor is not None else np.zeros(len(truth))
    out_pos = np.full((t.size, 2), np.nan)
    out_floor = np.full(t.size, np.nan)
    if len(truth) >= 2:
        i = np.clip(np.searchsorted(tt, t, side="right") - 1, 0, len(tt) - 2)
        span = (t >= tt[i]) & (t <= tt[i + 1]) & (floor[i] == floor[i + 1]) & (tt[i + 1] - tt[i] <= max_span_s)
        a = np.clip((t - tt[i]) / (tt[i + 1] - tt[i]), 0.0, 1.0)[:, None]
        out_pos[span] = ((1 - a) * pos[i] + a * pos[i + 1])[span]
        out_floor[span] = floor[i][span]
    else:
        span = np.zeros(t.size, bool)
    k = nearest(tt, t)
    held = ~span & (np.abs(tt[k] - t) <= margin_s)
    out_pos[held] = pos[k[held]]
    out_floor[held] = floor[k[held]]
    return out_pos, out_floor, span | held


def range_samples(rec: Recording, margin_s: float = TRUTH_MARGIN_S, max_span_s: float = TRUTH_MAX_SPAN_S):
    """A recording's readings of surveyed beacons paired with its truth (:func:`truth_at`); None
    without readings, truth or ``meta["beacons"]``."""
    positions = rec.meta.get("beacons")
    if rec.beacons is None or rec.truth is None or not positions:
        return None
    b = rec.beacons
    known = np.isin(b.beacon, list(positions))
    pos, floor, ok = truth_at(rec.truth, b.t, margin_s, max_span_s)
    keep = known & ok
    where = np.array([positions[name] for name in b.beacon[keep]], np.float64).reshape(-1, 3)
    n = int(keep.sum())
    return RangeSamples(
        rssi_dbm=b.rssi_dbm[keep],
        horizontal_m=np.linalg.norm(pos[keep] - where[:, :2], axis=1),
        floors=np.abs(floor[keep] - where[:, 2]),
        beacon=b.beacon[keep],
        device=np.full(n, str(rec.meta.get("device", "")), dtype=object),
        recording=np.full(n, rec.name, dtype=object),
    )


def fit_path_loss(
    recordings: Iterable[Recording] | RangeSamples,
    floor_height_m: float = FLOOR_HEIGHT_M,
    d_min_m: float = D_MIN_M,
    noise: str = "auto",
) -> PathLoss:
    """Least-squares fit of p0, n, the floor loss and each named phone's offset on training walks
    with truth (or on :class:`RangeSamples`); then the noise: Gaussian σ of the residuals, or a
    Student-t fitted to them (``noise`` "gauss", "t", or "auto": t where the AIC gains more than
    :data:`T_NOISE_MIN_AIC_GAIN`). ``fit`` records the counts and the residual spread."""
    if isinstance(recordings, RangeSamples):
        s = recordings
    else:
        parts = [p for p in (range_samples(r) for r in recordings) if p is not None and len(p)]
        if not parts:
            raise ValidationError("fit_path_loss: no beacon readings with truth and beacon positions")
        s = RangeSamples.concat(parts)
    if noise not in ("auto", "gauss", "t"):
        raise ValidationError(f"fit_path_loss: noise {noise!r} is not auto, gauss or t")
    d = np.maximum(np.hypot(s.horizontal_m, s.floors * floor_height_m), d_min_m)
    devices = sorted(set(s.device))
    named = [dev for dev in devices if dev]
    # Columns: p0, n, floor loss, one indicator per phone but the first (the first phone's gain is
    # in p0; re-centred below so that p0 is the average named phone).
    cols = [np.ones(len(s)), -10.0 * np.log10(d), -s.floors.astype(np.float64)]
    cols += [(s.device == dev).astype(np.float64) for dev in devices[1:]]
    x = np.column_stack(cols)
    same_floor = not np.any(s.floors)  # every beacon heard on the walker's floor: no floor loss to fit
    if same_floor:
        x[:, 2] = 0.0
    if np.linalg.matrix_rank(x) < x.shape[1] - same_floor:
        raise ValidationError("fit_path_loss: the readings do not separate p0, n and the floor loss")
    coef, *_ = np.linalg.lstsq(x, s.rssi_dbm, rcond=None)  # a zero column gets a zero coefficient
    residual = s.rssi_dbm - x @ coef
    gains = {dev: (0.0 if k == 0 else float(coef[2 + k])) for k, dev in enumerate(devices)}
    centre = float(np.mean([gains[dev] for dev in named])) if named else gains[devices[0]]
    p0 = float(coef[0]) + centre
    offsets = {dev: round(gains[dev] - centre, 3) for dev in named}
    sigma = float(np.sqrt(np.sum(residual**2) / (len(s) - x.shape[1])))
    t_nu, _, t_scale = stats.t.fit(residual, floc=0.0)
    aic_gauss = -2 * np.sum(stats.norm.logpdf(residual, 0.0, sigma)) + 2
    aic_t = -2 * np.sum(stats.t.logpdf(residual, t_nu, 0.0, t_scale)) + 4
    use_t = noise == "t" or (noise == "auto" and aic_gauss - aic_t > T_NOISE_MIN_AIC_GAIN)
    fit = {
        "readings": len(s),
        "recordings": len(set(s.recording)),
        "readings_by_device": {dev or "unknown": int(np.sum(s.device == dev)) for dev in devices},
        "residual_sd_db": round(sigma, 3),
        "residual_mad_sigma_db": round(float(1.4826 * np.median(np.abs(residual - np.median(residual)))), 3),
        "residual_p5_p95_db": [round(float(v), 2) for v in np.percentile(residual, [5, 95])],
        # ν beyond STUDENT_T_NU_GAUSS is Gaussian for any purpose (the fit can run off to 1e13)
        "student_t": {"nu": round(min(float(t_nu), STUDENT_T_NU_GAUSS), 3), "scale_db": round(float(t_scale), 3)},
        "aic_gauss_minus_t": round(float(aic_gauss - aic_t), 1),
        "noise": "student-t" if use_t else "gaussian",
    }
    return PathLoss(
        p0_dbm=round(p0, 3),
        n=round(float(coef[1]), 4),
        sigma_db=round(float(t_scale) if use_t else sigma, 3),
        nu=round(float(t_nu), 3) if use_t else None,
        d_min_m=d_min_m,
        floor_height_m=floor_height_m,
        floor_loss_db=round(float(coef[2]), 3),
        offset_db=offsets,
        fit=fit,
    )
