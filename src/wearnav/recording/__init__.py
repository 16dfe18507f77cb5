"""The one in-memory data model of wearnav and its HDF5 storage.

A :class:`Recording` holds what one walk produced: the IMU stream of each worn device
(:class:`DeviceStream`), optionally the true body trajectory (:class:`Trajectory`), noisy location
fixes (:class:`Fixes`), interval labels and free metadata; where the source has them, BLE beacon
readings, Wi-Fi scans, the magnetometer, barometer pressure and floor plans
(:mod:`wearnav.recording.radio`, re-exported here).
Streams keep their own rates and clocks; resampling to a common clock is :mod:`wearnav.preprocess`'s
job.

Units are SI: seconds, metres, m/s² (accelerometer *including* gravity, device frame), rad/s.
Quaternions are (w, x, y, z) and rotate device-frame vectors into the world frame (z up).

Everything is validated on construction (the checks: :mod:`wearnav.recording.checks`), so a
Recording that exists is well-formed; loading a file re-validates and names the file in any error.

Decision: docs/decisions/0001-data-model-refinements.md.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd

from wearnav.core.fileio import atomic_path, require_regular_file
from wearnav.core.timeseries import rate
from wearnav.errors import FormatError, ValidationError
from wearnav.recording.checks import (
    POS_ABS_MAX,
    _as_array,
    _as_flags,
    _check_position,
    _check_range,
    _check_rows,
    _check_time,
    check_name,
    check_text,
)
from wearnav.recording.radio import BeaconReadings as BeaconReadings
from wearnav.recording.radio import FloorPlan as FloorPlan
from wearnav.recording.radio import MagneticField as MagneticField
from wearnav.recording.radio import Pressure as Pressure
from wearnav.recording.radio import WifiScans as WifiScans

FORMAT_NAME = "wearnav.recording"
FORMAT_VERSION = 1
CANONICAL_DEVICES = ("phone", "watch", "earbuds")
LABEL_COLUMNS = ["start", "end", "kind", "value"]

# meta["quat_frame"] of a recording whose phone orientation is Android's rotation vector (ILC2, IPIN 2023):
# its world frame is east, magnetic north, up, so a path in it needs no heading offset (wearnav.fuse)
ANDROID_ENU_FRAME = "Android rotation vector: world = east, magnetic north, up"
STANDARD_GRAVITY = 9.80665  # m/s²; "g" of files that give acceleration in g
# |acc| of a device is dominated by gravity (9.81 m/s²). A median far outside this band means the
# data is in g (≈ 1), has gravity removed (≈ 0–3), or is not an accelerometer at all. The band is
# wide on purpose: real data reaches 18.4 m/s² (MotionSense jogging, phone in a thigh pocket) and
# 6.7 m/s² (short, vigorous ILC2 traces).
ACC_NORM_MEDIAN_RANGE = (4.0, 25.0)
# Walking rarely exceeds a few rad/s; a median above this is almost surely deg/s.
GYRO_NORM_MEDIAN_MAX = 15.0
# Full-scale ranges of consumer IMUs (phones, watches, earbuds): ±16 g accelerometers and
# ±2000 °/s gyroscopes are the largest settings of the common parts (Bosch BMI160/BMI270,
# ST LSM6DS*, InvenSense ICM-4xxxx), applied per axis as the sensors saturate per axis. A value
# beyond them was not measured by such a sensor: a corrupt file, a wrong unit or a sentinel.
ACC_AXIS_MAX = 16 * STANDARD_GRAVITY  # m/s²
GYRO_AXIS_MAX = float(np.deg2rad(2000.0))  # rad/s
# Truth and fixes describe the same walk as the devices: times farther than this outside the
# devices' span are on another clock or corrupt.
MAX_TIME_OUTSIDE_S = 600.0


def device_order(name: str) -> tuple[int, str]:
    """Sort key: phone, watch, earbuds first (HDF5 hands devices back alphabetically), then the rest."""
    return (CANONICAL_DEVICES.index(name) if name in CANONICAL_DEVICES else len(CANONICAL_DEVICES), name)


def _text(v: Any) -> str:
    """A string read back from HDF5 (h5py hands variable-length UTF-8 back as bytes)."""
    return v.decode() if isinstance(v, bytes) else str(v)


@dataclass
class DeviceStream:
    """One device's IMU stream on its own clock.

    ``gyro`` is None for accelerometer-only devices (never filled with fake zeros); ``quat`` is
    the device's orientation world←device (w, x, y, z) when the device reports one; ``worn`` is
    False where the device was taken off (samples may continue, e.g. lying on a table).
    """

    t: np.ndarray
    acc: np.ndarray
    gyro: np.ndarray | None = None
    quat: np.ndarray | None = None
    worn: np.ndarray | None = None
    check_units: bool = field(default=True, repr=False)

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Convert and check every field (again: they are public and may have been reassigned)."""
        self.t = _as_array(self.t, np.float64, "t")
        self.acc = _as_array(self.acc, np.float32, "acc")
        if self.gyro is not None:
            self.gyro = _as_array(self.gyro, np.float32, "gyro")
        if self.quat is not None:
            self.quat = _as_array(self.quat, np.float32, "quat")
        if self.worn is not None:
            self.worn = _as_flags(self.worn, "worn")
        _check_time(self.t, "t")
        n = self.t.size
        _check_rows(self.acc, n, 3, "acc")
        _check_rows(self.gyro, n, 3, "gyro")
        _check_rows(self.quat, n, 4, "quat")
        if self.quat is not None:
            norm = np.linalg.norm(self.quat, axis=1)
            if np.any(np.abs(norm - 1) > 0.05):
                raise ValidationError("quat: not unit quaternions (|q| deviates from 1 by > 0.05)")
            if np.any(np.abs(norm - 1) > 1e-6):  # leave float32-unit quaternions bit-exact
                self.quat = (self.quat / norm[:, None]).astype(np.float32)
        if self.worn is not None and self.worn.shape != (n,):
            raise ValidationError(f"worn: shape {self.worn.shape}, expected ({n},)")
        if self.check_units and n >= 10:
            with np.errstate(over="ignore", invalid="ignore"):  # absurd values: the range check's job
                med = float(np.median(np.linalg.norm(self.acc, axis=1)))
                gmed = float(np.median(np.linalg.norm(self.gyro, axis=1))) if self.gyro is not None else 0.0
            lo, hi = ACC_NORM_MEDIAN_RANGE
            if not lo <= med <= hi:
                hint = f" (looks like g, multiply by {STANDARD_GRAVITY})" if 0.6 < med < 1.4 else ""
                raise ValidationError(
                    f"acc: median |acc| is {med:.3g}, expected about 9.8 m/s² including gravity{hint}"
                )
            if self.gyro is not None:
                if gmed > GYRO_NORM_MEDIAN_MAX:
                    raise ValidationError(
                        f"gyro: median |gyro| is {gmed:.3g} rad/s, implausible (deg/s instead of rad/s?)"
                    )
        # After the unit check, whose hint is more specific for a whole file in g or deg/s.
        _check_range(self.acc, ACC_AXIS_MAX, "m/s² (16 g)", "acc")
        _check_range(self.gyro, GYRO_AXIS_MAX, "rad/s (2000 °/s)", "gyro")

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def rate(self) -> float:
        """Median sampling rate in Hz (0 for a single sample)."""
        return rate(self.t)

    @property
    def has_gyro(self) -> bool:
        return self.gyro is not None


