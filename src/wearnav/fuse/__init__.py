"""Fusing an odometry path with every location fix of a walk (issue 25): the path a user gets.

The odometry (a learned model or PDR, integrated from (0, 0) in an arbitrary horizontal frame)
has a good shape but an unknown heading, a scale that is often off (learned paths run ~17 %
short on unseen buildings) and a heading that drifts slowly. The phone's fixes have the right
frame but are biased for minutes at a time indoors. Three anchorings place
the path on the fixes (:data:`ANCHORS`, `track --anchor`): ``first-fixes`` and ``rigid``
(:mod:`.anchor`) and ``smooth``, the default (:mod:`.smoother`).

Before any fit, every fix is classified by :func:`wearnav.fixcheck.check_fixes` (issue 18 §5): a
NaN position, a time outside the walk, an accuracy wider than ``wide_m``, a stale repeat of the
previous fix (a phone re-reporting its last fix says nothing new) or a jump no walker could make
(a cached first fix hundreds of metres away) is dropped, with its reason, in all three
anchorings; the rest are marked used, or down-weighted where the robust loss gives them less than a
fifth of a weight (smoother), or unused (first-fix anchoring, after its first minute).
:attr:`FuseResult.fixes` holds the status, reason and weight of every fix given; ``info`` the
counts (``fix_status``, ``fixes_dropped`` by reason, ``fixes_dropped_index``). Fallbacks, each said
in the result's ``warnings``: no kept fix inside the walk → the path is returned unmoved (from
(0, 0)); one fix, or fixes that do not spread (all identical) → translation onto them only; most
fixes down-weighted (they disagree with the odometry and each other) → the first-fix anchoring of
:func:`first_fix_anchor`.

One job per module:

:mod:`.config`     the smoother's constants (:class:`FuseConfig`), its result (:class:`FuseResult`),
                   a fix's σ from its reported accuracy;
:mod:`.anchor`     the fixes' check and the rigid anchorings (first-fix, rigid);
:mod:`.smoother`   the smoother's model, its solve and each point's σ;
:mod:`.calibrate`  the smoother's calibration for a model and a recording (odometry walk, σ scale,
                   heading prior): :func:`config_for`;
:mod:`.live`       the smoother as a fixed-lag smoother, for the live receiver.

:class:`wearnav.fuse.live.IncrementalFuser` is the same estimate as a fixed-lag smoother for the live
receiver: each update solves only the last ``lag_s`` seconds, the walk before them marginalised into a
Gaussian prior on the window's start state, so its cost does not grow with the session; scipy
rather than GTSAM, so that batch and fixed-lag share one residual function (measurements and why:
Decision: docs/decisions/0020-fused-path-smoother.md).
"""

from __future__ import annotations

from wearnav.errors import ValidationError
from wearnav.fuse.anchor import first_fix_anchor, rigid_anchor, rigid_fit
from wearnav.fuse.calibrate import (
    calibrated,
    config_for,
    fix_lag_of,
    fix_lags,
    known_heading_deg,
    odometry_walk_sigma,
    sigma_scale_of,
)
from wearnav.fuse.config import (
    ANCHOR_S,
    CALIBRATION_JSON,
    DOWNWEIGHT,
    MAX_FIX_LAG_S,
    MEASURED_FIX_BIAS,
    RADIUS_68,
    RAYLEIGH_MEDIAN,
    FuseConfig,
    FuseResult,
    fix_sigma_m,
)
from wearnav.fuse.smoother import smooth

ANCHORS = {"first-fixes": first_fix_anchor, "rigid": rigid_anchor, "smooth": smooth}


def fuse(t, xy, fix_t, fix_pos, fix_accuracy, anchor: str = "smooth", cfg: FuseConfig = FuseConfig()) -> FuseResult:
    """The path of odometry ``xy`` placed on the fixes by ``anchor`` (first-fixes | rigid | smooth)."""
    if anchor not in ANCHORS:
        raise ValidationError(f"unknown anchoring {anchor!r}; one of {', '.join(ANCHORS)}")
    return ANCHORS[anchor](t, xy, fix_t, fix_pos, fix_accuracy, cfg)


__all__ = [
    "ANCHORS",
    "ANCHOR_S",
    "CALIBRATION_JSON",
    "DOWNWEIGHT",
    "MAX_FIX_LAG_S",
    "MEASURED_FIX_BIAS",
    "RADIUS_68",
    "RAYLEIGH_MEDIAN",
    "FuseConfig",
    "FuseResult",
    "calibrated",
    "config_for",
    "first_fix_anchor",
    "fix_lag_of",
    "fix_lags",
    "fix_sigma_m",
    "fuse",
    "known_heading_deg",
    "odometry_walk_sigma",
    "rigid_anchor",
    "rigid_fit",
    "sigma_scale_of",
    "smooth",
]
