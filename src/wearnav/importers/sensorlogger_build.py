"""Sensor Logger tables → one multi-device Recording: what the CSV importer
(:mod:`wearnav.importers.sensorlogger`) and the live receiver (:mod:`wearnav.live`) both do once they
hold each sensor's rows as a :class:`~wearnav.importers.sensorlogger_map.Table` (names, units and
signs: :mod:`wearnav.importers.sensorlogger_map`).

Phone accelerometer (device ``phone``)
  * ``acc = s * TotalAcceleration`` when ``TotalAcceleration.csv`` exists, else
    ``acc = s * (Accelerometer + Gravity)``, all in m/s² as written. UNITS.md: Accelerometer "`x`, `y`
    and `z` in meters per second squared"; on Android "**Accelerometer.csv**: measures acceleration
    _without_ gravity" and "**TotalAcceleration.csv**: measures acceleration _with_ gravity
    included"; "On iOS, only **Accelerometer.csv** is logged. You may create acceleration with
    gravity by combining the Accelerometer and Gravity sensor readings"; Gravity "in meters per
    second squared". Accelerometer.csv without Gravity.csv or TotalAcceleration.csv is an error:
    there is no gravity to add back; the export's other devices are still imported, and one
    warning line (and ``meta["left_out"]``) says which file was left out and why.
  * The phone's clock is the faster acceleration source: TotalAcceleration.csv, or Accelerometer.csv
    plus Gravity.csv (on Android TotalAcceleration can run at ~59 Hz beside 100 Hz Accelerometer /
    Gravity / Gyroscope / Orientation); ``meta["phone_clock"]`` names the file and every phone
    file's rate.
  * ``gyro = Gyroscope`` rad/s as written. UNITS.md: Gyroscope "in radians per second (rad/s)".
  * Gravity, Gyroscope and Orientation are interpolated onto the accelerometer's timestamps
    (``timeseries.interp_onto``: linear; quaternions sign-aligned, linear, renormalised). README.md: "they
    **do not necessarily align** due to varied sampling rates". Accelerometer samples outside
    another phone file's span, or inside one of its gaps longer than ``common.MAX_INTERP_GAP_S``, are
    dropped, never filled (count in ``meta["dropped_uncovered"]``).


Orientation (phone ``qw,qx,qy,qz``; watch and earbuds ``quaternionW/X/Y/Z``)
  * Read as (w, x, y, z) rotating device-frame vectors into a z-up reference frame (world←device).
    COORDINATES.md: orientation is "a Tait-Bryan Z-X'-Y'' (yaw → pitch → roll) intrinsic rotation
    sequence, meaning the device is first rotated around the z axis (yaw), then the rotated x axis
    (pitch), and finally the twice-rotated y axis (roll)", with "the `x-north-z-vertical` reference
    frame". Rotating the device by those angles is R = Rz·Rx·Ry, whose columns are the device axes
    in the reference frame, i.e. world←device. The yaw reference (north, magnetic or true) is kept
    as it is; the Recording only needs a gravity-aligned frame with a fixed yaw.
  * The docs do not say outright which way the quaternion maps, so every device's quaternions are
    checked against its own data: the accelerometer rotated to the world frame must average to
    about +z (within ``TILT_TOLERANCE_DEG``), and where the gyroscope saw enough rotation, the
    rotation between successive quaternions must agree with it (``MAX_GYRO_RESIDUAL``). If the
    quaternions pass only as their inverse, the inverse is used and ``meta["quat_inverted"]``
    lists the device; if neither passes, the import fails (the usual cause: a wrong ``platform`` /
    ``standardisation`` in Metadata.csv, i.e. a flipped accelerometer sign).
  * ``yaw``, ``pitch`` and ``roll`` are not read: their signs differ between platforms
    (COORDINATES.md, "Differences Between iOS and Android" items 2 and 3).

Location (``Location.csv`` → ``Recording.fixes``)
  * ``latitude`` / ``longitude`` (UNITS.md: "in degrees") are projected to local east/north metres
    about the first fix with :func:`wearnav.core.geo.latlon_to_local` (WGS-84 east-north-up); the origin
    is kept in ``meta["origin_lat"]`` / ``meta["origin_lon"]``, the converter's name in
    ``meta["projection"]``. Fixes are 2-D (altitude is not used).
  * A cached fix from before the recording (negative ``seconds_elapsed``; usually far away with a
    huge accuracy) is dropped (``meta["dropped_stale_fixes"]``): it must not start the clock.
  * ``accuracy = horizontalAccuracy`` m, NaN where negative or absent. UNITS.md: "`horizontalAccuracy`,
    in meters as the radius of uncertainty. ... Negative values indicate it is invalid."

Holes longer than ``REPORT_GAP_S`` in any device's stream (e.g. 10+ s inside a nominally 100 Hz
WristMotion.csv) are listed in ``meta["gaps"]`` with one warning line; the preprocessing masks them.

Sensor Logger records no ground truth: ``truth`` is None and ``labels`` is empty.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Collection
from pathlib import Path

import numpy as np

from wearnav.core import geo
from wearnav.core.rotations import NotUnitQuaternion, from_wxyz, increments, normalize_wxyz, to_wxyz
from wearnav.core.timeseries import interp_onto
from wearnav.errors import FormatError, ValidationError, WearnavError, WearnavWarning
from wearnav.importers.common import MAX_INTERP_GAP_S, check_latlon
from wearnav.importers.sensorlogger_map import (
    DEVICE_FILES,
    ORIENTATION_COLS,
    XYZ,
    Table,
    acceleration_convention,
    quat_cols,
    wearable_acceleration,
    xyz_cols,
)
from wearnav.recording import STANDARD_GRAVITY as G
from wearnav.recording import DeviceStream, Fixes, Recording

SOURCE = "sensorlogger"
# The world-frame mean of a device's specific force must lie this close to +z (gravity).
TILT_TOLERANCE_DEG = 20.0
# Tolerance on the mean world-vertical specific force (real phone data: 9.4–10.1 m/s²).
MAX_VERTICAL_ERROR = 1.5
# The gyroscope check on quaternions runs only after this much integrated rotation (rad).
MIN_ROTATION_FOR_CHECK = 2.0
# Largest relative mismatch between quaternion increments and gyro increments that still passes.
MAX_GYRO_RESIDUAL = 0.5
# The gyro residual leaves out this share of the worst increments (at least 2): a single start-up
# glitch (one quaternion ~1 rad off, seen in real Android Orientation.csv and AirPods
# Headphone.csv) makes two huge increments that would otherwise dominate the sum of squares.
GYRO_RESIDUAL_TRIM = 0.01
# Holes longer than this in a motion stream are reported (meta["gaps"] and a warning); the
# preprocessing masks them (it never interpolates across more than a few sample periods).
REPORT_GAP_S = 1.0
# Acceleration files whose rates differ by less than this fraction count as equally fast.
RATE_TIE = 0.05


class Unusable(FormatError):
    """A device's stream lacks what it needs (gravity, overlap); the export's other devices are
    still imported."""


class VerticalForceError(FormatError):
    """The orientation puts gravity up, but the mean vertical specific force (``vertical``, m/s²) is
    not g: gravity counted twice (~19.6) or missing (~0) over a walk; over a few seconds of hard
    motion (a compass calibration's figure eights) also an orientation that lags the motion (the live
    receiver waits for more data then: :mod:`wearnav.live.buffer`)."""

    def __init__(self, reason: str, source, vertical: float):
        super().__init__(reason, source)
        self.vertical = vertical


def build_recording(
    tables: dict[str, Table],
    platform: str,
    standardised: bool,
    folder: Path,
    name: str,
    file: str,
    info: dict | None = None,
    quat_inverted: Collection[str] | None = None,
    t0_ns: int | None = None,
    origin: tuple[float, float] | None = None,
    unclear: list[str] | None = None,
) -> Recording:
    """One Recording from an export's tables (by file name, e.g. ``"WristMotion.csv"``).

    ``folder`` is what errors and warnings name; ``info`` goes to meta as it is. ``quat_inverted``
    None checks each device's quaternion direction against its data (the module docstring);
    a collection skips the checks and takes those devices' quaternions as inverted, the others'
    as written (the receiver decides once, on enough data, and keeps to it). ``t0_ns`` (ns since the
    epoch) replaces the earliest sample as the time origin and ``origin`` (lat, lon) the first fix as
    the local frame's origin: the receiver's slices of a session keep the session's. ``unclear`` (a
    list) is given the devices whose checked quaternions passed both ways (too little rotation to
    tell: the documented direction taken), so that the receiver knows which checks more data may
    turn."""
    info = info or {}
    s, u = acceleration_convention(platform, standardised)
    units = (
        f"acceleration read as {'m/s²' if standardised else 'g'} because Metadata.csv says "
        f"standardisation is {'on' if standardised else 'off'}"
    )

    t_acc, acc_lin, grav, gyro, ori, loc = (
        tables.get(f)
        for f in (
            "TotalAcceleration.csv",
            "Accelerometer.csv",
            "Gravity.csv",
            "Gyroscope.csv",
            "Orientation.csv",
            "Location.csv",
        )
    )
    wrist, head = tables.get(DEVICE_FILES["watch"]), tables.get(DEVICE_FILES["earbuds"])
    motion = [x for x in (t_acc, acc_lin, grav, gyro, ori, wrist, head) if x is not None]
    if not any(x is not None for x in (t_acc, acc_lin, wrist, head)):
        raise FormatError(
            "no motion file (Accelerometer.csv, TotalAcceleration.csv, WristMotion.csv or Headphone.csv)", folder
        )
    stale = stale_fixes(loc, min(int(x.t_ns[0]) for x in motion)) if loc is not None else None
    if loc is not None and stale is not None and stale.any():
        loc = loc.rows(~stale)
    used = [*motion, *([loc] if loc is not None and len(loc.t_ns) else [])]
    t0 = min(int(x.t_ns[0]) for x in used) if t0_ns is None else int(t0_ns)

    def sec(t_ns: np.ndarray) -> np.ndarray:
        return (t_ns - t0).astype(np.float64) * 1e-9

    inverted: list[str] = []
    unclear = [] if unclear is None else unclear
    uncovered: dict[str, int] = {}
    devices: dict[str, DeviceStream] = {}
    left_out: dict[str, str] = {}
    clock_info: dict = {}

    def phone() -> DeviceStream:
        base, add_gravity = _phone_acceleration(t_acc, acc_lin, grav)
        clock_info.update(
            file=base.path.name,
            rate_hz=round(_rate(base), 2),
            rates_hz={x.path.name: round(_rate(x), 2) for x in (t_acc, acc_lin, grav, gyro, ori) if x is not None},
        )
        t = sec(base.t_ns)
        acc = base.values(XYZ)
        keep = np.ones(len(t), bool)
        w = q = None
        if add_gravity:
            assert grav is not None  # add_gravity: Gravity.csv is there (_phone_acceleration)
            g, ok = interp_onto(t, sec(grav.t_ns), grav.values(XYZ), max_gap=MAX_INTERP_GAP_S)
            acc, keep = acc + g, keep & ok
        if gyro is not None:
            w, ok = interp_onto(t, sec(gyro.t_ns), gyro.values(XYZ), max_gap=MAX_INTERP_GAP_S)
            keep &= ok
        if ori is not None:
            q, ok = interp_onto(
                t,
                sec(ori.t_ns),
                _unit_quats(ori.values(ORIENTATION_COLS), ori.path),
                max_gap=MAX_INTERP_GAP_S,
                quaternion=True,
            )
            keep &= ok
        if keep.sum() < 2:
            others = ", ".join(x.path.name for x in (grav if add_gravity else None, gyro, ori) if x is not None)
            raise Unusable(f"{base.path.name} does not overlap in time with {others}", folder)
        if not keep.all():
            uncovered["phone"] = int((~keep).sum())
            t, acc = t[keep], acc[keep]
            w = None if w is None else w[keep]
            q = None if q is None else q[keep]
        return _stream(
            "phone",
            t,
            s * acc,
            w,
            q,
            base.path,
            ori.path if ori else None,
            "phone acceleration is m/s² in every export (UNITS.md)",
            inverted,
            quat_inverted,
            unclear,
        )

    def wearable(dev: str, tab) -> DeviceStream:
        acc = wearable_acceleration(dev, tab.values(xyz_cols("acceleration")), tab.values(xyz_cols("gravity")), s, u)
        return _stream(
            dev,
            sec(tab.t_ns),
            acc,
            tab.values(xyz_cols("rotationRate")),
            _unit_quats(tab.values(quat_cols()), tab.path),
            tab.path,
            tab.path,
            units,
            inverted,
            quat_inverted,
            unclear,
        )

    def watch() -> DeviceStream:
        return wearable("watch", wrist)

    def earbuds() -> DeviceStream:
        return wearable("earbuds", head)

    # Each device on its own: a stream that lacks what it needs (Unusable) leaves the others
    # importable (one warning line); only when none is usable does the import fail, with the first
    # device's reason. A failed plausibility check stays fatal: it usually means a wrong
    # Metadata.csv, which concerns every device.
    errors: list[WearnavError] = []
    for dev, present, build in (
        ("phone", t_acc is not None or acc_lin is not None, phone),
        ("watch", wrist is not None, watch),
        ("earbuds", head is not None, earbuds),
    ):
        if not present:
            continue
        try:
            devices[dev] = build()
        except Unusable as exc:
            errors.append(exc)
            left_out[dev] = str(exc)
    if not devices:
        raise errors[0]
    if left_out:
        warnings.warn(
            WearnavWarning(
                f"{folder}: imported {', '.join(devices)} only; left out "
                + "; ".join(f"{d} ({r})" for d, r in left_out.items())
            ),
            stacklevel=2,
        )
    gaps = {dev: g for dev, st in devices.items() if (g := _gaps(st.t))}
    if gaps:
        warnings.warn(
            WearnavWarning(
                f"{folder}: "
                + "; ".join(
                    f"{dev} has {len(g)} gap(s) over {REPORT_GAP_S:g} s (longest {max(b - a for a, b in g):.1f} s)"
                    for dev, g in gaps.items()
                )
                + "; they are masked, never interpolated"
            ),
            stacklevel=2,
        )

    meta = {
        "source": SOURCE,
        "dataset": "Sensor Logger export",
        "subject": "",
        "mode": "",
        "placement": "",
        "platform": platform,
        "standardisation": standardised,
        **info,
        "t0_unix_ns": t0,
        "quat_frame": "Sensor Logger orientation, world z up; phone yaw 0 with x north (iOS true, "
        "Android magnetic north); watch / earbuds yaw reference not documented",
        "quat_inverted": inverted,
        "dropped_duplicates": {x.path.name: x.duplicates for x in used if x.duplicates},
        "dropped_uncovered": uncovered,
        "file": file,
    }
    if "phone" in devices:
        meta["phone_clock"] = clock_info
    if left_out:
        meta["left_out"] = left_out
    if gaps:
        meta["gaps"] = gaps
    if stale is not None and stale.any():
        meta["dropped_stale_fixes"] = int(stale.sum())
    if "earbuds" in devices and head is not None and head.has("devicelocation"):
        sides = head.text("devicelocation").dropna().astype(str)
        if len(sides):
            meta["earbud_side"] = str(sides.mode().iloc[0])
    fixes = None
    if loc is not None and len(loc.t_ns):
        fixes, where = _fixes(loc, sec(loc.t_ns), origin)
        meta.update(where)
    return Recording(name=name, devices=devices, fixes=fixes, meta=meta)


def _rate(x: Table) -> float:
    dt = np.diff(x.t_ns) * 1e-9
    return float(1.0 / np.median(dt)) if dt.size else 0.0


def _phone_acceleration(t_acc: Table | None, acc_lin: Table | None, grav: Table | None) -> tuple[Table, bool]:
    """The phone's acceleration clock: TotalAcceleration.csv as written, or Accelerometer.csv plus
    Gravity.csv (interpolated onto it), whichever is faster (on a tie the total, which needs no
    interpolation). On Android TotalAcceleration.csv can run at ~59 Hz while Accelerometer,
    Gravity, Gyroscope and Orientation run at 100 Hz; the chosen file is ``meta["phone_clock"]``."""
    if acc_lin is None or grav is None:  # no Accelerometer.csv + Gravity.csv: the total or nothing
        if t_acc is not None:
            return t_acc, False
        assert acc_lin is not None  # the phone is built only where one acceleration file is there
        raise Unusable(
            "holds acceleration without gravity (UNITS.md) and neither Gravity.csv nor "
            "TotalAcceleration.csv is there to add it back",
            acc_lin.path,
        )
    if t_acc is not None and not _rate(acc_lin) > (1 + RATE_TIE) * _rate(t_acc):
        return t_acc, False
    return acc_lin, True


def stale_fixes(loc: Table, t_motion_ns: int) -> np.ndarray:
    """Fixes from before the recording: a cached first fix that the app writes with a negative
    ``seconds_elapsed`` (README.md: negative entries come from "buffering or caching"), often far
    away and with a huge accuracy. Without that column, fixes more than 1 s before the first motion
    sample. They are dropped (count in ``meta["dropped_stale_fixes"]``) so they neither start the
    recording's clock nor set the local origin."""
    if loc.has("seconds_elapsed"):
        se = loc.numeric("seconds_elapsed")
        return np.isfinite(se) & (se < 0)
    return loc.t_ns < t_motion_ns - 1_000_000_000


