"""The ``wearnav`` commands that make and score a run folder: ``train`` (an odometry model into a run
folder) and ``eval`` (its metrics, trajectories and plots). Registered on the main app by
:mod:`wearnav.cli`; imports stay inside the commands so that ``--help`` stays fast."""

from __future__ import annotations

import warnings
from enum import Enum
from pathlib import Path

import typer

from wearnav.cli.common import (
    HEADING_FRAME_HELP,
    RECIPE_HELP,
    VEL_LOSS_HELP,
    Recipe,
    VelLoss,
    echo_json,
    on_interrupt,
    progress_enabled,
    split_list,
)
from wearnav.errors import ConfigError, MissingFileError, WearnavWarning


class TestFrame(str, Enum):
    """The test recordings' frame (wearnav.preprocess.frames): honest, or the old time-varying diagnostic."""

    initial = "initial"
    truth = "truth"


class Strategy(str, Enum):
    """Lightning's strategies for one training on several devices (wearnav.train.common)."""

    auto = "auto"
    ddp = "ddp"
    ddp_spawn = "ddp_spawn"


def train(
    model: str = typer.Argument(..., help="A registered model (see `wearnav models`)."),
    data: Path = typer.Option(..., "--data", help="Dataset folder with truth (e.g. from `wearnav simulate`)."),
    out: Path = typer.Option(..., "--out", help="Run folder to write (resumed if it holds this run)."),
    devices: str | None = typer.Option(
        None, help="Device layout, comma-separated (default: the dataset's devices, phone, watch, earbuds first)."
    ),
    epochs: int = typer.Option(100, help="Maximum epochs (early stopping may end sooner)."),
    seed: int = typer.Option(
        0, help="Random seed: initial weights, batch order, augmentation (the run's hash includes it)."
    ),
    recipe: Recipe = typer.Option(Recipe.fast, help=RECIPE_HELP),
    vel_loss: VelLoss = typer.Option(VelLoss.mse, "--vel-loss", help=VEL_LOSS_HELP),
    heading_frame: bool = typer.Option(False, "--heading-frame", help=HEADING_FRAME_HELP),
    lr: float | None = typer.Option(None, help="Learning rate (default: the recipe's)."),
    batch: int | None = typer.Option(None, help="Batch size (default: the model's paper value)."),
    patience: int = typer.Option(10, help="Early-stopping patience in epochs."),
    max_time: float | None = typer.Option(
        None, "--max-time", help="Total training minutes of the run (over resumes too)."
    ),
    evaluate: bool = typer.Option(True, help="Evaluate on the test split afterwards."),
    num_devices: int = typer.Option(
        1,
        "--num-devices",
        min=1,
        help="GPUs (or, without one, CPU processes) that "
        "train at once, each on its share of every batch (not the sensor --devices).",
    ),
    strategy: Strategy = typer.Option(
        Strategy.auto,
        help="ddp: one process per device (Lightning re-runs this "
        "command in each). The run and its folder are the same on any number.",
    ),
    data_on_device: bool | None = typer.Option(
        None,
        "--data-on-device/--data-on-host",
        help="Keep every training window in the device's memory and gather batches there (default: on a "
        "single GPU). The batches are the same either way.",
    ),
):
    """Train an odometry model into a run folder (config.yaml, checkpoints/, training.json).

    \b
    Example:
      wearnav train suitein++ --data data/sim --out runs/sipp --max-time 5
    """
    if not data.is_dir():  # before torch is imported (as wearnav.dataset.Dataset.open says it)
        raise MissingFileError("no such dataset folder", data)
    if out.exists() and not out.is_dir():
        raise ConfigError("exists and is not a folder; choose another --out", out)
    from wearnav.evaluate import evaluate_run
    from wearnav.runs import locked
    from wearnav.train.odometry import configure, fit, prepare_run
    from wearnav.trust import LEARN_ADVICE, did_not_learn

    cfg, eval_splits, notes = configure(
        model,
        data,
        split_list(devices) if devices is not None else None,
        ("test",) if evaluate else (),
        epochs=epochs,
        seed=seed,
        lr=lr,
        recipe=recipe.value,
        vel_loss=vel_loss.value,
        **({"heading_frame": True, "augment": ()} if heading_frame else {}),
        batch=batch,
        patience=patience,
        max_minutes=max_time,
    )
    run = prepare_run(cfg, out, eval_splits=eval_splits)
    for note in notes:  # what the data decided (devices, truth gaps, validation, no test split)
        typer.echo(note, err=True)
    evaluate = bool(eval_splits)
    on_interrupt(f"{run} keeps the last finished epoch; run the same command again to resume")
    with locked(run):  # one process per run folder, from training through its metrics
        record = fit(
            cfg, run, progress=progress_enabled(), devices=num_devices, strategy=strategy.value, resident=data_on_device
        )
        echo_json({"run": str(run), "training": {k: v for k, v in record.items() if k != "training_data"}})
        if (unlearned := did_not_learn(record)) is not None:  # wearnav.trust
            warnings.warn(WearnavWarning(f"{run}: {unlearned}: {LEARN_ADVICE}"), stacklevel=1)
        if evaluate:
            m = evaluate_run(run, splits=("test",), training=record, progress=progress_enabled())
            echo_json({"test": m["splits"]["test"]["summary"]})


def eval_(
    run: Path = typer.Argument(..., help="A run folder written by `wearnav train`."),
    data: Path | None = typer.Option(None, "--data", help="Dataset to evaluate on (default: the training data)."),
    split: str = typer.Option("test", help="Split(s) to evaluate, comma-separated."),
    test_frame: TestFrame | None = typer.Option(
        None,
        "--test-frame",
        help="initial (default, the run's "
        "own): one constant yaw from the first 10 s of truth; truth: "
        "the truth's yaw over time, a diagnostic (needs --out).",
    ),
    out: Path | None = typer.Option(
        None, "--out", help="Write metrics.json, trajectories/ and plots/ here instead of the run folder."
    ),
):
    """Evaluate a run: metrics.json, trajectories/*.csv and plots (trajectories, error CDF, ATE box).

    \b
    Example:
      wearnav eval runs/sipp --split test,cross_subject
    """
    from wearnav.runs import read_config

    read_config(run)  # a run folder (config.yaml), before torch is imported
    if data is not None and not data.is_dir():
        raise MissingFileError("no such dataset folder", data)
    if test_frame == TestFrame.truth and out is None:
        raise ConfigError(
            "--test-frame truth is a diagnostic (ground truth inside the test input); "
            "give --out so that the run's own metrics stay honest"
        )
    from wearnav.evaluate import evaluate_run

    dest = out if out is not None else run
    on_interrupt(f"{dest / 'metrics.json'} is written only when every split is scored; run the same command again")
    pre = {"eval_frame_align": test_frame.value} if test_frame is not None else None
    m = evaluate_run(run, data=data, splits=split_list(split), progress=progress_enabled(), preprocess=pre, out_dir=out)
    echo_json({s: m["splits"][s]["summary"] for s in split_list(split)})
    typer.echo(f"wrote {dest / 'metrics.json'} and {dest / 'plots'}")


def register(app: typer.Typer) -> None:
    app.command()(train)
    app.command("eval")(eval_)
