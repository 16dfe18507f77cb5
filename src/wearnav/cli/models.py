"""The ``wearnav`` commands about models themselves: ``models`` (what is registered and what
ships), ``pretrain`` (train, measure and install the shipped models), ``adapt`` (a model to the
user's own walks, from their fixes) and ``export`` (a run as one ONNX or TorchScript file). Registered on the main
app by :mod:`wearnav.cli`; heavy imports (torch and what loads it) stay inside the commands so that
``--help`` stays fast."""

from __future__ import annotations

from enum import Enum
from pathlib import Path

import typer

from wearnav import pretrained  # light (no torch): names and folders of the shipped models
from wearnav.cli.common import choice_value, echo_json, progress_enabled, suite_folder
from wearnav.errors import ConfigError
from wearnav.models import catalogue  # the registry's table: no torch (issue 58 §7)


class AdaptMethod(str, Enum):  # wearnav.adapt.METHODS
    scale = "scale"
    finetune = "finetune"


class ExportFormat(str, Enum):  # wearnav.export.header.FORMATS
    onnx = "onnx"
    torchscript = "torchscript"


def models_():
    """List the registered models (name, task, device layout, parameters), then the models shipped
    with this installation (used by `track` and `classify` without --model).

    \b
    Example:
      wearnav models
    """

    specs = catalogue.read()
    w = max(15, *(len(spec.name) for spec in specs))  # the name column as wide as the longest name
    typer.echo(f"{'model':{w}s} {'task':9s} {'layout':7s} {'parameters':>12s}  description")
    for spec in specs:
        n = "?" if spec.parameters is None else f"{spec.parameters:,}"  # None: not built with defaults
        typer.echo(f"{spec.name:{w}s} {spec.task:9s} {spec.layout:7s} {n:>12s}  {spec.description}")
    typer.echo("\nshipped (pretrained; `wearnav track`/`classify` use them without --model, card: MODEL_CARD.md):")
    typer.echo(f"{'name':20s} {'task':9s} {'devices':22s} size and card")
    for s in pretrained.SHIPPED.values():
        where = (
            f"{s.size_bytes() / 1e6:.1f} MB  {s.path / pretrained.CARD}"
            if s.installed
            else "not installed (wearnav pretrain --install)"
        )
        typer.echo(f"{s.name:20s} {s.task:9s} {','.join(s.devices):22s} {where}")
        typer.echo(f"{'':20s} {s.summary}")
        if s.task == "odometry" and s.installed:  # read from the model's own run (issue 58 §7)
            typer.echo(f"{'':20s} frame: {pretrained.shipped_frame_words(s)}")
            speed = pretrained.recorded_speed(s.path)  # what `track` and `live` take by default
            typer.echo(f"{'':20s} speed: {pretrained.SPEED_WORDS[speed]} (`--speed {speed}`, the default)")


def pretrain(
    data: Path = typer.Option(
        Path("../shared/data"), "--data", help="Folder holding the public datasets (ILC2, IPIN 2023, MotionSense)."
    ),
    out: Path = typer.Option(
        Path("runs/pretrained"), "--out", help="Suite folder: run folders, leave-one-building-out suites, results.md."
    ),
    work: Path | None = typer.Option(
        None, "--work", help="Where imported, simulated and mixed data go (default OUT/data)."
    ),
    epochs: int = typer.Option(8, min=1, help="Epochs of every odometry model (the schedule is set by them)."),
    max_time: float | None = typer.Option(
        45.0, "--max-time", help="Cap on each odometry run's minutes (slow machines)."
    ),
    jobs: int = typer.Option(1, min=1, help="Runs at once in local processes (1: one after another in this process)."),
    install: bool = typer.Option(
        False, "--install", help="Copy the trained models into the package (wearnav/pretrained/models)."
    ),
    models: str = typer.Option(
        "phone,phone-watch-earbuds,activity,activity-watch",
        "--models",
        help="Which shipped models to make (comma-separated); the others stay as installed.",
    ),
):
    """Train the shipped models, measure them in buildings they never saw, write model cards; resumes.
    The odometry models (phone; phone+watch+earbuds) train on the simulator alone and are scored in
    IPIN and ILC2, buildings they never saw; the activity models train on every labelled source,
    measured leave-one-dataset-out.

    \b
    Example:
      wearnav pretrain --data ../shared/data --out runs/pretrained --jobs 2 --install
      wearnav pretrain --models phone --out runs/pretrained --install
    """
    from wearnav.bench.executor import Execution

    chosen = tuple(pretrained.get(m.strip()).name for m in models.split(",") if m.strip())  # before torch loads
    if not chosen:
        raise ConfigError("--models: name at least one shipped model")
    from wearnav.pretrained.recipe import Recipe
    from wearnav.pretrained.recipe import pretrain as pretrain_

    suite_folder(out, "pretrain")
    page = pretrain_(
        data,
        out,
        work,
        Recipe(epochs=epochs, max_minutes=max_time),
        Execution(jobs=jobs),
        install=install,
        progress=progress_enabled(),
        echo=typer.echo,
        models=chosen,
    )
    typer.echo(f"wrote {page}")


