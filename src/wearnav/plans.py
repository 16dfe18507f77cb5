"""Floor plans: where a walker can be (issue 36).

A :class:`~wearnav.recording.FloorPlan` stores a floor's walkable space as polygons in the
recording's own metric frame. This module turns it into geometry the map-aware path uses:

* :class:`Walkable`, the plan rasterised once into an occupancy grid (``cell_m`` cells, a cell is
  walkable when its centre is inside the walkable space), so that testing a thousand particle
  positions is one array lookup instead of a thousand polygon tests; ``shapely`` builds the grid and
  answers exact questions (area, distance).
* :func:`read_geojson_plan`, a user's own plan: an RFC 7946 GeoJSON file (WGS-84 lon/lat) whose
  Polygon / MultiPolygon features are walkable space or obstacles (the ``kind`` property:
  ``"walkable"`` or ``"obstacle"``), placed in a recording's local frame with :mod:`wearnav.core.geo`
  as fixes are. Walkable space = the union of the walkable polygons minus the obstacles. A
  ``floor`` property (integer) splits the file into one plan per floor.
* :func:`plan_from_lonlat`, the same from polygons already parsed (the ILC2 importer uses it with
  its own lon/lat → plan-metre transform).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon, shape
from shapely.geometry.base import BaseGeometry
from shapely.ops import unary_union

from wearnav.core import geo
from wearnav.core.textio import read_json
from wearnav.errors import FormatError
from wearnav.recording import FloorPlan

# Occupancy grid cell (m): a corridor is ≥ 1.2 m wide (building codes' minimum for public
# corridors), so 0.25 m cells keep at least four cells across it; an ILC2 floor (240 × 176 m) is
# then 676 k cells, rasterised in ~0.3 s.
CELL_M = 0.25
PLAN_KINDS = ("walkable", "obstacle")


def plan_geometry(plan: FloorPlan) -> BaseGeometry:
    """The walkable space of ``plan`` as one shapely geometry (holes are obstacles)."""
    polys = [Polygon(poly[0], poly[1:]) for poly in plan.polygons]
    return shapely.make_valid(MultiPolygon(polys)) if len(polys) > 1 else shapely.make_valid(polys[0])


def plan_from_geometry(name: str, floor: int | None, geom: BaseGeometry) -> FloorPlan:
    """A FloorPlan from a shapely (Multi)Polygon in local metres (other parts are dropped)."""
    polys = [g for g in getattr(geom, "geoms", [geom]) if isinstance(g, Polygon) and not g.is_empty]
    polys += [p for g in getattr(geom, "geoms", []) if isinstance(g, MultiPolygon) for p in g.geoms]
    if not polys:
        raise FormatError(f"floor plan {name!r}: no walkable area left")
    rings = [[np.asarray(p.exterior.coords)[:-1]] + [np.asarray(r.coords)[:-1] for r in p.interiors] for p in polys]
    return FloorPlan(name=name, floor=floor, polygons=rings)


@dataclass
class Walkable:
    """A floor plan rasterised: ``grid[i, j]`` is True where cell (row i = y, column j = x) is walkable.

    Cell (i, j) covers x in [x0 + j·cell_m, x0 + (j+1)·cell_m) and y likewise from y0; positions
    outside the grid are not walkable.
    """

    name: str
    floor: int | None
    grid: np.ndarray
    x0: float
    y0: float
    cell_m: float
    area_m2: float

    @classmethod
    def of(cls, plan: FloorPlan, cell_m: float = CELL_M) -> Walkable:
        geom = plan_geometry(plan)
        x0, y0, x1, y1 = geom.bounds
        x0, y0 = x0 - cell_m, y0 - cell_m  # a border of non-walkable cells
        nx, ny = int(np.ceil((x1 - x0) / cell_m)) + 2, int(np.ceil((y1 - y0) / cell_m)) + 2
        xs = x0 + (np.arange(nx) + 0.5) * cell_m
        ys = y0 + (np.arange(ny) + 0.5) * cell_m
        gx, gy = np.meshgrid(xs, ys)
        shapely.prepare(geom)
        grid = shapely.contains_xy(geom, gx.ravel(), gy.ravel()).reshape(ny, nx)
        return cls(plan.name, plan.floor, grid, float(x0), float(y0), float(cell_m), float(geom.area))

    def inside(self, xy: np.ndarray) -> np.ndarray:
        """Whether each position (…, 2) in metres is in a walkable cell."""
        xy = np.asarray(xy)
        j = np.floor((xy[..., 0] - self.x0) / self.cell_m).astype(np.int64)
        i = np.floor((xy[..., 1] - self.y0) / self.cell_m).astype(np.int64)
        ok = (i >= 0) & (i < self.grid.shape[0]) & (j >= 0) & (j < self.grid.shape[1])
        out = np.zeros(xy.shape[:-1], dtype=bool)
        out[ok] = self.grid[i[ok], j[ok]]
        return out

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` positions drawn uniformly over the walkable cells (a cell's centre ± half a cell)."""
        i, j = np.nonzero(self.grid)
        k = rng.integers(0, i.size, n)
        u = rng.random((n, 2))
        return np.stack([self.x0 + (j[k] + u[:, 0]) * self.cell_m, self.y0 + (i[k] + u[:, 1]) * self.cell_m], axis=1)


