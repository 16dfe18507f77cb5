"""The floor from the barometer, and the start floor without truth (issue 36).

Pressure rises by ~0.12 hPa per metre down (hydrostatic: ρ g, :func:`hpa_per_m`), so a floor
change moves the barometer by a few tenths of a hPa within a stair or lift ride; the weather moves
it by ~1 hPa over hours, and doors or ventilation by a few hundredths for seconds.
:func:`floor_track` follows the floor from a known start:

1. the readings are binned onto a :data:`GRID_S` grid (median per bin) and smoothed by a running
   median over ``smooth_s`` (spikes from doors and the phone's own noise go);
2. a reference pressure holds the current floor's level; while the smoothed pressure stays within
   ``drift_band`` of a step of it, the reference follows it with time constant ``drift_tau_s``
   (the weather), and it freezes during a larger excursion;
3. the floor whose level (relative to the current floor's) is nearest to the excursion becomes a
   candidate; a candidate held for ``hold_s`` is the new floor, from the moment it first appeared,
   and the reference moves by the two floors' level difference (not to the reading: a switch in the
   middle of a stair does not shift the next floor's level).

A floor's level comes from :class:`FloorLevels`: per-floor pressures measured on training walks
(:func:`fit_floor_levels`; a venue's floors are not equally high: at IPIN 2023, 0 → -1 is
0.37 hPa and -1 → -2 0.30 hPa), or one step per floor. With measured levels only those floors
exist.

The start floor without truth (:func:`start_floor`), in turn:

1. the floors the barometer's relative track can start from (a walk that goes two floors down from
   its start in a building of three starts at the top);
2. sharp fixes (median reported accuracy at most :data:`GROUND_FIX_ACCURACY_M` over the fixes
   while the walker is on the start floor) mean the walker is not underground: floors below 0
   are out;
3. among those left, the one under which the beacons heard are most likely
   (:func:`beacon_floor_loglik`: the path-loss model with the walker's horizontal distance unknown,
   uniform over a disc);
4. else the first fix's floor where fixes carry one, else 0 (or the candidate nearest 0).

Measured on IPIN 2023 (wearnav.bench.ipin_radio, leave one trial out): without step 2 the beacons
pick the wrong floor on 14 of the 20 one-floor walks on floor 0 (its two beacons are far from where
trials 1–4 go, and floor -1, with no beacon, sits "between" both floors' beacons) and the right
one on all 20 on floor -2; the 4 walks that change floor are decided by the barometer (step 1).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any

import numpy as np
from scipy import ndimage

from wearnav.errors import ValidationError
from wearnav.fuse.beacons import PathLoss
from wearnav.recording import BeaconReadings, Fixes, Pressure, Recording

GRID_S = 0.5  # pressure grid spacing, s
R_DRY_AIR = 287.05  # J/(kg K)
G = 9.80665  # m/s²
# One floor's step where no level was measured: 3 m of air at ~1000 hPa, 15 °C.
DEFAULT_STEP_HPA = 0.35
POSI_WINDOW_S = 1.0  # a surveyed point's pressure: the median of the readings within ± this
# Beacon likelihood of a floor: the walker is anywhere within this horizontal distance of a beacon
# heard (the venue is ~100 m across; the loudest readings come from within 30 m).
BEACON_HORIZONTAL_MAX_M = 50.0
# Fixes this sharp are not underground. IPIN 2023 training walks, median reported accuracy of the
# fixes on the start floor: 4–6 m on the 20 one-floor walks on floor 0, 8–36 m on the 20 on floor
# -2 (the threshold sits in that gap, chosen on these walks: wearnav.bench.ipin_radio).
GROUND_FIX_ACCURACY_M = 7.0
MIN_GROUND_FIXES = 10  # fewer fixes on the start floor say nothing


def hpa_per_m(p_hpa: float = 1000.0, temp_c: float = 15.0) -> float:
    """Hydrostatic pressure gradient ρ g (hPa per metre of height) at pressure ``p_hpa``, dry air."""
    rho = p_hpa * 100.0 / (R_DRY_AIR * (temp_c + 273.15))
    return rho * G / 100.0


@dataclasses.dataclass(frozen=True)
class FloorTrackConfig:
    """The constants of :func:`floor_track` (module docstring)."""

    smooth_s: float = 5.0  # running median: longer than a door's pressure spike
    hold_s: float = 6.0  # a new floor must hold this long (a landing on a stair takes ~2 s)
    drift_tau_s: float = 120.0  # the reference follows slow drift with this time constant
    drift_band: float = 0.3  # ... while within this share of a floor step of it


@dataclasses.dataclass(frozen=True)
class FloorLevels:
    """Pressure of each floor minus floor 0's, hPa (lower floors are higher); ``step_hpa`` per floor
    for floors without a measured level. ``levels_hpa`` empty: any floor, one step each."""

    levels_hpa: dict[int, float] = dataclasses.field(default_factory=dict)
    step_hpa: float = DEFAULT_STEP_HPA
    fit: dict[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.step_hpa > 0:
            raise ValidationError(f"floor levels: step_hpa {self.step_hpa} must be > 0")

    @property
    def floors(self) -> list[int] | None:
        """The floors that exist: every one from the lowest measured to the highest (None: any)."""
        return list(range(min(self.levels_hpa), max(self.levels_hpa) + 1)) if self.levels_hpa else None

    def level(self, floor: int) -> float:
        """The level of ``floor`` (hPa relative to floor 0): measured; else interpolated between the
        measured floors below and above; else one step per floor from the nearest measured floor."""
        if floor in self.levels_hpa:
            return self.levels_hpa[floor]
        if not self.levels_hpa:
            return -self.step_hpa * floor
        below = [f for f in self.levels_hpa if f < floor]
        above = [f for f in self.levels_hpa if f > floor]
        if below and above:
            lo, hi = max(below), min(above)
            a = (floor - lo) / (hi - lo)
            return (1 - a) * self.levels_hpa[lo] + a * self.levels_hpa[hi]
        nearest = max(below) if below else min(above)
        return self.levels_hpa[nearest] - self.step_hpa * (floor - nearest)

    def height_m(self, floor: int, p_hpa: float = 1000.0) -> float:
        """Height of ``floor`` above floor 0 (m), from its level."""
        return -self.level(floor) / hpa_per_m(p_hpa)

    def to_dict(self) -> dict[str, Any]:
        return {
            "levels_hpa": {str(k): v for k, v in self.levels_hpa.items()},
            "step_hpa": self.step_hpa,
            "fit": self.fit,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> FloorLevels:
        return cls({int(k): float(v) for k, v in d["levels_hpa"].items()}, float(d["step_hpa"]), dict(d.get("fit", {})))


def pressure_at(pressure: Pressure, t: np.ndarray, window_s: float = POSI_WINDOW_S) -> np.ndarray:
    """Median pressure (hPa) of the readings within ± ``window_s`` of each time (NaN where none)."""
    t = np.asarray(t, np.float64)
    lo = np.searchsorted(pressure.t, t - window_s)
    hi = np.searchsorted(pressure.t, t + window_s, side="right")
    return np.array([np.median(pressure.hpa[a:b]) if b > a else np.nan for a, b in zip(lo, hi)])


def fit_floor_levels(recordings: Iterable[Recording]) -> FloorLevels:
    """Each floor's level from training walks with truth floors: the pressure at each surveyed point
    (:func:`pressure_at`) is ``walk offset + level[floor]`` (least squares, level[0] = 0, walks on
    one floor only fix their own offset); the step is the least-squares slope of level on floor.
    Weather drift within a walk is not modelled (IPIN's walks last 2.5–5.5 min: the residual SD is
    0.022 hPa)."""
    rows: list[tuple[int, int, float]] = []
    names: list[str] = []
    for rec in recordings:
        if rec.pressure is None or rec.truth is None or rec.truth.floor is None:
            continue
        p = pressure_at(rec.pressure, rec.truth.t)
        ok = np.isfinite(p) & np.isfinite(rec.truth.floor)
        if len(set(rec.truth.floor[ok])) < 2:
            continue
        names.append(rec.name)
        rows += [(len(names) - 1, int(f), float(v)) for f, v in zip(rec.truth.floor[ok], p[ok])]
    floors = sorted({f for _, f, _ in rows})
    if 0 not in floors or len(floors) < 2:
        raise ValidationError(f"fit_floor_levels: no walk over floor 0 and another with pressure (floors {floors})")
    others = [f for f in floors if f != 0]
    x = np.zeros((len(rows), len(names) + len(others)))
    y = np.array([v for *_, v in rows])
    for i, (w, f, _) in enumerate(rows):
        x[i, w] = 1.0
        if f != 0:
            x[i, len(names) + others.index(f)] = 1.0
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    residual = y - x @ coef
    levels = {0: 0.0} | {f: round(float(c), 4) for f, c in zip(others, coef[len(names) :])}
    fl = np.array(sorted(levels), np.float64)
    step = -float(np.polyfit(fl, [levels[int(f)] for f in fl], 1)[0])
    fit = {
        "walks": names,
        "points": len(rows),
        "residual_sd_hpa": round(float(np.std(residual)), 4),
        "p_median_hpa": round(float(np.median(y)), 2),
    }
    return FloorLevels(levels, round(step, 4), fit)


def _grid(pressure: Pressure, smooth_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The readings on a GRID_S grid (median per bin, gaps interpolated), smoothed by a running
    median over ``smooth_s``."""
    t0 = pressure.t[0]
    k = np.floor((pressure.t - t0) / GRID_S).astype(int)
    t_grid = t0 + GRID_S * (np.arange(k[-1] + 1) + 0.5)
    order = np.argsort(k, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(k[order]) > 0])
    bins = k[order][starts]
    med = np.array([np.median(v) for v in np.split(pressure.hpa[order], starts[1:])])
    p = np.interp(t_grid, t_grid[bins], med)
    size = max(1, int(round(smooth_s / GRID_S)) | 1)
    return t_grid, ndimage.median_filter(p, size=size, mode="nearest")


