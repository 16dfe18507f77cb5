"""The side tables a :class:`~wearnav.recording.Recording` may carry beside its IMU streams: BLE
beacon readings (:class:`BeaconReadings`), barometer pressure (:class:`Pressure`) and floor plans
(:class:`FloorPlan`). Validated on construction, as every part of a Recording; stored and loaded
by :mod:`wearnav.recording`, which re-exports these names."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from wearnav.errors import ValidationError
from wearnav.recording.checks import _as_array, _check_position, _check_time, check_name

# Received power of a BLE beacon: -110 dBm is below any phone's sensitivity, 0 dBm at the antenna.
RSSI_DBM_RANGE = (-130.0, 0.0)
# Air pressure anywhere people walk: Dead Sea shore ~1070 hPa, 5000 m altitude ~540 hPa.
PRESSURE_HPA_RANGE = (300.0, 1100.0)


@dataclass
class BeaconReadings:
    """Received signal strengths of radio beacons (BLE), one row per reading.

    ``beacon`` names the beacon (the key of ``meta["beacons"]``, which gives its surveyed
    position ``[x_m, y_m, floor]`` in the recording's local frame where the source has one);
    ``rssi_dbm`` is the received power in dBm (negative; -100 is at the edge of reception).
    """

    t: np.ndarray
    beacon: np.ndarray
    rssi_dbm: np.ndarray

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        self.t = _as_array(self.t, np.float64, "beacons.t")
        self.rssi_dbm = _as_array(self.rssi_dbm, np.float64, "beacons.rssi_dbm")
        self.beacon = np.asarray(self.beacon, dtype=object).astype(str).astype(object)
        _check_time(self.t, "beacons.t", repeats=True)  # several beacons heard at one instant
        for what, a in (("beacon", self.beacon), ("rssi_dbm", self.rssi_dbm)):
            if a.shape != self.t.shape:
                raise ValidationError(f"beacons.{what}: shape {a.shape}, expected {self.t.shape}")
        bad = ~((self.rssi_dbm >= RSSI_DBM_RANGE[0]) & (self.rssi_dbm <= RSSI_DBM_RANGE[1]))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise ValidationError(
                f"beacons.rssi_dbm: {self.rssi_dbm[i]:.4g} at reading {i} is not a received power "
                f"in {RSSI_DBM_RANGE[0]:g}..{RSSI_DBM_RANGE[1]:g} dBm"
            )

    def __len__(self) -> int:
        return int(self.t.size)


@dataclass
class Pressure:
    """Barometer readings (hPa): a floor change moves it by ~0.4 hPa (≈ 3.5 m of air)."""

    t: np.ndarray
    hpa: np.ndarray

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        self.t = _as_array(self.t, np.float64, "pressure.t")
        self.hpa = _as_array(self.hpa, np.float64, "pressure.hpa")
        _check_time(self.t, "pressure.t")
        if self.hpa.shape != self.t.shape:
            raise ValidationError(f"pressure.hpa: shape {self.hpa.shape}, expected {self.t.shape}")
        bad = ~((self.hpa >= PRESSURE_HPA_RANGE[0]) & (self.hpa <= PRESSURE_HPA_RANGE[1]))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise ValidationError(
                f"pressure.hpa: {self.hpa[i]:.6g} at reading {i} is not an air pressure in "
                f"{PRESSURE_HPA_RANGE[0]:g}..{PRESSURE_HPA_RANGE[1]:g} hPa (kPa or Pa?)"
            )

    def __len__(self) -> int:
        return int(self.t.size)


@dataclass
class FloorPlan:
    """One floor's walkable space in the recording's own local frame (metres, as ``truth.pos``).

    ``polygons`` is a list of polygons, each a list of rings: the outer boundary first, then its
    holes (obstacles inside it: shops, walls, voids), each ring an (K, 2) array of x, y in metres.
    ``floor`` is the floor index the recording's ``truth.floor`` uses (``None`` if unknown).
    Geometry (inside tests, distances, rasters) lives in :mod:`wearnav.plans`.
    """

    name: str
    floor: int | None
    polygons: list[list[np.ndarray]]

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        check_name(self.name, "floor plan name")
        if self.floor is not None and not isinstance(self.floor, (int, np.integer)):
            raise ValidationError(f"floor plan {self.name!r}: floor {self.floor!r} is not an integer")
        if not self.polygons:
            raise ValidationError(f"floor plan {self.name!r} has no walkable polygon")
        rings = []
        for k, poly in enumerate(self.polygons):
            if not poly:
                raise ValidationError(f"floor plan {self.name!r}: polygon {k} has no ring")
            out = []
            for ring in poly:
                r = _as_array(ring, np.float64, f"floor plan {self.name!r} ring")
                if r.ndim != 2 or r.shape[1] != 2 or r.shape[0] < 3:
                    raise ValidationError(
                        f"floor plan {self.name!r}: polygon {k} has a ring of shape {r.shape}, expected (K>=3, 2)"
                    )
                _check_position(r, f"floor plan {self.name!r}")
                out.append(r)
            rings.append(out)
        self.polygons = rings

    def to_feature(self) -> dict[str, Any]:
        """A GeoJSON-shaped Feature (MultiPolygon) in local metres: how it is stored."""
        return {
            "type": "Feature",
            "properties": {"name": self.name, "floor": self.floor, "frame": "local metres"},
            "geometry": {
                "type": "MultiPolygon",
                "coordinates": [[np.round(r, 3).tolist() for r in poly] for poly in self.polygons],
            },
        }

    @classmethod
    def from_feature(cls, feature: dict[str, Any]) -> FloorPlan:
        props, geom = feature["properties"], feature["geometry"]
        floor = props.get("floor")
        return cls(
            name=str(props["name"]),
            floor=None if floor is None else int(floor),
            polygons=[[np.asarray(r, dtype=np.float64) for r in poly] for poly in geom["coordinates"]],
        )
