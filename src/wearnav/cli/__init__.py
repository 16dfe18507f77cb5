"""The ``wearnav`` command: a thin layer over the package's functions.

Every command imports what it needs when it runs, so ``wearnav --help`` stays fast. Bad input
raises a :class:`wearnav.errors.WearnavError`; :func:`main` is the one place that turns any
failure into one line on stderr (see :func:`main`).
"""

from __future__ import annotations

import logging
import math
import os
import signal
import sys
import threading
import warnings
from enum import Enum
from pathlib import Path

import typer

from wearnav import pretrained  # light: the shipped models' names and records (no torch)
from wearnav.cli.bench import bench_app
from wearnav.cli.common import (
    KEPT,
    NOTHING_KEPT,
    ImportFormat,
    check_input,
    choice_value,
    echo_json,
    on_interrupt,
    progress_enabled,
    split_list,
    suite_folder,
)
from wearnav.cli.label import register as register_label_commands
from wearnav.cli.live import register as register_live_commands
from wearnav.cli.models import register as register_model_commands
from wearnav.cli.radiomap import radiomap_app
from wearnav.cli.train import register as register_train_commands
from wearnav.core.interrupts import noting_lost_interrupts, raise_lost_interrupt
from wearnav.errors import (
    ConfigError,
    Terminated,
    ValidationError,
    WearnavError,
    WearnavWarning,
    one_line,
)

app = typer.Typer(
    help="Inertial odometry and activity recognition from everyday wearables.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
    rich_markup_mode=None,  # click's plain help: flags read as flags (`--quick`, not `--quick <bool>`)
)
app.add_typer(bench_app, name="bench")
app.add_typer(radiomap_app, name="radiomap")


# Options with a fixed set of values: typer lists them in --help and rejects any other (exit 2).
# Each mirrors the library's own list (tests/test_cli.py checks that they agree); a command passes
# ``.value`` on, a plain str. The simulator presets and Sensor Logger platforms are spelt out here
# rather than imported, so that `wearnav --help` does not load the simulator or pandas' importers.


class Platform(str, Enum):  # wearnav.importers.sensorlogger.PLATFORMS
    ios = "ios"
    watchos = "watchos"
    android = "android"


class Anchor(str, Enum):  # wearnav.fuse.ANCHORS
    smooth = "smooth"
    rigid = "rigid"
    first_fixes = "first-fixes"


class Speed(str, Enum):  # wearnav.train.odometry.SPEED_SOURCES
    model = "model"
    pdr = "pdr"
    cadence = "cadence"
    pointing = "pointing"
    snapped = "snapped"


class Preset(str, Enum):  # wearnav.simulate.presets.PRESETS
    tiny = "tiny"
    small = "small"
    default = "default"


class SimFormat(str, Enum):
    dataset = "dataset"  # a wearnav dataset folder (the --preset)
    sensorlogger = "sensorlogger"  # one walk as a Sensor Logger export (wearnav.importers.sensorlogger_export)


@app.command()
def simulate(
    out: Path = typer.Option(..., "--out", help="Dataset folder to write."),
    preset: Preset = typer.Option(Preset.small, help="Simulator preset."),
    seed: int = typer.Option(0, min=0, help="Random seed (the dataset is a pure function of preset+seed)."),
    format_: SimFormat = typer.Option(
        SimFormat.dataset,
        "--format",
        help="sensorlogger: one walk (phone, watch, "
        "earbuds, GPS fixes) as an iPhone's Sensor Logger export, to try `wearnav "
        "track` or `wearnav import sensorlogger` on (--preset is not used).",
    ),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace the dataset that --out already holds."),
    corridor_m: float | None = typer.Option(
        None,
        "--corridor-m",
        min=1.0,
        max=20.0,
        help="Give every walk a floor plan: corridors this wide (m) along its own route, to try the "
        "map-aware path (`wearnav track --map auto`) on walks with known truth.",
    ),
):
    """Simulate a flexiwear-bodynet dataset (phone, watch, earbuds) with truth and location fixes.

    \b
    Example:
      wearnav simulate --preset tiny --out data/sim
    """
    if format_ is SimFormat.sensorlogger:
        from wearnav.importers.sensorlogger_export import simulated_export

        echo_json(simulated_export(out, seed=seed))
        return
    from wearnav.outputs import check_new_dataset
    from wearnav.simulate import simulate_dataset

    check_new_dataset(out, overwrite, "simulate")
    on_interrupt(f"nothing was written to {out}; run the same command again")
    ds = simulate_dataset(preset.value, out, seed=seed, progress=progress_enabled(), corridor_m=corridor_m)
    echo_json(ds.summary())


