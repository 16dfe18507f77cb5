"""A live session's Wi-Fi scans (issue 60 §3, ``wearnav live --radiomap``): :class:`WifiRows`.

Sensor Logger (Android) pushes each scan's readings as payload entries named ``wifi`` whose
``values`` are the columns of its ``WiFi.csv`` (UNITS.md "WiFi": ``ssid``, ``bssid``, ``frequency``
MHz, ``level`` dBm; :mod:`wearnav.importers.sensorlogger_radio`). The receiver stores them as it
stores every sensor it does not read (:mod:`wearnav.live.push`: any JSON values, the body kept
whole); the session buffer hands each message's ``wifi`` entries here, and the tracker asks for the
scans since an update's start (:meth:`WifiRows.scans`) to turn them into radio positions
among the update's fixes (:class:`wearnav.live.radio.RadioFixes`). Light on purpose: the receiver
imports it, and a receiver that only stores (``--no-track``) never loads torch. A reading the importer would refuse (no BSSID, a
level or frequency that is not one) is left out and counted (``dropped``), never failing the session:
it reached the store unchecked. A reading repeated within a scan (same time and BSSID) counts once.
"""

from __future__ import annotations

import bisect
import threading

import numpy as np

from wearnav.recording import WifiScans
from wearnav.recording.radio import RSSI_DBM_RANGE, WIFI_FREQ_MHZ_RANGE, repeated_readings

PUSH_NAME = "wifi"
NS = 1_000_000_000


def _number(x) -> float:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) else float("nan")


class WifiRows:
    """The session's Wi-Fi readings so far: time (ns), BSSID, SSID, frequency (MHz), level (dBm)."""

    def __init__(self) -> None:
        self._rows: list[tuple[int, str, str, float, float]] = []  # in time order
        self._times: list[int] = []  # their times (ns), for the start of a slice
        self._lock = threading.Lock()
        self.dropped = 0

    def __len__(self) -> int:
        return len(self._rows)

    def add(self, payload: list[dict]) -> int:
        """The ``wifi`` entries of one message's payload; returns how many readings were kept."""
        rows, dropped = [], 0
        for item in payload:
            if item.get("name") != PUSH_NAME:
                continue
            v, t = item.get("values"), item.get("time")
            if not isinstance(v, dict) or not isinstance(t, int) or isinstance(t, bool):
                dropped += 1
                continue
            raw = v.get("bssid")
            bssid = raw.strip().lower() if isinstance(raw, str) else ""
            level, freq = _number(v.get("level")), _number(v.get("frequency"))
            ok = (
                bssid != ""
                and RSSI_DBM_RANGE[0] <= level <= RSSI_DBM_RANGE[1]
                and WIFI_FREQ_MHZ_RANGE[0] <= freq <= WIFI_FREQ_MHZ_RANGE[1]
            )
            if not ok:
                dropped += 1
                continue
            ssid = v.get("ssid")
            rows.append((t, bssid, ssid if isinstance(ssid, str) else "", freq, level))
        with self._lock:
            for r in sorted(rows, key=lambda r: r[0]):  # kept in time order (stable: a scan's order kept)
                if not self._times or r[0] >= self._times[-1]:
                    self._times.append(r[0])
                    self._rows.append(r)
                else:  # a late message: in its place
                    i = bisect.bisect_right(self._times, r[0])
                    self._times.insert(i, r[0])
                    self._rows.insert(i, r)
            self.dropped += dropped
        return len(rows)

    def scans(self, t0_ns: int, t_from_s: float | None = None) -> WifiScans | None:
        """The readings at or after ``t_from_s`` (s since ``t0_ns``, the session's clock; None: all)
        as :class:`~wearnav.recording.WifiScans`, sorted by time; None where there are none."""
        with self._lock:  # the receiver's thread may be adding
            lo = 0 if t_from_s is None else bisect.bisect_left(self._times, int(t0_ns) + int(round(t_from_s * NS)))
            rows = self._rows[lo:]
        if not rows:
            return None
        t = (np.array([r[0] for r in rows], np.int64) - int(t0_ns)).astype(np.float64) / NS
        bssid = np.array([r[1] for r in rows], object)
        keep = np.ones(len(rows), bool)
        keep[repeated_readings(t, bssid)] = False
        ssid = np.array([r[2] for r in rows], object)
        freq, level = (np.array([r[k] for r in rows], np.float64) for k in (3, 4))
        return WifiScans(t[keep], bssid[keep], ssid[keep], freq[keep], level[keep])


__all__ = ["PUSH_NAME", "WifiRows"]