def _gaps(t: np.ndarray) -> list[list[float]]:
    """[start, end] (s) of every hole longer than REPORT_GAP_S."""
    d = np.diff(t)
    i = np.flatnonzero(d > REPORT_GAP_S)
    return [[round(float(t[k]), 3), round(float(t[k + 1]), 3)] for k in i]


def _unit_quats(q: np.ndarray, path: Path) -> np.ndarray:
    try:
        return normalize_wxyz(q)
    except NotUnitQuaternion as exc:
        raise FormatError(
            f"quaternion at line {exc.row + 2} has norm {exc.norm:.3g}, not a unit quaternion", path
        ) from None


def _stream(
    dev: str,
    t,
    acc,
    gyro,
    quat,
    path: Path,
    qpath: Path | None,
    units: str,
    inverted: list[str],
    forced: Collection[str] | None = None,
    unclear: list[str] | None = None,
) -> DeviceStream:
    try:
        stream = DeviceStream(t=t, acc=acc, gyro=gyro, quat=None)
    except ValidationError as exc:
        raise FormatError(f"device {dev!r}: {exc.reason}; {units}", path) from None
    if quat is not None:
        if forced is not None:
            convention = "device<-world (inverted on import)" if dev in forced else "world<-device"
            quat = to_wxyz(from_wxyz(quat).inv()) if dev in forced else quat
        else:
            assert qpath is not None  # an orientation comes from a file
            quat, convention, clear = _check_orientation(quat, acc, gyro, t, qpath)
            if not clear and unclear is not None:
                unclear.append(dev)
        if convention != "world<-device":
            inverted.append(dev)
        stream.quat = quat
        stream.validate()
    return stream