@app.command()
def info(path: Path = typer.Argument(..., help="A recording (.h5) or a dataset folder.")):
    """Summarise a recording or a dataset (durations, device rates, labels, truth and fixes).

    \b
    Example:
      wearnav info data/sim
    """
    from wearnav.core.geo import needs_reimport
    from wearnav.dataset import Dataset
    from wearnav.recording import Recording
    from wearnav.report.stats import dataset_stats

    if not path.is_dir():
        if not path.exists() and (path.parent / "manifest.csv").is_file():  # a name the dataset lacks
            raise ValidationError(
                f"no such recording; {path.parent} holds {Dataset.open(path.parent).names_line()}", path
            )
        rec = Recording.load(path)
        if (stale := needs_reimport(rec.meta, has_fixes=rec.fixes is not None)) is not None:
            warnings.warn(WearnavWarning(f"{path}: {stale}"), stacklevel=1)
        echo_json(rec.summary())
        return
    ds = Dataset.open(path)
    summary = ds.summary()
    summary["names"] = ds.names_line()  # what `wearnav info DATASET/<name>.h5` and `plot --name` can show
    stats = dataset_stats(ds, progress=progress_enabled())
    summary["device_rates"] = {
        dev: {
            "rate_hz": round(d["rate_hz"], 2),
            "jitter_iqr_ms": round(d["jitter_iqr_ms"], 3),
            "gyro_share": round(d["gyro_share"], 3),
            "orientation_share": round(d["orientation_share"], 3),
        }
        for dev, d in stats["devices"].items()
    }
    labels: dict = {}
    for (kind, value), c in stats["labels"].items():
        labels.setdefault(kind, {})[value] = c["intervals"]
    summary["labels"] = labels
    summary["truth_points"] = stats["truth_points"]
    summary["fixes"] = stats["fixes"]
    if stats["fix_error_m"]:
        summary["fix_error_at_truth_m"] = {
            k: round(v, 3) if isinstance(v, float) else v for k, v in stats["fix_error_m"].items()
        }
    if stats["needs_reimport"]:
        warnings.warn(WearnavWarning(f"{path}: {stats['needs_reimport']}"), stacklevel=1)
    echo_json(summary)


@app.command("import")
def import_(
    fmt: ImportFormat = typer.Argument(..., metavar="FORMAT", help="The dataset's format (importer)."),
    src: Path = typer.Argument(..., help="The dataset's folder (or file / zip) in its original layout."),
    out: Path = typer.Option(..., "--out", help="Dataset folder to write."),
    limit: int | None = typer.Option(None, min=0, help="Import at most this many recordings."),
    platform: Platform | None = typer.Option(
        None, help="sensorlogger only: for exports without Metadata.csv (overrides its platform)."
    ),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace the dataset that --out already holds."),
):
    """Import real recordings into a wearnav dataset folder.

    \b
    Example:
      wearnav import ilc2 ../shared/data/ilc2_indoor_location --out data/ilc2 --limit 2
    """
    from wearnav.importers import import_dataset
    from wearnav.outputs import check_new_dataset

    fmt_name, platform_name = fmt.value, choice_value(platform)
    if platform_name is not None and fmt_name != "sensorlogger":
        raise typer.BadParameter("--platform is for the sensorlogger format only")
    check_new_dataset(out, overwrite, "import")
    on_interrupt(f"nothing was written to {out}; run the same command again")
    options = {"platform": platform_name} if platform_name is not None else {}
    ds = import_dataset(fmt_name, src, out, limit=limit, progress=progress_enabled(), **options)
    echo_json(ds.summary())


