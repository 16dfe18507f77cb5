"""The radio map measured on walks it never saw (issue 60 §4): `wearnav radiomap eval`.

Radio only (each scan's position from the map, no odometry), scored at each held-out scan against
the walk's position at its time (:mod:`wearnav.fuse.survey`: the PDR path warped onto the surveyed
points; the truth a map is built from, never an input of the map that scores it):

``ipin2023``  leave one trial out: each trial's walks (its repetitions of one route) scored by the
              map of the other trials (the map's own σ calibration grouped by trial too);
``ilc2``      per floor of site 1, walks held out in ``folds`` groups (scikit-learn's GroupKFold):
              each walk scored by the map of the other walks of its floor; and the floor right with
              one map of every floor, walks held out the same way;
``placement`` how well the survey placement fills a gap between surveyed points (skip-one:
              :func:`wearnav.fuse.survey.skip_one_errors`), odometry against the straight line.

Per model (``models``: the map's k-nearest neighbours, scikit-learn's extra trees for comparison):
median / p75 / p95 error (m), the share of floors right and of errors inside the 68 % radius of the
map's calibrated σ (0.68 where calibrated). :func:`measure` writes ``metrics.json`` into the run folder.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from wearnav.core.fileio import write_text_atomic
from wearnav.fuse.config import RADIUS_68
from wearnav.fuse.radiobuild import survey_scans
from wearnav.fuse.radiomap import RadioMapConfig, error_summary, from_scans, shared_frame, walk_group
from wearnav.fuse.radioscans import Scans, fingerprints
from wearnav.fuse.survey import odometry_path, skip_one_errors
from wearnav.recording import Recording

METRICS_JSON = "metrics.json"


@dataclasses.dataclass
class Scored:
    """Held-out scans scored: error (m), σ (m), floor right, each (N,)."""

    error_m: list[np.ndarray] = dataclasses.field(default_factory=list)
    sigma_m: list[np.ndarray] = dataclasses.field(default_factory=list)
    floor_right: list[np.ndarray] = dataclasses.field(default_factory=list)
    unplaced: int = 0  # held-out scans sharing too few access points with the map

    def add(self, err: np.ndarray, sigma: np.ndarray, right: np.ndarray) -> None:
        self.error_m.append(err)
        self.sigma_m.append(sigma)
        self.floor_right.append(right)

    def summary(self) -> dict[str, Any]:
        err = np.concatenate(self.error_m) if self.error_m else np.empty(0)
        sig = np.concatenate(self.sigma_m) if self.sigma_m else np.empty(0)
        right = np.concatenate(self.floor_right) if self.floor_right else np.empty(0)
        out = error_summary(err, right)
        if err.size:
            out["share_inside_68_radius"] = round(float(np.mean(err <= RADIUS_68 * sig)), 4)
        out["scans_without_position"] = self.unplaced
        return out


def score_held_out(train: Scans, test: Scans, cfg: RadioMapConfig, groups: dict[str, str], scored: Scored) -> None:
    """Build the map of ``train`` (its σ calibrated over ``groups``) and score ``test``'s scans."""
    rmap = from_scans(train, cfg, groups=groups)
    x, common = fingerprints(test, rmap.bssids, cfg.missing_dbm)
    use = common >= cfg.min_common_aps
    scored.unplaced += int((~use).sum())
    if not use.any():
        return
    xy, sigma, floor = rmap.predict(x[use])
    assert test.xy is not None and test.floor is not None
    scored.add(np.linalg.norm(xy - test.xy[use], axis=1), sigma, floor == test.floor[use])


def placed(recs: Sequence[Recording], cfg: RadioMapConfig) -> dict[str, Scans]:
    """Each survey walk's placed scans (walks without any left out)."""
    out = {}
    for rec in recs:
        s, _ = survey_scans(rec, cfg)
        if s is not None and len(s):
            out[rec.name] = s
    return out


def ipin_leave_one_trial_out(recs: Sequence[Recording], cfg: RadioMapConfig, scans: dict[str, Scans]) -> dict[str, Any]:
    """Every trial scored by the map of the other trials (module docstring)."""
    groups = {r.name: walk_group(r, "trial") for r in recs}
    scored, per_trial = Scored(), {}
    for trial in sorted(set(groups.values())):
        test = [scans[w] for w, g in groups.items() if g == trial and w in scans]
        train = [scans[w] for w, g in groups.items() if g != trial and w in scans]
        if not test or not train:
            continue
        one = Scored()
        score_held_out(Scans.concat(train), Scans.concat(test), cfg, groups, one)
        per_trial[trial] = one.summary()
        scored.error_m += one.error_m
        scored.sigma_m += one.sigma_m
        scored.floor_right += one.floor_right
        scored.unplaced += one.unplaced
    return {"all": scored.summary(), "per_trial": per_trial, "trials": len(per_trial)}


