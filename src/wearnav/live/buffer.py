"""One live session's samples, kept per sensor and turned into a Recording on demand.

Each accepted push adds its payload here (after the store committed it). Samples are kept as the
app sent them, per sensor (:data:`wearnav.importers.sensorlogger_map.PUSH_NAMES`), sorted by sample
time whatever order the messages came in; a repeated sample time keeps the sample that arrived
first (``timeseries.drop_duplicate_times``' rule). :meth:`SessionBuffer.recording` hands them to
the same tables → Recording step as the CSV importer
(:func:`wearnav.importers.sensorlogger_build.build_recording`), so the devices, units, signs and
frames are the importer's: a session holding the same samples as an export gives the same
Recording.

Slices (``t_from``) keep the session's time origin, its local-frame origin (the first fix) and
the quaternion direction decided once on the first ``DECIDE_S`` seconds (the importer's checks),
so every slice lies in one frame.
"""

from __future__ import annotations

import copy
import hashlib
import math
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.errors import FormatError, MissingFileError
from wearnav.importers.sensorlogger_build import VerticalForceError, build_recording, stale_fixes
from wearnav.importers.sensorlogger_map import SENSORS, Table
from wearnav.live.push import TEXT_COLS, Columns, Push, columns_of, parse_stored
from wearnav.live.wifi import PUSH_NAME as WIFI
from wearnav.live.wifi import WifiRows
from wearnav.recording import STANDARD_GRAVITY as G
from wearnav.recording import DeviceStream, Fixes, Recording

NS = 1_000_000_000
DECIDE_S = 10.0  # seconds of data after which the quaternion direction is decided for good
# Before the decision, the whole session's checked build (the importer's, some 8 ms whatever its
# length) is redone every RECHECK_S of data; in between, slices are read in the direction it last
# found (issue 61: it was redone at every update, 2 ms of a 30-s phone-only walker's 10.6 ms a
# second). A direction that the next check turns is taken from then on, as at every update before.
# The checks fall on a grid offset by the session's phase, and the decision at DECIDE_S + phase ×
# RECHECK_S: sessions that start together (a crowd's may) do not all build in one tick. A check
# whose data told every device's two directions apart (one passed, the other failed; the platform
# given) is not redone before the decision: only a check that both directions passed (too little
# rotation to tell) can be turned by more data (issue 61: the rechecks were a third of a starting
# session's tracking CPU in a crowd).
RECHECK_S = 2.0
# A decision whose check finds the vertical force off by less than g / 2 (hard motion at the start,
# not gravity counted twice or missing) waits for more data, at most until this much has arrived.
DECIDE_LATEST_S = 60.0
MARGIN_S = 2.0  # a slice reads this much earlier data, for interpolation at its start
AUTO = "auto"  # a session whose push URL gave no platform: decided from its data
CONNECTED_S = 5.0  # a device this far behind the newest (sample time) no longer holds the path back
# The distinct readings of an app's acceleration (sign, unit: sensorlogger_map.acceleration_convention),
# tried in this order: iOS with "Standardise Units & Frames" off (the app's default), on, and Android.
CONVENTIONS = (("ios", False), ("ios", True), ("android", False))
_BUILD_LOCK = threading.Lock()  # warnings.catch_warnings is process-wide


