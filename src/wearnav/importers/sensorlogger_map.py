"""The one mapping of Sensor Logger's sensors onto wearnav's devices, units and signs.

The CSV importer (:mod:`wearnav.importers.sensorlogger`), the export writer
(:mod:`wearnav.importers.sensorlogger_export`) and the live receiver (:mod:`wearnav.live`) all take
sensor names, columns, devices, units and signs from here, so that they cannot disagree. An export
names a sensor by its file (``WristMotion.csv``); HTTP Push and MQTT name it by ``name`` with its
columns nested under ``values`` (UNITS.md: "the HTTP Push and MQTT payloads instead use `name`, nest
the fields under `values`, and have no `seconds_elapsed`"): :data:`PUSH_NAMES` maps one onto the other.

Unit and frame conversions, each with the line of the Sensor Logger documentation it rests on
(``UNITS.md`` / ``COORDINATES.md`` of tszheichoi/awesome-sensor-logger at b10f5c5, copied to
``shared/data/sensor_logger_format``; ``README.md`` and ``CROSSPLATFORM.md`` of the same repository
where noted). "The Recording convention" is specific force including gravity, m/s², device frame,
reading about +9.81 on z for a device lying screen-up on a table.

Sign convention of accelerations (``s = -1`` flips, ``s = +1`` keeps)
  * Android is the Recording convention. COORDINATES.md: "When you place your phone flat on a table,
    the gravity vector points in `-z` on iOS and `+z` on Android", and "there is a negative sign
    difference for all three axes between iOS and Android" for acceleration.
  * ``s = -1`` for iOS exports made with "Standardise Units & Frames" off, ``s = +1`` otherwise.
    COORDINATES.md: "Toggling **Standardise Units & Frames** ... will eliminate this difference by
    automatically converting values logged on iOS to the Android convention".
  * ``watchos`` (an export recorded on the Apple Watch alone, layout version 4) is read as iOS:
    the watch follows the iPhone's convention (below).
  * Both facts come from ``Metadata.csv``; without it the import fails unless ``platform`` is
    given (``wearnav import sensorlogger --platform``), and standardisation is then read as off.
    A push carries neither: the receiver takes them from the push URL or decides them from the data
    (:mod:`wearnav.live.buffer`). ``platform``: README.md, "Accessing Recording Metadata":
    "platform: Either iOS or Android". ``standardisation`` (true / false) is not in the
    documentation; it is the column name real exports carry (header ``version,device name,
    recording epoch time,recording time,recording timezone,platform,appVersion,device id,sensors,
    sampleRateMs,standardisation,platform version``). An export without it predates the toggle
    (version 1.29) and is read as off (CROSSPLATFORM.md: "This is _turned off_ by default").
  * Apple Watch and AirPods get the same ``s`` as the iPhone. COORDINATES.md: "Acceleration data from
    the Apple Watch follows the same convention as the iPhone", "The coordinate system across the
    three pictured devices is always the same and consistent", and the toggle "will convert _all
    measurements from Apple Watch and AirPods_ to Android's convention". (A Wear OS watch on an
    Android export is assumed to report the Android convention: ``s = +1``; undocumented.)
  * Rotation rates are never flipped. COORDINATES.md: "For the rotation rate readings from the
    Gyroscope sensor, iOS and Android have consistent definitions." The device axes themselves are
    the same on both platforms ("the directions of the axes are the same across platforms").

Phone: its own files are m/s² whatever the toggle, so only ``s`` applies (the assembly, with the
phone's clock and gravity, is :mod:`wearnav.importers.sensorlogger_build`'s).

Apple Watch (``WristMotion.csv`` → device ``watch``)
  * ``acc = s * u * (acceleration + gravity)`` with ``u = 9.80665`` when the toggle is off, ``u = 1``
    when on. UNITS.md, WristMotion: "`gravityX`, `gravityY` and `gravityZ`, in standard gravity (g),
    when "Standardise Units & Frames" is off (default). The unit is ms-2 when ... on" and the same
    sentence for `accelerationX/Y/Z`; ``acceleration`` is the user part (the file reports gravity
    separately, as CoreMotion's device motion does). 9.80665: UNITS.md "Assumes `g` to be 9.80665ms-2".
  * ``gyro = rotationRate`` rad/s. UNITS.md: "`rotationRateX`, ... in radians per second (rad/s)".

AirPods (``Headphone.csv`` → device ``earbuds``)
  * ``acc = s * (u * acceleration + gravity)``. UNITS.md, Headphone: "`accelerationX`, ... in standard
    gravity (g), when "Standardise Units & Frames" is off (default). The unit is ms-2 when ... on"
    and "`gravityX`, `gravityY` and `gravityZ`, in meters per second squared (ms-2); Assumes `g` to
    be 9.80665ms-2, regardless of whether "Standardise Units & Frames" is turned on or not".
  * ``gyro = rotationRate`` rad/s (UNITS.md: "in radians per second (rad/s)"). ``devicelocation``
    (left / right) goes to ``meta["earbud_side"]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.recording import STANDARD_GRAVITY as G  # UNITS.md: "Assumes `g` to be 9.80665ms-2"

XYZ = ["x", "y", "z"]
ORIENTATION_COLS = ["qw", "qx", "qy", "qz"]
DEVICE_FILES = {"watch": "WristMotion.csv", "earbuds": "Headphone.csv"}  # the phone's are its own files
# UNITS.md: WristMotion's gravity follows the units toggle (g when off), Headphone's is m/s² always.
GRAVITY_IN_G = {"watch": True, "earbuds": False}
MOTION_FILES = ("Accelerometer.csv", "TotalAcceleration.csv", *DEVICE_FILES.values())
KNOWN_FILES = ("Metadata.csv", "Gravity.csv", "Gyroscope.csv", "Orientation.csv", "Location.csv", *MOTION_FILES)
# Platforms Metadata.csv names; a watch-only export says watchos and follows the iPhone's sign.
PLATFORMS = ("ios", "watchos", "android")
APPLE = ("ios", "watchos")


def xyz_cols(prefix: str) -> list[str]:
    return [f"{prefix}{a}" for a in "XYZ"]


def quat_cols() -> list[str]:
    return [f"quaternion{a}" for a in "WXYZ"]


WEARABLE_COLS = [*xyz_cols("rotationRate"), *xyz_cols("gravity"), *xyz_cols("acceleration"), *quat_cols()]


@dataclass(frozen=True)
class Sensor:
    """One sensor: its export file, the device it belongs to, the numeric columns read (required)
    and those read where present (other columns, e.g. Headphone's ``devicelocation``, pass as text)."""

    file: str
    device: str | None  # None: location fixes
    cols: tuple[str, ...]
    optional: tuple[str, ...] = ()


# Push ``name`` → sensor (the export file's name, lower case, as the app streams it). Any other
# name (magnetometer, barometer, battery, ...) is stored by the receiver and ignored.
PUSH_NAMES: dict[str, Sensor] = {
    "totalacceleration": Sensor("TotalAcceleration.csv", "phone", tuple(XYZ)),
    "accelerometer": Sensor("Accelerometer.csv", "phone", tuple(XYZ)),
    "gravity": Sensor("Gravity.csv", "phone", tuple(XYZ)),
    "gyroscope": Sensor("Gyroscope.csv", "phone", tuple(XYZ)),
    "orientation": Sensor("Orientation.csv", "phone", tuple(ORIENTATION_COLS)),
    "wrist motion": Sensor(DEVICE_FILES["watch"], "watch", tuple(WEARABLE_COLS)),
    "headphone": Sensor(DEVICE_FILES["earbuds"], "earbuds", tuple(WEARABLE_COLS)),
    "location": Sensor("Location.csv", None, ("latitude", "longitude"), ("horizontalAccuracy", "seconds_elapsed")),
}
SENSORS: dict[str, Sensor] = {s.file: s for s in PUSH_NAMES.values()}  # by export file name


def acceleration_convention(platform: str, standardised: bool) -> tuple[float, float]:
    """(sign, unit) of an export's acceleration: m/s² in wearnav's (Android) sign = sign × unit ×
    the value written. iOS / watchOS without "Standardise Units & Frames" write the opposite sign
    (CROSSPLATFORM.md) and the wearables' acceleration in g (UNITS.md); the phone's own files are
    m/s² always (their unit is not applied to them)."""
    sign = -1.0 if (platform in APPLE and not standardised) else 1.0
    return sign, (1.0 if standardised else G)


def wearable_acceleration(device: str, user: np.ndarray, gravity: np.ndarray, sign: float, unit: float) -> np.ndarray:
    """Specific force (m/s², Recording convention) of the watch or earbuds from the user
    acceleration and gravity columns as written: ``sign × (unit × user + unit_g × gravity)``, with
    ``unit_g = unit`` where the file writes gravity in g (the watch) and 1 where in m/s² (earbuds)."""
    unit_g = unit if GRAVITY_IN_G[device] else 1.0
    return sign * (unit * user + unit_g * gravity)


@dataclass
class Table:
    """One sensor's rows, by sample time: from an export's CSV file or the receiver's messages."""

    path: Path  # what errors name (the file, or the live session's sensor)
    t_ns: np.ndarray  # int64 ns since epoch, strictly increasing
    df: pd.DataFrame
    duplicates: int

    def values(self, cols: list[str]) -> np.ndarray:
        return self.df[cols].to_numpy(np.float64)

    def has(self, col: str) -> bool:
        return col in self.df.columns

    def column(self, col: str) -> np.ndarray:
        return self.df[col].to_numpy(np.float64)

    def numeric(self, col: str) -> np.ndarray:
        """``col`` as float64, NaN where a value is not a number."""
        return pd.to_numeric(self.df[col], errors="coerce").to_numpy(np.float64)

    def text(self, col: str) -> pd.Series:
        return self.df[col]

    def rows(self, keep: np.ndarray) -> Table:
        """The rows where ``keep`` (bool) is True."""
        return Table(self.path, self.t_ns[keep], self.df[keep].reset_index(drop=True), self.duplicates)


__all__ = [
    "APPLE",
    "DEVICE_FILES",
    "GRAVITY_IN_G",
    "KNOWN_FILES",
    "MOTION_FILES",
    "ORIENTATION_COLS",
    "PLATFORMS",
    "PUSH_NAMES",
    "SENSORS",
    "Sensor",
    "Table",
    "XYZ",
    "acceleration_convention",
    "quat_cols",
    "wearable_acceleration",
    "xyz_cols",
]
