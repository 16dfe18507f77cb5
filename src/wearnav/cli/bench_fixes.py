"""The bench commands that learn from a phone's own location fixes: EasyTrack (paper 004) and its
BaseModel study, and adapting a model to a user's fixes (issue 18 §3). Registered on
:data:`wearnav.cli.bench.bench_app` by :func:`register`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from wearnav.bench.executor import Backend
from wearnav.cli.common import (
    ADDRESS_HELP,
    EXECUTOR_HELP,
    JOBS_HELP,
    ImportFormat,
    VelLoss,
    choice_value,
    execution_of,
    progress_enabled,
    split_list,
    suite_folder,
)


def bench_easytrack(
    out: Path = typer.Option(Path("runs/easytrack"), "--out", help="Suite folder (data, run folders, results.md)."),
    quick: bool = typer.Option(False, "--quick", help="Tiny data, 1–2 epochs per phase: checks the pipeline only."),
    seeds: int = typer.Option(1, min=1, help="Seeds per method and level."),
    jobs: int = typer.Option(1, min=1, help=JOBS_HELP),
    executor: Backend = typer.Option(Backend.local, help=EXECUTOR_HELP),
    address: str | None = typer.Option(None, help=ADDRESS_HELP),
    data: Path | None = typer.Option(
        None,
        "--data",
        help="Real dataset (wearnav folder: phone IMU, fixes, sparse truth), e.g. an `wearnav import ipin2023` output.",
    ),
    test_routes: str | None = typer.Option(
        None,
        "--test-routes",
        help="Regex: recordings of --data held out for testing, the rest "
        "train (default: the dataset's `test` split, else IPIN's "
        "Trial(04|24|52)_, the real-odometry test trials).",
    ),
    km: float | None = typer.Option(None, help="Simulated walking per noise level, km (default 3; --quick 0.25)."),
    joint_epochs: int | None = typer.Option(None, "--joint-epochs", help="Joint epochs (paper 190; default 30)."),
    ae_epochs: int | None = typer.Option(None, "--ae-epochs", help="Auto-encoder pre-training epochs (paper 5)."),
    pre_epochs: int | None = typer.Option(None, "--pre-epochs", help="Per-model pre-training epochs (paper 5)."),
    stride: float | None = typer.Option(
        None,
        "--stride",
        help="Start a 1-s segment every STRIDE s (0.2: ~5 "
        "overlapping segments per second, as the paper's Table I counts; "
        "default: back to back).",
    ),
    levels: str | None = typer.Option(None, help="Noise levels, comma-separated (default L1,L2,L3)."),
    methods: str | None = typer.Option(None, help="Methods, comma-separated (default: all)."),
    loss: VelLoss = typer.Option(
        VelLoss.mse, "--loss", help="The models' loss on the displacements: mse (the paper's) or polar (issue 34)."
    ),
):
    """EasyTrack (paper 004): methods × noise levels on simulated phone labels, and a real GNSS test.

    \b
    Example:
      wearnav bench easytrack --out runs/easytrack --quick
    """
    import dataclasses as _dc

    from wearnav.bench.easytrack import BenchConfig, run_benchmark

    suite_folder(out, "bench easytrack")
    bc = BenchConfig.quick() if quick else BenchConfig()
    changes: dict[str, Any] = {}
    if km is not None:
        changes["km"] = km
    for key, value in (
        ("joint_epochs", joint_epochs),
        ("ae_epochs", ae_epochs),
        ("pre_epochs", pre_epochs),
        ("stride_s", stride),
        ("loss", loss.value),
    ):
        if value is not None:
            changes[key] = value
    if levels:
        changes["levels"] = tuple(split_list(levels))
    if methods:
        changes["methods"] = tuple(split_list(methods))
    page = run_benchmark(
        out,
        quick,
        seeds,
        execution_of(jobs, executor, address),
        data,
        test_routes,
        _dc.replace(bc, **changes),
        echo=typer.echo,
    )
    typer.echo(f"wrote {page}")


def bench_easytrack_base(
    out: Path = typer.Option(
        Path("runs/easytrack-base"), "--out", help="Suite folder (data, run folders, results.md)."
    ),
    km: float = typer.Option(8.5, help="Simulated L1 walking, km."),
    joint_epochs: int = typer.Option(40, "--joint-epochs", help="Joint epochs (after 5 AE + 5 pre-training)."),
    seeds: int = typer.Option(1, min=1, help="Seeds per variant."),
    jobs: int = typer.Option(1, min=1, help=JOBS_HELP),
):
    """Why EasyTrack's BaseModel-GT is far from the paper's: one input change at a time, per walk.

    \b
    Example:
      wearnav bench easytrack-base --out runs/easytrack-base --km 1 --joint-epochs 5
    """
    from wearnav.bench.easytrack import BenchConfig
    from wearnav.bench.easytrack_base import run_study

    suite_folder(out, "bench easytrack-base")
    page = run_study(
        out,
        BenchConfig(km=km, joint_epochs=joint_epochs),
        seeds,
        execution_of(jobs, Backend.local, None),
        echo=typer.echo,
    )
    typer.echo(f"wrote {page}")


def bench_adapt(
    model: Path = typer.Option(
        ..., "--model", help="The base run folder, or a shipped model by name (phone): a model never trained on --data."
    ),
    data: Path = typer.Option(
        ..., "--data", help="IPIN 2023: the imported dataset folder, or its original files with --format."
    ),
    out: Path = typer.Option(Path("runs/adapt"), "--out", help="Suite folder (split data, adapted runs, results.md)."),
    format_: ImportFormat | None = typer.Option(None, "--format", help="Importer for original-format --data."),
):
    """The adaptation table (issue 18 §3): adapt on the training trials' GNSS, score at the held-out POSI points.

    \b
    Example:
      wearnav bench adapt --model runs/base --data data/ipin --out runs/adapt
    """
    from wearnav.train.resolve import locate_model

    model = Path(locate_model(model, "odometry", files=False, baselines=False))  # a shipped name → its folder
    from wearnav.bench.adapt import adapt_table

    suite_folder(out, "bench adapt")
    doc = adapt_table(model, data, out, choice_value(format_), progress=progress_enabled())
    typer.echo(str(out / "results.md"))
    typer.echo(
        f"default method by the training trials: {doc['choice']['best']}; {doc['seconds']['total'] / 60:.1f} min"
    )


def register(app: typer.Typer) -> None:
    app.command("easytrack")(bench_easytrack)
    app.command("easytrack-base")(bench_easytrack_base)
    app.command("adapt")(bench_adapt)