def floor_track(
    pressure: Pressure,
    start_floor: int,
    t_out: np.ndarray,
    levels: FloorLevels = FloorLevels(),
    config: FloorTrackConfig = FloorTrackConfig(),
) -> np.ndarray:
    """The floor (int, (M,)) at each time of ``t_out`` (M,), from the barometer and a known start
    floor (module docstring). Before the first reading: ``start_floor``; after the last: the last."""
    allowed = levels.floors
    if allowed is not None and start_floor not in allowed:
        raise ValidationError(f"floor_track: start floor {start_floor} is not one of the floors {allowed}")
    t_grid, p = _grid(pressure, config.smooth_s)
    floors = np.empty(t_grid.size, np.int64)
    candidates = np.array(allowed if allowed is not None else [], np.int64)
    floor, ref = int(start_floor), float(p[0])
    pending, pending_since = floor, 0
    alpha = 1.0 - np.exp(-GRID_S / config.drift_tau_s)
    band = config.drift_band * levels.step_hpa
    for i, v in enumerate(p):
        excursion = v - ref
        if allowed is None:
            best = floor - int(round(excursion / levels.step_hpa))
        else:
            rel = np.array([levels.level(int(c)) - levels.level(floor) for c in candidates])
            best = int(candidates[np.argmin(np.abs(excursion - rel))])
        if best != pending:
            pending, pending_since = best, i
        if pending != floor and (i - pending_since) * GRID_S >= config.hold_s:
            ref += levels.level(pending) - levels.level(floor)
            floors[pending_since:i] = pending
            floor = pending
            excursion = v - ref
        if abs(excursion) <= band:
            ref += alpha * excursion
        floors[i] = floor
    k = np.clip(np.searchsorted(t_grid, np.asarray(t_out, np.float64), side="right") - 1, 0, t_grid.size - 1)
    out = floors[k]
    out[np.asarray(t_out) < t_grid[0]] = start_floor
    return out


