"""One Sensor Logger push body, parsed and checked before anything is stored.

The body is exactly what the app sends by HTTP Push and MQTT (PUSHING.md of
tszheichoi/awesome-sensor-logger)::

    {"messageId": 0, "sessionId": "...", "deviceId": "...",
     "payload": [{"name": "accelerometer", "time": <UTC epoch ns>, "values": {"x": ..., ...}}, ...]}

Every rule below turns a bad body into one :class:`BadPush` (an HTTP status and one line), so
that the receiver answers 4xx and stores nothing of it:

* not UTF-8 JSON, or JSON holding ``NaN`` / ``Infinity`` (or a number too large for a float) → 400;
* a field of the wrong type or missing; a payload entry without a ``name`` (str) and a ``time``
  (int, ns); a sensor this receiver reads (:data:`wearnav.importers.sensorlogger_map.PUSH_NAMES`)
  whose ``values`` is not a flat object holding its numeric columns → 422;
* a value no sensor reports: an acceleration or gravity over ``ACC_RAW_MAX``, a rotation rate
  over 2000 °/s, a quaternion whose norm is not 1, a latitude / longitude out of range, an
  accuracy radius over 2·10⁷ m → 422 (stored, one would make the session's Recording fail);
* a sample time more than ``max_future_s`` ahead of the server's clock or more than ``max_age_s``
  behind it → 422;
* a ``sessionId`` / ``deviceId`` that is not 1–128 of ``A-Z a-z 0-9 _ . : -`` or starts with a dot
  (it names rows and exported files; nothing with a path separator or ``..`` gets in) → 422.

Unknown sensor names (magnetometer, battery, camera, ...) pass with any JSON ``values``: they are
stored and ignored.

The cost (issue 61): a body is read by orjson and checked as arrays, one sensor at a time
(:func:`_fast`: the times, the columns and every rule above as numpy operations over the body),
and what passes is handed on as those arrays (:attr:`Push.columns`), which the session buffer
appends as they are. Whatever the fast reading cannot accept for certain (anything refused, a float
time, a column some rule reads that the sensor does not have, orjson's own refusals) is read again
by the rules one sample at a time (:func:`_slow`), whose answer is the one given: the fast path only
ever accepts bodies the per-sample rules accept, with the same samples (a test compares them on
fuzzed bodies), so the 4xx reasons are those of the per-sample rules.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from itertools import chain
from operator import itemgetter

import numpy as np
import orjson

from wearnav.core.rotations import UNIT_NORM_TOL
from wearnav.importers.sensorlogger_map import ORIENTATION_COLS, PUSH_NAMES, Sensor, quat_cols
from wearnav.recording import ACC_AXIS_MAX, GYRO_AXIS_MAX
from wearnav.recording.checks import POS_ABS_MAX

ID_RE = re.compile(r"[A-Za-z0-9_.:-]{1,128}")
MAX_NAME_LEN = 64
# A raw acceleration or gravity value: half the Recording's limit, so that user acceleration plus
# gravity stays within it (in m/s²; a wearable writing g stays far below in any case).
ACC_RAW_MAX = ACC_AXIS_MAX / 2
MAX_INT = 10**300  # larger JSON integers are refused as not finite (float() would overflow)
NS = 1_000_000_000
TEXT_COLS = {"Headphone.csv": "devicelocation"}  # a known sensor's column kept as text (the earbud's side)
ACC_NAMES = ("accelerometer", "totalacceleration", "gravity")  # their x, y, z are accelerations


class BadPush(Exception):
    """A body the receiver refuses: ``status`` (4xx) and one line saying why."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status
        self.message = message


@dataclass
class Columns:
    """One sensor's samples of one message, as arrays: ``t`` (n,) int64 ns, ``v`` (n, k) float64 in
    the sensor's ``[*cols, *optional]`` order (NaN where a sample has no number), the optional
    columns some sample holds (``seen``), and the text column where the sensor has one."""

    t: np.ndarray
    v: np.ndarray
    seen: frozenset = frozenset()
    text: list | None = None


