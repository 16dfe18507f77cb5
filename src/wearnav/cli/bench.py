"""``wearnav bench``: the papers' experiments as resumable suites of run folders (each command a
thin layer over its :mod:`wearnav.bench` module, imported when it runs so that ``--help`` stays fast)."""

from __future__ import annotations

import dataclasses
import os
from enum import Enum
from pathlib import Path

import typer

from wearnav.bench import experiments  # data and stdlib only: no torch
from wearnav.bench.executor import Backend
from wearnav.cli.bench_fixes import register as register_fix_commands
from wearnav.cli.bench_maps import register as register_map_commands
from wearnav.cli.common import (
    ADDRESS_HELP,
    EXECUTOR_HELP,
    HEADING_FRAME_HELP,
    JOBS_HELP,
    RECIPE_HELP,
    SEED_HELP,
    VEL_LOSS_HELP,
    ImportFormat,
    Recipe,
    VelLoss,
    choice_value,
    execution_of,
    progress_enabled,
    split_floats,
    split_list,
    suite_folder,
)
from wearnav.errors import ConfigError


class Clock(str, Enum):  # wearnav.bench.efficiency.CLOCKS
    wall = "wall"
    cpu = "cpu"


bench_app = typer.Typer(help="The papers' experiments as resumable suites of run folders.", no_args_is_help=True)


class Grid(str, Enum):  # wearnav.bench.odometry.GRIDS
    default = "default"
    paper = "paper"


def frame_and_augment(heading_frame: bool, augment: str | None) -> dict:
    """``bench odometry``'s TrainConfig fields for ``--heading-frame`` and ``--augment``: the heading
    frame keeps the device's heading, so random yaw is left out (TrainConfig refuses both)."""
    kw: dict = {"heading_frame": True, "augment": ()} if heading_frame else {}
    if augment is not None:
        kw["augment"] = tuple(a for a in split_list(augment) if not (heading_frame and a == "rotate_yaw"))
    return kw