class _Sensor:
    """One sensor's samples: sorted by time, a repeated time keeping the first to arrive.

    Kept in arrays that grow by doubling, so that the usual message (later than everything so far)
    costs only its own rows; one that arrives out of order re-sorts only the rows after its first
    time, into new arrays (a snapshot handed out before stays as it was)."""

    def __init__(self, cols: list[str], text: bool):
        self.cols = cols
        self.chunks: list[tuple[np.ndarray, np.ndarray, list | None]] = []
        self.optional_seen: set = set()
        self.n = 0
        self._t = np.zeros(0, np.int64)
        self._v = np.zeros((0, len(cols)), np.float64)
        self._text = np.zeros(0, object) if text else None
        self.duplicates = 0
        self.last_seen_unix_s = 0.0

    @property
    def t(self) -> np.ndarray:
        return self._t[: self.n]

    @property
    def vals(self) -> np.ndarray:
        return self._v[: self.n]

    @property
    def text(self) -> np.ndarray | None:
        return None if self._text is None else self._text[: self.n]

    def consolidate(self) -> None:
        """Merge the pending chunks (module docstring's order rule)."""
        if not self.chunks:
            return
        t = np.concatenate([c[0] for c in self.chunks])
        v = np.concatenate([c[1] for c in self.chunks])
        x = (
            None
            if self._text is None
            else np.array([y for c in self.chunks for y in (c[2] or [None] * len(c[0]))], object)
        )
        self.chunks = []
        if t.size and (not self.n or t[0] > self._t[self.n - 1]) and bool((t[1:] > t[:-1]).all()):
            self._append(t, v, x)  # the usual message: later than everything so far, in order, no repeats
            return
        if self.n and t.min() <= self._t[self.n - 1]:  # out of order: merge with the rows from t.min() on
            i = int(np.searchsorted(self.t, t.min(), side="left"))
            t, v = np.concatenate([self._t[i : self.n], t]), np.concatenate([self._v[i : self.n], v])
            x = None if x is None or self._text is None else np.concatenate([self._text[i : self.n], x])
            self._t, self._v = self._t[:i].copy(), self._v[:i].copy()  # new arrays: snapshots keep theirs
            self._text = None if x is None or self._text is None else self._text[:i].copy()
            self.n = i
        order = np.argsort(t, kind="stable")  # earlier arrivals first on equal times
        t, v = t[order], v[order]
        keep = np.concatenate([[True], np.diff(t) > 0])
        self.duplicates += int((~keep).sum())
        t, v = t[keep], v[keep]
        if x is not None:
            x = x[order][keep]
        self._append(t, v, x)

    def _append(self, t: np.ndarray, v: np.ndarray, x: np.ndarray | None) -> None:
        """Rows ``t`` (sorted, all later than the rows kept) after the rows kept."""
        need = self.n + t.size
        if need > self._t.size:  # grow by doubling (new arrays)
            cap = max(need, 2 * self._t.size, 1024)
            self._t = np.concatenate([self._t[: self.n], np.zeros(cap - self.n, np.int64)])
            self._v = np.concatenate([self._v[: self.n], np.zeros((cap - self.n, self._v.shape[1]))])
            if self._text is not None:
                self._text = np.concatenate([self._text[: self.n], np.zeros(cap - self.n, object)])
        self._t[self.n : need], self._v[self.n : need] = t, v
        if x is not None and self._text is not None:  # x is there exactly when _text is
            self._text[self.n : need] = x
        self.n = need