@dataclass
class Push:
    session_id: str
    device_id: str
    message_id: int
    payload: list[dict]
    # the known sensors' samples by export file name (what the buffer keeps), and the samples of
    # sensors this receiver does not read, by name
    columns: dict[str, Columns] = field(default_factory=dict)
    ignored: dict[str, int] = field(default_factory=dict)


def _no_constant(name: str):
    raise BadPush(400, f"the body holds {name}, which is not a number in JSON (NaN / inf are refused)")


def check_id(value, field: str) -> str:
    if not isinstance(value, str):
        raise BadPush(422, f"{field} must be a string")
    if not ID_RE.fullmatch(value) or value.startswith("."):
        raise BadPush(422, f"{field} must be 1-128 of A-Z a-z 0-9 _ . : - and not start with a dot")
    return value


def _is_int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _sample_time(x, k: int) -> int:
    """ns since the epoch: an integer, or a float that the app's JavaScript wrote for one."""
    if _is_int(x):
        return x
    if isinstance(x, float) and math.isfinite(x):
        return int(round(x))
    raise BadPush(422, f"payload[{k}].time must be an integer (ns since the epoch)")


def _finite(x, where: str) -> None:
    """No inf anywhere in ``x`` (``1e999`` parses as inf; NaN / Infinity are refused at parsing)."""
    if isinstance(x, float) and not math.isfinite(x):
        raise BadPush(400, f"{where} is not finite")
    if isinstance(x, int) and not isinstance(x, bool) and abs(x) > MAX_INT:  # no float holds it
        raise BadPush(400, f"{where} is not finite (an integer of {len(str(abs(x)))} digits)")
    if isinstance(x, dict):
        for key, v in x.items():
            _finite(v, f"{where}.{key}")
    elif isinstance(x, list):
        for i, v in enumerate(x):
            _finite(v, f"{where}[{i}]")


def _check_values(values, name: str, k: int) -> None:
    """A sensor this receiver reads: ``values`` a flat object with its numeric columns. Any other
    sensor: whatever JSON the app sends (stored, ignored), finite."""
    _finite(values, f"payload[{k}].values")
    sensor = PUSH_NAMES.get(name)
    if sensor is None:
        return
    if not isinstance(values, dict):
        raise BadPush(422, f"payload[{k}].values must be an object")
    for key, v in values.items():
        if not (v is None or isinstance(v, (int, float, str, bool))):
            raise BadPush(422, f"payload[{k}].values.{key} must be a number, string, boolean or null")
    for col in sensor.cols:
        v = values.get(col)
        if not (isinstance(v, (int, float)) and not isinstance(v, bool)):
            raise BadPush(422, f"payload[{k}] ({name}) needs a number in values.{col}")
    for col in sensor.optional:
        v = values.get(col)
        if v is not None and not (isinstance(v, (int, float)) and not isinstance(v, bool)):
            raise BadPush(422, f"payload[{k}] ({name}) values.{col} must be a number or absent")
    _plausible(values, name, k)


