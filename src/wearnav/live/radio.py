"""A radio map's positions of a live session's Wi-Fi scans among each update's fixes (issue 60 §3,
``wearnav live --radiomap``): :class:`RadioFixes`, which :class:`wearnav.live.tracker.LiveTracker`
holds; the scans come from the session buffer (:class:`wearnav.live.wifi.WifiRows`)."""

from __future__ import annotations

import dataclasses

from wearnav.fuse.radiofixes import with_radio_fixes
from wearnav.fuse.radiomap import RadioMap
from wearnav.recording import Recording


class RadioFixes:
    """A radio map's positions of a session's scans among each update's fixes (``LiveTracker(radiomap=)``)."""

    def __init__(self, rmap: RadioMap):
        self.rmap = rmap
        self._said: set[str] = set()

    def join(self, rec: Recording, buf) -> tuple[Recording, list[str]]:
        """``rec`` (an update's slice of the session) with the positions of the session's scans since
        its start among its fixes (:func:`wearnav.fuse.radiofixes.with_radio_fixes`: in ``rec``'s frame,
        beside the phone's fixes as ``track --radiomap`` weighs them); and the map's warnings not said
        before (without the recording's name: the session's page says whose)."""
        wifi = getattr(buf, "wifi", None)
        if wifi is None or buf.t0_unix_ns is None:
            return rec, []
        scans = wifi.scans(buf.t0_unix_ns, min(float(s.t[0]) for s in rec.devices.values()))
        if scans is None:
            return rec, []
        out, _, _, warnings = with_radio_fixes(dataclasses.replace(rec, wifi=scans), self.rmap)
        new = [w.split(": ", 1)[1] for w in warnings]
        new = [w for w in new if w not in self._said]
        self._said.update(new)
        return out, new


__all__ = ["RadioFixes"]