@app.command()
def plot(
    path: Path = typer.Argument(..., help="A recording (.h5) or a dataset folder (with --name)."),
    out: Path = typer.Option(..., "--out", help="PNG file to write."),
    name: str | None = typer.Option(None, help="Recording name inside a dataset folder (default: the first)."),
):
    """Plot a recording: device acc/gyro norms, label bands, and a map of truth and fixes.

    \b
    Example:
      wearnav plot data/sim --out sim.png
    """
    from wearnav.dataset import Dataset
    from wearnav.recording import Recording
    from wearnav.report.plots import plot_recording

    if path.is_dir():
        ds = Dataset.open(path)
        if not len(ds):
            raise ValidationError("dataset has no recordings to plot", path)
        if name is None:
            typer.echo(f"plotting {ds.names[0]} (--name picks another: {ds.names_line()})", err=True)
        rec = ds.load(name or ds.names[0])
    else:
        rec = Recording.load(path)
    typer.echo(str(plot_recording(rec, out)))


@app.command()
def track(
    src: Path = typer.Argument(
        ..., metavar="INPUT", help="A Sensor Logger export (folder or .zip), a recording (.h5), or a dataset folder."
    ),
    model: Path | None = typer.Option(
        None,
        "--model",
        help="A run folder of `wearnav train`, one of its "
        "checkpoints, a file of `wearnav export` (.onnx, .pt), a shipped model or "
        "an untrained baseline by name (pdr); default: phone-watch-earbuds where the recording has a "
        "watch or earbuds, else the shipped phone model where it measured better than PDR in every "
        "building it never saw, else pdr (track.json's model_choice says which; `wearnav models`).",
    ),
    out: Path = typer.Option(..., "--out", help="Folder for trajectory.csv / .png / .geojson and track.json."),
    name: str | None = typer.Option(
        None, help="Which recording of a dataset folder (or export of a folder of exports)."
    ),
    platform: Platform | None = typer.Option(None, help="For an export without Metadata.csv."),
    anchor: Anchor = typer.Option(
        Anchor.smooth,
        help="How the path is placed on the recording's location "
        "fixes: smooth (a robust smoother over every fix), rigid (one rotation + "
        "translation over every fix), first-fixes (over the first minute's).",
    ),
    map_plan: str = typer.Option(
        "auto",
        "--map",
        help="A floor plan keeps the path inside walkable space (a particle filter): auto (the plan the "
        "recording carries, e.g. ILC2's), none, or a GeoJSON file (RFC 7946 lon/lat; polygons with "
        "'kind': 'walkable' or 'obstacle').",
    ),
    start: str | None = typer.Option(
        None,
        "--start",
        metavar="X,Y,HEADING_DEG",
        help="A known start pose: X, Y (m) in the recording's frame, the heading of travel in degrees "
        "counter-clockwise from +x. With a floor plan the map-aware path starts there (and weighs in the "
        "fixes); without one the path is the odometry turned and moved to it, the fixes unused "
        "(track.json anchoring.method: start).",
    ),
    speed: Speed | None = typer.Option(
        None,
        help="Where a learned model's speed comes from: model (its own), pdr (its direction, detected "
        "steps × 0.67 m), cadence (its direction, steps as long as the cadence makes them), pointing "
        "(its speed along where the phone points; a heading-frame model), snapped (cadence, its direction "
        "turned onto where the phone points wherever within 30° of it; a heading-frame model). Default: what the model "
        "records ("
        + "".join(f"the shipped {n} model's default: {sp}; " for n, sp in pretrained.shipped_speeds().items())
        + "a file of `wearnav export`: its run's, carried in the file), else model.",
    ),
    fix_lag: float | None = typer.Option(
        None,
        "--fix-lag",
        min=0.0,
        max=10.0,  # fuse.MAX_FIX_LAG_S; fuse (scipy) is not imported before a command runs
        help="Seconds the location fixes lag the walker (the smoother, and the map-aware path with --map, "
        "read a fix as where the walker was that long before its time stamp; IPIN 2023's indoor fixes: 4). "
        "Default: 0.",
    ),
    radiomap: Path | None = typer.Option(
        None,
        "--radiomap",
        help="A radio map folder of `wearnav radiomap build`: the positions it gives the recording's Wi-Fi "
        "scans join the location fixes (and give the floor); a map of another site is not used (a warning).",
    ),
):
    """The walking path of one recording: predict, integrate from (0, 0), place it on the location fixes.

    \b
    Example:
      wearnav track my_walk.zip --out walk
      wearnav track data/sim --model runs/sipp --out walk
    """
    from wearnav.outputs import check_out_folder
    from wearnav.track.files import TRACK_FILES, TRACK_JSON
    from wearnav.train.resolve import locate_model

    # Refused before torch is imported (a mistake is said in well under a second, not 6 s).
    check_out_folder(out, TRACK_FILES, TRACK_JSON, "track")
    if model is not None:
        locate_model(model, "odometry")
    start_pose = parse_start(start)
    check_input(src)
    if map_plan not in ("auto", "none") and not Path(map_plan).is_file():
        raise ConfigError(f"--map {map_plan}: not auto, none or a GeoJSON plan file")
    if radiomap is not None and not (radiomap / "card.json").is_file():
        raise ConfigError(
            f"--radiomap {radiomap}: not a radio map folder (no card.json; `wearnav radiomap build` writes one)"
        )
    from wearnav.track import model_line  # torch: after the cheap checks
    from wearnav.track import track as track_

    summary = track_(
        src,
        model,
        out,
        name=name,
        platform=choice_value(platform),
        progress=progress_enabled(),
        anchor=choice_value(anchor),
        plan=map_plan,
        start=start_pose,
        speed=choice_value(speed),
        fix_lag_s=fix_lag,
        radiomap=radiomap,
    )
    typer.echo(model_line(summary))  # the model, the devices it read, its speed and frames (said once)
    echo_json(
        {k: summary[k] for k in ("recording", "duration_s", "path", "files") if k in summary}
        | {"odometry": {k: v for k, v in summary["odometry"].items() if k != "frame"}}  # the frame: the line above
        | {"anchoring": summary.get("anchoring", "no location fixes")}
        | ({"radiomap": summary["radiomap"]} if "radiomap" in summary else {})
    )