def beacon_floor_loglik(
    beacons: BeaconReadings,
    positions: dict[str, list[float]],
    path_loss: PathLoss,
    floor_at: np.ndarray,
    horizontal_max_m: float = BEACON_HORIZONTAL_MAX_M,
) -> float:
    """Log-likelihood of the readings of surveyed beacons if the walker was on floor ``floor_at``
    (one per reading, (N,)) at each: the path-loss model averaged over a horizontal distance uniform
    over a disc of radius ``horizontal_max_m`` about the beacon."""
    known = np.isin(beacons.beacon, list(positions))
    if not np.any(known):
        return 0.0
    beacon_floor = np.array([positions[b][2] for b in beacons.beacon[known]], np.float64)
    floors = np.abs(np.asarray(floor_at, np.float64)[known] - beacon_floor)
    # Disc quadrature: radii at the midpoints of equal-area rings.
    n_ring = 64
    r = horizontal_max_m * np.sqrt((np.arange(n_ring) + 0.5) / n_ring)
    ll = path_loss.loglik(
        beacons.rssi_dbm[known][:, None], path_loss.distance_m(r[None, :], floors[:, None]), floors[:, None]
    )
    top = ll.max(axis=1, keepdims=True)
    return float(np.sum(top[:, 0] + np.log(np.mean(np.exp(ll - top), axis=1))))