def _plausible(values: dict, name: str, k: int) -> None:
    """Values no sensor reports (beyond the Recording's limits, whatever the session's units) are
    refused here: once stored, one would make every later Recording of the session fail."""

    def bad(col: str, why: str):
        raise BadPush(422, f"payload[{k}] ({name}) values.{col} = {values[col]:g} is {why}")

    for col, v in values.items():
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            continue
        if (col in "xyz" and name in ("accelerometer", "totalacceleration", "gravity")) or col.startswith(
            ("acceleration", "gravity")
        ):
            if abs(v) > ACC_RAW_MAX:
                bad(col, f"beyond any acceleration ({ACC_RAW_MAX:.0f}, half of 16 g in m/s²)")
        elif (col in "xyz" and name == "gyroscope") or col.startswith("rotationRate"):
            if abs(v) > GYRO_AXIS_MAX:
                bad(col, f"beyond any rotation rate ({GYRO_AXIS_MAX:.1f} rad/s)")
    quat = ORIENTATION_COLS if name == "orientation" else quat_cols() if name in ("wrist motion", "headphone") else None
    if quat is not None:
        norm = math.hypot(*(float(values[c]) for c in quat))  # no overflow for 1e300
        if abs(norm - 1.0) > UNIT_NORM_TOL:
            raise BadPush(422, f"payload[{k}] ({name}) quaternion has norm {norm:.3g}, not 1")
    if name == "location":
        if abs(values["latitude"]) > 90 or abs(values["longitude"]) > 180:
            raise BadPush(422, f"payload[{k}] (location) latitude/longitude out of range")
        acc = values.get("horizontalAccuracy")
        if isinstance(acc, (int, float)) and acc > POS_ABS_MAX:
            bad("horizontalAccuracy", "not an accuracy radius")


def _days(ns: int) -> str:
    """A time span (ns, any size: a corrupt time may be a 300-digit integer) in days, as text."""
    days = ns // (86400 * NS)
    return f"{ns / (86400 * NS):.3g}" if days < 10**6 else "over a million"


def parse(body: bytes, now_ns: int, max_future_s: float, max_age_s: float) -> Push:
    """The checked push in ``body`` (module docstring), or :class:`BadPush`."""
    lo, hi = now_ns - int(max_age_s * NS), now_ns + int(max_future_s * NS)
    push = _fast(body, lo, hi)
    if push is None:
        push = _slow(body, now_ns, max_future_s, max_age_s)
        push.columns, push.ignored = columns_of(push.payload)
    return push


def parse_stored(body: str | bytes) -> Push:
    """A body the receiver stored (so it passed :func:`parse` when it arrived), read again, as a
    tracker process or a restarted receiver reads it: any sample time is taken. Read without the
    rules (:func:`_stored`; issue 61: they were half of a tracker process's 0.23 ms a body), or
    where it is not of the shape they let through, as :func:`parse` reads it."""
    raw = body.encode("utf-8") if isinstance(body, str) else body
    push = _stored(raw)
    if push is None:
        push = _fast(raw, -(2**63), 2**63 - 1)
    if push is None:
        push = _slow(raw, 0, 1e30, 1e30)
        push.columns, push.ignored = columns_of(push.payload)
    return push


def columns_of(payload: list[dict]) -> tuple[dict[str, Columns], dict[str, int]]:
    """A checked payload's samples as :class:`Columns` per known sensor (one sample at a time: the
    way the buffer read a payload before :func:`_fast`), and the unknown sensors' sample counts."""
    rows: dict[str, list[dict]] = {}
    ignored: dict[str, int] = {}
    for item in payload:
        sensor = PUSH_NAMES.get(item["name"])
        if sensor is None:
            ignored[item["name"]] = ignored.get(item["name"], 0) + 1
            continue
        rows.setdefault(sensor.file, []).append(item)
    out = {}
    for fname, items in rows.items():
        spec = PUSH_NAMES[items[0]["name"]]
        cols = [*spec.cols, *spec.optional]
        t = np.fromiter((it["time"] for it in items), np.int64, len(items))
        v = np.array([[_num(it["values"].get(c)) for c in cols] for it in items], np.float64).reshape(-1, len(cols))
        seen = frozenset(c for c in spec.optional if any(c in it["values"] for it in items))
        tc = TEXT_COLS.get(fname)
        out[fname] = Columns(t, v, seen, [it["values"].get(tc) for it in items] if tc else None)
    return out, ignored


def _num(x) -> float:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) else math.nan


