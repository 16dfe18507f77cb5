"""``wearnav radiomap``: a Wi-Fi radio map from survey walks (``build``) and what it is worth on walks
it never saw (``eval``), issue 60. Registered on the main app by :mod:`wearnav.cli`
(``app.add_typer(radiomap_app, name="radiomap")``); the heavy imports stay inside the commands."""

from __future__ import annotations

import warnings
from pathlib import Path

import typer

from wearnav.cli.common import echo_json
from wearnav.errors import ConfigError, WearnavWarning

radiomap_app = typer.Typer(
    help="A Wi-Fi radio map from survey walks: build one, measure it on held-out walks.",
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode=None,
)

MODELS = ("knn", "extra-trees")  # wearnav.fuse.radiomap.MODELS (not imported: it loads scikit-learn)


def recordings_of(data: Path, limit: int | None = None) -> list:
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
    from wearnav.fuse.radiobuild import build as build_map
    from wearnav.fuse.radiomap import CARD_JSON, RadioMapConfig

    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not (out / CARD_JSON).is_file())):
        raise ConfigError(f"--out {out}: exists and is not a radio map folder: choose a new one")
    if model not in MODELS:
        raise ConfigError(f"--model {model}: one of {', '.join(MODELS)}")
    torch_one_thread()
    recs = recordings_of(data, limit)
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
    out: Path = typer.Option(..., "--out", help="Run folder for metrics.json."),
    ipin: Path | None = typer.Option(
        None, "--ipin", help="IPIN 2023 walks: a dataset folder of `wearnav import ipin2023`."
    ),
    ilc2: Path | None = typer.Option(None, "--ilc2", help="ILC2 walks: a dataset folder of `wearnav import ilc2`."),
    models: str = typer.Option("knn", "--models", help="Comma-separated: knn, extra-trees."),
    folds: int = typer.Option(10, "--folds", min=2, help="ILC2: walks held out in this many groups per floor."),
    slow_floors: str = typer.Option("F2", "--slow-floors", help="ILC2 floors extra-trees runs on (it is slow)."),
):
    """Radio-only error on held-out walks (IPIN 2023 leave one trial out, ILC2 per floor held out by walk).
    Writes metrics.json. The path `track` makes with the radio map: `wearnav bench radio-track`.

    \b
    Example:
      wearnav radiomap eval --ipin data/ipin2023 --ilc2 data/ilc2 --out runs/radiomap
    """
    from wearnav.bench.radiomap import measure

    if ipin is None and ilc2 is None:
        raise ConfigError("give --ipin and/or --ilc2 (dataset folders of `wearnav import`)")
    chosen = _models(models)
    torch_one_thread()
    ipin_recs = recordings_of(ipin) if ipin is not None else []
    ilc2_recs = recordings_of(ilc2) if ilc2 is not None else []
    out.mkdir(parents=True, exist_ok=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WearnavWarning)  # the importers' notes on each walk
        result = measure(
            out,
            ipin_recs,
            ilc2_recs,
            chosen,
            folds,
            {"extra-trees": [f.strip() for f in slow_floors.split(",") if f.strip()]},
            log=typer.echo,
        )
    echo_json({k: v for k, v in result.items() if k != "config"})


def torch_one_thread() -> None:
    import torch

    torch.set_num_threads(1)