def parse_start(text: str | None) -> tuple[float, float, float] | None:
    """``--start X,Y,HEADING_DEG`` as three finite numbers (a clear error otherwise)."""
    if text is None:
        return None
    parts = text.split(",")
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        vals = ()
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
        raise ConfigError(f"--start {text!r}: expected X,Y,HEADING_DEG, three numbers (e.g. 12.5,3,90)")
    return vals[0], vals[1], vals[2]


@app.command("datasets-report")
def datasets_report(
    data: Path = typer.Option(Path("../shared/data"), help="Folder holding the public datasets."),
    out: Path = typer.Option(Path("docs/datasets.md"), help="Markdown file to write."),
    work: Path = typer.Option(Path("runs/datasets"), help="Where imported datasets are written."),
):
    """Import every shipped real dataset and write per-dataset sanity figures as Markdown.

    \b
    Example:
      wearnav datasets-report --data ../shared/data --out docs/datasets.md
    """
    from wearnav.report.datasets_page import write_datasets_report

    on_interrupt(f"datasets imported so far are kept in {work}; run the same command again")
    typer.echo(str(write_datasets_report(data, out, work)))


register_train_commands(app)  # train, eval (wearnav.cli.train), listed after datasets-report
register_label_commands(app)  # label-from-fixes, classify (wearnav.cli.label), after them