@bench_app.command("odometry")
def bench_odometry(
    data: Path = typer.Option(..., "--data", help="Simulated dataset (e.g. `wearnav simulate --preset default`)."),
    out: Path = typer.Option(Path("runs/odometry"), "--out", help="Suite folder (run folders + results.md)."),
    grid: Grid | None = typer.Option(
        None,
        help="Named model grid: default (suitein++, suitein, ronin, ronin*, pdr; "
        "the default) or paper (every model of Tables III–V; wearnav.bench.odometry.GRIDS).",
    ),
    models: str | None = typer.Option(None, help="Models, comma-separated, instead of --grid."),
    seeds: str = typer.Option(
        "0",
        help="Training seeds, comma-separated (e.g. 0,1,2): one run per model and seed; "
        "each is part of its run's hash.",
    ),
    epochs: int = typer.Option(100, help="Maximum epochs per model (the same budget for every model)."),
    patience: int = typer.Option(10, min=1, help="Early stopping: epochs without a better validation loss."),
    max_time: float | None = typer.Option(
        None, "--max-time", help="Total training minutes per model (raise it to resume a run for longer)."
    ),
    recipe: Recipe = typer.Option(Recipe.fast, help=RECIPE_HELP),
    lr: float | None = typer.Option(None, help="Learning rate for every model (default: the recipe's)."),
    vel_loss: VelLoss = typer.Option(VelLoss.mse, "--vel-loss", help=VEL_LOSS_HELP),
    heading_frame: bool = typer.Option(False, "--heading-frame", help=HEADING_FRAME_HELP),
    devices: str | None = typer.Option(
        None,
        help="Device layout of every model, comma-separated (default: phone, watch, earbuds); with "
        "--heading-frame the first present device gives the frame (e.g. earbuds,phone,watch).",
    ),
    augment: str | None = typer.Option(
        None,
        "--augment",
        help="The learned models' batch augmentations, comma-separated (wearnav.preprocess.augment, e.g. "
        "rotate_yaw,drop_devices; default: rotate_yaw, none with --heading-frame); '' for none.",
    ),
    jobs: int = typer.Option(1, min=1, help=JOBS_HELP),
    executor: Backend = typer.Option(Backend.local, help=EXECUTOR_HELP),
    address: str | None = typer.Option(None, help=ADDRESS_HELP),
    report_only: bool = typer.Option(
        False,
        "--report-only",
        help='Train nothing: write the page from the runs already complete ("n of N seeds" where a row is unfinished).',
    ),
):
    """Train and evaluate the odometry comparison, every model × seed; complete runs are skipped
    (the suite resumes). The page: Suite-IN++ Tables III–VI (mean ± std over seeds) and Figs. 7, 11.

    \b
    Example:
      wearnav bench odometry --data data/default --out runs/odometry --seeds 0,1,2 --epochs 30 --jobs 2
    """
    from wearnav.bench.odometry import GRIDS, run_folder, run_suite, suite_configs
    from wearnav.bench.odometry_tables import write_grid_report

    try:
        seed_list = [int(s) for s in split_list(seeds)]
    except ValueError:
        raise ConfigError(f"--seeds takes comma-separated integers, got {seeds!r}") from None
    if any(s < 0 for s in seed_list):
        raise ConfigError(f"--seeds must be ≥ 0, got {seeds!r}")
    if models and grid:
        raise ConfigError("give --models or --grid, not both")
    grid = grid or Grid.default
    entries = list(split_list(models)) if models else GRIDS[grid.value]
    from wearnav.dataset import Dataset

    layout = split_list(devices) if devices is not None else None
    given = frame_and_augment(heading_frame, augment)
    augmented = given["augment"] if augment is not None else ()
    configs = suite_configs(
        data,
        entries,
        seeds=seed_list,
        epochs=epochs,
        patience=patience,
        max_minutes=max_time,
        lr=lr,
        recipe=recipe.value,
        vel_loss=vel_loss.value,
        **given,
        **({"devices": layout} if layout is not None else {}),
    )
    suite_folder(out, "bench odometry")
    if report_only:
        folders = [run_folder(out, c) for c in configs]
    else:
        folders = run_suite(
            configs, out, progress=progress_enabled(), echo=typer.echo, execution=execution_of(jobs, executor, address)
        )
    prov = Dataset.open(data).provenance
    made = (
        f"simulator preset `{prov['preset']['name'] if isinstance(prov.get('preset'), dict) else prov.get('preset')}`, "
        f"seed {prov.get('seed')}, wearnav commit {prov.get('commit')}"
        if prov.get("generator") == "wearnav.simulate"
        else f"imported by {prov.get('importer', prov.get('generator', '?'))}"
    )
    import platform

    from wearnav.core.fileio import shown_path

    # whose heading frame: the first device of the layout present (preprocess._carrier_heading)
    frame = "the phone's heading frame"
    if layout and layout[0] != "phone":
        frame = f"the heading frame of the {layout[0]} (else the next device present)"

    note = (
        f"Data: `{shown_path(data)}` ({made}). Machine: {platform.machine()}, {os.cpu_count()} CPUs, torch "
        f"{__import__('torch').__version__}, shared with other work while it ran. Grid: "
        + (f"--models {models}" if models else f"`{grid.value}`")
        + f", seeds {seeds}; at most {epochs} epochs "
        f"per run, patience {patience}"
        + (
            f", {max_time:g} min of training per run (a run given more time resumes from its last "
            "checkpoint: attempts > 1)"
            if max_time
            else ""
        )
        + f", recipe `{recipe.value}`"
        + (f", Adam lr {lr:g} for every model" if lr else "")
        + (f", velocity loss `{vel_loss.value}` for every learned model" if vel_loss != VelLoss.mse else "")
        + (f", devices {', '.join(layout)}" if layout is not None else "")
        + (f", each window in {frame} (no random yaw)" if heading_frame else "")
        + (f", batch augmentations {', '.join(augmented) or 'none'}" if augment is not None else "")
        + "."
    )
    setting = [f"`{vel_loss.value}` loss"] if vel_loss != VelLoss.mse else []
    setting += [frame] if heading_frame else []
    setting += [f"augmented with `{'`, `'.join(augmented)}`"] if augmented else []
    title = "Odometry comparison (Suite-IN++ Tables III–VI)" + (f", {' and '.join(setting)}" if setting else "")
    page = write_grid_report(folders, out, title=title, expected_seeds=len(seed_list), note=note)
    typer.echo(f"wrote {page}")


