"""Send a Sensor Logger export to a receiver as the app would push it while recording.

The export (folder or ``.zip``, as :func:`wearnav.importers.sensorlogger_export.write_export`
writes it) is read with the importer's own CSV reader, so the values sent are the values the
importer reads. Every sensor's rows (phone, watch, earbuds, location, and ``WiFi.csv``'s scans as
entries named ``wifi``: interleaved by sample time) go out in batches of ``batch_s`` of sample time,
one message per batch with ``messageId`` 0, 1, 2, ..., one ``sessionId`` and one ``deviceId``
(PUSHING.md), ``values`` holding the file's columns but ``time`` / ``seconds_elapsed``. Sample times are shifted by one constant so that the
export's last sample is the moment the replay starts (the receiver refuses times from the
future), which leaves every time difference as it was. The export's platform and
standardisation (Metadata.csv; the app does not push them) go in the URL's query, as a user
types them into the app's push URL (``platform=False``: not, and the receiver decides them).

``speed`` N sends N seconds of samples per wall second. A message that fails (connection refused,
5xx, 429) is sent again until acknowledged, so a receiver killed and restarted mid-replay gets
every message.
"""

from __future__ import annotations

import json
import tempfile
import time
import uuid
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from urllib.parse import parse_qsl, urlencode, urlsplit, urlunsplit

import httpx
import numpy as np

from wearnav.errors import ConfigError, FormatError, MissingFileError
from wearnav.importers import sensorlogger
from wearnav.importers.common import find_file, read_csv
from wearnav.importers.sensorlogger_map import KNOWN_FILES, PUSH_NAMES
from wearnav.importers.sensorlogger_radio import WIFI_FILE, read_wifi
from wearnav.live.push import ID_RE
from wearnav.live.wifi import PUSH_NAME as WIFI

SKIP_COLS = ("time", "seconds_elapsed")  # the push has neither as a value (UNITS.md)


@dataclass
class Replay:
    session_id: str
    device_id: str
    platform: str
    standardised: bool
    messages: list[dict]  # ready to send, messageId in order
    samples: int
    shift_ns: int  # added to every sample time of the export


@dataclass
class Result:
    sent: int = 0
    acknowledged: list[int] = field(default_factory=list)  # messageIds answered 200
    retries: int = 0
    ack_latency_s: list[float] = field(default_factory=list)
    wall_s: float = 0.0
    late_s: float = 0.0  # how far behind schedule the last message went out


def _wifi_rows(folder: Path) -> list[tuple[int, str, dict]]:
    """``WiFi.csv``'s readings as the app pushes them (entries named ``wifi``: wearnav.live.wifi),
    checked as the importer checks them (:func:`wearnav.importers.sensorlogger_radio.read_wifi`)."""
    try:
        path = find_file(folder / WIFI_FILE)
    except MissingFileError:
        return []
    read_wifi(folder, 0, {})  # the importer's one-line refusals, before anything is sent
    df = read_csv(path, required=["time"], dtype={"bssid": str, "ssid": str}, keep_default_na=False)
    cols = [c for c in df.columns if c not in SKIP_COLS]
    times = df["time"].astype("int64").tolist()
    return [(t, WIFI, {k: _plain(v) for k, v in rec.items()}) for t, rec in zip(times, df[cols].to_dict("records"))]


@contextmanager
def export_folder(src: str | Path) -> Iterator[Path]:
    """``src`` itself, or a temporary folder holding the known files of the one export in a zip."""
    src = Path(src)
    if src.is_dir():
        yield src
        return
    if not zipfile.is_zipfile(src):
        raise FormatError("not a Sensor Logger export folder or .zip", src)
    with zipfile.ZipFile(src) as zf, tempfile.TemporaryDirectory(prefix="wearnav-replay-") as tmp:
        for info in zf.infolist():
            name = PurePosixPath(info.filename).name
            if not info.is_dir() and name in (*KNOWN_FILES, WIFI_FILE) and "__MACOSX" not in info.filename:
                (Path(tmp) / name).write_bytes(zf.read(info))
        yield Path(tmp)


