"""The ``wearnav`` command: a thin layer over the package's functions.

Every command imports what it needs when it runs, so ``wearnav --help`` stays fast. Bad input
raises a :class:`wearnav.errors.WearnavError`; :func:`main` prints it in one line and exits 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Optional

import typer

from wearnav.errors import WearnavError

app = typer.Typer(
    help="Inertial odometry and activity recognition from everyday wearables.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _echo_json(obj) -> None:
    typer.echo(json.dumps(obj, indent=2, default=str))


@app.command()
def simulate(
    out: Path = typer.Option(..., "--out", help="Dataset folder to write."),
    preset: str = typer.Option("small", help="tiny | small | default"),
    seed: int = typer.Option(0, help="Random seed (the dataset is a pure function of preset+seed)."),
):
    """Simulate a flexiwear-bodynet dataset (phone, watch, earbuds) with truth and location fixes."""
    from wearnav.simulate import simulate_dataset

    ds = simulate_dataset(preset, out, seed=seed, progress=True)
    _echo_json(ds.summary())


@app.command()
def info(path: Path = typer.Argument(..., help="A recording (.h5) or a dataset folder.")):
    """Summarise a recording or a dataset (durations, device rates, labels, truth and fixes)."""
    from wearnav.dataset import Dataset
    from wearnav.recording import Recording
    from wearnav.report import dataset_stats

    if not path.is_dir():
        _echo_json(Recording.load(path).summary())
        return
    ds = Dataset.open(path)
    summary = ds.summary()
    stats = dataset_stats(ds, progress=True)
    summary["device_rates"] = {
        dev: {"rate_hz": round(d["rate_hz"], 2), "jitter_iqr_ms": round(d["jitter_iqr_ms"], 3),
              "gyro_share": round(d["gyro_share"], 3), "orientation_share": round(d["orientation_share"], 3)}
        for dev, d in stats["devices"].items()
    }
    labels: dict = {}
    for (kind, value), c in stats["labels"].items():
        labels.setdefault(kind, {})[value] = c["intervals"]
    summary["labels"] = labels
    summary["truth_points"] = stats["truth_points"]
    summary["fixes"] = stats["fixes"]
    if stats["fix_error_m"]:
        summary["fix_error_at_truth_m"] = {k: round(v, 3) if isinstance(v, float) else v
                                           for k, v in stats["fix_error_m"].items()}
    _echo_json(summary)


@app.command("import")
def import_(
    fmt: str = typer.Argument(..., metavar="FORMAT",
                              help="ilc2 | ipin2023 | motionsense | uci-hapt | uji-phone-watch | oxford-steps | sensorlogger"),
    src: Path = typer.Argument(..., help="The dataset's folder (or file / zip) in its original layout."),
    out: Path = typer.Option(..., "--out", help="Dataset folder to write."),
    limit: Optional[int] = typer.Option(None, help="Import at most this many recordings."),
):
    """Import real recordings into a wearnav dataset folder."""
    from wearnav.importers import import_dataset

    ds = import_dataset(fmt, src, out, limit=limit, progress=True)
    _echo_json(ds.summary())


@app.command()
def plot(
    path: Path = typer.Argument(..., help="A recording (.h5) or a dataset folder (with --name)."),
    out: Path = typer.Option(..., "--out", help="PNG file to write."),
    name: Optional[str] = typer.Option(None, help="Recording name inside a dataset folder (default: the first)."),
):
    """Plot a recording: device acc/gyro norms, label bands, and a map of truth and fixes."""
    from wearnav.dataset import Dataset
    from wearnav.recording import Recording
    from wearnav.report import plot_recording

    if path.is_dir():
        ds = Dataset.open(path)
        rec = ds.load(name or ds.names[0])
    else:
        rec = Recording.load(path)
    typer.echo(str(plot_recording(rec, out)))


@app.command("datasets-report")
def datasets_report(
    data: Path = typer.Option(Path("../shared/data"), help="Folder holding the public datasets."),
    out: Path = typer.Option(Path("docs/datasets.md"), help="Markdown file to write."),
    work: Path = typer.Option(Path("runs/datasets"), help="Where imported datasets are written."),
):
    """Import every shipped real dataset and write per-dataset sanity figures as Markdown."""
    from wearnav.report import write_datasets_report

    typer.echo(str(write_datasets_report(data, out, work)))


@app.command()
def realism(
    data: Path = typer.Option(Path("../shared/data"), help="Folder holding the public datasets."),
    out: Path = typer.Option(Path("docs/realism.md"), help="Markdown file to write (PNGs go to its img/)."),
    work: Path = typer.Option(Path("runs/realism"), help="Where the real calibration subsets are imported."),
    n_sim: int = typer.Option(12, help="Simulated walks (walkers) per placement."),
    limit: Optional[int] = typer.Option(None, help="At most this many recordings per real source."),
    before: Optional[Path] = typer.Option(None, help="An earlier realism JSON to show beside this one."),
    json_out: Optional[Path] = typer.Option(None, "--json", help="JSON to write (default: OUT with .json)."),
    seed: int = typer.Option(0),
):
    """Compare simulated walking with real recordings, device by device and placement by placement."""
    from wearnav.realism import realism_report

    realism_report(data, out, work, n_sim=n_sim, limit=limit, seed=seed, before=before,
                   json_out=json_out, progress=True)
    typer.echo(str(out))


@app.command()
def demo(
    out: Path = typer.Option(Path("runs/demo"), "--out", help="Folder for the demo's outputs."),
    seed: int = typer.Option(0),
):
    """The main job on built-in data: simulate the small preset, summarise it, plot trajectories."""
    from wearnav.dataset import Dataset
    from wearnav.report import plot_trajectories, walk_tables
    from wearnav.simulate import simulate_dataset

    data_dir = out / "data"
    if (data_dir / "manifest.csv").exists():
        ds = Dataset.open(data_dir)
        typer.echo(f"using existing simulated dataset {data_dir}")
    else:
        ds = simulate_dataset("small", data_dir, seed=seed, progress=True)
    _echo_json(ds.summary())
    for by, table in walk_tables(ds, ("mode", "noise_level")).items():
        typer.echo(f"\nby {by} (fix label noise: median error of the 1-s displacements between "
                   "location fixes; EasyTrack targets L1/L2/L3 = 21.6/27.6/33.5 cm):")
        typer.echo(table.to_string(index=False))
        table.to_csv(out / f"summary_by_{by}.csv", index=False)
    png = plot_trajectories(ds, out / "trajectories.png")
    typer.echo(f"\ntrajectory plot: {png}")


def main() -> None:
    try:
        app()
    except WearnavError as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(2)