@bench_app.command("real-odometry")
def bench_real_odometry(
    data: Path = typer.Option(
        ..., "--data", help="A real building: an imported dataset folder, or its original files with --format."
    ),
    out: Path = typer.Option(Path("runs/real"), "--out", help="Suite folder (split data, run folders, results.md)."),
    format_: ImportFormat | None = typer.Option(
        None, "--format", help="Importer for --data when it is not imported yet."
    ),
    test_data: Path | None = typer.Option(None, "--test-data", help="Another building to test on (never trained on)."),
    test_format: ImportFormat | None = typer.Option(None, "--test-format", help="Importer for --test-data."),
    group_by: str | None = typer.Option(
        None, help="Meta key that groups recordings by place (default per source: ilc2 floor_name, ipin2023 trial)."
    ),
    test_groups: str | None = typer.Option(
        None, help="Held-out groups, comma-separated (default per source: ilc2 F2,F4; ipin2023 4,24,52)."
    ),
    test_group_by: str | None = typer.Option(None, help="--group-by for --test-data."),
    test_test_groups: str | None = typer.Option(None, help="--test-groups for --test-data."),
    train_data: Path | None = typer.Option(
        None,
        "--train-data",
        help="Train the learned models on this dataset instead: the simulator (sim-to-real) or a mix of sources (wearnav.pretrained.mix).",
    ),
    models: str = typer.Option("ronin,suitein++,pdr", help="Models, comma-separated."),
    devices: str = typer.Option(
        "phone",
        "--devices",
        help="The learned models' devices, comma-separated, the phone among them (e.g. phone,watch,earbuds: only "
        "with a simulated --train-data; the real walks carry the phone alone, the others are absent there). With "
        "--heading-frame the first device present gives the frame: earbuds,phone,watch frames the simulated walks "
        "by the earbuds and the real ones by the phone (train with --augment drop_devices to show it both).",
    ),
    augment: str = typer.Option(
        "rotate_yaw",
        "--augment",
        help="The learned models' batch augmentations, comma-separated (wearnav.preprocess.augment, e.g. "
        "rotate_yaw,drop_devices; the heading frame leaves rotate_yaw out); '' for none.",
    ),
    epochs: int = typer.Option(100, min=1, help="Maximum epochs per model."),
    max_time: float | None = typer.Option(
        None, "--max-time", help="Total training minutes per model (raise it to resume a run for longer)."
    ),
    lr: float = typer.Option(1e-3, help="Adam learning rate for every learned model."),
    seed: int = typer.Option(0, min=0, help=SEED_HELP),
    seeds: str | None = typer.Option(
        None,
        help="Several seeds, comma-separated (e.g. 0,1,2): a suite per seed in OUT/seed-<s>/ and one page "
        "over them with walk-paired intervals against PDR (replaces --seed).",
    ),
    vel_loss: VelLoss = typer.Option(VelLoss.mse, "--vel-loss", help=VEL_LOSS_HELP),
    heading_frame: bool = typer.Option(False, "--heading-frame", help=HEADING_FRAME_HELP),
    speed_warp: str | None = typer.Option(
        None,
        "--speed-warp",
        help="Also train the learned models on the walks played this many times as fast, comma-separated "
        "(e.g. 0.8,1.25; one more copy each, wearnav.preprocess.time_warped).",
    ),
    jobs: int = typer.Option(1, min=1, help=JOBS_HELP),
    executor: Backend = typer.Option(Backend.local, help=EXECUTOR_HELP),
    address: str | None = typer.Option(None, help=ADDRESS_HELP),
):
    """Phone-only odometry trained on some floors/routes of a real building, scored at the surveyed
    points of held-out ones (and of another building); PDR and the raw phone fixes beside them.

    \b
    Example:
      wearnav bench real-odometry --data data/ilc2 --test-data data/ipin --out runs/real/ilc2 --max-time 15
    """
    from wearnav.bench.real import PlanPlace, RealBench, run_benchmark
    from wearnav.bench.real_seeds import run_seeds

    suite_folder(out, "bench real-odometry")
    seed_list = tuple(int(s) for s in split_list(seeds)) if seeds else (seed,)
    bench = RealBench(
        models=split_list(models),
        epochs=epochs,
        max_minutes=max_time,
        seed=seed_list[0],
        lr=lr,
        train_data=str(train_data) if train_data else None,
        vel_loss=vel_loss.value,
        heading_frame=heading_frame,
        speed_warp=split_floats(speed_warp, "--speed-warp") if speed_warp else (),
        devices=split_list(devices),
        augment=split_list(augment),
    )
    where = PlanPlace(
        test_data=test_data,
        fmt=choice_value(format_),
        test_fmt=choice_value(test_format),
        group_by=group_by,
        test_groups=split_list(test_groups) if test_groups else None,
        test_group_by=test_group_by,
        test_test_groups=split_list(test_test_groups) if test_test_groups else None,
    )
    execution = execution_of(jobs, executor, address)
    if len(seed_list) > 1:
        page = run_seeds(data, out, seed_list, bench, execution, progress_enabled(), typer.echo, **where)
    else:
        page = run_benchmark(
            data, out, **where, bench=bench, progress=progress_enabled(), echo=typer.echo, execution=execution
        )
    typer.echo(f"wrote {page}")