def ilc2_by_walk(recs: Sequence[Recording], cfg: RadioMapConfig, scans: dict[str, Scans], folds: int) -> dict[str, Any]:
    """Per floor: walks held out in ``folds`` groups, each scored by the map of its floor's other
    walks; the floor right with one map of every floor (module docstring)."""
    from sklearn.model_selection import GroupKFold

    by_floor: dict[str, list[str]] = {}
    for r in recs:
        if r.name in scans:
            by_floor.setdefault(str(r.meta.get("floor_name", "")), []).append(r.name)
    groups = {w: w for w in scans}

    def folds_of(walks: list[str], scored: Scored) -> None:
        idx = np.arange(len(walks))
        for train, test in GroupKFold(min(folds, len(walks))).split(idx, groups=walks):
            tr = Scans.concat([scans[walks[i]] for i in train])
            te = Scans.concat([scans[walks[i]] for i in test])
            score_held_out(tr, te, cfg, groups, scored)

    out: dict[str, Any] = {"per_floor": {}}
    pooled = Scored()
    for floor, walks in sorted(by_floor.items()):
        one = Scored()
        folds_of(walks, one)
        out["per_floor"][floor] = one.summary() | {"walks": len(walks)}
        pooled.error_m += one.error_m
        pooled.sigma_m += one.sigma_m
        pooled.unplaced += one.unplaced
    out["all_floors_pooled"] = pooled.summary()
    if len(by_floor) < 2:  # one floor: nothing to vote on
        return out
    every = Scored()
    folds_of(sorted(w for ws in by_floor.values() for w in ws), every)
    out["floor_from_one_map_of_every_floor"] = {
        "floor_right": round(float(np.mean(np.concatenate(every.floor_right))), 4) if every.floor_right else None,
        "n": int(sum(a.size for a in every.floor_right)),
    }
    return out


def placement(recs: Sequence[Recording], odometry: str) -> dict[str, Any]:
    """Skip-one errors of the survey placement: the odometry-warped and the straight-line fill."""
    warped, line = [], []
    for rec in recs:
        if rec.truth is None or len(rec.truth) < 3:
            continue
        t, xy = odometry_path(rec, odometry)
        a, b = skip_one_errors(rec.truth, t, xy)
        warped.append(a)
        line.append(b)
    cat = np.concatenate
    return {
        "odometry": odometry,
        "warped": error_summary(cat(warped) if warped else np.empty(0)),
        "straight_line": error_summary(cat(line) if line else np.empty(0)),
    }


def measure(
    out: str | Path,
    ipin: Sequence[Recording] = (),
    ilc2: Sequence[Recording] = (),
    models: Sequence[str] = ("knn",),
    folds: int = 10,
    ilc2_models_floors: dict[str, list[str]] | None = None,
    log: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Every number of the module docstring for the walks given; ``ilc2_models_floors``: model → the
    ILC2 floors it is run on (a slow model on fewer; default every floor). Writes ``metrics.json``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    result: dict[str, Any] = {"config": dataclasses.asdict(RadioMapConfig()), "models": list(models), "folds": folds}
    for name, recs in (("ipin2023", ipin), ("ilc2", ilc2)):
        if not recs:
            continue
        t0 = time.time()
        base = RadioMapConfig(per_floor=not shared_frame(recs))
        scans = placed(recs, base)
        part: dict[str, Any] = {"walks": len(recs), "walks_with_placed_scans": len(scans), "per_floor": base.per_floor}
        part["scans"] = int(sum(len(s) for s in scans.values()))
        part["placement"] = placement(recs, base.odometry)
        for model in models:
            cfg = dataclasses.replace(base, model=model)
            t1 = time.time()
            if name == "ipin2023":
                part[model] = ipin_leave_one_trial_out(recs, cfg, scans)
            else:
                floors = (ilc2_models_floors or {}).get(model)
                keep = [r for r in recs if floors is None or str(r.meta.get("floor_name")) in floors]
                part[model] = ilc2_by_walk(keep, cfg, scans, folds) | ({"floors_run": floors} if floors else {})
            part[model]["seconds"] = round(time.time() - t1, 1)
            log(f"{name} {model}: {json.dumps(part[model].get('all') or part[model].get('all_floors_pooled'))}")
        part["seconds"] = round(time.time() - t0, 1)
        result[name] = part
    write_text_atomic(json.dumps(result, indent=2), out / METRICS_JSON)
    return result
