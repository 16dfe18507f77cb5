"""The ``wearnav`` command: a thin layer over the package's functions.

Every command imports what it needs when it runs, so ``wearnav --help`` stays fast. Bad input
raises a :class:`wearnav.errors.WearnavError`; :func:`main` is the one place that turns any
failure into one line on stderr (see :func:`main`).
"""

from __future__ import annotations

import json
import os
import sys
import warnings
from pathlib import Path
from typing import Optional

import typer

from wearnav.errors import Terminated, ValidationError, WearnavError, WearnavWarning, one_line

app = typer.Typer(
    help="Inertial odometry and activity recognition from everyday wearables.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _echo_json(obj) -> None:
    typer.echo(json.dumps(obj, indent=2, default=str))


def _progress() -> bool:
    """Progress bars only on a terminal: on a pipe or in a log file their carriage-return updates
    stay behind as fragments before the real output or error."""
    return sys.stderr.isatty()


@app.command()
def simulate(
    out: Path = typer.Option(..., "--out", help="Dataset folder to write."),
    preset: str = typer.Option("small", help="tiny | small | default"),
    seed: int = typer.Option(0, min=0, help="Random seed (the dataset is a pure function of preset+seed)."),
):
    """Simulate a flexiwear-bodynet dataset (phone, watch, earbuds) with truth and location fixes."""
    from wearnav.simulate import simulate_dataset

    ds = simulate_dataset(preset, out, seed=seed, progress=_progress())
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
    stats = dataset_stats(ds, progress=_progress())
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
    limit: Optional[int] = typer.Option(None, min=0, help="Import at most this many recordings."),
):
    """Import real recordings into a wearnav dataset folder."""
    from wearnav.importers import import_dataset

    ds = import_dataset(fmt, src, out, limit=limit, progress=_progress())
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
        if not len(ds):
            raise ValidationError("dataset has no recordings to plot", path)
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
def demo(
    out: Path = typer.Option(Path("runs/demo"), "--out", help="Folder for the demo's outputs."),
    seed: int = typer.Option(0, min=0),
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
        ds = simulate_dataset("small", data_dir, seed=seed, progress=_progress())
    _echo_json(ds.summary())
    for by, table in walk_tables(ds, ("mode", "noise_level")).items():
        typer.echo(f"\nby {by} (fix label noise: median error of the 1-s displacements between "
                   "location fixes; EasyTrack targets L1/L2/L3 = 21.6/27.6/33.5 cm):")
        typer.echo(table.to_string(index=False))
        table.to_csv(out / f"summary_by_{by}.csv", index=False)
    png = plot_trajectories(ds, out / "trajectories.png")
    typer.echo(f"\ntrajectory plot: {png}")


def _os_error_line(exc: OSError) -> str:
    where = " -> ".join(str(f) for f in (exc.filename, exc.filename2) if f is not None)
    reason = exc.strerror or str(exc) or exc.__class__.__name__
    return f"{where}: {reason}" if where else reason


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"warning: {one_line(str(message))}", file=sys.stderr if file is None else file)


def _fail(message: str, code: int) -> None:
    sys.stdout.flush()
    print(f"error: {one_line(message)}", file=sys.stderr)
    sys.exit(code)


def main() -> None:
    """Run the command line; the boundary where every failure becomes one line on stderr.

    ``error: FILE: reason`` and exit 2 for bad input (a :class:`WearnavError`, a bad option, an
    ``OSError`` such as a read-only or missing folder), 130 for Ctrl-C, 143 for SIGTERM; anything
    else is a bug in wearnav and says so in one line, exit 1 (``WEARNAV_DEBUG=1`` re-raises it
    with its traceback). Warnings are one line each (``warning: ...``).
    """
    with warnings.catch_warnings():
        # Only wearnav's own warnings concern the user (a truncated file imported flagged); a
        # library's RuntimeWarning about arithmetic on values that are then refused is noise.
        warnings.simplefilter("ignore")
        warnings.simplefilter("default", WearnavWarning)
        warnings.showwarning = _show_warning
        try:
            code = app(standalone_mode=False)
        except typer.TyperException as exc:  # bad options / arguments (the parser's UsageError)
            if not exc.format_message():  # no arguments at all: the help was shown instead
                sys.exit(exc.exit_code)
            ctx = getattr(exc, "ctx", None)
            hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
            _fail(exc.format_message() + hint, exc.exit_code)
        except typer.Abort:
            _fail("aborted", 1)
        except WearnavError as exc:
            _fail(str(exc), 2)
        except OSError as exc:
            _fail(_os_error_line(exc), 2)
        except (Terminated, KeyboardInterrupt) as exc:
            _fail("interrupted" if isinstance(exc, KeyboardInterrupt) else "terminated (SIGTERM)",
                  130 if isinstance(exc, KeyboardInterrupt) else 143)
        except Exception as exc:
            if os.environ.get("WEARNAV_DEBUG"):
                raise
            _fail(f"internal error ({exc.__class__.__name__}: {exc}); this is a bug in wearnav, "
                  "please report it with the command you ran (WEARNAV_DEBUG=1 shows the traceback)", 1)
        if isinstance(code, int) and code:  # typer turns Ctrl-C into exit code 130
            _fail("interrupted" if code == 130 else f"exit code {code}", code)