@dataclass
class Trajectory:
    """Positions over time in the recording's local world frame (metres, z up).

    Dense truth (a simulator, VIO) or sparse surveyed waypoints alike; ``floor`` is an optional
    per-point floor index for multi-storey indoor data.
    """

    t: np.ndarray
    pos: np.ndarray
    quat: np.ndarray | None = None
    floor: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        self.t = _as_array(self.t, np.float64, "truth.t")
        self.pos = _as_array(self.pos, np.float64, "truth.pos")
        if self.quat is not None:
            self.quat = _as_array(self.quat, np.float64, "truth.quat")
        if self.floor is not None:
            self.floor = _as_array(self.floor, np.float64, "truth.floor")
        _check_time(self.t, "truth.t")
        _check_rows(self.pos, self.t.size, (2, 3), "truth.pos")
        _check_position(self.pos, "truth.pos")
        _check_rows(self.quat, self.t.size, 4, "truth.quat")
        if self.floor is not None and self.floor.shape != self.t.shape:
            raise ValidationError(f"truth.floor: shape {self.floor.shape}, expected {self.t.shape}")
        if self.floor is not None and not np.all(np.isfinite(self.floor)):
            raise ValidationError(
                f"truth.floor: non-finite values (first at point "
                f"{int(np.argmax(~np.isfinite(self.floor)))}); truth knows its floor"
            )

    def __len__(self) -> int:
        return int(self.t.size)


