"""The bad push bodies the receiver must refuse, each with its status and a word of its one-line
reason: what the tests and ``wearnav live bench`` send (and count in docs/results.md)."""

from __future__ import annotations

import json
import time

DAY_S = 86400.0


def body(**over) -> dict:
    """A good push (an accelerometer sample and a fix, now), with ``over`` replacing fields."""
    now = time.time_ns()
    doc = {
        "messageId": 3,
        "sessionId": "s-1",
        "deviceId": "phone.A:1",
        "payload": [
            {"name": "accelerometer", "time": now, "values": {"x": 0.1, "y": -0.2, "z": 0.3}},
            {
                "name": "location",
                "time": now,
                "values": {"latitude": 49.4, "longitude": 11.1, "horizontalAccuracy": 4.0},
            },
        ],
    }
    doc.update(over)
    return doc


def sample(**over) -> dict:
    item = {"name": "gyroscope", "time": time.time_ns(), "values": {"x": 0.0, "y": 0.0, "z": 0.1}}
    item.update(over)
    return item


def enc(doc) -> bytes:
    return json.dumps(doc).encode()


def catalogue() -> dict[str, tuple[bytes, int, str]]:
    """name → (body, status, a word of the reason), times relative to now."""
    now, day_ns = time.time_ns(), int(DAY_S * 1e9)
    return {
        "not JSON": (b'{"messageId": 1,', 400, "not JSON"),
        "not UTF-8": (enc(body()).decode().encode("utf-16"), 400, "UTF-8"),
        "NaN": (enc(body()).replace(b"0.1", b"NaN"), 400, "NaN"),
        "Infinity": (enc(body()).replace(b"0.1", b"-Infinity"), 400, "Infinity"),
        "huge number": (enc(body()).replace(b"0.1", b"1e999"), 400, "not finite"),
        "not an object": (b"[1, 2]", 422, "JSON object"),
        "no payload": (enc({k: v for k, v in body().items() if k != "payload"}), 422, "payload"),
        "messageId a string": (enc(body(messageId="3")), 422, "messageId"),
        "messageId negative": (enc(body(messageId=-1)), 422, "messageId"),
        "messageId a boolean": (enc(body(messageId=True)), 422, "messageId"),
        "payload an object": (enc(body(payload={"name": "x"})), 422, "payload must be a list"),
        "entry not an object": (enc(body(payload=[1])), 422, "payload[0]"),
        "name missing": (enc(body(payload=[{"time": 1, "values": {}}])), 422, "name"),
        "time a string": (enc(body(payload=[sample(time="now")])), 422, "time"),
        "values a list": (enc(body(payload=[sample(values=[1, 2, 3])])), 422, "values"),
        "value nested": (enc(body(payload=[sample(values={"x": {"a": 1}, "y": 0, "z": 0})])), 422, "values.x"),
        "known sensor, string value": (enc(body(payload=[sample(values={"x": "1", "y": 0, "z": 0})])), 422, "values.x"),
        "known sensor, column missing": (enc(body(payload=[sample(values={"x": 1, "y": 0})])), 422, "values.z"),
        "time in the future": (enc(body(payload=[sample(time=now + day_ns)])), 422, "future"),
        "time years ago": (enc(body(payload=[sample(time=now - 3 * 365 * day_ns)])), 422, "past"),
        "sessionId with a slash": (enc(body(sessionId="../../etc/passwd")), 422, "sessionId"),
        "sessionId dot-dot": (enc(body(sessionId="..")), 422, "sessionId"),
        "sessionId hidden": (enc(body(sessionId=".wal")), 422, "sessionId"),
        "deviceId with a backslash": (enc(body(deviceId="a\\b")), 422, "deviceId"),
        "deviceId empty": (enc(body(deviceId="")), 422, "deviceId"),
        "sessionId a number": (enc(body(sessionId=7)), 422, "sessionId"),
        "acceleration 1e30": (enc(body()).replace(b"0.1", b"1e30"), 422, "beyond any acceleration"),
        "rotation rate 1e5": (enc(body(payload=[sample(values={"x": 1e5, "y": 0, "z": 0})])), 422, "rotation rate"),
        "quaternion not unit": (
            enc(
                body(
                    payload=[
                        {"name": "orientation", "time": now, "values": {"qw": 0.0, "qx": 0.0, "qy": 0.0, "qz": 0.0}}
                    ]
                )
            ),
            422,
            "norm",
        ),
        "latitude 999": (enc(body()).replace(b"49.4", b"999"), 422, "out of range"),
        "quaternion 1e300": (
            enc(
                body(
                    payload=[
                        {"name": "orientation", "time": now, "values": {"qw": 1e300, "qx": 0.0, "qy": 0.0, "qz": 0.0}}
                    ]
                )
            ),
            422,
            "norm",
        ),
        "an integer of 400 digits": (enc(body()).replace(b"0.1", b"1" + b"0" * 400), 400, "not finite"),
    }


__all__ = ["body", "catalogue", "enc", "sample"]
