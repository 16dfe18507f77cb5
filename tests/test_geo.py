"""wearnav.core.geo: lat/lon ↔ local metres (WGS-84 east-north-up), and the re-import check.

The reference is written here independently of wearnav.core.geo (geodetic → ECEF → ENU, the textbook
formulas) and agrees with ``pymap3d.geodetic2enu``; the points lie 0.1, 1 and 10 km from the
origin in eight directions, at the equator and at 60° N.
"""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest

from wearnav.core import geo

A_M = 6378137.0  # WGS-84 semi-major axis
F = 1 / 298.257223563  # WGS-84 flattening
E2 = F * (2 - F)


def ecef(lat_deg, lon_deg):
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    n = A_M / np.sqrt(1 - E2 * np.sin(lat) ** 2)
    return np.stack([n * np.cos(lat) * np.cos(lon), n * np.cos(lat) * np.sin(lon), n * (1 - E2) * np.sin(lat)], axis=-1)


def reference_enu(lat_deg, lon_deg, lat0_deg, lon0_deg) -> np.ndarray:
    """East/north (N, 2) m of points at height 0 in the ENU frame of (lat0, lon0, 0)."""
    d = ecef(lat_deg, lon_deg) - ecef(lat0_deg, lon0_deg)
    la, lo = np.radians(lat0_deg), np.radians(lon0_deg)
    east = -np.sin(lo) * d[:, 0] + np.cos(lo) * d[:, 1]
    north = -np.sin(la) * np.cos(lo) * d[:, 0] - np.sin(la) * np.sin(lo) * d[:, 1] + np.cos(la) * d[:, 2]
    return np.stack([east, north], axis=1)


def old_equirectangular(lat_deg, lon_deg, lat0_deg, lon0_deg) -> np.ndarray:
    """The projection wearnav used before (equatorial radius on both axes): kept here only to show
    that the tests below would have caught it."""
    east = np.radians(lon_deg - lon0_deg) * A_M * np.cos(np.radians(lat0_deg))
    north = np.radians(lat_deg - lat0_deg) * A_M
    return np.stack([east, north], axis=1)


def points_around(lat0, lon0, dist_m):
    """(lat, lon) of points at height 0 about ``dist_m`` from the origin in eight directions."""
    ang = np.radians(np.arange(0, 360, 45))
    lat, lon, _ = pymap3d.enu2geodetic(dist_m * np.cos(ang), dist_m * np.sin(ang), 0.0, lat0, lon0, 0.0)
    return np.asarray(lat), np.asarray(lon)


ORIGINS = [(0.0, 10.0), (60.0, 10.0)]
DISTANCES_M = [100.0, 1000.0, 10000.0]


@pytest.mark.parametrize("lat0, lon0", ORIGINS, ids=["equator", "60N"])
@pytest.mark.parametrize("dist_m", DISTANCES_M, ids=["0.1km", "1km", "10km"])
def test_latlon_to_local_matches_enu_to_1_cm(lat0, lon0, dist_m):
    lat, lon = points_around(lat0, lon0, dist_m)
    ref = reference_enu(lat, lon, lat0, lon0)
    e, n, _ = pymap3d.geodetic2enu(lat, lon, 0.0, lat0, lon0, 0.0)
    np.testing.assert_allclose(np.stack([e, n], axis=1), ref, atol=1e-3)  # the reference is right
    got = geo.latlon_to_local(lat, lon, lat0, lon0)
    assert got.shape == (8, 2)
    assert np.max(np.linalg.norm(got - ref, axis=1)) <= 0.01
    assert np.linalg.norm(got, axis=1) == pytest.approx(dist_m, rel=1e-3)


@pytest.mark.parametrize("lat0, lon0", ORIGINS, ids=["equator", "60N"])
@pytest.mark.parametrize("dist_m", DISTANCES_M, ids=["0.1km", "1km", "10km"])
def test_round_trip_local_latlon_local_to_1_mm(lat0, lon0, dist_m):
    rng = np.random.default_rng(0)
    pos = rng.uniform(-dist_m, dist_m, (50, 2))
    lat, lon = geo.local_to_latlon(pos, lat0, lon0)
    assert lat.shape == lon.shape == (50,)
    back = geo.latlon_to_local(lat, lon, lat0, lon0)
    assert np.max(np.linalg.norm(back - pos, axis=1)) <= 1e-3
    # and the lat/lon are the points on the ellipsoid that the reference puts there
    assert np.max(np.linalg.norm(reference_enu(lat, lon, lat0, lon0) - pos, axis=1)) <= 1e-3


def test_the_old_equirectangular_projection_fails_these_tests():
    """At 10 km from an origin at 60° N the old formula is off by metres (the ellipsoid's radii of
    curvature differ from the equatorial radius: −0.08 % north, −0.25 % east there), so the 1 cm
    test above has teeth."""
    lat0, lon0 = ORIGINS[1]
    lat, lon = points_around(lat0, lon0, 10000.0)
    err = np.linalg.norm(old_equirectangular(lat, lon, lat0, lon0) - reference_enu(lat, lon, lat0, lon0), axis=1)
    assert np.max(err) > 5.0
    north_only = reference_enu(np.array([lat0 + 0.09]), np.array([lon0]), lat0, lon0)[0, 1]
    old_north = old_equirectangular(np.array([lat0 + 0.09]), np.array([lon0]), lat0, lon0)[0, 1]
    assert abs(old_north - north_only) > 1.0


def test_scalar_and_list_inputs():
    pos = geo.latlon_to_local([49.45], [11.1], 49.45, 11.1)
    np.testing.assert_allclose(pos, [[0.0, 0.0]], atol=1e-9)
    lat, lon = geo.local_to_latlon([0.0, 0.0], 49.45, 11.1)
    np.testing.assert_allclose([lat[0], lon[0]], [49.45, 11.1], atol=1e-12)


# ---- needs re-import ----------------------------------------------------------------------------


def test_needs_reimport():
    old = {"source": "ipin2023", "origin_lat": 49.45, "origin_lon": 11.1}
    msg = geo.needs_reimport(old)
    assert msg is not None and "\n" not in msg
    assert "wearnav import ipin2023" in msg and "equirectangular" in msg
    assert geo.needs_reimport({**old, "projection": geo.PROJECTION}) is None
    assert "'utm'" in geo.needs_reimport({**old, "projection": "utm"})
    # fixes from an importer that projects lat/lon, but no origin stored: still old
    assert "wearnav import sensorlogger" in geo.needs_reimport({"source": "sensorlogger"}, has_fixes=True)
    # simulated fixes are metres from the start (no lat/lon ever), and a recording without fixes
    assert geo.needs_reimport({"source": "simulate"}, has_fixes=True) is None
    assert geo.needs_reimport({"source": "ipin2023"}) is None