@dataclass
class Fixes:
    """Noisy location fixes (GNSS / network location), local frame metres.

    ``accuracy`` is the device's reported horizontal accuracy radius in metres (NaN where the
    source does not report one).
    """

    t: np.ndarray
    pos: np.ndarray
    accuracy: np.ndarray
    floor: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        self.t = _as_array(self.t, np.float64, "fixes.t")
        self.pos = _as_array(self.pos, np.float64, "fixes.pos")
        self.accuracy = _as_array(self.accuracy, np.float64, "fixes.accuracy")
        if self.floor is not None:
            self.floor = _as_array(self.floor, np.float64, "fixes.floor")
        _check_time(self.t, "fixes.t")
        _check_rows(self.pos, self.t.size, (2, 3), "fixes.pos")
        _check_position(self.pos, "fixes.pos")
        if self.accuracy.shape != self.t.shape:
            raise ValidationError(f"fixes.accuracy: shape {self.accuracy.shape}, expected {self.t.shape}")
        bad = ~np.isnan(self.accuracy) & ~((self.accuracy >= 0) & (self.accuracy <= POS_ABS_MAX))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise ValidationError(
                f"fixes.accuracy: {self.accuracy[i]:.4g} m at fix {i} is not a radius "
                f"in 0..{POS_ABS_MAX:.0e} m (NaN where unknown)"
            )
        if self.floor is not None and self.floor.shape != self.t.shape:
            raise ValidationError(f"fixes.floor: shape {self.floor.shape}, expected {self.t.shape}")

    def __len__(self) -> int:
        return int(self.t.size)


_EMPTY_LABELS: pd.DataFrame | None = None  # the validated empty table, built once (make_labels)


def make_labels(rows=None) -> pd.DataFrame:
    """A labels table (columns start, end, kind, value) from rows or records; validated.

    No rows (None, empty, or an empty labels table) returns a copy of one empty table built once:
    building it costs ~1.3 ms of pandas, paid twice for every Recording, which was 19 % of a live
    tracker's time (issue 37's profile)."""
    global _EMPTY_LABELS
    empty = rows is None or (isinstance(rows, (list, tuple)) and not rows)
    if isinstance(rows, pd.DataFrame) and not len(rows) and list(rows.columns) == LABEL_COLUMNS:
        empty = _EMPTY_LABELS is not None and rows.dtypes.equals(_EMPTY_LABELS.dtypes)
    if empty and _EMPTY_LABELS is not None:
        return _EMPTY_LABELS.copy()
    if empty:
        _EMPTY_LABELS = _make_labels(None)
        return _EMPTY_LABELS.copy()
    return _make_labels(rows)