@app.command("results")
def results_(
    suites: list[Path] | None = typer.Argument(
        None,
        help="Suite folders, each holding a generated results.md "
        "(none with --keep: the page's sections rebuilt as they are).",
    ),
    out: Path = typer.Option(Path("docs/results.md"), "--out", help="The page to write."),
    keep: bool = typer.Option(
        False, "--keep", help="Keep the page's other sections (a suite replaces the one answering its questions)."
    ),
    drop: list[str] | None = typer.Option(
        None,
        "--drop",
        help="With --keep: remove this suite's kept section, SUITE or SUITE=WHY (a line in history.md; "
        "a suite folder name, or an unmarked section's heading; repeatable).",
    ),
):
    """Stitch the suites' generated pages into one results page, one section per question
    (wearnav.bench.questions.QUESTIONS; figures copied to its img/). A suite folder that answers no
    registered question, or two sections for one question, is refused; a replaced section gets a
    line in docs/history.md, and README.md's first-screen table is rewritten from the page.

    \b
    Example:
      wearnav results --keep runs/odometry runs/efficiency --out docs/results.md
    """
    from wearnav.bench.results import collect

    if not suites and not keep:
        raise typer.BadParameter("give suite folders, or --keep to rebuild the page from its own sections")
    typer.echo(str(collect(suites or [], out, keep=keep, drop=tuple(drop or ()))))


@app.command()
def realism(
    data: Path = typer.Option(Path("../shared/data"), help="Folder holding the public datasets."),
    out: Path = typer.Option(Path("docs/realism.md"), help="Markdown file to write (PNGs go to its img/)."),
    work: Path = typer.Option(Path("runs/realism"), help="Where the real calibration subsets are imported."),
    n_sim: int = typer.Option(12, help="Simulated walks (walkers) per placement."),
    limit: int | None = typer.Option(None, help="At most this many recordings per real source."),
    before: Path | None = typer.Option(None, help="An earlier realism JSON to show beside this one."),
    json_out: Path | None = typer.Option(None, "--json", help="JSON to write (default: OUT with .json)."),
    seed: int = typer.Option(0, help="Random seed of the simulated walks."),
):
    """Compare simulated walking with real recordings, device by device and placement by placement.

    \b
    Example:
      wearnav realism --data ../shared/data --out docs/realism.md --limit 2
    """
    from wearnav.realism import realism_report

    on_interrupt(f"subsets imported so far are kept in {work}; run the same command again")
    realism_report(
        data, out, work, n_sim=n_sim, limit=limit, seed=seed, before=before, json_out=json_out, progress=True
    )
    typer.echo(str(out))


# The demo's training budget per learned model. Epochs, not minutes: a time cap made the demo's
# figures depend on the machine's load (6 epochs and 17.9 m ATE on a busy machine, ~3 m on a quiet one).
# 30: on `small` Suite-IN++ starts to learn after ~5 epochs at lr 1e-3 and its validation MSE still
# fell at epoch 19 of a 20-epoch run (0.63 → 0.015 (m/s)²); RoNIN early-stopped at 17.
DEMO_EPOCHS = 30