_NUMBER = frozenset((int, float))
_OPTIONAL = frozenset((int, float, type(None)))
_SCALAR = frozenset((int, float, str, bool, type(None)))
_TIME = frozenset((int,))
# the fast path's norm (the root of a sum of squares) may differ from math.hypot's in the last bits:
# it accepts only norms this much inside the tolerance, the per-sample rules decide the rest
_QUAT_TOL = UNIT_NORM_TOL - 1e-12
_RULED: dict[tuple[str, frozenset], bool] = {}  # (sensor, columns beyond its own) -> whether a rule reads one


def _ruled(col: str, name: str) -> bool:
    """Whether :func:`_plausible` holds ``col`` of sensor ``name`` to a limit."""
    return bool(
        (col in "xyz" and name in (*ACC_NAMES, "gyroscope"))
        or col.startswith(("acceleration", "gravity", "rotationRate"))
        or (name == "location" and col in ("latitude", "longitude", "horizontalAccuracy"))
    )


def _limits(sensor: Sensor, name: str) -> tuple[list[int], list[int]]:
    """The columns (indices into ``sensor.cols``) held to the acceleration and the rotation-rate limit."""
    acc, gyro = [], []
    for i, col in enumerate(sensor.cols):
        if (col in "xyz" and name in ACC_NAMES) or col.startswith(("acceleration", "gravity")):
            acc.append(i)
        elif (col in "xyz" and name == "gyroscope") or col.startswith("rotationRate"):
            gyro.append(i)
    return acc, gyro


def _spec(name: str, s: Sensor) -> tuple:
    """What :func:`_sensor_columns` needs of sensor ``name``: its keys, a getter of its columns,
    their limits (``limit`` per column, inf where none), its quaternion's columns, and whether every
    column of it is held to one limit (then a body's values are checked at once)."""
    acc, gyro = _limits(s, name)
    limit = np.full(len(s.cols), np.inf)
    limit[acc], limit[gyro] = ACC_RAW_MAX, GYRO_AXIS_MAX
    quat_of = {"orientation": ORIENTATION_COLS, "wrist motion": quat_cols(), "headphone": quat_cols()}
    quat = itemgetter(*[list(s.cols).index(c) for c in quat_of[name]]) if name in quat_of else None
    keys = frozenset((*s.cols, *s.optional, *([TEXT_COLS[s.file]] if s.file in TEXT_COLS else [])))
    one = float(limit[0]) if len(set(limit.tolist())) == 1 and np.isfinite(limit[0]) else None
    return keys, set(s.cols), itemgetter(*s.cols), limit if np.isfinite(limit).any() else None, quat, one


_SPEC = {name: _spec(name, s) for name, s in PUSH_NAMES.items()}


def _fast(body: bytes, lo: int, hi: int) -> Push | None:
    """The push in ``body`` where it passes every rule of the module docstring for certain, read and
    checked as arrays per sensor; None where it may not (:func:`_slow` then decides and says why)."""
    try:
        doc = orjson.loads(body)
    except orjson.JSONDecodeError:
        return None
    if type(doc) is not dict:
        return None
    try:
        mid, sid, did, payload = doc["messageId"], doc["sessionId"], doc["deviceId"], doc["payload"]
    except KeyError:
        return None
    if type(mid) is not int or not 0 <= mid < 2**62 or type(payload) is not list:
        return None
    for value in (sid, did):
        if type(value) is not str or not ID_RE.fullmatch(value) or value.startswith("."):
            return None
    columns: dict[str, Columns] = {}
    ignored: dict[str, int] = {}
    try:
        times = [item["time"] for item in payload]  # an entry that is not an object: TypeError
        if payload and (not set(map(type, times)) <= _TIME or min(times) < lo or max(times) > hi):
            return None
        groups: dict[str, list[dict]] = {}
        for item in payload:
            groups.setdefault(item["name"], []).append(item)
        for name, items in groups.items():
            if type(name) is not str or not 0 < len(name) <= MAX_NAME_LEN:
                return None
            sensor = PUSH_NAMES.get(name)
            if sensor is None:  # stored, not read: any JSON (orjson reads nothing that is not finite)
                ignored[name] = len(items)
                continue
            got = _sensor_columns(name, sensor, items)
            if got is None or sensor.file in columns:  # (two names for one file: not a body the app sends)
                return None
            columns[sensor.file] = got
    except (KeyError, TypeError, ValueError, OverflowError):
        return None
    return Push(sid, did, mid, payload, columns, ignored)


