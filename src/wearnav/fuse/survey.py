"""Where a survey walk was at any time between its surveyed points (issue 60 §2): the positions a
radio map (:mod:`wearnav.fuse.radiomap`) labels each scan with.

A survey walk has truth only at sparse surveyed points (IPIN's POSI every 10–25 s, ILC2's
waypoints every few seconds to a minute). A straight line between two points is wrong wherever the
walker turned; instead the walk's own odometry (:data:`SURVEY_ODOMETRY`, PDR: steps along the
phone's pointing direction, cadence-scaled stride, :mod:`wearnav.models.pdr`) gives the shape, and
each segment between consecutive surveyed points is rotated and scaled (one complex factor, a 2-D
similarity) so that the odometry's displacement over the segment joins the two points exactly:

    p(t) = p_a + m · (o(t) − o(t_a)),   m = (p_b − p_a) / (o(t_b) − o(t_a))   (complex x + iy)

A segment falls back to the straight line where the odometry barely moved (< :data:`MIN_ODO_M`),
spans less than :data:`MIN_COVERED` of it, or the factor's scale is implausible (outside
:data:`SCALE_RANGE`: a missed or doubled step count);
it is not placed at all where it spans more than :data:`MAX_SPAN_S` or changes floor (stairs and
lifts: the floor and the shape are both unknown there). Times before the first or after the last
surveyed point are not placed.

Measured (skip-one: every other surveyed point left out and placed from its neighbours, so the
spans are twice as long as in use; :func:`skip_one_errors`, `wearnav radiomap eval`), median / p75 /
p95: IPIN 2023, 44 walks, 256 points: straight line 2.98 / 4.54 / 7.01 m, plain PDR (``pdr``) 0.88 /
1.64 / 3.05, this odometry 0.86 / 1.52 / 2.57; ILC2 site 1, 571 walks, 1541 points: straight line
2.11 / 3.41 / 5.64, plain PDR 1.82 / 2.77 / 5.60, this odometry 1.47 / 2.16 / 3.49 (1.51 / 2.56 / 4.69
when a segment had to be covered whole: the odometry starts ~2 s into a walk, :data:`MIN_COVERED`).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from wearnav.evaluate import odometry
from wearnav.fuse.config import SURVEY_ODOMETRY  # the registry's PDR that measured best above
from wearnav.recording import Recording, Trajectory

MAX_SPAN_S = 120.0  # longer gaps between surveyed points are not placed
MIN_ODO_M = 0.5  # the odometry moved less than this over a segment: the straight line
SCALE_RANGE = (1 / 3, 3.0)  # |m| outside: the step count is off, the straight line instead
MIN_COVERED = 0.5  # share of a segment's time the odometry must span for it to be warped


@functools.lru_cache(maxsize=4)
def _model(name: str):
    from wearnav.train.resolve import locate_model, resolve_model

    return resolve_model(locate_model(name, "odometry"), "odometry")


def odometry_path(rec: Recording, model_name: str = SURVEY_ODOMETRY) -> tuple[np.ndarray, np.ndarray]:
    """The registry model ``model_name``'s path of ``rec`` (times (N,), positions (N, 2) from (0, 0),
    in the recording's world frame), as `wearnav track` integrates it; empty where the walk is
    shorter than one window."""
    model, cfg = _model(model_name)
    *_, t, xy = odometry(model, cfg, rec)  # as `wearnav track` runs it (:func:`wearnav.evaluate.odometry`)
    return t, xy


def _at(t_odo: np.ndarray, xy_odo: np.ndarray, times: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(times, t_odo, xy_odo[:, j]) for j in range(2)], axis=1)


def positions_between(
    truth: Trajectory,
    t_odo: np.ndarray,
    xy_odo: np.ndarray,
    times: np.ndarray,
    max_span_s: float = MAX_SPAN_S,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    """The walk's position (N, 2) and floor (N,) at ``times`` (N,), and which are placed (N,) bool,
    from its surveyed points ``truth`` and its odometry ``t_odo``, ``xy_odo`` (module docstring);
    ``info``: how many segments were warped by the odometry, straight or not placed."""
    times = np.asarray(times, np.float64)
    tt, pp = truth.t, truth.pos[:, :2]
    floor = truth.floor if truth.floor is not None else np.zeros(len(truth))
    xy = np.full((times.size, 2), np.nan)
    fl = np.full(times.size, np.nan)
    info = {"segments_odometry": 0, "segments_straight": 0, "segments_not_placed": 0}
    if len(tt) < 2:
        return xy, fl, np.zeros(times.size, bool), info
    seg_ok = (np.diff(tt) <= max_span_s) & (floor[1:] == floor[:-1])
    # a segment is warped where the odometry covers at least MIN_COVERED of it (it starts at the first
    # window's centre, ~2 s into a walk; np.interp holds its ends outside)
    if t_odo.size >= 2:
        inside = np.minimum(tt[1:], t_odo[-1]) - np.maximum(tt[:-1], t_odo[0])
        covered = inside >= MIN_COVERED * np.diff(tt)
    else:
        covered = np.zeros(len(tt) - 1, bool)
    o = _at(t_odo, xy_odo, tt) if t_odo.size >= 2 else np.zeros((len(tt), 2))
    d = (o[1:, 0] - o[:-1, 0]) + 1j * (o[1:, 1] - o[:-1, 1])
    dp = (pp[1:, 0] - pp[:-1, 0]) + 1j * (pp[1:, 1] - pp[:-1, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        m = dp / d
    warp = covered & (np.abs(d) >= MIN_ODO_M) & (np.abs(m) >= SCALE_RANGE[0])
    warp &= np.abs(m) <= SCALE_RANGE[1]
    info["segments_odometry"] = int((warp & seg_ok).sum())
    info["segments_straight"] = int((~warp & seg_ok).sum())
    info["segments_not_placed"] = int((~seg_ok).sum())
    k = np.searchsorted(tt, times, side="right") - 1
    inside = (k >= 0) & (k < len(tt) - 1)
    k = np.clip(k, 0, len(tt) - 2)
    placed = inside & seg_ok[k]
    lam = np.clip((times - tt[k]) / (tt[k + 1] - tt[k]), 0.0, 1.0)
    line = pp[k] + lam[:, None] * (pp[k + 1] - pp[k])
    use = placed & warp[k]
    if use.any():
        oq = _at(t_odo, xy_odo, times[use])
        z = ((oq[:, 0] - o[k[use], 0]) + 1j * (oq[:, 1] - o[k[use], 1])) * m[k[use]]
        line[use] = pp[k[use]] + np.stack([z.real, z.imag], axis=1)
    xy[placed] = line[placed]
    fl[placed] = floor[k[placed]]
    return xy, fl, placed, info


def skip_one_errors(truth: Trajectory, t_odo: np.ndarray, xy_odo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How well the placement fills a gap: every other surveyed point (1, 3, 5 ...) left out and
    placed from the rest; errors (m) of the odometry-warped and of the straight-line placement."""
    keep = np.arange(0, len(truth), 2)
    probe = np.arange(1, len(truth) - 1, 2)
    if probe.size == 0:
        return np.empty(0), np.empty(0)
    thin = Trajectory(truth.t[keep], truth.pos[keep], floor=None if truth.floor is None else truth.floor[keep])
    xy, _, ok, _ = positions_between(thin, t_odo, xy_odo, truth.t[probe])
    line, _, ok_line, _ = positions_between(thin, np.empty(0), np.empty((0, 2)), truth.t[probe])
    err = np.linalg.norm(xy - truth.pos[probe, :2], axis=1)
    err_line = np.linalg.norm(line - truth.pos[probe, :2], axis=1)
    return err[ok], err_line[ok_line]