def build(
    src: str | Path,
    batch_s: float = 0.2,
    session_id: str | None = None,
    device_id: str | None = None,
    start_ns: int | None = None,
) -> Replay:
    """The messages replaying ``src`` (module docstring); ``start_ns``: the export's last sample
    becomes this time (default now)."""
    if batch_s <= 0:
        raise ConfigError(f"batch period {batch_s!r} s must be positive")
    with export_folder(src) as folder:
        platform, standardised, _info, tables = sensorlogger.export_tables(folder)
        wifi = _wifi_rows(folder)
    rows = []  # (time_ns, name, values), in PUSH_NAMES order before sorting
    for name, sensor in PUSH_NAMES.items():
        table = tables.get(sensor.file)
        if table is None:
            continue
        cols = [c for c in table.df.columns if c not in SKIP_COLS]
        for t, rec in zip(table.t_ns.tolist(), table.df[cols].to_dict("records")):
            rows.append((t, name, {k: _plain(v) for k, v in rec.items()}))
    rows += wifi
    if not rows:
        raise FormatError("no sensor rows to replay", src)
    rows.sort(key=lambda r: r[0])  # stable: on equal times the file order above
    t_first, t_last = rows[0][0], rows[-1][0]
    shift = (time.time_ns() if start_ns is None else start_ns) - t_last
    session_id = session_id or f"replay-{uuid.uuid4().hex[:12]}"
    device_id = device_id or "replay-phone"
    for v, what in ((session_id, "session id"), (device_id, "device id")):
        if not ID_RE.fullmatch(v):
            raise ConfigError(f"{what} {v!r} is not 1-128 of A-Z a-z 0-9 _ . : -")
    period = int(round(batch_s * 1e9))
    batch_of = np.array([(r[0] - t_first) // period for r in rows])
    messages = []
    for k, start in enumerate(np.flatnonzero(np.r_[True, np.diff(batch_of) > 0])):
        end = start + int(np.searchsorted(batch_of[start:], batch_of[start], side="right"))
        payload = [{"name": n, "time": t + shift, "values": v} for t, n, v in rows[start:end]]
        messages.append(
            {
                "messageId": k,
                "sessionId": session_id,
                "deviceId": device_id,
                "payload": payload,
                "_due_s": float((batch_of[start] + 1) * batch_s),
            }
        )
    return Replay(session_id, device_id, platform, standardised, messages, len(rows), shift)


def _plain(v):
    """A CSV cell as JSON has it: an empty cell (NaN) is null, as the app sends a missing value."""
    if isinstance(v, (np.floating, float)):
        return float(v) if np.isfinite(v) else None
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, str) or v is None:
        return v
    return v.item() if hasattr(v, "item") else v


def push_url(url: str, replay: Replay, token: str | None = None, platform: bool = True) -> str:
    """``url`` with the export's platform and standardisation (``platform`` False: not, as a push
    URL typed without them; the receiver then decides them from the data) and the token."""
    parts = urlsplit(url)
    query = dict(parse_qsl(parts.query))
    if platform:
        query.update(platform=replay.platform, standardisation="true" if replay.standardised else "false")
    if token:
        query["token"] = token
    return urlunsplit(parts._replace(query=urlencode(query)))


def send(
    replay: Replay,
    url: str,
    speed: float = 1.0,
    token: str | None = None,
    retry_for_s: float = 60.0,
    stop_after: int | None = None,
    on_ack=None,
    platform: bool = True,
) -> Result:
    """POST every message in order at ``speed`` × real time; a failed message is retried (every
    0.1 s, for at most ``retry_for_s`` without any success) before the next is sent."""
    if speed <= 0:
        raise ConfigError(f"speed {speed!r} must be positive")
    target = push_url(url, replay, token, platform)
    res = Result()
    t_start = time.perf_counter()
    with httpx.Client(timeout=10.0) as client:
        for msg in replay.messages[:stop_after]:
            due = t_start + msg["_due_s"] / speed
            wait = due - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            res.late_s = max(0.0, -wait)
            body = json.dumps({k: v for k, v in msg.items() if not k.startswith("_")}).encode()
            give_up = time.perf_counter() + retry_for_s
            while True:
                t0 = time.perf_counter()
                try:
                    r = client.post(target, content=body, headers={"content-type": "application/json"})
                    status = r.status_code
                except httpx.TransportError:
                    status = None
                res.sent += 1
                if status == 200:
                    res.ack_latency_s.append(time.perf_counter() - t0)
                    res.acknowledged.append(msg["messageId"])
                    if on_ack is not None:
                        on_ack(msg["messageId"])
                    break
                if status is not None and status < 500 and status != 429:
                    raise ConfigError(f"the receiver refused message {msg['messageId']}: {status} {r.text[:200]}")
                if time.perf_counter() > give_up:
                    raise ConfigError(f"no answer from {url} for {retry_for_s:g} s (message {msg['messageId']})")
                res.retries += 1
                time.sleep(0.1)
    res.wall_s = time.perf_counter() - t_start
    return res


__all__ = ["Replay", "Result", "build", "export_folder", "push_url", "send"]