class SessionBuffer:
    """One session's samples so far, already in the Recording convention (the importer's mapping)."""

    def __init__(self, session_id: str, platform: str = "ios", standardised: bool = False):
        self.session_id = session_id
        self.infer = platform == AUTO  # decided from the data (see _full) until then
        self.platform, self.standardised = CONVENTIONS[0] if self.infer else (platform, standardised)
        self.platform_from = "the data" if self.infer else "the push URL / wearnav live --platform"
        self.t0_unix_ns: int | None = None
        self.version = 0
        self.messages = 0
        self.ignored: dict[str, int] = {}  # unknown sensor names → samples (stored, not read)
        self.warnings: list[str] = []
        self.wifi = WifiRows()  # the Wi-Fi scans' readings (wearnav.live.wifi), for a radio map
        self._sensors: dict[str, _Sensor] = {}
        self._lock = threading.Lock()
        self._quat_inverted: list[str] | None = None
        self.phase = session_phase(session_id)
        self._decide_s = DECIDE_S + self.phase * RECHECK_S
        # (covered_until, direction, clear) of the last check; clear: the data told every device's
        # directions apart (one passed, the other failed), the platform given
        self._provisional: tuple[float, list[str], bool] | None = None
        self._cache: tuple | None = None
        self._snap: tuple[int, dict[str, tuple]] | None = None  # the latest _snapshot, by version
        self._fresh_cache: tuple[tuple, np.ndarray] | None = None  # _first_fresh_row's last answer
        self._covered: tuple[int, float] | None = None  # covered_until's last answer, by version
        # the live tracker's last fixes in metres (wearnav.live.lean._lean_fixes): origin, times, (N, 2)
        self.fix_metres: tuple[tuple[float, float], np.ndarray, np.ndarray] | None = None

    @classmethod
    def from_store(cls, store, session_id: str) -> SessionBuffer:
        """The session rebuilt from a :class:`wearnav.live.store.Store` (on restart, for export):
        its messages in the order they were stored, with the time each was received."""
        sessions = store.sessions()
        if session_id not in sessions:
            known = ", ".join(sessions) or "none"
            raise MissingFileError(f"no session {session_id!r} in the store (sessions: {known})", store.path)
        buf = cls(session_id, sessions[session_id]["platform"], sessions[session_id]["standardised"])
        for _device, _mid, received_ns, body in store.messages(session_id):
            buf.add_body(body, received_unix_s=received_ns / NS)
        return buf

    # ---- input ------------------------------------------------------------------------------

    def add(self, payload: list[dict], received_unix_s: float | None = None) -> int:
        """Add one accepted message's payload (checked by :func:`wearnav.live.push.parse`);
        returns how many samples of known sensors it held."""
        columns, ignored = columns_of(payload)
        if WIFI in ignored:  # stored unread by the receiver; the tracker's radio map reads them
            self.wifi.add(payload)
        return self.add_columns(columns, ignored, received_unix_s)

    def add_push(self, push: Push, received_unix_s: float | None = None) -> int:
        """Add one accepted message (:func:`wearnav.live.push.parse`'s, or
        :func:`~wearnav.live.push.parse_stored`'s), as the arrays it was checked as."""
        if WIFI in push.ignored:
            self.wifi.add(push.payload)
        return self.add_columns(push.columns, push.ignored, received_unix_s)

    def add_body(self, body: str | bytes, received_unix_s: float | None = None) -> int:
        """Add one stored message's body (as the store holds it: checked when it arrived)."""
        return self.add_push(parse_stored(body), received_unix_s)

    def add_columns(
        self, columns: dict[str, Columns], ignored: dict[str, int], received_unix_s: float | None = None
    ) -> int:
        """Add one message's samples, by sensor file (:class:`wearnav.live.push.Columns`), and count
        its unknown sensors' samples; returns how many samples of known sensors it held."""
        now = time.time() if received_unix_s is None else received_unix_s
        n = 0
        with self._lock:
            for name, k in ignored.items():
                self.ignored[name] = self.ignored.get(name, 0) + k
            for fname, c in columns.items():
                spec = SENSORS[fname]
                s = self._sensors.get(fname)
                if s is None:
                    s = self._sensors[fname] = _Sensor([*spec.cols, *spec.optional], fname in TEXT_COLS)
                s.optional_seen.update(c.seen)
                s.chunks.append((c.t, c.v, c.text))
                s.last_seen_unix_s = now
                n += len(c.t)
            self.version += 1
            self.messages += 1
        return n

    # ---- output -----------------------------------------------------------------------------

    def _snapshot(self) -> tuple[int, dict[str, tuple]]:
        with self._lock:
            if self._snap is not None and self._snap[0] == self.version:  # nothing added since
                return self._snap
            for s in self._sensors.values():
                s.consolidate()
            snap = {
                f: (
                    s.t,
                    s.vals,
                    [*s.cols[: len(SENSORS[f].cols)], *[c for c in SENSORS[f].optional if c in s.optional_seen]],
                    s.text,
                    s.duplicates,
                )
                for f, s in self._sensors.items()
                if s.t.size
            }
            version = self.version
        self.t0_unix_ns = self._t0(snap)
        self._snap = (version, snap)
        return version, snap

    def _t0(self, snap: dict) -> int | None:
        motion = [v[0][0] for f, v in snap.items() if SENSORS[f].device is not None]
        if not motion:
            return None
        starts = list(motion)
        if "Location.csv" in snap:
            fresh = self._first_fresh_fix(snap["Location.csv"], int(min(motion)))
            if fresh is not None:
                starts.append(fresh)
        return int(min(starts))

    def _first_fresh_fix(self, entry: tuple, t_motion_ns: int) -> int | None:
        """The time of the first fix that is not stale (``stale_fixes``), or None. ``stale_fixes``
        judges each fix by its own row, so once found it stays the first while the rows up to it are
        the same (checked on their times) and the motion start is too: kept, not recomputed (a pandas
        table per push was 8 % of a session's tracking)."""
        k = self._first_fresh_row(entry, t_motion_ns)
        return None if k is None else int(entry[0][k])

    def _first_fresh_row(self, entry: tuple, t_motion_ns: int) -> int | None:
        """:meth:`_first_fresh_fix`'s row in ``entry`` (the Location snapshot), or None."""
        t, key = entry[0], (t_motion_ns, tuple(entry[2]))  # the columns decide stale_fixes' rule
        c = self._fresh_cache
        if c is not None and c[0] == key and t.size >= c[1].size and np.array_equal(t[: c[1].size], c[1]):
            return c[1].size - 1
        loc = _table("", "Location.csv", entry, 0)
        fresh = np.flatnonzero(~stale_fixes(loc, t_motion_ns))
        if not fresh.size:
            return None
        k = int(fresh[0])
        self._fresh_cache = (key, t[: k + 1].copy())
        return k

    def _tables(self, snap: dict, lo_ns: int | None) -> dict[str, Table]:
        out = {}
        for fname, entry in snap.items():
            i = 0 if lo_ns is None else int(np.searchsorted(entry[0], lo_ns))
            if entry[0].size - i > 0:
                out[fname] = _table(self.session_id, fname, entry, i)
        return out

    def _build(self, tables: dict[str, Table], convention: tuple[str, bool] | None = None, **kw) -> Recording:
        platform, standardised = convention or (self.platform, self.standardised)
        with _BUILD_LOCK, warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            rec = build_recording(
                tables,
                platform,
                standardised,
                Path(f"live:{self.session_id}"),
                self.session_id,
                f"live session {self.session_id}",
                {"platform_from": self.platform_from},
                t0_ns=self.t0_unix_ns,
                **kw,
            )
        self.warnings = [str(w.message) for w in caught]
        return rec

    def recording(self, t_from: float | None = None) -> Recording:
        """Every device's stream (and the fixes) with t >= t_from (s since t0), sorted by time;
        meta as the importer sets it. ``t_from`` None: all of it, with the importer's checks."""
        version, snap = self._snapshot()
        key = (version, t_from)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        if self.t0_unix_ns is None:
            raise FormatError("no motion samples yet", f"live:{self.session_id}")
        inverted = self.quat_direction()
        if t_from is None or inverted is None:
            rec = self._full(snap)
            if t_from is not None:
                rec = cut(rec, t_from)
        else:
            full_loc = snap.get("Location.csv")
            origin = None
            if full_loc is not None:  # the first fresh fix (kept, not recomputed: _first_fresh_row)
                motion0 = min(v[0][0] for f, v in snap.items() if SENSORS[f].device is not None)
                k = self._first_fresh_row(full_loc, int(motion0))
                if k is not None:
                    lat, lon = (full_loc[2].index(c) for c in ("latitude", "longitude"))
                    origin = (float(full_loc[1][k, lat]), float(full_loc[1][k, lon]))
            lo = self.t0_unix_ns + int(round((t_from - MARGIN_S) * NS))
            rec = cut(self._build(self._tables(snap, lo), quat_inverted=inverted, origin=origin), t_from)
        self._cache = (key, rec)
        return rec

    def quat_direction(self) -> list[str] | None:
        """The devices whose quaternions slices read inverted: as decided on the first ``DECIDE_S``
        seconds (and the session's phase), or before that as the whole session's last check found
        until the next check (every ``RECHECK_S``, on a grid offset by the phase, where that check
        could not tell the directions apart; else the decision); None: a check of the whole session
        is due (:meth:`recording` runs it)."""
        if self._quat_inverted is not None:
            return self._quat_inverted
        p = self._provisional
        if p is None:
            return None
        span = self.covered_until()
        if span >= self._decide_s or (
            not p[2] and math.floor(span / RECHECK_S + self.phase) != math.floor(p[0] / RECHECK_S + self.phase)
        ):
            return None
        return p[1]

    def _full(self, snap: dict) -> Recording:
        """The whole session with the importer's checks. Until ``DECIDE_S`` seconds are in, data too
        short for the checks is read the documented way (quaternions world←device). A session
        without a given platform (``AUTO``) is read in the first of ``CONVENTIONS`` that passes the
        checks (the acceleration sign and the wearables' unit decide whether gravity lies along
        the orientation's up), provisionally until ``DECIDE_S`` seconds, for good after."""
        tables = self._tables(snap, None)
        span = self.covered_until()
        decided = span >= self._decide_s
        tried = [(self.platform, self.standardised)] + (
            [c for c in CONVENTIONS if c != (self.platform, self.standardised)] if self.infer else []
        )
        first_error = None
        for convention in tried:
            unclear: list[str] = []
            try:
                rec = self._build(tables, convention, unclear=unclear)
            except FormatError as exc:
                first_error = first_error or exc
                continue
            if self.infer:
                self.platform, self.standardised = convention
            if decided:
                if self.infer:
                    self.infer, self.platform_from = (
                        False,
                        "the data (the first reading that passes the importer's checks)",
                    )
                if self._quat_inverted is None:
                    self._quat_inverted = list(rec.meta.get("quat_inverted", []))
            self._provisional = (span, list(rec.meta.get("quat_inverted", [])), not unclear and not self.infer)
            return rec
        assert first_error is not None  # every convention tried (at least one) failed
        if not self.infer and (not decided or self._postpone(first_error, span)):
            self._provisional = (span, [], False)
            return self._build(tables, quat_inverted=())
        if not decided:
            raise FormatError(
                f"the phone's platform is decided from the data once {DECIDE_S:g} s are in (the "
                "push URL does not say it: ?platform=ios|android&standardisation=true|false)",
                first_error.source,
            )
        raise FormatError(  # the push carries no platform: say where it is set
            f"{first_error.reason} (this session is read as platform {self.platform}, standardisation "
            f"{'on' if self.standardised else 'off'}{', none of ' + str(len(tried)) + ' readings fits' if self.infer else ''}: "
            "the push URL's ?platform=android / &standardisation=true, or wearnav live --platform / "
            "--standardised, say otherwise)",
            first_error.source,
        ) from None

    @staticmethod
    def _postpone(error: FormatError, span: float) -> bool:
        """Whether the decision's failed check waits for more data (the session read the documented
        way meanwhile, as before the decision; checked again at every update): the orientation put
        gravity up but the mean vertical force over the session so far is off by less than half of g
        (not gravity counted twice, ~2 g, or missing, ~0: a phone swung hard, e.g. a compass
        calibration's figure eights, whose orientation lags the motion), and less than
        ``DECIDE_LATEST_S`` has arrived. Measured on an IPIN 2023 walk that starts so: 7.7-8.4 m/s²
        over 4-s windows of its first 30 s, 9.47 over the whole walk, which the importer accepts."""
        return isinstance(error, VerticalForceError) and abs(error.vertical - G) < G / 2 and span < DECIDE_LATEST_S

    def covered_until(self) -> float:
        """s since t0: min over connected IMU devices of their latest sample time (a device's: the
        earliest of its sensors' latest, as its stream needs them all). Connected: its latest
        sample is within ``CONNECTED_S`` of the newest of any device (sample time, so that a replay
        or a restart sees what the live session saw): earbuds taken out do not stop the path."""
        version, snap = self._snapshot()
        got = self._covered
        if got is not None and got[0] == version:  # asked again before anything was added
            return got[1]
        last: dict[str, int] = {}
        for fname, entry in snap.items():
            dev = SENSORS[fname].device
            if dev is not None:
                last[dev] = min(last.get(dev, entry[0][-1]), int(entry[0][-1]))
        if not last or self.t0_unix_ns is None:
            return 0.0
        newest = max(last.values())
        covered = (min(t for t in last.values() if t >= newest - CONNECTED_S * NS) - self.t0_unix_ns) / NS
        self._covered = (version, covered)
        return covered

    def motion_span_s(self) -> float:
        """s from the earliest to the latest motion sample (any device's sensors): no device's stream
        spans more (each is made of its sensors' samples), so a tracker can tell without building a
        Recording that the session is still too short to start."""
        _, snap = self._snapshot()
        motion = [entry[0] for fname, entry in snap.items() if SENSORS[fname].device is not None]
        if not motion:
            return 0.0
        return (max(int(t[-1]) for t in motion) - min(int(t[0]) for t in motion)) / NS

    def devices(self) -> dict[str, dict]:
        """{"phone": {"rate_hz": 99.8, "last_seen_unix_s": ..., "samples": n}, ...}: each device's
        fastest sensor's rate over its last 2 s of samples, and when a message last carried it."""
        _, snap = self._snapshot()
        with self._lock:
            seen = {f: s.last_seen_unix_s for f, s in self._sensors.items()}
        out: dict[str, dict] = {}
        for fname, (t, *_rest) in snap.items():
            dev = SENSORS[fname].device
            if dev is None:
                continue
            recent = t[int(np.searchsorted(t, t[-1] - 2 * NS)) :]
            rate = (
                (recent.size - 1) / ((recent[-1] - recent[0]) / NS)
                if recent.size > 1 and recent[-1] > recent[0]
                else 0.0
            )
            d = out.setdefault(dev, {"rate_hz": 0.0, "last_seen_unix_s": 0.0, "samples": 0})
            if rate >= d["rate_hz"]:
                d["rate_hz"], d["samples"] = round(float(rate), 1), int(t.size)
            d["last_seen_unix_s"] = max(d["last_seen_unix_s"], seen[fname])
        return out