@bench_app.command("efficiency")
def bench_efficiency(
    out: Path = typer.Option(Path("runs/efficiency"), "--out", help="Folder for results.md / results.json."),
    models: str = typer.Option("suitein++,suitein,ronin,ronin*,pdr", help="Models, comma-separated."),
    threads: int | None = typer.Option(None, min=1, help="Intra-op threads (default: torch's)."),
    clock: Clock = typer.Option(
        Clock.wall, help="cpu: the process's CPU time (steadier on a shared machine with 1 thread)."
    ),
    min_run_time: float = typer.Option(0.2, min=0.001, help="Seconds each timing runs (torch's blocked_autorange)."),
    odometry_suite: Path | None = typer.Option(None, help="Odometry suite folder: adds its training s/epoch."),
    device: str = typer.Option("cpu", help="Where the models run: cpu, or cuda (a GPU; wall clock only)."),
    batches: str = typer.Option("1,256", help="Inference batch sizes, comma-separated."),
    faster_b1: bool = typer.Option(
        False, "--faster-b1", help="Also batch 1 through torch.compile and, on a GPU, as a replayed CUDA graph."
    ),
):
    """Parameters, FLOPs per window, inference windows/s at batch 1 and 256, fraction of the FLOP-bound limit.

    \b
    Example:
      wearnav bench efficiency --out runs/efficiency --models pdr,ronin
    """
    try:
        sizes = tuple(int(b) for b in split_list(batches))
    except ValueError:
        raise typer.BadParameter("--batches: whole numbers, comma-separated") from None
    if not sizes or min(sizes) < 1:
        raise typer.BadParameter("--batches: whole numbers ≥ 1, comma-separated")
    if device not in ("cpu", "cuda") and not device.startswith("cuda:"):
        raise typer.BadParameter(f"--device: cpu or cuda, got {device!r}")
    if device != "cpu" and clock is not Clock.wall:
        raise typer.BadParameter("--clock: a GPU is timed with the wall clock")
    from wearnav.bench.efficiency import measure, write_report
    from wearnav.models.registry import check_models
    from wearnav.outputs import check_suite_folder

    check_suite_folder(out, "bench efficiency")  # its page is written at the end: nothing kept before
    rows = []
    for m in check_models(split_list(models)):  # every name before the first is measured
        typer.echo(f"measuring {m} ...")
        rows.append(
            measure(
                m,
                threads=threads,
                clock=clock.value,
                min_run_time_s=min_run_time,
                batches=sizes,
                device=device,
                faster_b1=faster_b1,
            )
        )
    typer.echo(str(write_report(rows, out, odometry_suite)))


