"""The map-aware path of `wearnav track` (issue 36): the floor plans ``--map`` asks for, and the path
placed on them from ``--start`` or the first kept fix by the particle filter of
:func:`wearnav.fuse.placement.place` (walls of the plan, every kept fix weighed in), in place of
the smoother's anchoring. :mod:`wearnav.track` calls :func:`map_path` and writes what it returns.

Decision: docs/decisions/0027-particle-filter-map-aware.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from tqdm import tqdm

from wearnav import fuse, plans
from wearnav.fixcheck import UNUSED, check_fixes
from wearnav.fuse import placement
from wearnav.fuse.mapcheck import DOUBTFUL, MapVerdict, check_map_path, diagnostics
from wearnav.fuse.particles import START_DIR_M, MapConfig, start_heading_offset
from wearnav.recording import FloorPlan, Recording

MAP_CHOICES = ("auto", "none")  # or a GeoJSON plan file (wearnav.plans.read_geojson_plan)


def map_plans(rec: Recording, plan: str | Path) -> tuple[list[FloorPlan], str]:
    """The floor plans ``--map`` asks for and where they come from: ``auto`` the recording's own
    (``rec.plans``, from its importer; "no plan: why" where the importer could not read it,
    ``meta["no_plan"]``), ``none`` no plan, else a GeoJSON plan file placed in the
    recording's local frame (:func:`wearnav.plans.read_geojson_plan`; its lat/lon origin, or the
    plan's own centre where the recording has none)."""
    if str(plan) == "none":
        return [], "none"
    if str(plan) == "auto":
        if not rec.plans and rec.meta.get("no_plan"):  # the importer could not read it (e.g. ILC2's)
            return [], f"no plan: {rec.meta['no_plan']}"
        return list(rec.plans), "the recording's own" if rec.plans else "none in the recording"
    path = Path(plan)
    lat0, lon0 = rec.meta.get("origin_lat"), rec.meta.get("origin_lon")
    if lat0 is None or lon0 is None:
        lat0, lon0 = plans.geojson_centre(path)
        rec.meta["origin_lat"], rec.meta["origin_lon"] = lat0, lon0
        how = f"{path.name}, about its own centre ({lat0:.7f}, {lon0:.7f}): the recording has no lat/lon origin"
    else:
        how = f"{path.name}, in the recording's local frame"
    return plans.read_geojson_plan(path, float(lat0), float(lon0)), how


def place_on_map(
    rec: Recording,
    t: np.ndarray,
    xy: np.ndarray,
    floor_plans: list[FloorPlan],
    start: tuple[float, float, float] | None,
    cfg: MapConfig = MapConfig(),
    progress: bool = False,
) -> tuple[fuse.FuseResult, MapVerdict] | None:
    """The map-aware path (:func:`wearnav.fuse.placement.place`: the particle filter with the plan's
    walls and the recording's fixes) of the odometry path ``xy`` on ``floor_plans``, as a FuseResult
    (method "map", its ``info["trust"]`` the verdict and ``info["diagnostics"]``: :mod:`wearnav.fuse.mapcheck`),
    with :func:`wearnav.fuse.mapcheck.check_map_path`'s verdict; None where there is no plan. The start
    is ``start`` (x, y in the plan's frame, the heading of travel in degrees counter-clockwise from +x)
    or the first kept fix."""
    if not floor_plans:
        return None
    with tqdm(total=100, desc="map-aware path", unit="%", disable=not progress, leave=False) as bar:

        def tick(k: int, n: int) -> None:
            bar.update(int(100 * k / n) - bar.n)

        res, check = placement.place(rec, t, xy, None, floor_plans, start, cfg, tick)
    verdict = check_map_path(res, cfg)
    info = res.info | {
        "trust": {"status": verdict.status, "reason": verdict.reason, **verdict.figures},
        "diagnostics": diagnostics(res),
    }
    return fuse.FuseResult(res.xy, res.sigma_m, "map", info, [], check), verdict


