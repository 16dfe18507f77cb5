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
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass

from wearnav.core.rotations import UNIT_NORM_TOL
from wearnav.importers.sensorlogger_map import ORIENTATION_COLS, PUSH_NAMES, quat_cols
from wearnav.recording import ACC_AXIS_MAX, GYRO_AXIS_MAX
from wearnav.recording.checks import POS_ABS_MAX

ID_RE = re.compile(r"[A-Za-z0-9_.:-]{1,128}")
MAX_NAME_LEN = 64
# A raw acceleration or gravity value: half the Recording's limit, so that user acceleration plus
# gravity stays within it (in m/s²; a wearable writing g stays far below in any case).
ACC_RAW_MAX = ACC_AXIS_MAX / 2
MAX_INT = 10**300  # larger JSON integers are refused as not finite (float() would overflow)
NS = 1_000_000_000


class BadPush(Exception):
    """A body the receiver refuses: ``status`` (4xx) and one line saying why."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status
        self.message = message


@dataclass
class Push:
    session_id: str
    device_id: str
    message_id: int
    payload: list[dict]


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


__all__ = ["BadPush", "ID_RE", "Push", "check_id", "parse"]
