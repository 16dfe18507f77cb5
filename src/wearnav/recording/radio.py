"""The side tables a :class:`~wearnav.recording.Recording` may carry beside its IMU streams: BLE
beacon readings (:class:`BeaconReadings`), Wi-Fi scans (:class:`WifiScans`), the magnetometer
(:class:`MagneticField`), barometer pressure (:class:`Pressure`) and floor plans
(:class:`FloorPlan`). Validated on construction, as every part of a Recording; stored and loaded
by :mod:`wearnav.recording`, which re-exports these names. The radio tables are what a radio map
is built from and read with (issue 60, :mod:`wearnav.fuse.radiomap`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from wearnav.errors import ValidationError
from wearnav.recording.checks import (
    _as_array,
    _check_position,
    _check_range,
    _check_rows,
    _check_time,
    check_name,
    check_text,
)

# Received power of a BLE beacon: -110 dBm is below any phone's sensitivity, 0 dBm at the antenna.
RSSI_DBM_RANGE = (-130.0, 0.0)
# Wi-Fi channels: 2.4 GHz (2412-2484 MHz), 5 GHz (5160-5885), 6 GHz (5955-7115), 60 GHz 802.11ad/ay
# (58-70 GHz); a value outside 2000..72000 MHz is not a Wi-Fi frequency (kHz, GHz or a shifted column).
WIFI_FREQ_MHZ_RANGE = (2000.0, 72000.0)
# The largest full-scale range of phone magnetometers (AKM AK09918: ±4912 µT); the Earth's field is
# 25-65 µT. A larger value per axis was not measured by a phone (gauss? nT?).
MAGNETIC_UT_AXIS_MAX = 5000.0
# Air pressure anywhere people walk: Dead Sea shore ~1070 hPa, 5000 m altitude ~540 hPa.
PRESSURE_HPA_RANGE = (300.0, 1100.0)


def _check_rssi(rssi_dbm: np.ndarray, name: str) -> None:
    """Every received power finite and in :data:`RSSI_DBM_RANGE` (NaN is refused too)."""
    bad = ~((rssi_dbm >= RSSI_DBM_RANGE[0]) & (rssi_dbm <= RSSI_DBM_RANGE[1]))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ValidationError(
            f"{name}: {rssi_dbm[i]:.4g} at reading {i} is not a received power "
            f"in {RSSI_DBM_RANGE[0]:g}..{RSSI_DBM_RANGE[1]:g} dBm"
        )


def _as_names(x, n: int, name: str) -> np.ndarray:
    """Text identifiers (BSSIDs, SSIDs, beacon names) as an object array of str of shape (n,); each
    distinct value checked once (:func:`check_text`: HDF5 must store it), not every reading."""
    a = np.asarray(x, dtype=object)
    if a.shape != (n,):
        raise ValidationError(f"{name}: shape {a.shape}, expected ({n},)")
    uniques = pd.unique(a)  # hashing: ~40x faster than converting every reading to str
    if not all(type(u) is str for u in uniques):
        a = a.astype(str).astype(object)
        uniques = pd.unique(a)
    for text in uniques:
        check_text(text, name)
    return a


def _optional_column(x, n: int, name: str) -> np.ndarray | None:
    """An optional per-reading number (NaN where the source does not give it), shape (n,)."""
    if x is None:
        return None
    a = _as_array(x, np.float64, name)
    if a.shape != (n,):
        raise ValidationError(f"{name}: shape {a.shape}, expected ({n},)")
    if np.any(np.isinf(a)):
        raise ValidationError(f"{name}: infinite value at reading {int(np.argmax(np.isinf(a)))} (NaN where unknown)")
    return a


def repeated_readings(t: np.ndarray, source: np.ndarray, t_seen: np.ndarray | None = None) -> np.ndarray:
    """Indices (increasing) of the readings repeating the time, source (BSSID, beacon) and own
    timestamp of an earlier one: a row written twice. (One scan may report an access point twice
    with different own timestamps: ILC2's phone lists a hidden network's cached reading beside its
    fresh one.)"""
    codes = pd.factorize(np.asarray(source, dtype=object), use_na_sentinel=False)[0]
    cols = [np.asarray(t, np.float64), codes] + ([] if t_seen is None else [np.asarray(t_seen, np.float64)])
    order = np.lexsort(cols[::-1])  # stable: of equal rows the earliest comes first
    same = np.ones(max(t.size - 1, 0), bool)
    for c in cols:
        sc = c[order]
        same &= sc[1:] == sc[:-1]
    return np.sort(order[1:][same])


@dataclass
class BeaconReadings:
    """Received signal strengths of radio beacons (BLE), one row per reading.

    ``beacon`` names the beacon (the key of ``meta["beacons"]``, which gives its surveyed
    position ``[x_m, y_m, floor]`` in the recording's local frame where the source has one; an
    iBeacon without a surveyed position is named ``UUID:major:minor:MAC``, see the importers);
    ``rssi_dbm`` is the received power in dBm (negative; -100 is at the edge of reception).
    Where the source gives them (ILC2's ``TYPE_BEACON``): ``tx_power_dbm``, the power the beacon
    advertises (its RSSI at 1 m), and ``distance_m``, the app's own range estimate from the two
    (NaN where the app could not tell); None where the source has neither.
    """

    t: np.ndarray
    beacon: np.ndarray
    rssi_dbm: np.ndarray
    tx_power_dbm: np.ndarray | None = None
    distance_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        self.t = _as_array(self.t, np.float64, "beacons.t")
        self.rssi_dbm = _as_array(self.rssi_dbm, np.float64, "beacons.rssi_dbm")
        _check_time(self.t, "beacons.t", repeats=True)  # several beacons heard at one instant
        n = self.t.size
        self.beacon = _as_names(self.beacon, n, "beacons.beacon")
        if self.rssi_dbm.shape != self.t.shape:
            raise ValidationError(f"beacons.rssi_dbm: shape {self.rssi_dbm.shape}, expected {self.t.shape}")
        _check_rssi(self.rssi_dbm, "beacons.rssi_dbm")
        self.tx_power_dbm = _optional_column(self.tx_power_dbm, n, "beacons.tx_power_dbm")
        self.distance_m = _optional_column(self.distance_m, n, "beacons.distance_m")
        if self.distance_m is not None and np.any(self.distance_m < 0):
            i = int(np.argmax(self.distance_m < 0))
            raise ValidationError(
                f"beacons.distance_m: {self.distance_m[i]:.4g} m at reading {i} is not a distance (NaN where unknown)"
            )

    def __len__(self) -> int:
        return int(self.t.size)


@dataclass
class WifiScans:
    """Wi-Fi scan results, one row per access point heard in a scan (issue 60 §1).

        ``t`` (s, the recording's clock) is when the scan was delivered: every reading of one scan
        shares it. ``bssid`` names the access point (its MAC address, lower case as the phone gives it;
        the key of a radio map), ``ssid`` the network's name ("" where the source drops it),
        ``freq_mhz`` its channel's centre frequency, ``rssi_dbm`` the received power. A scan may hold an
    access point twice with different ``t_seen`` (a fresh and a cached reading), never twice with the
    same (a repeated row: refused).
        ``t_seen`` (s, same clock; NaN where unknown; None where the source has no such column) is
        the reading's own timestamp: Android's ``ScanResult.timestamp``, when the access point was last
        heard. A phone hands cached results on in later scans (ILC2: median 4.8 s, up to 30 s before
        the scan), so the reading describes where the walker was at ``t_seen``, not ``t``.
    """

    t: np.ndarray
    bssid: np.ndarray
    ssid: np.ndarray
    freq_mhz: np.ndarray
    rssi_dbm: np.ndarray
    t_seen: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        self.t = _as_array(self.t, np.float64, "wifi.t")
        _check_time(self.t, "wifi.t", repeats=True)  # one scan: many access points at one instant
        n = self.t.size
        self.bssid = _as_names(self.bssid, n, "wifi.bssid")
        self.ssid = _as_names(self.ssid, n, "wifi.ssid")
        self.freq_mhz = _as_array(self.freq_mhz, np.float64, "wifi.freq_mhz")
        self.rssi_dbm = _as_array(self.rssi_dbm, np.float64, "wifi.rssi_dbm")
        for what, a in (("freq_mhz", self.freq_mhz), ("rssi_dbm", self.rssi_dbm)):
            if a.shape != (n,):
                raise ValidationError(f"wifi.{what}: shape {a.shape}, expected ({n},)")
        _check_rssi(self.rssi_dbm, "wifi.rssi_dbm")
        lo, hi = WIFI_FREQ_MHZ_RANGE
        bad = ~((self.freq_mhz >= lo) & (self.freq_mhz <= hi))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise ValidationError(
                f"wifi.freq_mhz: {self.freq_mhz[i]:.6g} at reading {i} is not a Wi-Fi channel in {lo:g}..{hi:g} MHz"
            )
        self.t_seen = _optional_column(self.t_seen, n, "wifi.t_seen")
        dup = repeated_readings(self.t, self.bssid, self.t_seen)
        if dup.size:
            i = int(dup[0])
            raise ValidationError(
                f"wifi: access point {self.bssid[i]} heard twice in the scan at t={self.t[i]:.6f} "
                f"(reading {i}){' with the same own timestamp' if self.t_seen is not None else ''}: duplicated rows?"
            )

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def scan_starts(self) -> np.ndarray:
        """Index of each scan's first reading (a scan: the readings sharing one ``t``), then ``len``."""
        return np.concatenate([[0], np.flatnonzero(np.diff(self.t) > 0) + 1, [self.t.size]])


@dataclass
class MagneticField:
    """The magnetometer (µT, device frame, calibrated: hard-iron offsets removed by the phone), on
    its own clock like :class:`Pressure`; ~50 Hz on IPIN 2023's phones."""

    t: np.ndarray
    ut: np.ndarray

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        self.t = _as_array(self.t, np.float64, "magnetic.t")
        self.ut = _as_array(self.ut, np.float32, "magnetic.ut")
        _check_time(self.t, "magnetic.t")
        _check_rows(self.ut, self.t.size, 3, "magnetic.ut")
        _check_range(self.ut, MAGNETIC_UT_AXIS_MAX, "µT (a phone magnetometer's full scale)", "magnetic.ut")

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