def session_phase(session_id: str) -> float:
    """A number in [0, 1) fixed by the session id: where in its period a session's periodic work
    falls (issue 61: sessions that start together would otherwise all do it in the same tick)."""
    return int.from_bytes(hashlib.blake2b(session_id.encode(), digest_size=8).digest(), "big") / 2.0**64


def _table(session_id: str, fname: str, entry: tuple, i: int) -> Table:
    """The rows of ``entry`` (a :meth:`SessionBuffer._snapshot` entry) from row ``i`` on, as the
    importer's Table (:class:`_ArrayTable`: its numbers read from the buffer's arrays)."""
    t, vals, cols, text, dups = entry
    return _ArrayTable(
        Path(f"live:{session_id}/{fname}"),
        t[i:],
        vals[i:],
        cols,
        [*SENSORS[fname].cols, *SENSORS[fname].optional],
        None if text is None else (TEXT_COLS[fname], text[i:]),
        dups,
    )


class _ArrayTable(Table):
    """A :class:`~wearnav.importers.sensorlogger_map.Table` over the buffer's arrays: ``values``
    reads the columns from them (``has``, ``column``, ``numeric``, ``text``, ``rows`` too), the same
    numbers the DataFrame holds (float64, as the buffer keeps them), and the DataFrame is made only
    where something asks for it (nothing in the importer's step does): a DataFrame per sensor and
    update, and pandas' column lookups, were a third of an update's build (issue 37)."""

    def __init__(
        self,
        path: Path,
        t_ns: np.ndarray,
        vals: np.ndarray,
        cols: list[str],
        all_cols: list[str],
        text: tuple[str, np.ndarray] | None,
        duplicates: int,
    ):
        self.path, self.t_ns, self.duplicates = path, t_ns, duplicates
        self._vals, self._cols, self._all, self._text = vals, cols, all_cols, text
        self._df: pd.DataFrame | None = None

    @property
    def df(self) -> pd.DataFrame:
        if self._df is None:
            vals, cols = self._vals, self._cols
            df = (
                pd.DataFrame(vals[:, : len(cols)], columns=cols)
                if len(cols) == vals.shape[1]
                else pd.DataFrame(vals, columns=self._all)[cols]
            )
            if self._text is not None:
                df[self._text[0]] = self._text[1]
            self._df = df
        return self._df

    def values(self, cols: list[str]) -> np.ndarray:
        missing = [c for c in cols if c not in self._cols]
        if missing:  # as pandas says it
            raise KeyError(f"{missing} not in index")
        return self._vals[:, [self._all.index(c) for c in cols]]

    def has(self, col: str) -> bool:
        return col in self._cols or (self._text is not None and col == self._text[0])

    def column(self, col: str) -> np.ndarray:
        return self.values([col])[:, 0]

    def numeric(self, col: str) -> np.ndarray:  # the buffer keeps numbers, NaN for anything else (_num)
        return self.column(col)

    def text(self, col: str) -> pd.Series:
        if self._text is None or col != self._text[0]:
            return super().text(col)
        return pd.Series(self._text[1])

    def rows(self, keep: np.ndarray) -> Table:
        text = None if self._text is None else (self._text[0], self._text[1][keep])
        return _ArrayTable(self.path, self.t_ns[keep], self._vals[keep], self._cols, self._all, text, self.duplicates)


