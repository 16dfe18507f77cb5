"""Radio positions as location fixes (issue 60 §3): :func:`with_radio_fixes` adds a recording's
scans' positions from a :class:`wearnav.fuse.radiomap.RadioMap` to its fixes, for the smoother and
the particle filter as any fix, beside the phone's own fixes, whose accuracy
:func:`phone_accuracy_scale` grows where they disagree with the radio positions. Decisions:
docs/decisions/0049-radio-map-bench-floor-weights.md, 0050-radio-sigma-without-gnss.md."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from wearnav.core import geo
from wearnav.core.timeseries import nearest
from wearnav.fuse.config import RADIUS_68
from wearnav.fuse.radiomap import NO_FIT, RadioMap, RadioPositions
from wearnav.recording import Fixes, Recording

PAIR_S = 1.0  # a phone fix and a radio position this close in time are compared (phone_accuracy_scale)
MIN_PAIRS = 5  # fewer pairs: the phone's accuracy is kept as reported
# Beside the phone's own fixes, a radio position counts as if its accuracy were this share of its
# calibrated 68 % radius. Chosen by leaving one IPIN 2023 trial out (of 1, 0.7, 0.5, 0.35, 0.25,
# 0.18; 9 of 12 folds chose 0.35, 3 chose 0.5; scored on the trial left out 3.70 / 5.73 / 10.15 m
# against 4.28 / 6.45 / 11.63 at 1): the smoother's robust loss takes the radio positions' heavy tail
# itself, and their 68 % radius is set by that tail. Growing the phone's accuracy instead (by 1/0.35)
# measured worse (4.04 / 5.78 / 10.38). Without phone fixes the radio positions keep their radius:
# against the odometry alone a smaller one made IPIN's radio-only path worse. Only IPIN has both.
RADIO_BESIDE_FIXES = 0.35
# A radio map and a recording whose positions cannot be put in one frame (in_recordings_frame)
NO_PLACE = (
    "the radio map's positions and this recording's are not in one frame (one has a lat/lon origin, the other none)"
)
MAX_ACCURACY_SCALE = 30.0  # the phone's accuracy grows at most this much (a fix is then all but ignored)


def with_radio_fixes(rec: Recording, rmap: RadioMap) -> tuple[Recording, np.ndarray, dict[str, Any], list[str]]:
    """``rec`` with its scans' radio positions added to its location fixes (accuracy: the 68 % radius,
    times :data:`RADIO_BESIDE_FIXES` beside the phone's own fixes; floor: the map's), for the smoother
    and the particle filter as any fix, the phone's own fixes' accuracy grown where they disagree with
    the radio positions (:func:`phone_accuracy_scale`); (M,) bool which fixes are
    the radio map's; what was done (``used``, ``positions`` ...); warnings. A map sharing no access
    point with the recording is not used (:data:`NO_FIT`): ``rec`` comes back unchanged."""
    none = np.zeros(0 if rec.fixes is None else len(rec.fixes), bool)
    info: dict[str, Any] = {"used": False, "access_points_in_map": len(rmap.bssids)}
    if rec.wifi is None:
        why = "the recording has no Wi-Fi scans"
        return rec, none, info | {"why": why}, [f"{rec.name}: {why}: the radio map is not used"]
    if not rmap.fits(rec):
        return rec, none, info | {"why": NO_FIT}, [f"{rec.name}: {NO_FIT}"]
    # σ by groups beside the phone's fixes, the one scale without them (module docstring)
    pos = rmap.locate(rec.wifi, by_group=rec.fixes is not None)
    info |= pos.info
    if not len(pos):
        why = f"no scan shares {rmap.cfg.min_common_aps} access points with the radio map"
        return rec, none, info | {"why": why}, [f"{rec.name}: {why}: the radio map is not used"]
    rec, pos, apart = in_recordings_frame(rec, rmap, pos)
    if apart is not None:
        return rec, none, info | {"why": apart}, [f"{rec.name}: {apart}: the radio map is not used"]
    floors, counts = np.unique(pos.floor, return_counts=True)
    info |= {
        "used": True,
        "median_sigma_m": round(float(np.median(pos.sigma_m)), 2),
        "floors": {str(int(f)): int(n) for f, n in zip(floors, counts)},
    }
    old = rec.fixes
    if old is None:
        t, xy, acc, fl, radio = pos.t, pos.xy, pos.accuracy_m, pos.floor, np.ones(len(pos), bool)
    else:
        old_floor = old.floor if old.floor is not None else np.full(len(old), np.nan)
        scale = phone_accuracy_scale(old.t, old.pos[:, :2], old.accuracy, pos)
        info["phone_accuracy_scale"] = None if scale is None else round(scale, 3)
        t = np.concatenate([old.t, pos.t])
        xy = np.concatenate([old.pos[:, :2], pos.xy])
        acc = np.concatenate([old.accuracy * (scale or 1.0), RADIO_BESIDE_FIXES * pos.accuracy_m])
        fl = np.concatenate([old_floor, pos.floor])
        radio = np.concatenate([np.zeros(len(old), bool), np.ones(len(pos), bool)])
    order = np.lexsort((radio, t))
    t = t[order].copy()
    for k in range(1, t.size):  # a fix and a scan at one instant: the scan a millisecond later
        if t[k] <= t[k - 1]:
            t[k] = t[k - 1] + 1e-3
    fixes = Fixes(t, xy[order], acc[order], fl[order])
    return dataclasses.replace(rec, fixes=fixes), radio[order], info, []


def in_recordings_frame(
    rec: Recording, rmap: RadioMap, pos: RadioPositions
) -> tuple[Recording, RadioPositions, str | None]:
    """``pos`` (the map's frame) in ``rec``'s: unchanged where both are about one lat/lon origin (or
    neither has one: one local frame, as a site plan's walks and their map); converted through lat/lon
    where both have one (a user's own recording, about its first fix, with a map of a venue); a
    recording without fixes and without an origin takes the map's (its path then lies where the map
    does). A map without an origin cannot join a recording that has one: the reason (third item)."""
    lat0, lon0 = rec.meta.get("origin_lat"), rec.meta.get("origin_lon")
    rec_o = None if lat0 is None or lon0 is None else (float(lat0), float(lon0))
    map_o = rmap.origin
    if map_o == rec_o or (map_o is not None and rec_o is not None and np.allclose(map_o, rec_o, rtol=0, atol=1e-10)):
        return rec, pos, None
    if map_o is None:  # a map whose card predates its origin says so
        return (
            rec,
            pos,
            NO_PLACE + ("" if "origin" in rmap.card else " (this map's card predates its origin: build it again)"),
        )
    if rec_o is None:
        if rec.fixes is not None:  # fixes in a local frame of no known place: they cannot be related
            return rec, pos, NO_PLACE
        meta = {**rec.meta, "origin_lat": map_o[0], "origin_lon": map_o[1], "projection": geo.PROJECTION}
        return dataclasses.replace(rec, meta=meta), pos, None
    lat, lon = geo.local_to_latlon(pos.xy, *map_o)
    return rec, dataclasses.replace(pos, xy=geo.latlon_to_local(lat, lon, *rec_o)), None


def phone_accuracy_scale(
    fix_t: np.ndarray, fix_xy: np.ndarray, fix_accuracy: np.ndarray, pos: RadioPositions
) -> float | None:
    """How many times the phone's reported accuracy must grow for its fixes to agree with the radio
    positions as two independent estimates should: the smallest scale s ≥ 1 that puts 68 % of the
    distances between a fix and the radio position nearest in time (within :data:`PAIR_S`) inside
    the 68 % radius of their combined σ, √((s σ_fix)² + σ_radio²). The radio map's σ is calibrated on
    walks it never saw; the phone's accuracy is its own claim, and underground (IPIN 2023's floor −2)
    it claims 5–10 m for fixes 9–15 m off. At most :data:`MAX_ACCURACY_SCALE`; None with fewer than
    :data:`MIN_PAIRS` pairs."""
    if not len(pos) or not len(fix_t):
        return None
    k = nearest(pos.t, fix_t)
    near = np.abs(pos.t[k] - fix_t) <= PAIR_S
    if near.sum() < MIN_PAIRS:
        return None
    d = np.linalg.norm(fix_xy[near] - pos.xy[k[near]], axis=1)
    s_fix, s_radio = fix_accuracy[near] / RADIUS_68, pos.sigma_m[k[near]]

    def inside(scale: float) -> float:
        return float(np.mean(d <= RADIUS_68 * np.hypot(scale * s_fix, s_radio)))

    if inside(1.0) >= 0.68:
        return 1.0
    if inside(MAX_ACCURACY_SCALE) < 0.68:
        return MAX_ACCURACY_SCALE
    lo, hi = 1.0, MAX_ACCURACY_SCALE
    for _ in range(40):  # bisection: inside() grows with the scale
        mid = float(np.sqrt(lo * hi))
        lo, hi = (lo, mid) if inside(mid) >= 0.68 else (mid, hi)
    return hi
