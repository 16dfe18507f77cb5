"""The phone-only session's update Recording straight from the live buffer's arrays (issue 61 §2):
:func:`lean_recording`, what :class:`wearnav.live.tracker.LiveTracker` asks for before
``SessionBuffer.recording``; tests/test_live_batched.py checks it against the importer's step."""

from __future__ import annotations

import copy

import numpy as np

from wearnav.core import geo
from wearnav.core.rotations import from_wxyz, to_wxyz
from wearnav.core.timeseries import interp_onto
from wearnav.errors import FormatError
from wearnav.importers import sensorlogger_build as slb
from wearnav.importers.common import MAX_INTERP_GAP_S
from wearnav.importers.sensorlogger_map import ORIENTATION_COLS, XYZ, acceleration_convention
from wearnav.live.buffer import MARGIN_S, NS, cut, derived
from wearnav.recording import Fixes, Recording

# The phone-only session's update Recording from the buffer's arrays (issue 61 §2): the importer's
# phone step (:func:`wearnav.importers.sensorlogger_build.build_recording`) for the one input the
# crowd mostly sees (Sensor Logger's Accelerometer + Gravity, Gyroscope, Orientation, Location, the
# quaternion direction decided), without the checks a slice of checked data does not need (the
# DeviceStream's and the Recording's, the quaternion direction's) and without the meta that only
# the whole session's import uses (its own for each slice: rates, gaps, dropped counts; the template's
# are kept). Any other input, or anything the lean step cannot read, goes the importer's way.
_LEAN_FILES = frozenset({"Accelerometer.csv", "Gravity.csv", "Gyroscope.csv", "Orientation.csv", "Location.csv"})
_LEAN_NEEDS = frozenset({"Accelerometer.csv", "Gravity.csv", "Gyroscope.csv", "Orientation.csv"})


def lean_recording(buf, t_from: float, template: Recording) -> Recording | None:
    """``buf.recording(t_from)``'s devices and fixes made straight from ``buf``'s arrays (the block
    comment above), ``template`` (an earlier Recording of the session) giving the rest; None where
    the session is not the phone-only input this handles (the caller asks ``buf.recording``)."""

    direction = getattr(buf, "quat_direction", None)  # decided, or provisional (buffer.RECHECK_S)
    inverted = direction() if direction is not None else None
    if inverted is None or set(template.devices) != {"phone"}:
        return None
    _version, snap = buf._snapshot()
    if not (set(snap) <= _LEAN_FILES and _LEAN_NEEDS <= set(snap)) or buf.t0_unix_ns is None:
        return None
    t0 = int(buf.t0_unix_ns)
    lo = t0 + int(round((t_from - MARGIN_S) * NS))
    tabs = buf._tables(snap, lo)
    if not _LEAN_NEEDS <= set(tabs):
        return None
    acc_t, grav, gyro, ori = (tabs[f] for f in ("Accelerometer.csv", "Gravity.csv", "Gyroscope.csv", "Orientation.csv"))

    def sec(t_ns: np.ndarray) -> np.ndarray:
        return (t_ns - t0).astype(np.float64) * 1e-9

    t = sec(acc_t.t_ns)
    g, keep = interp_onto(t, sec(grav.t_ns), grav.values(XYZ), max_gap=MAX_INTERP_GAP_S)
    acc = acc_t.values(XYZ) + g
    w, ok = interp_onto(t, sec(gyro.t_ns), gyro.values(XYZ), max_gap=MAX_INTERP_GAP_S)
    keep = keep & ok
    try:
        q_src = slb._unit_quats(ori.values(ORIENTATION_COLS), ori.path)
    except FormatError:
        return None
    q, ok = interp_onto(t, sec(ori.t_ns), q_src, max_gap=MAX_INTERP_GAP_S, quaternion=True)
    keep = keep & ok
    if keep.sum() < 2:
        return None
    if not keep.all():
        t, acc, w, q = t[keep], acc[keep], w[keep], q[keep]
    if "phone" in inverted:
        q = to_wxyz(from_wxyz(q).inv())
    s, _ = acceleration_convention(buf.platform, buf.standardised)
    stream = copy.copy(template.devices["phone"])  # no __init__: a slice of checked data (as buffer.sliced)
    stream.t, stream.acc = t, (s * acc).astype(np.float32)
    stream.gyro, stream.quat, stream.worn = np.asarray(w, np.float32), np.asarray(q, np.float32), None
    meta = dict(template.meta)
    meta["t0_unix_ns"] = t0
    fixes = None
    loc = tabs.get("Location.csv")
    if loc is not None:
        motion0 = min(int(x.t_ns[0]) for x in (acc_t, grav, gyro, ori))
        stale = slb.stale_fixes(loc, motion0)
        if stale.any():
            loc = loc.rows(~stale)
        if len(loc.t_ns):
            full_loc = snap["Location.csv"]
            k = buf._first_fresh_row(full_loc, int(min(v[0][0] for f, v in snap.items() if f != "Location.csv")))
            if k is None:
                return None
            lat, lon = (full_loc[2].index(c) for c in ("latitude", "longitude"))
            try:
                fixes, where = _lean_fixes(
                    buf, loc, sec(loc.t_ns), (float(full_loc[1][k, lat]), float(full_loc[1][k, lon]))
                )
            except FormatError:
                return None
            meta.update(where)
    rec = derived(template, {"phone": stream}, fixes)
    rec.meta = meta
    return cut(rec, t_from)


def _lean_fixes(buf, loc, t: np.ndarray, origin: tuple[float, float]) -> tuple[Fixes, dict]:
    """The importer's fixes (:func:`wearnav.importers.sensorlogger_build._fixes`) of ``loc`` in the
    frame at ``origin``, each row's metres converted once: an update's slice holds the last seconds'
    fixes, nearly all of which the previous update converted (``buf.fix_metres``: the rows it
    converted, by sample time). The converter works row by row, so a row's metres are the same
    whichever rows it is converted with (tests/test_live_batched.py compares them bit for bit)."""
    t_ns = loc.t_ns

    def to_local(lat: np.ndarray, lon: np.ndarray, lat0: float, lon0: float) -> np.ndarray:
        pos, had = np.empty((len(lat), 2)), buf.fix_metres
        hit = np.zeros(len(t_ns), bool)
        if had is not None and had[0] == (lat0, lon0) and len(had[1]):
            i = np.minimum(np.searchsorted(had[1], t_ns), len(had[1]) - 1)
            hit = had[1][i] == t_ns
            pos[hit] = had[2][i[hit]]
        if not hit.all():
            pos[~hit] = geo.latlon_to_local(lat[~hit], lon[~hit], lat0, lon0)
        buf.fix_metres = ((lat0, lon0), np.array(t_ns), pos.copy())
        return pos

    return slb._fixes(loc, t, origin, to_local)
