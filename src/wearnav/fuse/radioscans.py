"""A recording's Wi-Fi scans as a radio map reads them (issue 60 §2): :class:`Scans` (a long table
of readings by scan), :func:`scans_of` (stale and repeated readings left out) and :func:`fingerprints`
(one RSSI per access point of a map). Split out of :mod:`wearnav.fuse.radiomap`, which builds and
uses maps from them (and re-exports these names)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import pandas as pd

from wearnav.recording import WifiScans


@dataclasses.dataclass
class Scans:
    """Scans as a long table: scan ``t`` (S,), and per reading its scan index ``scan`` (R,), ``bssid``
    (R,) and ``rssi_dbm`` (R,) (stale readings already left out, one reading per access point and
    scan). Survey scans also carry ``xy`` (S, 2), ``floor`` (S,) and ``walk`` (S,) names."""

    t: np.ndarray
    scan: np.ndarray
    bssid: np.ndarray
    rssi_dbm: np.ndarray
    xy: np.ndarray | None = None
    floor: np.ndarray | None = None
    walk: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.t.size)

    def subset(self, keep: np.ndarray) -> Scans:
        """The scans where ``keep`` (S,) bool, renumbered."""
        new = np.full(self.t.size, -1)
        new[keep] = np.arange(int(keep.sum()))
        r = keep[self.scan]
        opt = {
            k: None if v is None else v[keep] for k, v in (("xy", self.xy), ("floor", self.floor), ("walk", self.walk))
        }
        return Scans(self.t[keep], new[self.scan[r]], self.bssid[r], self.rssi_dbm[r], **opt)

    @classmethod
    def concat(cls, parts: Sequence[Scans]) -> Scans:
        offsets = np.cumsum([0] + [len(p) for p in parts[:-1]])
        cat = np.concatenate
        return cls(
            cat([p.t for p in parts]),
            cat([p.scan + o for p, o in zip(parts, offsets)]).astype(np.int64),
            cat([p.bssid for p in parts]),
            cat([p.rssi_dbm for p in parts]),
            *(
                None if any(getattr(p, k) is None for p in parts) else cat([getattr(p, k) for p in parts])
                for k in ("xy", "floor", "walk")
            ),
        )


def scans_of(wifi: WifiScans, stale_s: float) -> Scans:
    """A recording's scans (readings sharing one time), readings older than ``stale_s`` left out and,
    of an access point heard twice in a scan, the fresher reading kept (the louder where equally fresh)."""
    starts = wifi.scan_starts
    scan = np.repeat(np.arange(starts.size - 1), np.diff(starts))
    age = np.zeros(len(wifi)) if wifi.t_seen is None else np.nan_to_num(wifi.t - wifi.t_seen, nan=0.0)
    fresh = age <= stale_s
    df = pd.DataFrame({"scan": scan, "bssid": wifi.bssid, "rssi": wifi.rssi_dbm, "age": age})[fresh]
    df = df.sort_values(["scan", "bssid", "age", "rssi"], ascending=[True, True, True, False], kind="stable")
    df = df.drop_duplicates(["scan", "bssid"])
    return Scans(
        wifi.t[starts[:-1]],
        df["scan"].to_numpy(np.int64),
        df["bssid"].to_numpy(object),
        df["rssi"].to_numpy(np.float64),
    )


def fingerprints(scans: Scans, bssids: Sequence[str], missing_dbm: float) -> tuple[np.ndarray, np.ndarray]:
    """(S, A) RSSI of each scan at each of ``bssids`` (``missing_dbm`` where not heard, weaker readings
    clipped to it) and (S,) how many of them each scan heard."""
    col = pd.Index(list(bssids)).get_indexer(scans.bssid)
    known = col >= 0
    x = np.full((len(scans), len(bssids)), missing_dbm, np.float32)
    x[scans.scan[known], col[known]] = np.maximum(scans.rssi_dbm[known], missing_dbm)
    return x, np.bincount(scans.scan[known], minlength=len(scans))


__all__ = ["Scans", "fingerprints", "scans_of"]
