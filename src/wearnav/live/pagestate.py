"""What a session's page draws, made from its tracker's path, fixes and plan without redoing the
part that has not changed: :class:`PageRows`, which :class:`wearnav.live.tracker.LiveTracker` keeps
one of and asks at every update that changed something (its ``_snapshot``, the live contract).

The path's points are ``page_points`` of the whole path (tests/test_live_batched.py checks them
row for row); the points of its settled part, the fixes and the plan's rings are made once and
kept, so that an update's page state costs what is new, not the session's length (issue 61)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from wearnav import plans
from wearnav.report.trajectory_page import POINT_S, page_points


class PageRows:
    """The page's rows of one session, kept between updates (module docstring); ``plan``: a
    GeoJSON floor plan (:func:`wearnav.plans.read_geojson_plan`) drawn under the path once the
    session has a lat/lon origin (its first fix), placed in that origin's frame once."""

    def __init__(self, plan: str | Path | None = None):
        self.plan_file = None if plan is None else Path(plan)
        self._plan: tuple[tuple[float, float], list] | None = None  # (origin, rings)
        self._fixes: list[list] = []  # the fixes rounded for the page
        self._path: tuple[Any, list] = (None, [])  # (the solve they came from, the settled points)

    def path(self, t: np.ndarray, xy: np.ndarray, sig: np.ndarray, rate: float, solve: Any, settled: int) -> list:
        """``page_points(t, xy, sig, rate)``, the points before sample ``settled`` kept from the last
        call while ``solve`` (the smoother's result that placed them, None: the final odometry) is
        the same object; a new solve places them anew."""
        step = max(1, int(round(POINT_S * rate)))
        key, rows = self._path
        if key is not solve:
            rows = []
        # the kept rows are the grid points 0, step, ...; the rest from the grid point i0 on, which
        # is at most the path's last sample (page_points' own last point, where it is off the grid)
        i0 = min(len(rows), max(0, len(t) - 1) // step) * step
        rows = rows[: i0 // step]
        new = page_points(t[i0:], xy[i0:], sig[i0:], rate)
        keep = min(max(0, -(-(settled - i0) // step)), len(new))  # the grid points before ``settled``
        self._path = (solve, rows + new[:keep])
        return rows + new

    def fixes(self, fixes: list[tuple[float, float, float, float]]) -> list:
        """The fixes (t, east, north, accuracy) as the page has them, a new list each time (a state
        once handed out stays as it was); each row rounded once, as it arrives (``fixes`` only grows)."""
        rows = self._fixes
        rows += [
            [round(t, 3), round(e, 3), round(n, 3), round(a, 2) if np.isfinite(a) else None]
            for t, e, n, a in fixes[len(rows) :]
        ]
        return list(rows)

    def plan(self, origin: tuple[float, float] | None) -> list:
        """The plan's walkable polygons in the frame at ``origin`` (empty without a plan or origin)."""
        if self.plan_file is None or origin is None:
            return []
        if self._plan is None or self._plan[0] != origin:
            rings = [
                [[np.round(r, 2).tolist() for r in poly] for poly in p.polygons]
                for p in plans.read_geojson_plan(self.plan_file, *origin)
            ]
            self._plan = (origin, rings)
        return self._plan[1]


__all__ = ["PageRows"]
