"""IPIN 2023's beacons and barometer, measured (issue 36): ``python -m wearnav.bench.ipin_radio DATA``.

:func:`measure` imports every log of the IPIN 2023 Track 3 folder ``DATA`` (the dataset root, e.g.
``../shared/data/ipin2023_track3``) and measures, on the training walks with their surveyed points:

``path_loss``   :func:`wearnav.fuse.beacons.fit_path_loss` on all walks (its parameters and residual
                spread), and leave-one-trial-out (each trial's walks scored by the model fitted on
                the other trials): the residual σ and how informative a reading is as a range, the
                median |range − true 3-D distance| for readings louder than
                :data:`LOUD_DBM` and for the rest;
``floor_levels`` :func:`wearnav.fuse.floors.fit_floor_levels` on all walks (each floor's pressure
                 against floor 0, the height of a floor);
``floors``      floor accuracy at the surveyed points (share of points whose floor
                :func:`~wearnav.fuse.floors.floor_track` gives right), leave-one-trial-out (levels
                and path loss fitted without the scored trial), on all walks and on the multi-floor
                trials (51, 52), with the start floor (a) from truth's first point, (b) without
                truth (:func:`~wearnav.fuse.floors.start_floor`), and (b) with beacons only (no
                fixes), to show what each cue does.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from wearnav.errors import ValidationError
from wearnav.fuse.beacons import PathLoss, RangeSamples, fit_path_loss, range_samples
from wearnav.fuse.floors import FloorLevels, fit_floor_levels, floor_track, hpa_per_m, start_floor
from wearnav.importers import ipin2023
from wearnav.recording import Recording

LOUD_DBM = -75.0  # the readings louder than this are scored apart (near a beacon)
MULTI_FLOOR_TRIALS = (51, 52, 53)  # the trials that change floor (53 is not in the shared copy)


def _trial(rec: Recording) -> Any:
    return rec.meta.get("trial") or rec.name


def measure(data_root: str | Path, recordings: list[Recording] | None = None) -> dict[str, Any]:
    """Every number of the module docstring, as one JSON-able dict (``recordings``: already
    imported walks of the dataset instead of importing ``data_root``)."""
    recs = [
        r
        for r in (recordings if recordings is not None else list(ipin2023.read(Path(data_root))))
        if r.truth is not None and r.truth.floor is not None
    ]
    trials = sorted({_trial(r) for r in recs}, key=lambda t: (isinstance(t, str), str(t).zfill(9)))
    levels_all = fit_floor_levels(recs)
    p_median = float(levels_all.fit["p_median_hpa"])
    floor_height_m = levels_all.step_hpa / hpa_per_m(p_median)
    path_loss_all = fit_path_loss(recs, floor_height_m=round(floor_height_m, 2))

    held_out: list[tuple[PathLoss, RangeSamples]] = []  # each walk's readings, the model without its trial
    points: dict[str, list[np.ndarray]] = {"a_truth_start": [], "b_no_truth": [], "b_beacons_only": []}
    multi: dict[str, list[np.ndarray]] = {k: [] for k in points}
    walks = []
    for trial in trials:
        train = [r for r in recs if _trial(r) != trial]
        levels = _levels_or(train, levels_all)
        model = fit_path_loss(train, floor_height_m=path_loss_all.floor_height_m)
        for rec in (r for r in recs if _trial(r) == trial):
            assert rec.truth is not None and rec.truth.floor is not None  # filtered above
            s = range_samples(rec)
            if s is not None and len(s):
                held_out.append((model, s))
            if rec.pressure is None:
                continue
            positions = rec.meta.get("beacons")
            one = model.for_device(str(rec.meta.get("device", "")))
            start_b, how_b = start_floor(rec.pressure, levels, rec.beacons, positions, one, rec.fixes)
            start_c, how_c = start_floor(rec.pressure, levels, rec.beacons, positions, one, None)
            truth_floor = rec.truth.floor.astype(int)
            got = {
                "a_truth_start": floor_track(rec.pressure, int(truth_floor[0]), rec.truth.t, levels),
                "b_no_truth": floor_track(rec.pressure, start_b, rec.truth.t, levels),
                "b_beacons_only": floor_track(rec.pressure, start_c, rec.truth.t, levels),
            }
            for k, v in got.items():
                points[k].append(v == truth_floor)
                if _trial(rec) in MULTI_FLOOR_TRIALS:
                    multi[k].append(v == truth_floor)
            walks.append(
                {
                    "walk": rec.name,
                    "floors": sorted({int(f) for f in truth_floor}),
                    "start_floor_truth": int(truth_floor[0]),
                    "start_floor_b": start_b,
                    "start_floor_b_by": how_b["by"],
                    "start_floor_beacons_only": start_c,
                    **{f"right_{k}": round(float(np.mean(v == truth_floor)), 3) for k, v in got.items()},
                }
            )

    def share(parts: list[np.ndarray]) -> dict[str, Any]:
        if not parts:
            return {"points": 0, "right": None}
        right = np.concatenate(parts)
        return {"points": int(right.size), "walks": len(parts), "right": round(float(right.mean()), 4)}

    return {
        "walks": len(recs),
        "trials": [str(t) for t in trials],
        "path_loss": {
            "fitted_on_all_walks": path_loss_all.to_dict(),
            "leave_one_trial_out": _pooled_ranging(held_out),
        },
        "floor_levels": {
            **levels_all.to_dict(),
            "hpa_per_m": round(hpa_per_m(p_median), 4),
            "floor_height_m": round(floor_height_m, 3),
            "heights_m": {str(f): round(levels_all.height_m(f, p_median), 2) for f in levels_all.floors or []},
        },
        "floors": {
            "protocol": "leave one trial out: levels and path loss fitted on the other trials",
            "all_walks": {k: share(v) for k, v in points.items()},
            "multi_floor_trials": {k: share(v) for k, v in multi.items()},
            "walks": walks,
        },
    }


def _levels_or(train: list[Recording], fallback: FloorLevels) -> FloorLevels:
    """Levels fitted on ``train``; where no walk there changes floor, one step per floor of
    ``fallback``'s size (no measured level)."""
    try:
        return fit_floor_levels(train)
    except ValidationError:  # no walk of train changes floor
        return FloorLevels(step_hpa=fallback.step_hpa)