@bench_app.command("fusion")
def bench_fusion(
    data: Path = typer.Option(..., "--data", help="A simulated dataset (`wearnav simulate`): dense truth and fixes."),
    out: Path = typer.Option(Path("runs/fusion"), "--out", help="Folder for results.md / results.json."),
    model: str = typer.Option(
        "pdr", help="The odometry: an untrained baseline (pdr), a shipped model (phone) or a phone-only run folder."
    ),
    split: str | None = typer.Option(
        None,
        help="One split of --data (default: every recording but the training walks, which calibrate the smoother).",
    ),
    live_min: float = typer.Option(
        0.0,
        "--live-min",
        min=0.0,
        help="Also time the live receiver's fixed-lag smoother on one simulated walk this long (minutes; 0: not).",
    ),
):
    """Odometry alone, fixes alone and the smoother against the simulator's truth, per walking mode,
    the smoother's seconds per hour of walk, and (--live-min) the fixed-lag smoother's time per update.

    \b
    Example:
      wearnav bench fusion --data data/sim --out runs/fusion --live-min 60
    """
    from wearnav.bench.fusion import fusion_table, live_walk, write_fusion_page
    from wearnav.outputs import check_suite_folder

    check_suite_folder(out, "bench fusion")  # its page is written at the end: nothing kept before
    live = live_walk(live_min, model) if live_min > 0 else None
    typer.echo(str(write_fusion_page(fusion_table(data, model, split), data, out, live)))


# ---- activity / placement recognition (issue 9, paper 002) ------------------------------------


@bench_app.command("har")
def bench_har(
    out: Path = typer.Option(Path("runs/har"), "--out", help="Suite folder (imported data, run folders, results.md)."),
    data: Path = typer.Option(Path("../shared/data"), "--data", help="Folder holding the public datasets."),
    datasets: str | None = typer.Option(None, help="Datasets, comma-separated (default: all; --quick: uci-hapt)."),
    seeds: int | None = typer.Option(None, min=1, help="Seeds per technique (default 3; --quick 1)."),
    jobs: int = typer.Option(1, min=1, help=JOBS_HELP),
    executor: Backend = typer.Option(Backend.local, help=EXECUTOR_HELP),
    address: str | None = typer.Option(None, help=ADDRESS_HELP),
    epochs: int | None = typer.Option(None, min=1, help="Epochs per run (default 30; --quick 1)."),
    steps: int | None = typer.Option(
        None,
        min=1,
        help="Instead of --epochs: each dataset's epochs give the "
        "baseline about this many gradient steps (expanded sets the same epochs).",
    ),
    techniques: str | None = typer.Option(None, help="Techniques, comma-separated (default: all applicable)."),
    max_time: float | None = typer.Option(None, "--max-time", help="Minutes of training per run (not hashed)."),
    quick: bool = typer.Option(False, "--quick", help="A tiny subset and 1 epoch: checks the pipeline only."),
    threads: int = typer.Option(1, min=1, help="Torch intra-op threads per run (1 is fastest for this small model)."),
):
    """The paper-002 HAR benchmark: baseline and ten techniques per dataset; runs resume.

    \b
    Example:
      wearnav bench har --out runs/har --datasets uci-hapt --techniques baseline --seeds 1
    """
    from wearnav.bench.har import run_benchmark

    suite_folder(out, "bench har")
    page = run_benchmark(
        data,
        out,
        split_list(datasets) if datasets else None,
        seeds or (1 if quick else 3),
        execution_of(jobs, executor, address, threads),
        quick,
        epochs,
        split_list(techniques) if techniques else None,
        max_time,
        echo=typer.echo,
        steps=steps,
    )
    typer.echo(f"wrote {page}")


