"""``wearnav radiomap``: a Wi-Fi radio map from survey walks (``build``) and what it is worth on walks
it never saw (``eval``), issue 60. Registered on the main app by :mod:`wearnav.cli`
(``app.add_typer(radiomap_app, name="radiomap")``); the heavy imports stay inside the commands."""

from __future__ import annotations

import dataclasses
import json
import shutil
import warnings
from pathlib import Path
from typing import Any

import typer

from wearnav.cli.common import echo_json
from wearnav.core.fileio import write_text_atomic
from wearnav.core.textio import read_json
from wearnav.errors import ConfigError, WearnavWarning

radiomap_app = typer.Typer(
    help="A Wi-Fi radio map from survey walks: build one, measure it on held-out walks.",
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode=None,
)

MODELS = ("knn", "extra-trees")  # wearnav.fuse.radiomap.MODELS (not imported: it loads scikit-learn)


def _recordings(data: Path, limit: int | None = None) -> list:
    """The recordings of ``data``: a dataset folder of `wearnav import`, or one ``.h5`` recording."""
    from wearnav.dataset import MANIFEST, Dataset
    from wearnav.recording import Recording

    if data.is_file() and data.suffix.lower() == ".h5":
        return [Recording.load(data)]
    if data.is_dir() and (data / MANIFEST).is_file():
        ds = Dataset.open(data)
        return [ds.load(n) for n in ds.names[:limit]]
    raise ConfigError(
        f"{data}: not a dataset folder of `wearnav import` nor a .h5 recording (import the survey walks first, "
        "e.g. `wearnav import ilc2 ../shared/data/ilc2_indoor_location --out data/ilc2`)"
    )


def _models(text: str) -> list[str]:
    models = [m.strip() for m in text.split(",") if m.strip()]
    bad = [m for m in models if m not in MODELS]
    if bad or not models:
        raise ConfigError(f"--models {text}: each of {', '.join(MODELS)}")
    return models


@radiomap_app.command("build")
def build(
    data: Path = typer.Argument(
        ...,
        help="Survey walks: a dataset folder of `wearnav import` (walks with Wi-Fi "
        "scans and surveyed points), or one .h5 recording.",
    ),
    out: Path = typer.Option(..., "--out", help="The map folder to write (radiomap.npz, card.json, README.md)."),
    group_by: str = typer.Option(
        "walk",
        "--group-by",
        help="What the validation holds out together: walk, or a "
        "meta key such as trial (IPIN 2023: a trial's repetitions walk one route).",
    ),
    model: str = typer.Option("knn", "--model", help="knn (k nearest neighbours) or extra-trees (scikit-learn)."),
    k: int = typer.Option(8, "--k", min=1, help="Neighbours of the floor vote and the position."),
    limit: int | None = typer.Option(None, min=1, help="Use at most this many walks of the dataset."),
):
    """A radio map from survey walks: each Wi-Fi scan placed where the walk was (its PDR path warped onto
    its surveyed points), a scikit-learn model from a scan to x, y and floor, σ calibrated on held-out walks.

    \b
    Example:
      wearnav radiomap build data/ipin2023 --group-by trial --out maps/ipin
    """
    from wearnav.fuse.radiomap import CARD_JSON, RadioMapConfig
    from wearnav.fuse.radiomap import build as build_map

    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not (out / CARD_JSON).is_file())):
        raise ConfigError(f"--out {out}: exists and is not a radio map folder: choose a new one")
    if model not in MODELS:
        raise ConfigError(f"--model {model}: one of {', '.join(MODELS)}")
    _torch_one_thread()
    recs = _recordings(data, limit)
    rmap = build_map(recs, RadioMapConfig(model=model, k=k), source=str(data), group_by=group_by)
    rmap.save(out)
    card = rmap.card
    echo_json(
        {
            "map": str(out),
            "walks": len(card["walks"]),
            "scans": card["scans"],
            "access_points": len(card["access_points"]),
            "floors": card["floors"],
            "positions": card["positions"],
            "sigma_scale": card["sigma_scale"],
            "validation": card["validation"],
        }
    )


