"""A radio map built from survey walks (issue 60 §2): :func:`build` (`wearnav radiomap build`) and
:func:`survey_scans`, each walk's Wi-Fi scans placed where the walker was (:mod:`wearnav.fuse.survey`:
the walk's PDR path warped onto its surveyed points). Apart from :mod:`wearnav.fuse.radiomap`, which
loads and uses a map, because placing a survey walk runs an odometry model (torch): a process that
only uses a map (`track --radiomap`, `wearnav live --radiomap`) loads neither."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any

import numpy as np

from wearnav.errors import ValidationError
from wearnav.fuse.floors import fit_floor_levels
from wearnav.fuse.radiofloor import floor_switch_rate
from wearnav.fuse.radiomap import RadioMap, RadioMapConfig, common_origin, from_scans, shared_frame, walk_group
from wearnav.fuse.radioscans import Scans, scans_of
from wearnav.fuse.survey import odometry_path, positions_between
from wearnav.recording import Recording


def survey_scans(rec: Recording, cfg: RadioMapConfig) -> tuple[Scans | None, dict[str, Any]]:
    """A survey walk's scans with the walker's position and floor at each (:mod:`wearnav.fuse.survey`),
    those that could not be placed left out; None where the walk has no Wi-Fi or no surveyed points."""
    if rec.wifi is None or rec.truth is None or len(rec.truth) < 2:
        return None, {"walk": rec.name, "scans": 0, "why": "no Wi-Fi scans or fewer than 2 surveyed points"}
    t_odo, xy_odo = odometry_path(rec, cfg.odometry)
    scans = scans_of(rec.wifi, cfg.stale_s)
    xy, floor, ok, info = positions_between(rec.truth, t_odo, xy_odo, scans.t)
    ok &= np.bincount(scans.scan, minlength=len(scans)) > 0
    placed = dataclasses.replace(
        scans, xy=xy, floor=np.nan_to_num(floor, nan=0.0), walk=np.full(len(scans), rec.name, dtype=object)
    )
    return placed.subset(ok), {"walk": rec.name, "scans": int(ok.sum()), "scans_not_placed": int((~ok).sum()), **info}


def build(
    recordings: Iterable[Recording], cfg: RadioMapConfig = RadioMapConfig(), source: str = "", group_by: str = "walk"
) -> RadioMap:
    """A radio map from survey walks (recordings with Wi-Fi and surveyed points; others are skipped);
    ``group_by``: a meta key whose walks are held out together in the validation (:func:`walk_group`)."""
    recordings = list(recordings)
    if cfg.per_floor is None:
        cfg = dataclasses.replace(cfg, per_floor=not shared_frame(recordings))
    parts, infos, groups = [], [], {}
    for rec in recordings:
        s, info = survey_scans(rec, cfg)
        infos.append(info)
        groups[rec.name] = walk_group(rec, group_by)
        if s is not None and len(s):
            parts.append(s)
    if not parts:
        raise ValidationError("no survey walk with Wi-Fi scans and surveyed points to build a radio map from")
    scans = Scans.concat(parts)
    rmap = from_scans(scans, cfg, infos, source, groups, group_by)
    assert scans.walk is not None and scans.floor is not None
    rmap.card["floor_switch_per_scan"] = floor_switch_rate(scans.t, scans.walk, scans.floor)
    origin = common_origin(recordings)
    rmap.card["origin"] = None if origin is None else list(origin)
    try:
        rmap.card["floor_levels"] = fit_floor_levels(recordings).to_dict()
    except ValidationError:  # no walk over two floors with a barometer: the Wi-Fi votes alone give the floor
        rmap.card["floor_levels"] = None
    return rmap


__all__ = ["build", "survey_scans"]