def export_(
    run: Path = typer.Argument(
        ..., metavar="RUN", help="A run folder of `wearnav train` (or a classifier's), or a shipped model by name."
    ),
    format_: ExportFormat = typer.Option(
        ..., "--format", help="onnx (ONNX Runtime; needs wearnav[onnx]) or torchscript (torch.jit)."
    ),
    out: Path = typer.Option(
        ...,
        "--out",
        help="The file to write: .onnx or .pt. It carries the model's window, "
        "rate, stride, devices and config (see README, Export).",
    ),
):
    """Export a run's network to one ONNX or TorchScript file, checked against PyTorch before it is kept.

    \b
    Example:
      wearnav export runs/sipp --format onnx --out sipp.onnx
      wearnav track walk.zip --model sipp.onnx --out walk
    """
    from wearnav.export.header import check_out_file
    from wearnav.train.resolve import locate_model

    # Refused before torch is imported: the run (a shipped model's name → its folder), --out.
    located = locate_model(run, None, files=False, baselines=False)
    check_out_file(choice_value(format_), out)
    from wearnav.export.write import export_run

    echo_json(export_run(located, choice_value(format_), out))


def adapt(
    recordings: list[Path] = typer.Argument(
        ...,
        metavar="RECORDINGS...",
        help="The user's own walks with location "
        "fixes: Sensor Logger exports (folder or .zip), recordings (.h5), dataset folders.",
    ),
    model: Path = typer.Option(
        ..., "--model", help="The run folder of `wearnav train` to adapt, or a shipped model by name (phone)."
    ),
    out: Path = typer.Option(..., "--out", help="New run folder for the adapted model (`wearnav track --model OUT`)."),
    method: AdaptMethod = typer.Option(
        AdaptMethod.finetune,
        help="finetune: a few epochs on the fix-labelled "
        "segments (the default, as measured: docs/design.md); scale: one factor on the "
        "model's speed (also for pdr, which has no weights).",
    ),
    split: str | None = typer.Option(None, help="Of a dataset folder, only this split's recordings."),
    segment_s: float = typer.Option(10.0, "--segment-s", help="Seconds between the two fixes of a segment."),
    max_accuracy: float = typer.Option(20.0, "--max-accuracy", help="Leave out fixes reporting a wider accuracy (m)."),
    epochs: int = typer.Option(5, min=1, help="finetune: maximum epochs (early stopping on held-out segments)."),
    lr: float = typer.Option(1e-4, help="finetune: learning rate."),
):
    """Adapt a trained odometry model to your own walks, using the phone's location fixes as labels.

    \b
    Example:
      wearnav adapt my_walks/*.zip --model runs/sipp --out runs/sipp-mine
      wearnav track walk.zip --model runs/sipp-mine --out walk
    """
    from wearnav.cli.common import check_input
    from wearnav.train.resolve import locate_model

    # Refused before torch is imported: the model (a shipped model's name → its folder), --out,
    # the recordings.
    model = Path(locate_model(model, "odometry", files=False, baselines=False))
    if out.exists() and not out.is_dir():
        raise ConfigError("exists and is not an empty folder; choose another --out for the adapted run", out)
    for src in recordings:
        check_input(src)
    from wearnav.adapt import AdaptConfig, read_recordings
    from wearnav.adapt import adapt as adapt_
    from wearnav.adapt.finetune import FinetuneConfig
    from wearnav.adapt.segments import SegmentConfig

    cfg = AdaptConfig(
        method=method.value,
        segments=SegmentConfig(segment_s=segment_s, max_accuracy_m=max_accuracy),
        finetune=FinetuneConfig(epochs=epochs, lr=lr),
    )
    record = adapt_(read_recordings(recordings, split), model, out, cfg)
    echo_json(
        {
            "run": str(out),
            **{
                k: record[k]
                for k in (
                    "method",
                    "velocity_scale",
                    "recordings",
                    "fixes_used",
                    "segments",
                    "held_out_before",
                    "held_out_after",
                    "wall_s",
                )
            },
        }
    )


def register(app: typer.Typer) -> None:
    app.command("models")(models_)
    app.command("pretrain")(pretrain)
    app.command("adapt")(adapt)
    app.command("export")(export_)