def map_path(
    rec: Recording,
    t: np.ndarray,
    xy: np.ndarray,
    plan: str | Path,
    start: tuple[float, float, float] | None,
    progress: bool = False,
    fix_lag_s: float = 0.0,
) -> tuple[fuse.FuseResult | None, dict, list[str]]:
    """The map-aware path of the odometry path ``xy`` (times ``t``) for ``--map plan`` and ``--start``:
    the placed path (:func:`place_on_map`; None where no plan is used), ``track.json``'s ``map`` (the
    plans requested and found, and whether they were ``used``) and the warnings to add. A plan is not
    used where the recording has no fixes and no ``start`` is given; where it is used it becomes
    ``rec.plans`` (what the page draws under the path). ``fix_lag_s``: how far the fixes lag the
    walker (``track --fix-lag``, as the smoother takes it)."""
    floor_plans, plan_from = map_plans(rec, plan)
    info: dict = {"requested": str(plan), "plans": [p.name for p in floor_plans], "from": plan_from}
    placed, warns = None, []
    if plan_from.startswith("no plan: "):
        warns.append(f"{plan_from}; the path is placed without a floor plan")
    if floor_plans and start is None and (rec.fixes is None or not len(rec.fixes)):
        warns.append(
            "the recording has a floor plan but no location fixes: give --start X,Y,HEADING_DEG to place the path on it"
        )
        info["used"] = False
    elif floor_plans:
        found = place_on_map(rec, t, xy, floor_plans, start, MapConfig(fix_lag_s=fix_lag_s), progress)
        assert found is not None
        placed, verdict = found
        info["trust"] = placed.info["trust"]
        rec.plans = floor_plans  # what the page draws under the path (a plan that did not fit too: see why)
        if verdict.use_map:
            info["used"] = True
            if verdict.status == DOUBTFUL:
                warns.append(verdict.reason)
        else:  # the walk does not fit the plan (issue 57): the path as if there were none, said
            info["used"] = False
            warns.append(verdict.reason)
            placed = place_from_start(rec, t, xy, start) if start is not None else None
    else:
        info["used"] = False
        if start is not None:  # no plan: the start alone places the path (issue 56 §4)
            placed = place_from_start(rec, t, xy, start)
    return placed, info, warns


def place_from_start(
    rec: Recording, t: np.ndarray, xy: np.ndarray, start: tuple[float, float, float]
) -> fuse.FuseResult:
    """The odometry path ``xy`` (times ``t``) placed by a start pose alone, where no floor plan is used
    (issue 56 §4): turned so that its first :data:`wearnav.fuse.particles.START_DIR_M` metres run along
    the heading of travel ``start[2]`` (degrees counter-clockwise from +x, as the map-aware path reads
    it: :func:`wearnav.fuse.particles.start_heading_offset`) and moved so that it starts at
    ``start[:2]``; from there it drifts freely, as the first-fixes anchoring's path does after its
    first minute. The user's start is honoured over the recording's fixes: they are checked
    (:func:`wearnav.fixcheck.check_fixes`, for ``fixes.csv``) and marked unused (without ``--start``
    the smoother places the path on them; with a plan the particle filter weighs them in)."""
    yaw = start_heading_offset(t, xy, float(np.radians(start[2])))
    c, s = np.cos(yaw), np.sin(yaw)
    placed = (xy - xy[0]) @ np.array([[c, s], [-s, c]]) + np.asarray(start[:2], np.float64)
    info: dict = {
        "start": [float(v) for v in start],
        "heading_offset_deg": float(np.degrees(yaw)),
        "heading_from_m": START_DIR_M,
    }
    fx, check = rec.fixes, None
    if fx is not None and len(fx):
        check = check_fixes(float(t[0]), float(t[-1]), fx.t, fx.pos[:, :2], fx.accuracy, fuse.FuseConfig().wide_m)
        check.mark(check.kept, UNUSED, "--start places the path (no floor plan to weigh the fixes in)")
        info.update(check.info(), fixes="not used: --start places the path; without it the fixes do")
    return fuse.FuseResult(placed, np.full(len(t), np.nan), "start", info, [], check)