def _check_orientation(
    q_wxyz: np.ndarray, acc: np.ndarray, gyro: np.ndarray | None, t: np.ndarray, path: Path
) -> tuple[np.ndarray, str, bool]:
    """Pick the quaternion direction the data agrees with (see module docstring), or fail; and
    whether the data told the two apart (False: both passed).

    A direction passes when the world-frame mean of the specific force lies within
    TILT_TOLERANCE_DEG of +z and, where the gyro saw enough rotation, the quaternions' rotation
    increments match the gyro's (relative residual <= MAX_GYRO_RESIDUAL). When both directions
    pass (a device that stays nearly upright), the one with the smaller gyro residual wins,
    the documented world←device reading on a tie.
    """
    rot = from_wxyz(q_wxyz)
    found = []
    for label, r, inverse in (
        ("world<-device", rot, False),
        ("device<-world (inverted on import)", rot.inv(), True),
    ):
        mean_world = r.apply(acc).mean(axis=0)
        tilt = float(np.degrees(np.arccos(np.clip(mean_world[2] / np.linalg.norm(mean_world), -1, 1))))
        res = _gyro_residual(q_wxyz, inverse, gyro, t)
        ok = tilt <= TILT_TOLERANCE_DEG and (res is None or res <= MAX_GYRO_RESIDUAL)
        found.append((ok, res if res is not None else 0.0, label, r, tilt, res))
    passing = [f for f in found if f[0]]
    if passing:
        _, _, label, r, _, _ = min(passing, key=lambda f: f[1])  # stable: world<-device on a tie
        # Over a walk the mean vertical specific force is g; gravity counted twice (an
        # acceleration column that already holds it) or not at all shows up here even when the
        # median |acc| looks plausible.
        vertical = float(r.apply(acc)[:, 2].mean())
        if abs(vertical - G) > MAX_VERTICAL_ERROR:
            raise VerticalForceError(
                f"mean vertical specific force in the world frame is {vertical:.1f} m/s², expected "
                f"{G:.1f} (gravity counted twice or missing?)",
                path,
                vertical,
            )
        return to_wxyz(r), label, len(passing) == 1
    (_, _, _, _, tilt_a, res_a), (_, _, _, _, tilt_b, res_b) = found
    gyro_note = "" if res_a is None else f", gyro residual {res_a:.2f} ({res_b:.2f} inverse)"
    if min(tilt_a, tilt_b) <= TILT_TOLERANCE_DEG:
        # Gravity agrees, so the acceleration sign (platform / standardisation) is right; what
        # disagrees is the orientation with the gyroscope.
        raise FormatError(
            f"orientation does not follow the gyroscope: its rotation between samples differs from "
            f"the gyroscope's by {res_a:.2f} of it ({res_b:.2f} with the inverse rotation), over "
            f"{MAX_GYRO_RESIDUAL:g} either way, although gravity agrees with it "
            f"({min(tilt_a, tilt_b):.0f}° from up); the orientation or gyroscope column is unusable",
            path,
        )
    raise FormatError(
        f"orientation does not fit the accelerometer: gravity rotated to the world frame is "
        f"{tilt_a:.0f}° from up ({tilt_b:.0f}° with the inverse rotation){gyro_note}; is "
        f"Metadata.csv's platform / standardisation right?",
        path,
    )