def _make_labels(rows) -> pd.DataFrame:
    if isinstance(rows, pd.DataFrame) and set(LABEL_COLUMNS) - set(rows.columns):
        raise ValidationError(
            f"labels: missing columns {sorted(set(LABEL_COLUMNS) - set(rows.columns))} "
            f"(a labels table has {', '.join(LABEL_COLUMNS)})"
        )
    try:
        df = pd.DataFrame(rows if rows is not None else [], columns=LABEL_COLUMNS)
    except (TypeError, ValueError) as exc:
        raise ValidationError(f"labels: not a table of ({', '.join(LABEL_COLUMNS)}) rows ({exc})") from None
    try:
        df = df.astype({"start": float, "end": float, "kind": str, "value": str})
    except (TypeError, ValueError) as exc:
        raise ValidationError(f"labels: start/end are not numbers ({exc})") from None
    if len(df):
        if not np.all(np.isfinite(df[["start", "end"]].to_numpy())):
            raise ValidationError("labels: non-finite start/end")
        if np.any(df["end"].to_numpy() < df["start"].to_numpy()):
            raise ValidationError("labels: an interval ends before it starts")
        for col in ("kind", "value"):
            for text in df[col].unique():
                check_text(text, f"labels: {col}")
    df = df.sort_values(["kind", "start"], kind="stable").reset_index(drop=True)
    _check_overlaps(df)
    return df


def _check_overlaps(df: pd.DataFrame) -> None:
    """Intervals of one kind must not overlap (they may touch): ``label_at`` would have to pick
    one, and a repeated table (every row twice) is the usual cause. Zero-length rows are events
    (e.g. steps) and may repeat."""
    spans = df[df["end"] > df["start"]]
    for kind, g in spans.groupby("kind", sort=False):
        start, end = g["start"].to_numpy(), g["end"].to_numpy()
        bad = np.flatnonzero(start[1:] < np.maximum.accumulate(end)[:-1])
        if bad.size:
            i = int(bad[0]) + 1
            raise ValidationError(
                f"labels: {kind!r} intervals overlap ([{start[i - 1]:g}, {end[i - 1]:g}) "
                f"{g['value'].iloc[i - 1]!r} and [{start[i]:g}, {end[i]:g}) {g['value'].iloc[i]!r}); "
                "repeated label rows?"
            )