@bench_app.command("har-lodo")
def bench_har_lodo(
    out: Path = typer.Option(
        Path("runs/har-lodo"), "--out", help="Suite folder (imported data, run folders, results.md)."
    ),
    data: Path = typer.Option(Path("../shared/data"), "--data", help="Folder holding the public datasets."),
    devices: str = typer.Option("phone,watch", help="Devices, comma-separated: phone, watch."),
    epochs: int | None = typer.Option(None, min=1, help="Epochs per run (default 8; --quick 1)."),
    steps: int | None = typer.Option(None, min=1, help="Batches of 64 per epoch (default 250; --quick 5)."),
    max_per_class: int = typer.Option(1500, min=1, help="Training windows kept per source and class (at random)."),
    seed: int = typer.Option(0, min=0, help=SEED_HELP),
    context: int = typer.Option(
        5, min=1, help="Windows each label is decided over (odd; 1: each window alone), as classify will."
    ),
    members: int = typer.Option(
        3, min=1, help="Networks per model, each from its own seed (seed, seed + 1, ...); their mean decides."
    ),
    amp_jitter: float | None = typer.Option(
        None,
        min=0.0,
        max=0.99,
        help="Training windows' motion scaled by a random factor within 1 ± this (0: none; default: the shipped recipe's).",
    ),
    final: bool = typer.Option(False, "--final", help="Also train each device's model on every source."),
    install: bool = typer.Option(
        False, "--install", help="With --final: write the cards and install the models into the package."
    ),
    install_decision: bool = typer.Option(
        False,
        "--install-decision",
        help="Write this suite's unknown threshold and standing/sitting rule into the installed models "
        "(and their cards), keeping their weights; the suite's recipe must be theirs.",
    ),
    quick: bool = typer.Option(
        False, "--quick", help="A few recordings per source, 1 epoch: checks the pipeline only."
    ),
    jobs: int = typer.Option(1, min=1, help=JOBS_HELP),
    executor: Backend = typer.Option(Backend.local, help=EXECUTOR_HELP),
    address: str | None = typer.Option(None, help=ADDRESS_HELP),
    threads: int = typer.Option(1, min=1, help="Torch intra-op threads per run (1 is fastest for this small model)."),
):
    """Activity recognition, leave one dataset out: per held-out source macro-F1, accuracy and walking
    recall beside the in-dataset numbers, and the calibrated `unknown` threshold; runs resume.

    \b
    Example:
      wearnav bench har-lodo --out runs/har-lodo --final --install
    """
    from wearnav.bench.har_lodo import run_lodo
    from wearnav.train.activity import ActivityRun

    if install and not final:
        raise ConfigError("--install installs the --final models; give both")
    if context % 2 == 0:
        raise ConfigError(f"--context must be odd (the window and as many on each side), got {context}")
    suite_folder(out, "bench har-lodo")
    base = ActivityRun(
        device="phone",
        sources=(),
        data={},
        epochs=epochs or (1 if quick else 8),
        steps=steps or (5 if quick else 250),
        max_per_class=max_per_class,
        seed=seed,
        context_windows=context,
        members=members,
    )
    if amp_jitter is not None:
        base = dataclasses.replace(base, amp_jitter=amp_jitter)
    names = split_list(devices)
    results = run_lodo(
        data, out, names, base, execution_of(jobs, executor, address, threads), quick, final, echo=typer.echo
    )
    if install:
        from wearnav.pretrained.recipe import install_activity

        for device in names:
            install_activity(device, results, echo=typer.echo)
    elif install_decision:
        from wearnav.pretrained.recipe import install_activity_decision

        for device in names:
            install_activity_decision(device, results, echo=typer.echo)
    typer.echo(f"wrote {out / 'results.md'}")