def _gyro_residual(q_wxyz: np.ndarray, inverse: bool, gyro: np.ndarray | None, t: np.ndarray) -> float | None:
    """Σ|Δθ_quat − Δθ_gyro|² / Σ|Δθ_gyro|² over successive samples (body-frame increments of the
    quaternions ``q_wxyz``, ``inverse``: of their inverses), leaving out the worst
    GYRO_RESIDUAL_TRIM of the increments (at least 2) from both sums.

    Near 0 when the quaternions are world←device and agree with the gyro; None when there is
    no gyro or too little rotation to tell. The trimmed sums make one glitched quaternion (two
    increments of ~1 rad) irrelevant, while the wrong direction disagrees at most samples.
    """
    if gyro is None or len(t) < 3:
        return None
    dt = np.diff(t)
    step = dt <= 2 * np.median(dt)  # across a gap the two increments need not match
    inc = increments(q_wxyz, inverse)[step]
    w = 0.5 * (gyro[:-1] + gyro[1:])[step] * dt[step, None]
    if np.linalg.norm(w, axis=1).sum() < MIN_ROTATION_FOR_CHECK:
        return None
    err = np.sum((inc - w) ** 2, axis=1)
    n_drop = min(max(2, int(GYRO_RESIDUAL_TRIM * err.size)), err.size - 1)
    keep = np.argsort(err)[: err.size - n_drop]
    return float(np.sum(err[keep]) / np.sum(w[keep] ** 2))


