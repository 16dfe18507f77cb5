"""A live session's fixes in the east/north frame of its first good fix: :class:`FixFrame`.

The buffer's Recordings give each update's fixes in metres about the session's first fresh fix
(``meta["origin_lat"]`` / ``["origin_lon"]``). The tracker's frame is the first fix that
:func:`wearnav.fixcheck.check_fixes` keeps, chosen once ``ORIGIN_MIN_FIXES`` are kept; until then
the fixes wait in the frame they came in. Where the two origins are the same (the usual case),
the metres are taken as they are; otherwise once through latitude and longitude
(:mod:`wearnav.core.geo`: the round trip gives back the same metres to 1e-9 m, at 1 ms a call,
issue 61). Split out of :mod:`wearnav.live.tracker`.
"""

from __future__ import annotations

import numpy as np

from wearnav.core import geo
from wearnav.fixcheck import check_fixes

ORIGIN_MIN_FIXES = 3  # the origin is the first good fix once this many fixes are kept


class FixFrame:
    """The fixes taken so far (``fixes``: t, east, north, accuracy) in the frame at ``origin``
    (lat, lon; None until chosen)."""

    def __init__(self) -> None:
        self.origin: tuple[float, float] | None = None
        self.fixes: list[tuple[float, float, float, float]] = []
        self._t = -np.inf  # the latest fix time taken, s
        # fixes not yet taken (before an origin, or in another frame): (t, east/north, accuracy, their frame's origin)
        self._pending: list[tuple[np.ndarray, np.ndarray, np.ndarray, tuple[float, float]]] = []

    def take(self, rec, wide_m: float) -> list[tuple[float, float, float, float]]:
        """The fixes of ``rec`` newer than the last taken, in this frame (a fix arriving late, older
        than the latest taken or than ``rec``'s start, is not taken): the rows added to ``fixes``,
        none while the origin waits for enough good fixes (``wide_m``: the check's wide fix)."""
        fx = rec.fixes
        if fx is None or len(fx) == 0:
            return []
        new = fx.t > self._t
        if not new.any():
            return []
        self._t = float(fx.t[new][-1])
        pos, acc, ft = fx.pos[new, :2], fx.accuracy[new], fx.t[new]
        lat0, lon0 = rec.meta.get("origin_lat"), rec.meta.get("origin_lon")
        same = self.origin is not None and self.origin == (lat0, lon0) and not self._pending
        if lat0 is None or lon0 is None or same:  # metres without a place on Earth, or in this frame
            return self._add(ft, pos, acc)
        self._pending.append((ft, pos, acc, (float(lat0), float(lon0))))
        if self.origin is None:
            t, p, a = self._pending_in(self._pending[0][3])
            check = check_fixes(-np.inf, np.inf, t, p, a, wide_m)
            if check.kept.sum() < ORIGIN_MIN_FIXES:
                return []
            first = int(np.flatnonzero(check.kept)[0])
            frame = self._pending[0][3]
            # the first kept fix's place; a fix at its frame's origin is that origin (no round trip)
            lat, lon = geo.local_to_latlon(p[first], *frame) if p[first].any() else ([frame[0]], [frame[1]])
            self.origin = (float(lat[0]), float(lon[0]))
        t, en, a = self._pending_in(self.origin)
        self._pending = []
        return self._add(t, en, a)

    def _pending_in(self, origin: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pending fixes' times, east/north in the frame at ``origin`` and accuracies: each
        group already in that frame as it is, the others through latitude and longitude."""
        t, en, a = [], [], []
        for ft, pos, acc, frame in self._pending:
            if frame != origin:
                pos = geo.latlon_to_local(*geo.local_to_latlon(pos, *frame), *origin)
            t.append(ft)
            en.append(pos)
            a.append(acc)
        return np.concatenate(t), np.concatenate(en), np.concatenate(a)

    def _add(self, t: np.ndarray, en: np.ndarray, acc: np.ndarray) -> list[tuple[float, float, float, float]]:
        rows = list(zip(t.tolist(), en[:, 0].tolist(), en[:, 1].tolist(), acc.tolist()))
        self.fixes += rows
        return rows


__all__ = ["ORIGIN_MIN_FIXES", "FixFrame"]