def start_floor(
    pressure: Pressure | None,
    levels: FloorLevels,
    beacons: BeaconReadings | None = None,
    positions: dict[str, list[float]] | None = None,
    path_loss: PathLoss | None = None,
    fixes: Fixes | None = None,
    config: FloorTrackConfig = FloorTrackConfig(),
) -> tuple[int, dict[str, Any]]:
    """The start floor without truth, and how it was chosen (module docstring): ``{"by": "barometer"
    | "fixes" | "beacons" | "fix floor" | "default", "candidates": [...], "loglik": {floor: value}}``."""
    allowed = levels.floors or [0]
    candidates = list(allowed)
    relative = None
    if pressure is not None and len(pressure) >= 2:
        # The barometer's track relative to the start (any floor, one step each): which starts keep it
        # on floors that exist.
        step_only = FloorLevels(step_hpa=levels.step_hpa)
        relative = floor_track(pressure, 0, pressure.t, step_only, config)
        lo, hi = int(relative.min()), int(relative.max())
        candidates = [s for s in allowed if s + lo >= min(allowed) and s + hi <= max(allowed)] or list(allowed)
    info: dict[str, Any] = {"candidates": candidates}
    if len(candidates) == 1:
        return candidates[0], info | {"by": "barometer"}
    if fixes is not None and len(fixes):
        on_start = (
            np.ones(len(fixes), bool)
            if relative is None or pressure is None
            else relative[np.clip(np.searchsorted(pressure.t, fixes.t) - 1, 0, len(relative) - 1)] == 0
        )
        acc = fixes.accuracy[on_start & np.isfinite(fixes.accuracy)]
        info["start_floor_fix_accuracy_m"] = round(float(np.median(acc)), 2) if acc.size else None
        if acc.size >= MIN_GROUND_FIXES and np.median(acc) <= GROUND_FIX_ACCURACY_M:
            above = [s for s in candidates if s >= 0]
            if len(above) == 1:
                return above[0], info | {"by": "fixes"}
            candidates = above or candidates
    if beacons is not None and positions and path_loss is not None and np.isin(beacons.beacon, list(positions)).any():
        rel = (
            np.zeros(len(beacons))
            if relative is None or pressure is None
            else relative[np.clip(np.searchsorted(pressure.t, beacons.t) - 1, 0, len(relative) - 1)]
        )
        scores = {s: beacon_floor_loglik(beacons, positions, path_loss, s + rel) for s in candidates}
        best = max(scores, key=lambda s: scores[s])
        return best, info | {"by": "beacons", "loglik": {s: round(v, 2) for s, v in scores.items()}}
    if fixes is not None and fixes.floor is not None and np.isfinite(fixes.floor).any():
        first = int(fixes.floor[np.isfinite(fixes.floor)][0])
        if first in candidates:
            return first, info | {"by": "fix floor"}
    return min(candidates, key=abs), info | {"by": "default"}


def floor_accuracy(rec: Recording, floors_at_truth: np.ndarray) -> float:
    """Share of the surveyed points whose floor is ``floors_at_truth`` (one per point)."""
    if rec.truth is None or rec.truth.floor is None:
        raise ValidationError(f"{rec.name}: no truth floors to score")
    return float(np.mean(np.asarray(floors_at_truth) == rec.truth.floor))