def _stored(raw: bytes) -> Push | None:
    """A body that passed the rules when it arrived, read as :func:`_fast` reads it but without
    them: each known sensor's samples as arrays. None where it is not the shape the rules let
    through (the checked readings then decide). tests/test_live_push.py: the same samples as the
    rules' on every body they accept."""
    try:
        doc = orjson.loads(raw)
        payload = doc["payload"]
        groups: dict[str, list[dict]] = {}
        for item in payload:
            groups.setdefault(item["name"], []).append(item)
        columns: dict[str, Columns] = {}
        ignored: dict[str, int] = {}
        for name, items in groups.items():
            sensor = PUSH_NAMES.get(name)
            if sensor is None:
                ignored[name] = len(items)
                continue
            if sensor.file in columns:
                return None
            vals = [it["values"] for it in items]
            v = np.array(list(map(_SPEC[name][2], vals)), np.float64).reshape(len(vals), len(sensor.cols))
            seen = frozenset(c for c in sensor.optional if any(c in d for d in vals))
            if sensor.optional:
                v = np.concatenate([v, _optional(sensor, vals, seen, checked=False)], axis=1)
            columns[sensor.file] = _columns(sensor, items, vals, v, seen)
        return Push(doc["sessionId"], doc["deviceId"], doc["messageId"], payload, columns, ignored)
    except (orjson.JSONDecodeError, KeyError, TypeError, ValueError, OverflowError, AttributeError):
        return None


def _sensor_columns(name: str, sensor: Sensor, items: list[dict]) -> Columns | None:
    """One known sensor's samples of a body as :class:`Columns`, or None where any rule may refuse them."""
    keys_known, cols, getter, limit, quat, one = _SPEC[name]
    vals = [it["values"] for it in items]
    rows = list(map(getter, vals))  # values not an object: TypeError; a column missing: KeyError
    flat = list(chain.from_iterable(rows))
    if not set(map(type, flat)) <= _NUMBER:
        return None
    keys = set(chain.from_iterable(vals))
    if keys != cols:  # more than the sensor's columns: each a scalar, none that a rule reads
        if not set(map(type, chain.from_iterable(map(dict.values, vals)))) <= _SCALAR:
            return None
        extra = frozenset(keys - keys_known)
        ruled = _RULED.get((name, extra))
        if ruled is None:
            ruled = _RULED[(name, extra)] = any(_ruled(k, name) for k in extra)
            if len(_RULED) > 1024:  # bounded: a client may send many key sets
                _RULED.clear()
        if ruled:
            return None
    if one is not None:
        if max(flat) > one or min(flat) < -one:
            return None
    v = np.array(rows, np.float64)
    if one is None and limit is not None and np.any(np.abs(v) > limit):
        return None
    if quat is not None:  # |q| within the tolerance of 1 (no square overflows: |q| <= 2 first)
        qs = list(map(quat, rows))
        qf = list(chain.from_iterable(qs))
        if max(qf) > 2.0 or min(qf) < -2.0:
            return None
        if max(abs(math.sqrt(w * w + x * x + y * y + z * z) - 1.0) for w, x, y, z in qs) > _QUAT_TOL:
            return None
    seen = frozenset(c for c in sensor.optional if c in keys)
    if sensor.optional:
        opt = _optional(sensor, vals, seen, checked=True)
        if opt is None:
            return None
        v = np.concatenate([v, opt], axis=1)
    if name == "location":
        if np.abs(v[:, 0]).max() > 90 or np.abs(v[:, 1]).max() > 180:
            return None
        k = sensor.optional.index("horizontalAccuracy") + len(sensor.cols)
        if np.nanmax(v[:, k], initial=-np.inf) > POS_ABS_MAX:
            return None
    return _columns(sensor, items, vals, v, seen)


