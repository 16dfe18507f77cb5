"""Every absolute observation of a recording in one map-aware path (issue 36 §2): the particle filter
of :mod:`.particles` fed with the recording's floor plans, its location fixes, its beacon readings
(a path-loss model, :mod:`.beacons`) and its floor over time (the barometer, :mod:`.floors`).

The site's radio and pressure models are fitted on the site's training walks with truth
(:func:`fit_site_models`; never on the walk being placed) and kept as plain data
(:class:`SiteModels`, JSON). :func:`place` takes what the recording has: without beacons or a
barometer those parts are left out; without a plan the walls are; with neither fixes nor a start
there is nothing to place the path by (an error).

Decision: docs/decisions/0027-particle-filter-map-aware.md.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from wearnav.errors import ValidationError
from wearnav.fixcheck import FixCheck, check_fixes
from wearnav.fuse.beacons import PathLoss, fit_path_loss
from wearnav.fuse.calibrate import known_heading_deg
from wearnav.fuse.config import FuseConfig
from wearnav.fuse.floors import FloorLevels, fit_floor_levels, floor_track, start_floor
from wearnav.fuse.particles import Beacons, MapConfig, MapResult, map_filter, start_heading_offset
from wearnav.fuse.radiofloor import floor_at
from wearnav.plans import Walkable
from wearnav.recording import FloorPlan, Recording


@dataclasses.dataclass
class SiteModels:
    """A site's fitted models: beacon path loss (None: no beacons) and floor pressure levels (None:
    no barometer), each as its module's dataclass."""

    path_loss: PathLoss | None = None
    levels: FloorLevels | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "path_loss": None if self.path_loss is None else self.path_loss.to_dict(),
            "levels": None if self.levels is None else self.levels.to_dict(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SiteModels:
        return cls(
            None if d.get("path_loss") is None else PathLoss.from_dict(d["path_loss"]),
            None if d.get("levels") is None else FloorLevels.from_dict(d["levels"]),
        )


def fit_site_models(recordings: Iterable[Recording]) -> SiteModels:
    """Path loss and floor levels from training walks with truth (each only where they have beacons
    with positions / a barometer and surveyed floors)."""
    recs = [r for r in recordings if r.truth is not None]
    radio = [r for r in recs if r.beacons is not None and len(r.beacons) and r.meta.get("beacons")]
    baro = [r for r in recs if r.pressure is not None and len(r.pressure) and r.truth.floor is not None]  # type: ignore[union-attr]
    path_loss = fit_path_loss(radio) if radio else None
    levels = fit_floor_levels(baro) if baro else None
    return SiteModels(path_loss, levels)


def _beacons(rec: Recording, model: PathLoss, sigma_scale: float = 1.0) -> Beacons | None:
    b, where = rec.beacons, rec.meta.get("beacons") or {}
    if b is None or not len(b) or not where:
        return None
    known = np.array([str(name) in where for name in b.beacon])
    if not known.any():
        return None
    pos = np.array([where[str(name)] for name in b.beacon[known]], np.float64)
    model = dataclasses.replace(
        model.for_device(str(rec.meta.get("device", ""))), sigma_db=model.sigma_db * sigma_scale
    )
    return Beacons(b.t[known], pos, b.rssi_dbm[known], model)


def floors_over_time(rec: Recording, site: SiteModels) -> tuple[Callable[[np.ndarray], np.ndarray] | None, dict]:
    """The recording's floor over time from its barometer and the site's floor levels, the start floor
    chosen without truth (:func:`wearnav.fuse.floors.start_floor`); None where there is no barometer
    or no levels."""
    if rec.pressure is None or len(rec.pressure) < 2 or site.levels is None:
        return None, {"floors": "no barometer or no floor levels for the site"}
    f0, how = start_floor(rec.pressure, site.levels, rec.beacons, rec.meta.get("beacons"), site.path_loss, rec.fixes)
    pressure, levels = rec.pressure, site.levels

    def floor_at(times: np.ndarray) -> np.ndarray:
        return floor_track(pressure, f0, np.asarray(times, np.float64), levels).astype(np.float64)

    return floor_at, {"start_floor": f0, "start_floor_by": how.get("by")}


def _fix_floors(t_fix: np.ndarray, floor_fix: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """The floor over time from the fixes that carry one (:func:`wearnav.fuse.radiofloor.floor_at`)."""
    return lambda times: floor_at(t_fix, floor_fix, np.asarray(times, np.float64))


def place(
    rec: Recording,
    t: np.ndarray,
    xy: np.ndarray,
    site: SiteModels | None = None,
    floor_plans: list[FloorPlan] | None = None,
    start: tuple[float, float, float] | None = None,
    cfg: MapConfig = MapConfig(),
    progress: Callable[[int, int], None] | None = None,
) -> tuple[MapResult, FixCheck | None]:
    """The odometry path ``xy`` (from (0, 0) in the recording's world frame) placed by everything the
    recording has (module docstring). ``start``: x, y (m) and the heading of travel (deg,
    counter-clockwise from +x) where known; else the first kept fix, the heading offset from the
    recording's frame where its importer documents it (:func:`wearnav.fuse.known_heading_deg`) or
    unknown. Returns the result (its ``info`` says what was used) and the fixes' check."""
    site = site or SiteModels()
    plans = rec.plans if floor_plans is None else floor_plans
    grids: dict[int | None, Walkable] = {p.floor: Walkable.of(p) for p in plans}
    fx, check, fixes = rec.fixes, None, None
    if fx is not None and len(fx):
        check = check_fixes(float(t[0]), float(t[-1]), fx.t, fx.pos[:, :2], fx.accuracy, FuseConfig().wide_m)
        k = check.kept
        fixes = (fx.t[k] - cfg.fix_lag_s, fx.pos[k, :2], fx.accuracy[k])  # when the walker was there
    if start is None and (fixes is None or not len(fixes[0])):
        raise ValidationError(
            "nothing to place the path by: give --start X,Y,HEADING_DEG (the recording has no usable location fix)"
        )
    if start is not None:
        start_xy: np.ndarray | None = np.array(start[:2], np.float64)
        offset: float | None = start_heading_offset(t, xy, np.radians(start[2]))
    else:
        start_xy, known = None, known_heading_deg(rec.meta, "phone")
        offset = None if known is None else float(np.radians(known))
    floor_at, floor_info = floors_over_time(rec, site)
    if floor_at is None and len(grids) > 1 and fx is not None and fx.floor is not None and np.isfinite(fx.floor).any():
        floor_at, floor_info = (
            _fix_floors(fx.t, fx.floor),
            {"floors": "from the fixes' floors (a radio map's, issue 60)"},
        )
    if floor_at is None and len(grids) > 1:  # several plans and no barometer: the recording's own floor
        f = rec.meta.get("floor_index")
        floor_at = None if f is None else (lambda times: np.full(np.shape(times), float(f)))
    beacons = _beacons(rec, site.path_loss, cfg.beacon_sigma_scale) if site.path_loss is not None else None
    res = map_filter(t, xy, grids, start_xy, offset, floor_at, fixes, beacons, cfg, progress)
    res.info.update(
        plans=[p.name for p in plans],
        start="given" if start is not None else "the first kept fix",
        heading_offset_prior="given by the start"
        if start is not None
        else ("known frame" if offset is not None else "unknown"),
        **floor_info,
    )
    if check is not None:
        res.info.update(check.info())
    return res, check
