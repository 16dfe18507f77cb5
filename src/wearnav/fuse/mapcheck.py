"""Whether a map-aware path can be trusted, and why it went where it did (issue 57).

A floor plan helps where the walk fits it: the walls then kill few particles and hold the path in the
corridor it is in. In a building the filter was not tuned in, or with a plan that is not where the walk
is (shifted, turned, another floor's), the walls either kill nearly every particle at every step (the
walk as the odometry draws it does not fit the plan anywhere near) or drag the cloud away from the
odometry, further than the odometry's own drift explains. :func:`check_map_path` reads both from the
filter's own per-step record (:attr:`wearnav.fuse.particles.MapResult.steps`) and the map-less path
from the same start, and says:

``fits``      the map-aware path is used;
``doubtful``  it is used, with a warning: the plan moved the path further from the odometry than its
              drift explains in 95 % of walks (:attr:`MapConfig.doubt_rel`), the path may be worse
              than the map-less one;
``no fit``    the plan has no walkable space within the given start's σ (``start_sigma_m``: the plan,
              or the start, is misplaced: a plan shifted by a corridor's width), or the walls took most of the weight
              at the average step (:data:`NO_FIT_KILL`): the walk does not fit the plan; or, where
              fixes were weighed in, the path lies outside most fixes' 68 % radius (their median
              distance over it above 1: the walls and the fixes disagree); the map-less path (or
              the fixes' smoothed one) is used instead, with a warning.

With it, :func:`diagnostics` gives one number per cause the issue names (what the walls did, the cloud's
collapse and spread, the start heading's correction, how open the space was), so a bench can say why
each walk went wrong. Decision: docs/decisions/0046-map-trust.md.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from wearnav.fuse.config import RADIUS_68
from wearnav.fuse.particles import MapConfig, MapResult

# The walls took more than half of the particles' weight at the average step: no tuning, the majority.
# On ILC2 site 1 with its own plans 0.9-9 % of walks per floor cross it; with the plan moved 8 m, 32 %.
NO_FIT_KILL = 0.5
FITS, DOUBTFUL, NO_FIT = "fits", "doubtful", "no fit"


@dataclasses.dataclass(frozen=True)
class MapVerdict:
    """:func:`check_map_path`'s answer: ``status`` (fits, doubtful, no fit), ``reason`` (one line,
    empty where it fits) and the figures it rests on."""

    status: str
    reason: str
    figures: dict

    @property
    def use_map(self) -> bool:
        return self.status != NO_FIT


def mapless_path(res: MapResult) -> np.ndarray | None:
    """The referee: the map-less path from the filter's start (None where the filter had no start
    heading: an unknown heading has no map-less path to compare with)."""
    ref = res.steps.get("referee")
    return None if ref is None else np.asarray(ref)


def _walked(res: MapResult) -> np.ndarray:
    odo = np.asarray(res.steps["odometry"])
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(odo, axis=0), axis=1))])


def check_map_path(res: MapResult, cfg: MapConfig = MapConfig()) -> MapVerdict:
    """Whether the map-aware path ``res`` can be used (module docstring)."""
    kill = np.asarray(res.steps["wall_kill"])[1:]
    figures: dict = {"wall_kill_mean": round(float(kill.mean()), 3) if kill.size else 0.0}
    ref = mapless_path(res)
    if ref is not None:
        dev = np.linalg.norm(np.asarray(res.steps["filter_xy"]) - ref, axis=1)
        allowed = np.maximum(cfg.doubt_m, cfg.doubt_rel * _walked(res))
        worst = int(np.argmax(dev / allowed))
        figures |= {
            "left_odometry_by_m": round(float(dev[worst]), 2),
            "odometry_drift_allows_m": round(float(allowed[worst]), 2),
            "at_s": round(float(res.steps["t"][worst] - res.steps["t"][0]), 1),
        }
    start_ok = res.steps.get("start_walkable")
    if start_ok is not None and not bool(np.all(start_ok)):
        return MapVerdict(
            NO_FIT,
            f"the floor plan has no walkable space within {cfg.start_sigma_m:g} m of the start: the plan (or the "
            "start) is misplaced; the path is placed without the plan",
            figures | {"start_walkable": False},
        )
    if "fix_t" in res.steps:  # the fixes weighed in: how far the path lies from them, in their 68 % radii
        ft, fxy = np.asarray(res.steps["fix_t"]), np.asarray(res.steps["fix_xy"])
        path, tk = np.asarray(res.steps["path_xy"]), np.asarray(res.steps["t"])
        at = np.stack([np.interp(ft, tk, path[:, 0]), np.interp(ft, tk, path[:, 1])], axis=1)
        radii = np.linalg.norm(at - fxy, axis=1) / (RADIUS_68 * np.asarray(res.steps["fix_sigma_m"]))
        figures["fixes_off_in_68_radii"] = round(float(np.median(radii)), 2)
        if figures["fixes_off_in_68_radii"] > 1.0:
            return MapVerdict(
                NO_FIT,
                f"the floor plan and the location fixes disagree: the map-aware path lies outside most fixes' "
                f"68 % radius (the median fix {figures['fixes_off_in_68_radii']:.1f} radii away); the path is "
                "placed without the plan",
                figures,
            )
    if figures["wall_kill_mean"] > NO_FIT_KILL:
        return MapVerdict(
            NO_FIT,
            f"the walk does not fit the floor plan: its walls took {figures['wall_kill_mean']:.0%} of the "
            "particles' weight at the average step; the path is placed without the plan",
            figures,
        )
    if ref is not None and figures["left_odometry_by_m"] > figures["odometry_drift_allows_m"]:
        return MapVerdict(
            DOUBTFUL,
            f"the floor plan moved the path {figures['left_odometry_by_m']:.1f} m from the odometry "
            f"{figures['at_s']:.0f} s in, where its drift explains {figures['odometry_drift_allows_m']:.1f} m "
            "in 95 % of walks: the map-aware path may be worse than the path without the plan",
            figures,
        )
    return MapVerdict(FITS, "", figures)


def diagnostics(res: MapResult) -> dict:
    """One figure per cause a map-aware path can go wrong by (issue 57), from the filter's record:
    ``wall_kill_mean`` / ``wall_kill_p90`` (how hard the walls fought the walk), ``open_share`` (steps
    where no particle met a wall: open space, the walls say nothing), ``ess_min`` and ``resamples``
    (collapse onto few hypotheses), ``lineages_left`` (distinct ancestors of the final cloud at the
    start: 1 = every hypothesis but one died), ``spread_max_m`` (the cloud's widest: rival corridors),
    ``heading_turned_deg`` (how far the walls turned the start heading: its error, or a wrong plan),
    ``referee_share`` (particles beyond the odometry's drift), ``scale`` (walls only: fixed)."""
    s = res.steps
    kill = np.asarray(s["wall_kill"])[1:]
    info = res.info
    return {
        "wall_kill_mean": round(float(kill.mean()), 3) if kill.size else 0.0,
        "wall_kill_p90": round(float(np.percentile(kill, 90)), 3) if kill.size else 0.0,
        "open_share": round(float(np.mean(kill == 0.0)), 3) if kill.size else 1.0,
        "ess_min": round(float(np.min(s["ess"])), 3),
        "resamples": info["resamples"],
        "lineages_left": int(s.get("lineages_left", 0)),
        "spread_max_m": round(float(np.max(s["filter_spread_m"])), 2),
        "heading_turned_deg": info.get("heading_turned_deg"),
        "referee_share": info.get("referee_share"),
        "scale": info["scale_median"],
    }