@dataclass
class Recording:
    """One walk: devices, optional truth / fixes / labels, and metadata."""

    name: str
    devices: dict[str, DeviceStream]
    truth: Trajectory | None = None
    fixes: Fixes | None = None
    labels: pd.DataFrame = field(default_factory=make_labels)
    meta: dict[str, Any] = field(default_factory=dict)
    beacons: BeaconReadings | None = None
    pressure: Pressure | None = None
    plans: list[FloorPlan] = field(default_factory=list)
    wifi: WifiScans | None = None
    magnetic: MagneticField | None = None

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Check everything again: the fields are public and may have changed since construction
        (:meth:`save` calls this, so nothing invalid is ever written)."""
        check_name(self.name, "recording name")
        if not isinstance(self.devices, dict) or not self.devices:
            raise ValidationError("recording has no device streams")
        for dev, s in self.devices.items():
            check_name(dev, "device name")
            if not isinstance(s, DeviceStream):
                raise ValidationError(f"device {dev!r} is not a DeviceStream")
        parts: tuple[tuple[str, Any, Any], ...] = (
            ("truth", self.truth, Trajectory),
            ("fixes", self.fixes, Fixes),
            ("beacons", self.beacons, BeaconReadings),
            ("pressure", self.pressure, Pressure),
            ("wifi", self.wifi, WifiScans),
            ("magnetic", self.magnetic, MagneticField),
        )
        for what, part, kind in parts:
            if part is not None and type(part) is not kind and not issubclass(type(part), kind):
                raise ValidationError(f"{what} is not a {kind.__name__}")
            if part is not None and len(part) and all(len(s) for s in self.devices.values()):
                lo, hi = self.t_start - MAX_TIME_OUTSIDE_S, self.t_end + MAX_TIME_OUTSIDE_S
                if part.t[0] < lo or part.t[-1] > hi:
                    raise ValidationError(
                        f"{what}.t spans {part.t[0]:.6g}..{part.t[-1]:.6g} s, far outside the devices' "
                        f"{self.t_start:.6g}..{self.t_end:.6g} s (another clock or a corrupt timestamp?)"
                    )
        if not isinstance(self.plans, list) or not all(isinstance(p, FloorPlan) for p in self.plans):
            raise ValidationError("plans is not a list of FloorPlan")
        self.labels = make_labels(self.labels)
        if not isinstance(self.meta, dict):
            raise ValidationError("meta is not a dict")
        try:
            json.dumps(self.meta)
        except (TypeError, ValueError) as exc:
            raise ValidationError(f"meta is not JSON-serialisable: {exc}") from None

    def _validate_parts(self) -> None:
        for dev, s in self.devices.items():
            try:
                s.validate()
            except ValidationError as exc:
                raise ValidationError(f"device {dev!r}: {exc.reason}") from None
        for part in (self.truth, self.fixes, self.beacons, self.pressure, self.wifi, self.magnetic, *self.plans):
            if part is not None:
                part.validate()

    # ---- time helpers -------------------------------------------------------------------
    @property
    def t_start(self) -> float:
        return min(float(s.t[0]) for s in self.devices.values())

    @property
    def t_end(self) -> float:
        return max(float(s.t[-1]) for s in self.devices.values())

    @property
    def duration(self) -> float:
        return self.t_end - self.t_start

    def label_at(self, kind: str, t: np.ndarray, default: str = "") -> np.ndarray:
        """The label of ``kind`` in force at each time of ``t`` (``default`` where none)."""
        t = np.asarray(t, dtype=np.float64)
        out = np.full(t.shape, default, dtype=object)
        for row in self.labels[self.labels["kind"] == kind].itertuples():
            out[(t >= row.start) & (t < row.end)] = row.value
        return out

    # ---- storage ------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write to one HDF5 file atomically (temporary file in the same folder, then rename)."""
        path = Path(path)
        self.validate()
        self._validate_parts()
        with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
            self._write(f)
        return path

    def _write(self, f: h5py.File) -> None:
        f.attrs["format"] = FORMAT_NAME
        f.attrs["version"] = FORMAT_VERSION
        f.attrs["name"] = self.name
        f.attrs["meta"] = json.dumps(self.meta)
        f.attrs["units"] = (
            "t: s; acc: m/s^2 incl. gravity, device frame; gyro: rad/s; pos: m; quat: w,x,y,z world<-device"
        )
        g = f.create_group("devices")
        for dev, s in self.devices.items():
            d = g.create_group(dev)
            d.create_dataset("t", data=s.t)
            d.create_dataset("acc", data=s.acc, compression="gzip", compression_opts=4)
            for key in ("gyro", "quat"):
                arr = getattr(s, key)
                if arr is not None:
                    d.create_dataset(key, data=arr, compression="gzip", compression_opts=4)
            if s.worn is not None:
                d.create_dataset("worn", data=s.worn)
        if self.truth is not None:
            tr = f.create_group("truth")
            for key in ("t", "pos", "quat", "floor"):
                arr = getattr(self.truth, key)
                if arr is not None:
                    tr.create_dataset(key, data=arr, compression="gzip", compression_opts=4)
        if self.fixes is not None:
            fx = f.create_group("fixes")
            for key in ("t", "pos", "accuracy", "floor"):
                arr = getattr(self.fixes, key)
                if arr is not None:
                    fx.create_dataset(key, data=arr)
        str_t = h5py.string_dtype("utf-8")
        if self.beacons is not None:
            b = f.create_group("beacons")
            b.create_dataset("t", data=self.beacons.t)
            b.create_dataset("beacon", data=self.beacons.beacon, dtype=str_t)
            b.create_dataset("rssi_dbm", data=self.beacons.rssi_dbm)
            for key in ("tx_power_dbm", "distance_m"):
                arr = getattr(self.beacons, key)
                if arr is not None:
                    b.create_dataset(key, data=arr)
        if self.wifi is not None:
            # The text columns as a table of their distinct values and an index per reading: a walk
            # hears a few hundred access points in thousands of readings.
            w = f.create_group("wifi")
            w.create_dataset("t", data=self.wifi.t, compression="gzip", compression_opts=4)
            for key in ("bssid", "ssid"):
                index, names = pd.factorize(getattr(self.wifi, key))
                w.create_dataset(f"{key}_names", data=names.astype(object), dtype=str_t)
                w.create_dataset(f"{key}_index", data=index.astype(np.int32), compression="gzip", compression_opts=4)
            w.create_dataset("freq_mhz", data=self.wifi.freq_mhz, compression="gzip", compression_opts=4)
            w.create_dataset("rssi_dbm", data=self.wifi.rssi_dbm, compression="gzip", compression_opts=4)
            if self.wifi.t_seen is not None:
                w.create_dataset("t_seen", data=self.wifi.t_seen, compression="gzip", compression_opts=4)
        if self.magnetic is not None:
            m = f.create_group("magnetic")
            m.create_dataset("t", data=self.magnetic.t)
            m.create_dataset("ut", data=self.magnetic.ut, compression="gzip", compression_opts=4)
        if self.pressure is not None:
            pr = f.create_group("pressure")
            pr.create_dataset("t", data=self.pressure.t)
            pr.create_dataset("hpa", data=self.pressure.hpa)
        if self.plans:  # one GeoJSON-shaped Feature per floor, as text (readable with h5dump)
            feats = [json.dumps(p.to_feature()) for p in self.plans]
            f.create_dataset("plans", data=np.array(feats, dtype=object), dtype=str_t)
        lab = f.create_group("labels")
        lab.create_dataset("start", data=self.labels["start"].to_numpy(np.float64))
        lab.create_dataset("end", data=self.labels["end"].to_numpy(np.float64))
        lab.create_dataset("kind", data=self.labels["kind"].to_numpy(object), dtype=str_t)
        lab.create_dataset("value", data=self.labels["value"].to_numpy(object), dtype=str_t)

    @classmethod
    def load(cls, path: str | Path) -> Recording:
        """Read a file written by :meth:`save`; any problem raises a WearnavError naming it."""
        path = Path(path)
        require_regular_file(path)
        try:
            with h5py.File(path, "r") as f:
                if f.attrs.get("format") != FORMAT_NAME:
                    raise FormatError("not a wearnav recording (missing 'format' attribute)", path)
                version = f.attrs.get("version")
                if not isinstance(version, (int, np.integer)) or not 1 <= version <= FORMAT_VERSION:
                    raise FormatError(
                        f"recording format version {version!r} is not one this wearnav "
                        f"reads (1..{FORMAT_VERSION}); written by a newer wearnav?",
                        path,
                    )
                return cls._read(f)
        except (FormatError, ValidationError) as exc:
            raise exc.with_source(path) from None
        except OSError as exc:
            raise FormatError(f"cannot read as HDF5 ({exc.__class__.__name__}: {exc})", path) from None
        except KeyError as exc:
            raise FormatError(f"corrupt recording: missing {exc}", path) from None
        except (TypeError, ValueError, AttributeError) as exc:
            # A file with the right 'format' attribute but a wrong layout (a dataset where a
            # group belongs, a meta attribute that is not JSON, text where numbers belong).
            raise FormatError(f"corrupt recording ({exc.__class__.__name__}: {exc})", path) from None

    @classmethod
    def _read(cls, f: h5py.File) -> Recording:
        def opt(g, key):
            return g[key][()] if key in g else None

        def group(parent, key):
            g = parent[key]
            if not isinstance(g, h5py.Group):
                raise FormatError(f"corrupt recording: {g.name!r} is not a group")
            return g

        meta = json.loads(f.attrs["meta"])
        if not isinstance(meta, dict):
            raise FormatError("corrupt recording: the 'meta' attribute is not a JSON object")
        devices = {}
        for dev, d in group(f, "devices").items():
            if not isinstance(d, h5py.Group):
                raise FormatError(f"corrupt recording: device {dev!r} is not a group")
            try:
                # Units were checked when the recording was made; don't refuse to open it.
                devices[dev] = DeviceStream(
                    t=d["t"][()],
                    acc=d["acc"][()],
                    gyro=opt(d, "gyro"),
                    quat=opt(d, "quat"),
                    worn=opt(d, "worn"),
                    check_units=False,
                )
            except ValidationError as exc:
                raise ValidationError(f"device {dev!r}: {exc.reason}") from None
        truth = None
        if "truth" in f:
            g = group(f, "truth")
            truth = Trajectory(g["t"][()], g["pos"][()], opt(g, "quat"), opt(g, "floor"))
        fixes = None
        if "fixes" in f:
            g = group(f, "fixes")
            fixes = Fixes(g["t"][()], g["pos"][()], g["accuracy"][()], opt(g, "floor"))
        beacons = None
        if "beacons" in f:
            g = group(f, "beacons")
            names = [v.decode() if isinstance(v, bytes) else v for v in g["beacon"][()]]
            beacons = BeaconReadings(
                g["t"][()],
                np.array(names, dtype=object),
                g["rssi_dbm"][()],
                opt(g, "tx_power_dbm"),
                opt(g, "distance_m"),
            )
        wifi = None
        if "wifi" in f:
            g = group(f, "wifi")
            text = {}
            for key in ("bssid", "ssid"):
                table = np.array([_text(v) for v in g[f"{key}_names"][()]], dtype=object)
                index = g[f"{key}_index"][()]
                if index.size and (index.min() < 0 or index.max() >= table.size):
                    raise FormatError(f"corrupt recording: wifi/{key}_index points outside wifi/{key}_names")
                text[key] = table[index] if index.size else np.array([], dtype=object)
            wifi = WifiScans(
                g["t"][()], text["bssid"], text["ssid"], g["freq_mhz"][()], g["rssi_dbm"][()], opt(g, "t_seen")
            )
        magnetic = None
        if "magnetic" in f:
            g = group(f, "magnetic")
            magnetic = MagneticField(g["t"][()], g["ut"][()])
        pressure = None
        if "pressure" in f:
            g = group(f, "pressure")
            pressure = Pressure(g["t"][()], g["hpa"][()])
        plans = []
        for text in f["plans"][()] if "plans" in f else []:
            plans.append(FloorPlan.from_feature(json.loads(text.decode() if isinstance(text, bytes) else text)))
        lab = group(f, "labels")
        labels = pd.DataFrame(
            {
                "start": lab["start"][()],
                "end": lab["end"][()],
                "kind": [v.decode() if isinstance(v, bytes) else v for v in lab["kind"][()]],
                "value": [v.decode() if isinstance(v, bytes) else v for v in lab["value"][()]],
            }
        )
        return cls(
            name=str(f.attrs["name"]),
            devices=devices,
            truth=truth,
            fixes=fixes,
            labels=labels,
            meta=meta,
            beacons=beacons,
            pressure=pressure,
            plans=plans,
            wifi=wifi,
            magnetic=magnetic,
        )

    def summary(self) -> dict[str, Any]:
        """A plain dict describing the recording (what ``wearnav info`` prints)."""
        out: dict[str, Any] = {
            "name": self.name,
            "duration_s": round(self.duration, 2),
            "devices": {
                dev: {
                    "samples": len(s),
                    "rate_hz": round(s.rate, 2),
                    "gyro": s.has_gyro,
                    "orientation": s.quat is not None,
                    **({"worn_share": round(float(s.worn.mean()), 3)} if s.worn is not None else {}),
                }
                for dev, s in self.devices.items()
            },
            "truth_points": 0 if self.truth is None else len(self.truth),
            "fixes": 0 if self.fixes is None else len(self.fixes),
            "beacon_readings": 0 if self.beacons is None else len(self.beacons),
            "pressure_readings": 0 if self.pressure is None else len(self.pressure),
            **(
                {"wifi_readings": len(self.wifi), "wifi_access_points": len(set(self.wifi.bssid.tolist()))}
                if self.wifi is not None
                else {}
            ),
            **({"magnetic_readings": len(self.magnetic)} if self.magnetic is not None else {}),
            "plans": [p.name for p in self.plans],
            "labels": {k: sorted(set(g["value"])) for k, g in self.labels.groupby("kind")},
            "meta": self.meta,
        }
        return out