@app.command()
def demo(
    out: Path = typer.Option(Path("runs/demo"), "--out", help="Folder for the demo's outputs."),
    seed: int = typer.Option(0, min=0, help="Random seed: the simulated data and every model's training."),
    models: str = typer.Option("suitein++,ronin,pdr", help="Models to compare, comma-separated."),
    epochs: int = typer.Option(
        DEMO_EPOCHS,
        min=1,
        help="Training epochs per learned model (a fixed count, so "
        "the figures are the same on a fast or a busy machine).",
    ),
    minutes: float | None = typer.Option(
        None,
        help="Also stop a model's training after this many minutes (its figures then depend on the machine's speed).",
    ),
    preset: Preset = typer.Option(Preset.small, hidden=True, help="Simulator preset (tests: tiny)."),
):
    """The main job on built-in data: simulate the small preset, train and compare odometry models,
    write a report with trajectory plots (runs resume: a second call reuses finished runs).

    \b
    Example:
      wearnav demo --out runs/demo
    """
    from wearnav.bench.demo import run_demo
    from wearnav.models.registry import check_models

    models_ = split_list(models)
    check_models(models_, "odometry")  # before anything is written
    suite_folder(out, "demo")
    page, tables = run_demo(
        out,
        models_,
        epochs,
        seed=seed,
        minutes=minutes,
        preset=preset.value,
        progress=progress_enabled(),
        echo=typer.echo,
    )
    for split, table in tables.items():
        typer.echo(f"\n{split} (metres):")
        typer.echo(table.to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    typer.echo(f"\nreport: {page} (trajectory plots per run under {out / 'runs'}/*/plots)")


register_model_commands(app)  # models, pretrain, export (wearnav.cli.models), listed after the rest
register_live_commands(app)  # live, live export, live bench, replay (wearnav.cli.live)


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


def _on_sigterm(signum, frame) -> None:
    raise Terminated("terminated (SIGTERM)")


def main() -> None:
    """Run the command line; the boundary where every failure becomes one line on stderr.

    ``error: FILE: reason`` and exit 2 for bad input (a :class:`WearnavError`, a bad option, an
    ``OSError`` such as a read-only or missing folder), 130 for Ctrl-C, 143 for SIGTERM; anything
    else is a bug in wearnav and says so in one line, exit 1 (``WEARNAV_DEBUG=1`` re-raises it
    with its traceback). Warnings are one line each (``warning: ...``).
    """
    # SIGTERM raises like Ctrl-C does, in every command: ``finally`` / ``with`` blocks clean up and
    # the exit code is 143 (training defers both to a batch boundary: wearnav.train.interrupt).
    main_thread = threading.current_thread() is threading.main_thread()
    old_sigterm = signal.signal(signal.SIGTERM, _on_sigterm) if main_thread else None
    try:
        with noting_lost_interrupts():  # a SIGTERM a finalizer swallowed still ends the command: 143
            _main()
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, old_sigterm)


def _log_to_stderr() -> None:
    """wearnav's log lines (progress without a terminal, "resuming from ...") as plain lines on stderr."""
    logger = logging.getLogger("wearnav")
    if not any(getattr(h, "_wearnav_cli", False) for h in logger.handlers):
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(message)s"))
        handler._wearnav_cli = True  # type: ignore[attr-defined]
        logger.addHandler(handler)
    logger.setLevel(logging.INFO)


def _main() -> None:
    _log_to_stderr()
    KEPT["line"] = NOTHING_KEPT
    with warnings.catch_warnings():
        # Only wearnav's own warnings concern the user (a truncated file imported flagged); a
        # library's RuntimeWarning about arithmetic on values that are then refused is noise.
        warnings.simplefilter("ignore")
        warnings.simplefilter("default", WearnavWarning)
        warnings.showwarning = _show_warning
        try:
            raise_lost_interrupt()  # one that came while the command line loaded (wearnav.__main__)
            code = app(standalone_mode=False)
            raise_lost_interrupt()
        except typer.TyperException as exc:  # bad options / arguments (the parser's UsageError)
            if type(exc).__name__ == "NoArgsIsHelpError":  # no arguments at all: the help, on stdout
                typer.echo(exc.format_message())
                sys.exit(exc.exit_code)
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
            _fail(
                ("interrupted" if isinstance(exc, KeyboardInterrupt) else "terminated (SIGTERM)") + f"; {KEPT['line']}",
                130 if isinstance(exc, KeyboardInterrupt) else 143,
            )
        except Exception as exc:
            if os.environ.get("WEARNAV_DEBUG"):
                raise
            _fail(
                f"internal error ({exc.__class__.__name__}: {exc}); this is a bug in wearnav, "
                "please report it with the command you ran (WEARNAV_DEBUG=1 shows the traceback)",
                1,
            )
        if isinstance(code, int) and code:  # typer turns Ctrl-C into exit code 130
            _fail(f"interrupted; {KEPT['line']}" if code == 130 else f"exit code {code}", code)