# ---- the registry of experiments (issue 58 §4) ---------------------------------------------------


@bench_app.command("experiment")
def bench_experiment(
    ctx: typer.Context,
    name: str | None = typer.Argument(None, metavar="[NAME]", help="A registered experiment (--list names them)."),
    list_: bool = typer.Option(
        False,
        "--list",
        help="Print the registry: each experiment, the questions it answers, shipped or not, its decision.",
    ),
    out: Path | None = typer.Option(None, "--out", help="Suite folder (default runs/NAME, the results page's name)."),
    data: Path = typer.Option(
        Path("runs/data"), "--data", help="Folder of the named datasets it reads (each made there where missing)."
    ),
    shared: Path = typer.Option(Path("../shared/data"), "--shared", help="Folder holding the public datasets."),
    jobs: int = typer.Option(1, min=1, help=JOBS_HELP + " For the commands that take --jobs."),
    dry_run: bool = typer.Option(False, "--dry-run", help="Print the commands (the missing data first); run nothing."),
):
    """Run a named experiment of the registry (wearnav.bench.experiments): the command that answers a
    question of docs/results.md, or a variant measured and not shipped, with the data it reads.

    \b
    Example:
      wearnav bench experiment --list
      wearnav bench experiment seeds-simonly-snapped-polar-heading --jobs 2 --dry-run
    """
    import shlex

    if list_:
        typer.echo(experiments.table())
        return
    if name is None:
        raise ConfigError("name an experiment, or give --list")
    exp = experiments.get(name)
    out = out if out is not None else Path("runs") / exp.name
    steps = [(d.command, {"path": str(data / d.name)}) for d in experiments.data_steps(exp, data)] + [
        (exp.command, {"out": str(out), "jobs": str(jobs)})
    ]
    for command, own in steps:
        argv = experiments.fill(command, data=str(data), shared=str(shared), **own)
        shown = argv if argv[0] == experiments.PYTHON else ["wearnav", *argv]
        typer.echo(shlex.join(shown))
        if not dry_run:
            run_step(argv, out, ctx.find_root().command)


def run_step(argv: list[str], out: Path, wearnav) -> None:
    """One command of an experiment: a ``wearnav`` command through this command line (``wearnav``,
    its root command, in this process), a script of ``scripts/`` with this interpreter; a failure
    is one line."""
    import subprocess
    import sys

    if argv[0] != experiments.PYTHON:
        code = wearnav.main(args=argv, prog_name="wearnav", standalone_mode=False)
        if isinstance(code, int) and code:
            raise ConfigError(f"wearnav {argv[0]} ended with exit code {code}")
        return
    src = Path(__file__).resolve().parents[2]  # src/, beside scripts/ in a checkout
    script = src.parent / argv[1]
    if not script.is_file():
        raise ConfigError(f"{argv[1]}: not here; it is a script of the wearnav checkout", script)
    Path(out).mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, (str(src), os.environ.get("PYTHONPATH"))))}
    code = subprocess.run([sys.executable, str(script), *argv[2:]], env=env).returncode
    if code:
        raise ConfigError(f"{argv[1]} ended with exit code {code}")


register_fix_commands(bench_app)  # easytrack, easytrack-base, adapt (wearnav.cli.bench_fixes)
register_map_commands(bench_app)  # map-lofo (wearnav.cli.bench_maps)