@radiomap_app.command("eval")
def eval_(
    out: Path = typer.Option(..., "--out", help="Run folder for metrics.json (and the maps and tracks of --track)."),
    ipin: Path | None = typer.Option(
        None, "--ipin", help="IPIN 2023 walks: a dataset folder of `wearnav import ipin2023`."
    ),
    ilc2: Path | None = typer.Option(None, "--ilc2", help="ILC2 walks: a dataset folder of `wearnav import ilc2`."),
    models: str = typer.Option("knn", "--models", help="Comma-separated: knn, extra-trees."),
    folds: int = typer.Option(10, "--folds", min=2, help="ILC2: walks held out in this many groups per floor."),
    slow_floors: str = typer.Option("F2", "--slow-floors", help="ILC2 floors extra-trees runs on (it is slow)."),
    track_walks: int = typer.Option(
        0,
        "--track",
        min=0,
        help="IPIN: run `track` with and without the radio map "
        "on the first repetition of this many trials (map from the other trials).",
    ),
    track_ilc2: int = typer.Option(
        0,
        "--track-ilc2",
        min=0,
        help="ILC2: run `track` (no GNSS, no start) with the radio map of the other walks of the floor, "
        "with and without the floor's plan, on this many walks spread over the floors.",
    ),
    radio: bool = typer.Option(
        True, "--radio/--no-radio", help="Measure radio-only positions (--no-radio: the tracks only)."
    ),
):
    """Radio-only error on held-out walks (IPIN 2023 leave one trial out, ILC2 per floor held out by walk),
    and `track` with the radio map against without on held-out IPIN walks (user protocol). Writes metrics.json.

    \b
    Example:
      wearnav radiomap eval --ipin data/ipin2023 --ilc2 data/ilc2 --track 4 --out runs/radiomap
    """
    from wearnav.bench.radiomap import METRICS_JSON, measure

    if ipin is None and ilc2 is None:
        raise ConfigError("give --ipin and/or --ilc2 (dataset folders of `wearnav import`)")
    chosen = _models(models)
    _torch_one_thread()
    ipin_recs = _recordings(ipin) if ipin is not None else []
    ilc2_recs = _recordings(ilc2) if ilc2 is not None else []
    out.mkdir(parents=True, exist_ok=True)
    # --no-radio: the tracks join the radio numbers already in the run folder
    result: dict[str, Any] = read_json(out / METRICS_JSON) if not radio and (out / METRICS_JSON).is_file() else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WearnavWarning)  # the importers' notes on each walk
        if radio:
            result = measure(
                out,
                ipin_recs,
                ilc2_recs,
                chosen,
                folds,
                {"extra-trees": [f.strip() for f in slow_floors.split(",") if f.strip()]},
                log=typer.echo,
            )
    if track_walks and ipin_recs:
        result.setdefault("ipin2023", {})["track"] = track_comparison(ipin_recs, out, track_walks)
    if track_ilc2 and ilc2_recs:
        result.setdefault("ilc2", {})["track"] = ilc2_track_comparison(ilc2_recs, out, track_ilc2)
    if (track_walks and ipin_recs) or (track_ilc2 and ilc2_recs):
        write_text_atomic(json.dumps(result, indent=2), out / METRICS_JSON)
    echo_json({k: v for k, v in result.items() if k != "config"})