def _fixes(
    loc: Table, t: np.ndarray, origin: tuple[float, float] | None = None, to_local: Callable | None = None
) -> tuple[Fixes, dict]:
    """The fixes of ``loc`` in metres about ``origin`` (default: its first fix); ``to_local`` in place of
    :func:`wearnav.core.geo.latlon_to_local` (the live tracker's, which reuses the rows it converted)."""
    lat, lon = loc.column("latitude"), loc.column("longitude")
    check_latlon(lat, lon, "Location", loc.path)
    if loc.has("horizontalAccuracy"):
        accuracy = loc.column("horizontalAccuracy")
        accuracy = np.where(accuracy >= 0, accuracy, np.nan)  # negative = invalid (UNITS.md)
    else:
        accuracy = np.full(len(t), np.nan)
    lat0, lon0 = (float(lat[0]), float(lon[0])) if origin is None else origin
    pos = (to_local or geo.latlon_to_local)(lat, lon, lat0, lon0)
    try:
        fixes = Fixes(t=t, pos=pos, accuracy=accuracy)
    except ValidationError as exc:
        raise FormatError(exc.reason, loc.path) from None
    return fixes, {"origin_lat": lat0, "origin_lon": lon0, "projection": geo.PROJECTION}


__all__ = ["REPORT_GAP_S", "Unusable", "build_recording", "stale_fixes"]
