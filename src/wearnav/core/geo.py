"""Geographic positions ↔ local metres: the one converter every importer, ``track`` and the maps use.

The local frame of a recording is the WGS-84 east-north-up (ENU) frame at its origin
(``meta["origin_lat"]``, ``meta["origin_lon"]``, degrees, on the ellipsoid: height 0): a point's
``east``, ``north`` (m) are the first two ENU coordinates of that point taken at height 0 (the
point on the ellipsoid below it), computed exactly by ``pymap3d`` (``geodetic2enu``). Heights are
not used: fixes and truth are 2-D. The inverse (:func:`local_to_latlon`) finds the point on the
ellipsoid whose ENU east/north are the given ones, so that a round trip returns the same metres.

This replaces an equirectangular projection with the equatorial radius on both axes, whose scale was
wrong by up to 0.7 % of the distance from the origin, differently per axis and latitude (at the IPIN
2023 venue, 49.46° N: +0.09 % north, −0.19 % east, i.e. 0.9 and 1.9 m per km; at the equator
+0.67 % north). Recordings imported with it carry no ``meta["projection"]``; :func:`needs_reimport`
says so.
"""

from __future__ import annotations

import numpy as np
import pymap3d

#: The name written to ``meta["projection"]`` by every importer that projects lat/lon.
PROJECTION = "enu-wgs84-pymap3d"
WGS84 = pymap3d.Ellipsoid.from_name("wgs84")
#: Importers that project lat/lon into a recording's positions (their ``wearnav import`` name).
PROJECTING_SOURCES = ("ipin2023", "sensorlogger")
# Steps of the inverse (lower "up" by the height reached): each leaves about (d / 6400 km)² of the
# previous height error at distance d, so two reach 1e-9 m at 100 km; three for margin.
_INVERSE_STEPS = 3


def latlon_to_local(lat_deg, lon_deg, lat0_deg: float, lon0_deg: float) -> np.ndarray:
    """WGS-84 latitude/longitude (degrees, shape (N,)) → local east/north (N, 2) float64 metres in the
    ENU frame at (lat0_deg, lon0_deg); all heights 0 (on the ellipsoid)."""
    lat = np.asarray(lat_deg, dtype=np.float64).reshape(-1)
    lon = np.asarray(lon_deg, dtype=np.float64).reshape(-1)
    e, n, _ = pymap3d.geodetic2enu(lat, lon, 0.0, float(lat0_deg), float(lon0_deg), 0.0, ell=WGS84)
    return np.stack([np.asarray(e, np.float64), np.asarray(n, np.float64)], axis=1)


def local_to_latlon(pos_m, lat0_deg: float, lon0_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Local east/north metres (N, 2) in the ENU frame at (lat0_deg, lon0_deg) → (latitude, longitude)
    in degrees, each (N,): the point on the ellipsoid whose :func:`latlon_to_local` is ``pos_m``.

    ``enu2geodetic`` of (east, north, up) gives a point at some height h; the point at height 0 is
    found by lowering ``up`` by h until h is 0 (:data:`_INVERSE_STEPS` steps).
    """
    pos = np.asarray(pos_m, dtype=np.float64).reshape(-1, 2)
    up = np.zeros(len(pos))
    for _ in range(_INVERSE_STEPS):
        lat, lon, h = pymap3d.enu2geodetic(pos[:, 0], pos[:, 1], up, float(lat0_deg), float(lon0_deg), 0.0, ell=WGS84)
        up = up - np.asarray(h, np.float64)
    return np.asarray(lat, np.float64).reshape(-1), np.asarray(lon, np.float64).reshape(-1)


def needs_reimport(meta: dict, has_fixes: bool = False) -> str | None:
    """One line saying that a recording needs re-import (``wearnav import``) because its positions
    were projected from lat/lon by an older converter, or None when they need not be.

    A recording is affected when it has a geographic origin (``origin_lat``/``origin_lon``), or
    fixes (``has_fixes``) from an importer that projects lat/lon, and its ``meta["projection"]`` is
    not :data:`PROJECTION`. Simulated recordings (fixes in metres, no origin) are never affected.
    """
    geographic = "origin_lat" in meta or "origin_lon" in meta
    source = str(meta.get("source", ""))
    if not (geographic or (has_fixes and source in PROJECTING_SOURCES)):
        return None
    used = meta.get("projection")
    if used == PROJECTION:
        return None
    how = f"projection {used!r}" if used else "the old equirectangular projection (off by up to 7 m per km)"
    fmt = source if source in PROJECTING_SOURCES else "<format>"
    return (
        f"needs re-import: its positions were projected from lat/lon with {how}, not {PROJECTION}; "
        f"run wearnav import {fmt} <original files> --out <dataset>"
    )


__all__ = ["PROJECTION", "latlon_to_local", "local_to_latlon", "needs_reimport"]