def _pooled_ranging(parts: list[tuple[PathLoss, RangeSamples]]) -> dict[str, Any]:
    """Residuals and range errors of each walk's readings under its model (each phone's own
    offset), pooled over the walks: residual σ (SD and 1.4826 MAD), and the median |range − true
    3-D distance| of the readings louder than LOUD_DBM and of the rest."""
    residual, error, loud, true_m = [], [], [], []
    for model, s in parts:
        for dev in set(s.device):
            m = s.device == dev
            one = model.for_device(dev)
            d = one.distance_m(s.horizontal_m[m], s.floors[m])
            residual.append(s.rssi_dbm[m] - one.expected_rssi(d, s.floors[m]))
            error.append(np.abs(one.range_m(s.rssi_dbm[m], s.floors[m]) - d))
            loud.append(s.rssi_dbm[m] > LOUD_DBM)
            true_m.append(d)
    res, err, is_loud, dist = (np.concatenate(x) for x in (residual, error, loud, true_m))

    def part(m: np.ndarray) -> dict[str, Any]:
        return {
            "readings": int(m.sum()),
            "median_abs_range_error_m": round(float(np.median(err[m])), 2) if m.any() else None,
            "median_true_distance_m": round(float(np.median(dist[m])), 2) if m.any() else None,
        }

    return {
        "readings": int(res.size),
        "residual_sd_db": round(float(np.std(res)), 3),
        "residual_mad_sigma_db": round(float(1.4826 * np.median(np.abs(res - np.median(res)))), 3),
        f"louder_than_{LOUD_DBM:g}_dbm": part(is_loud),
        f"at_most_{LOUD_DBM:g}_dbm": part(~is_loud),
    }


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m wearnav.bench.ipin_radio IPIN2023_TRACK3_FOLDER", file=sys.stderr)
        return 2
    print(json.dumps(measure(args[0]), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