def plan_from_lonlat(
    name: str,
    floor: int | None,
    walkable: list[BaseGeometry],
    obstacles: list[BaseGeometry],
    to_local: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> FloorPlan:
    """Walkable space (union of ``walkable`` minus ``obstacles``, lon/lat geometries) placed in local
    metres by ``to_local(lon, lat) -> (N, 2)``."""

    def place(g: BaseGeometry) -> BaseGeometry:
        return shapely.transform(g, lambda c: to_local(c[:, 0], c[:, 1]))

    space = unary_union([place(shapely.make_valid(g)) for g in walkable])
    if obstacles:
        space = space.difference(unary_union([place(shapely.make_valid(g)) for g in obstacles]))
    return plan_from_geometry(name, floor, space)


def read_geojson_plan(path: str | Path, origin_lat: float, origin_lon: float) -> list[FloorPlan]:
    """A user's plan file (see the module docstring) as one FloorPlan per floor, in the local ENU
    frame at (origin_lat, origin_lon) (:func:`wearnav.core.geo.latlon_to_local`)."""
    path = Path(path)
    doc = read_json(path)
    feats = doc.get("features") if isinstance(doc, dict) and doc.get("type") == "FeatureCollection" else None
    if not isinstance(feats, list):
        raise FormatError("not a GeoJSON FeatureCollection (RFC 7946)", path)
    floors: dict[int | None, dict[str, list]] = {}
    for k, f in enumerate(feats):
        geom = f.get("geometry") if isinstance(f, dict) else None
        if not isinstance(geom, dict) or geom.get("type") not in ("Polygon", "MultiPolygon"):
            continue  # points, lines: labels and routes on the plan, not space
        props: dict[str, Any] = f.get("properties") or {}
        kind = props.get("kind")
        if kind not in PLAN_KINDS:
            raise FormatError(
                f"feature {k}: property 'kind' is {kind!r}; a plan's polygons say 'walkable' or 'obstacle'", path
            )
        floor = props.get("floor")
        if floor is not None and not (isinstance(floor, int) and not isinstance(floor, bool)):
            raise FormatError(f"feature {k}: property 'floor' is {floor!r}, not an integer", path)
        try:
            g = shape(geom)
        except (ValueError, TypeError, AttributeError, shapely.errors.ShapelyError) as exc:
            raise FormatError(f"feature {k}: unreadable polygon ({exc})", path) from None
        lon, lat = np.asarray(g.bounds[0::2]), np.asarray(g.bounds[1::2])
        if np.any(np.abs(lat) > 90) or np.any(np.abs(lon) > 180):
            raise FormatError(f"feature {k}: coordinates are not lon/lat degrees (RFC 7946)", path)
        floors.setdefault(floor, {"walkable": [], "obstacle": []})[kind].append(g)
    if not any(parts["walkable"] for parts in floors.values()):
        raise FormatError("no polygon with 'kind': 'walkable'", path)
    plans = []
    for floor, parts in floors.items():
        if not parts["walkable"]:
            raise FormatError(f"floor {floor}: obstacles but no walkable polygon", path)
        label = f"{path.stem}" if floor is None else f"{path.stem}_floor{floor}"
        plans.append(
            plan_from_lonlat(
                label,
                floor,
                parts["walkable"],
                parts["obstacle"],
                lambda lon, lat: geo.latlon_to_local(lat, lon, origin_lat, origin_lon),
            )
        )
    return plans


def geojson_centre(path: str | Path) -> tuple[float, float]:
    """(lat, lon) of the centre of a GeoJSON file's bounding box: the origin of a user's plan when
    the recording has none (no fixes)."""
    doc = read_json(Path(path))
    try:
        geoms = [shape(f["geometry"]) for f in doc["features"] if f.get("geometry")]
        lon0, lat0, lon1, lat1 = unary_union(geoms).bounds
    except (KeyError, TypeError, ValueError, AttributeError, shapely.errors.ShapelyError) as exc:
        raise FormatError(f"not a readable GeoJSON plan ({exc.__class__.__name__}: {exc})", path) from None
    return (lat0 + lat1) / 2.0, (lon0 + lon1) / 2.0


def plan_for_floor(plans: list[FloorPlan], floor: int | None) -> FloorPlan | None:
    """The plan of ``floor`` (the only plan where there is one and the floor is unknown)."""
    for p in plans:
        if p.floor == floor:
            return p
    return plans[0] if len(plans) == 1 else None


def plans_to_geojson_text(plans: list[FloorPlan]) -> str:
    """The plans as one FeatureCollection in local metres (not RFC 7946: for pages and debugging)."""
    return json.dumps({"type": "FeatureCollection", "features": [p.to_feature() for p in plans]})