def cut(rec: Recording, t_from: float) -> Recording:
    """``rec`` from ``t_from`` (s) on: every stream and the fixes."""
    devices = {}
    for dev, s in rec.devices.items():
        i = int(np.searchsorted(s.t, t_from, side="left"))  # times increase: the rows from i on
        if i < len(s.t):
            devices[dev] = sliced(s, slice(i, None), worn=False)
    fixes = None
    if rec.fixes is not None and (k := rec.fixes.t >= t_from).any():
        fixes = Fixes(t=rec.fixes.t[k], pos=rec.fixes.pos[k], accuracy=rec.fixes.accuracy[k])
    if not devices:
        raise FormatError(f"no samples after t = {t_from:g} s yet", rec.meta.get("file"))
    return derived(rec, devices, fixes)


def sliced(s: DeviceStream, k: np.ndarray | slice, worn: bool = True) -> DeviceStream:
    """``s`` at the samples ``k`` (a mask, indices in order, or a slice: views of ``s``'s arrays, which
    nothing writes to), not validated again: a slice of a valid stream is valid, and its checks would
    change nothing (its times still increase, its values
    are finite and in range, its quaternions as unit as they were; the units check is off, as for
    any slice). ``worn`` False leaves the worn flags out. A DeviceStream's checks of every slice were
    a tenth of building an update's Recording."""
    out = copy.copy(s)  # no __init__: nothing converted or checked
    out.t, out.acc = s.t[k], s.acc[k]
    out.gyro = None if s.gyro is None else s.gyro[k]
    out.quat = None if s.quat is None else s.quat[k]
    out.worn = None if s.worn is None or not worn else s.worn[k]
    out.check_units = False
    return out


def derived(rec: Recording, devices: dict[str, DeviceStream], fixes: Fixes | None) -> Recording:
    """``rec`` with other ``devices`` and ``fixes`` cut from its own: a shallow copy, not validated
    again (a Recording's checks, its labels table's above all, cost milliseconds, and a slice of a
    valid recording is valid)."""
    out = copy.copy(rec)
    out.devices, out.fixes = devices, fixes
    return out


__all__ = ["AUTO", "CONVENTIONS", "DECIDE_S", "RECHECK_S", "SessionBuffer", "cut", "derived", "session_phase", "sliced"]