def _optional(sensor: Sensor, vals: list[dict], seen: frozenset, checked: bool) -> np.ndarray | None:
    """The sensor's optional columns of samples ``vals`` (NaN where a sample has none, or null);
    ``checked``: None where one is not a number or null."""
    opt = np.full((len(vals), len(sensor.optional)), np.nan)
    for j, c in enumerate(sensor.optional):
        if c in seen:
            col = [d.get(c) for d in vals]
            if checked and not set(map(type, col)) <= _OPTIONAL:
                return None
            opt[:, j] = [np.nan if x is None else x for x in col]
    return opt


def _columns(sensor: Sensor, items: list[dict], vals: list[dict], v: np.ndarray, seen: frozenset) -> Columns:
    """One sensor's :class:`Columns` of ``items`` (their ``values``: ``vals``), its numbers ``v``."""
    tc = TEXT_COLS.get(sensor.file)
    times = np.array([it["time"] for it in items], np.int64)
    return Columns(times, v, seen, [d.get(tc) for d in vals] if tc else None)


def _slow(body: bytes, now_ns: int, max_future_s: float, max_age_s: float) -> Push:
    """:func:`parse` one sample at a time, with the reason of the first rule a body breaks."""
    try:
        doc = json.loads(body.decode("utf-8"), parse_constant=_no_constant)
    except BadPush:
        raise
    except UnicodeDecodeError:
        raise BadPush(400, "the body is not UTF-8 text") from None
    except (ValueError, RecursionError) as exc:
        raise BadPush(400, f"the body is not JSON ({type(exc).__name__}: {str(exc)[:80]})") from None
    if not isinstance(doc, dict):
        raise BadPush(422, "the body must be a JSON object with messageId, sessionId, deviceId and payload")
    for key in ("messageId", "sessionId", "deviceId", "payload"):
        if key not in doc:
            raise BadPush(422, f"the body has no {key}")
    mid = doc["messageId"]
    if not _is_int(mid) or not 0 <= mid < 2**62:
        raise BadPush(422, "messageId must be a non-negative integer")
    session, device = check_id(doc["sessionId"], "sessionId"), check_id(doc["deviceId"], "deviceId")
    payload = doc["payload"]
    if not isinstance(payload, list):
        raise BadPush(422, "payload must be a list")
    lo, hi = now_ns - int(max_age_s * NS), now_ns + int(max_future_s * NS)
    for k, item in enumerate(payload):
        if not isinstance(item, dict):
            raise BadPush(422, f"payload[{k}] must be an object")
        name = item.get("name")
        if not isinstance(name, str) or not 0 < len(name) <= MAX_NAME_LEN:
            raise BadPush(422, f"payload[{k}].name must be a string of 1-{MAX_NAME_LEN} characters")
        t = _sample_time(item.get("time"), k)
        if t > hi:
            raise BadPush(
                422,
                f"payload[{k}].time is {_days(t - now_ns)} days in the future "
                f"(over {max_future_s:g} s ahead of this server's clock)",
            )
        if t < lo:
            raise BadPush(
                422, f"payload[{k}].time is {_days(now_ns - t)} days in the past (over {max_age_s / 86400:g} days)"
            )
        item["time"] = t
        _check_values(item.get("values"), name, k)
    return Push(session, device, mid, payload)


__all__ = ["BadPush", "Columns", "ID_RE", "Push", "TEXT_COLS", "check_id", "columns_of", "parse", "parse_stored"]
