"""A walk's floor from its radio positions' floor votes, and from the barometer (issue 60; decision 0049).

:func:`floor_sequence` makes a walk's votes one sequence (a hidden floor that changes as rarely as it
did between the survey walks' consecutive scans, :func:`floor_switch_rate`); :func:`floor_over_time`
follows the barometer from the start floor most votes agree with, or the votes alone, smoothed
(:func:`floor_at`). Used by :mod:`wearnav.fuse.radiomap` and :mod:`wearnav.fuse.placement`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from wearnav.core.timeseries import nearest
from wearnav.fuse.floors import FloorLevels, floor_track
from wearnav.recording import Pressure


def floor_at(t_fix: np.ndarray, floor_fix: np.ndarray, times: np.ndarray, window_s: float = 10.0) -> np.ndarray:
    """The floor at ``times``: at the nearest fix with a floor, the most frequent floor of those
    fixes within ``window_s`` s of it (one wrong scan does not change floor); NaN without any."""
    ok = np.isfinite(floor_fix)
    t_fix, floor_fix = t_fix[ok], floor_fix[ok]
    times = np.asarray(times, np.float64)
    if t_fix.size == 0:
        return np.full(times.shape, np.nan)
    lo = np.searchsorted(t_fix, t_fix - window_s)
    hi = np.searchsorted(t_fix, t_fix + window_s, side="right")
    smooth = np.empty(t_fix.size)
    for i, (a, b) in enumerate(zip(lo, hi)):
        vals, n = np.unique(floor_fix[a:b], return_counts=True)
        smooth[i] = vals[np.argmax(n)]
    return smooth[nearest(t_fix, times)]


def floor_switch_rate(t: np.ndarray, walk: np.ndarray, floor: np.ndarray) -> float:
    """How often the floor changes from one scan of a survey walk to its next (scans' times, walks and
    floors; Laplace's rule, so a survey that never changes floor still allows a change:
    (changes + 1) / (pairs + 2))."""
    order = np.lexsort((t, walk.astype(str)))
    walk, floor = walk.astype(str)[order], floor[order]
    same_walk = walk[1:] == walk[:-1]
    changes = int(np.sum(same_walk & (floor[1:] != floor[:-1])))
    return (changes + 1) / (int(same_walk.sum()) + 2)


def floor_sequence(votes: np.ndarray, floors: np.ndarray, vote_right: float, switch: float) -> np.ndarray:
    """The most likely floor of each scan of one walk (Viterbi): a hidden floor that changes from one
    scan to the next with probability ``switch`` (to any other floor alike), each scan's vote right
    with probability ``vote_right`` (the map's cross-validated floor accuracy), else any other floor
    alike. A single wrong vote, or a run of a few in a long walk, does not change floor."""
    n, m = votes.size, floors.size
    right = float(np.clip(vote_right, 0.5, 0.999))
    switch = float(np.clip(switch, 1e-9, 0.5))
    log_emit = np.where(votes[:, None] == floors[None, :], np.log(right), np.log((1 - right) / max(m - 1, 1)))
    log_stay, log_move = np.log(1 - switch), np.log(switch / max(m - 1, 1))
    trans = np.where(np.eye(m, dtype=bool), log_stay, log_move)
    score = log_emit[0] - np.log(m)
    back = np.zeros((n, m), np.int64)
    for i in range(1, n):
        cand = score[:, None] + trans  # from (rows) → to (columns)
        back[i] = np.argmax(cand, axis=0)
        score = cand[back[i], np.arange(m)] + log_emit[i]
    path = np.empty(n, np.int64)
    path[-1] = int(np.argmax(score))
    for i in range(n - 1, 0, -1):
        path[i - 1] = back[i, path[i]]
    return floors[path]


def floor_over_time(
    pressure: Pressure | None,
    levels: FloorLevels | None,
    t_radio: np.ndarray,
    floor_radio: np.ndarray,
    times: np.ndarray,
) -> tuple[np.ndarray, dict[str, Any]]:
    """The floor at ``times`` (module docstring): with a barometer and the site's floor ``levels``, the
    barometer's floor track (:func:`wearnav.fuse.floors.floor_track`) from the start floor whose track
    agrees with the most radio floor votes (``floor_radio`` at ``t_radio``; a tie goes to the floor
    the first votes name); else the votes alone (:func:`floor_at`). Also what was done."""
    ok = np.isfinite(floor_radio)
    t_radio, floor_radio = np.asarray(t_radio)[ok], np.asarray(floor_radio)[ok]
    if pressure is None or len(pressure) < 2 or levels is None or not t_radio.size:
        return floor_at(t_radio, floor_radio, times), {"floor_by": "Wi-Fi votes"}
    candidates = levels.floors or sorted({int(f) for f in floor_radio})
    first = floor_at(t_radio, floor_radio, t_radio[:1])[0]
    agree = {f: int(np.sum(floor_track(pressure, f, t_radio, levels) == floor_radio)) for f in candidates}
    start = max(candidates, key=lambda f: (agree[f], f == first))
    out = floor_track(pressure, start, np.asarray(times, np.float64), levels).astype(np.float64)
    return out, {
        "floor_by": "barometer from the start floor most Wi-Fi votes agree with",
        "start_floor": int(start),
        "votes_agreeing": round(agree[start] / t_radio.size, 3),
    }