def _score_tracks(
    cases: list[tuple[Any, Path]], variants: list[tuple[str, bool, str, bool]], out: Path
) -> dict[str, Any]:
    """Run `track` (the default model, user protocol) on each case (a held-out walk, the radio map
    without it) in each variant (label, keep the phone's fixes, --map, use the radio map) and score
    the path afterwards at the walk's surveyed points (from the second on, as the user protocol
    does; the truth is read only here) and its floor at them."""
    import numpy as np
    import pandas as pd

    from wearnav.bench.user_protocol import score_path
    from wearnav.fuse.radiomap import error_summary
    from wearnav.track import track as track_

    errors: dict[str, list] = {label: [] for label, *_ in variants}
    floors: dict[str, list] = {label: [] for label, *_ in variants}
    per_walk: dict[str, dict[str, Any]] = {}
    inputs = out / "inputs"
    inputs.mkdir(parents=True, exist_ok=True)
    for test, map_dir in cases:
        row: dict[str, Any] = {}
        for label, keep_fixes, plan, use_map in variants:
            rec = test if keep_fixes else dataclasses.replace(test, fixes=None, name=f"{test.name}_nofix")
            src = inputs / f"{rec.name}.h5"
            if not src.is_file():
                rec.save(src)
            folder = out / "track" / test.name / "".join(c if c.isalnum() else "_" for c in label)
            if folder.exists():
                shutil.rmtree(folder)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", WearnavWarning)
                summary = track_(src, None, folder, plan=plan, radiomap=map_dir if use_map else None)
            row["model"] = summary["model"]
            table = pd.read_csv(folder / "trajectory.csv")
            if "east" not in table:
                row[label] = {"placed": False}
                continue
            xy = table[["east", "north"]].to_numpy()
            err, _ = score_path(table["t"].to_numpy(), xy, test.truth.t, test.truth.pos[:, :2])
            errors[label].append(err)
            row[label] = {"median_m": round(float(np.median(err)), 2), "method": summary["anchoring"]["method"]}
            if "floor" in table and test.truth.floor is not None:
                near = np.clip(np.searchsorted(table["t"].to_numpy(), test.truth.t), 0, len(table) - 1)
                right = table["floor"].to_numpy()[near] == test.truth.floor
                floors[label].append(right)
                row[label]["floor_right"] = round(float(np.mean(right)), 3)
            if "radiomap" in summary:
                row[label]["radio_positions"] = summary["radiomap"].get("positions")
        per_walk[test.name] = row
    summary_rows = {
        label: error_summary(
            np.concatenate(errs) if errs else np.empty(0), np.concatenate(floors[label]) if floors[label] else None
        )
        | {"walks_placed": len(errs)}
        for label, errs in errors.items()
    }
    return {"walks": list(per_walk), "summary": summary_rows, "per_walk": per_walk}


def track_comparison(recs: list, out: Path, n_trials: int) -> dict[str, Any]:
    """IPIN 2023: the first repetition of ``n_trials`` trials (spread over the trial list), each with
    the radio map of the other trials: the phone's fixes (a) alone, (b) with the radio map, (c) the
    radio map and no fix at all (no GNSS, no start)."""
    import numpy as np

    from wearnav.fuse.radiomap import RadioMapConfig, walk_group
    from wearnav.fuse.radiomap import build as build_map

    groups = {r.name: walk_group(r, "trial") for r in recs}
    trials = sorted(set(groups.values()), key=lambda g: int(g.split()[-1]) if g.split()[-1].isdigit() else 0)
    picked = [trials[int(i)] for i in np.linspace(0, len(trials) - 1, min(n_trials, len(trials)))]
    cases = []
    for trial in picked:
        test = sorted((r for r in recs if groups[r.name] == trial), key=lambda r: r.name)[0]
        map_dir = out / "maps" / trial.replace(" ", "_")
        if not (map_dir / "card.json").is_file():
            train = [r for r in recs if groups[r.name] != trial]
            build_map(train, RadioMapConfig(), source="the other trials", group_by="trial").save(map_dir)
        cases.append((test, map_dir))
    variants = [
        ("fixes", True, "auto", False),
        ("fixes + radio map", True, "auto", True),
        ("radio map, no fixes", False, "auto", True),
    ]
    return _score_tracks(cases, variants, out)


def ilc2_track_comparison(recs: list, out: Path, n_walks: int) -> dict[str, Any]:
    """ILC2 site 1 (no GNSS): ``n_walks`` walks spread over the floors, each with the radio map of the
    other walks of its floor, no start: the radio map (a) with the floor's plan (the particle filter),
    (b) without (the smoother)."""
    import numpy as np

    from wearnav.fuse.radiomap import RadioMapConfig
    from wearnav.fuse.radiomap import build as build_map

    fit = sorted(
        (r for r in recs if r.truth is not None and len(r.truth) >= 3 and r.wifi is not None),
        key=lambda r: (str(r.meta.get("floor_name")), r.name),
    )
    picked = [fit[int(i)] for i in np.linspace(0, len(fit) - 1, min(n_walks, len(fit)))]
    cases = []
    for test in picked:
        map_dir = out / "maps_ilc2" / test.name
        if not (map_dir / "card.json").is_file():
            floor = test.meta.get("floor_name")
            train = [r for r in recs if r.meta.get("floor_name") == floor and r.name != test.name]
            build_map(train, RadioMapConfig(per_floor=True), source="the other walks of the floor").save(map_dir)
        cases.append((test, map_dir))
    variants = [("radio map + plan", False, "auto", True), ("radio map, no plan", False, "none", True)]
    return _score_tracks(cases, variants, out)


def _torch_one_thread() -> None:
    import torch

    torch.set_num_threads(1)
