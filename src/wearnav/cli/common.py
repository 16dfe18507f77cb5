"""What the ``wearnav`` command's modules share (:mod:`wearnav.cli`, :mod:`wearnav.cli.bench`, ...):
option values, JSON output, and the one line an interrupted command ends with."""

from __future__ import annotations

import json
from enum import Enum
from pathlib import Path
from typing import overload

import typer

from wearnav.bench.executor import Backend
from wearnav.errors import ConfigError, FormatError
from wearnav.importers import FORMATS

# Options with a fixed set of values that both modules take (wearnav.cli explains the enums).
# (members from FORMATS at run time, which mypy cannot list: it sees an Enum without members)
ImportFormat = Enum("ImportFormat", {f: f for f in FORMATS}, type=str)  # type: ignore[misc]


# How a suite's runs are spread (wearnav.bench.executor); none of it enters a run's hash.
JOBS_HELP = "Runs at once in local processes (1: one after another in this process)."
EXECUTOR_HELP = "local: this machine (--jobs processes); ray: a Ray cluster (pip install 'wearnav[cluster]')."
SEED_HELP = "Random seed of every run (its weights, batch order and augmentation; part of the run's hash)."
ADDRESS_HELP = (
    "With --executor ray: the cluster to join (host:port, or 'auto': the one `ray start` joined here); "
    "default: $RAY_ADDRESS or that cluster if there is one, else a new Ray on this machine."
)


def execution_of(jobs: int, executor: Backend, address: str | None, threads: int | None = None):
    """How a suite's runs are spread, from the bench commands' --jobs, --executor and --address."""
    from wearnav.bench.executor import Execution

    return Execution(jobs=jobs, backend=executor, address=address, threads=threads)


class Recipe(str, Enum):
    """How a run is optimised (wearnav.train.odometry.RECIPES)."""

    fast = "fast"
    paper = "paper"


RECIPE_HELP = (
    "fast: Adam lr 1e-3, 1-epoch warm-up, cosine decay over --epochs (learns in a short run); "
    "paper: the model's published schedule (Suite-IN++: lr 1e-4 constant; needs ~100 epochs)."
)


class VelLoss(str, Enum):
    """The velocity loss of a learned odometry model (wearnav.models.base.VEL_LOSSES)."""

    mse = "mse"
    polar = "polar"


VEL_LOSS_HELP = (
    "mse: the papers' squared error of the velocity vector (shortens a velocity whose direction is "
    "uncertain); polar: L1 on log speed plus a speed-weighted direction term (keeps the length)."
)
HEADING_FRAME_HELP = (
    "Each window of the learned model in the heading frame of the first device of its layout present (the "
    "phone, unless `train --devices` puts another first): turned by that device's own heading, its velocity "
    "turned back; without random yaw in training."
)


# What an interrupted command keeps and how to resume, said on the one line that ends it (exit
# 130 / 143); a command that writes sets it before its work starts (:func:`on_interrupt`).
NOTHING_KEPT = "nothing was written; run the same command again"
KEPT = {"line": NOTHING_KEPT}


@overload
def choice_value(choice: Enum) -> str: ...
@overload
def choice_value(choice: None) -> None: ...
@overload
def choice_value(choice: Enum | None) -> str | None: ...
def choice_value(choice: Enum | None) -> str | None:
    return None if choice is None else choice.value


def echo_json(obj) -> None:
    typer.echo(json.dumps(obj, indent=2, default=str))


def on_interrupt(line: str) -> None:
    KEPT["line"] = line


def suite_folder(out: Path, command: str) -> None:
    """A suite's --out: refused if its results.md is the user's; an interruption keeps finished runs."""
    from wearnav.outputs import check_suite_folder

    check_suite_folder(out, command)
    on_interrupt(f"finished runs are kept in {out}; run the same command again to resume")


def progress_enabled() -> bool:
    """Long work reports progress: a bar on a terminal, log lines every 30 s otherwise (the choice
    is :mod:`wearnav.core.progress`'s)."""
    return True


def split_list(text: str) -> tuple[str, ...]:
    """A comma-separated option (devices, splits, methods) as its items."""
    return tuple(d.strip() for d in text.split(",") if d.strip())


def split_floats(text: str, option: str) -> tuple[float, ...]:
    """A comma-separated option of numbers; a word that is not one is a one-line ConfigError."""
    try:
        return tuple(float(d) for d in split_list(text))
    except ValueError:
        raise ConfigError(f"{option}: numbers separated by commas, got {text!r}") from None


# The files a command reads a recording from: a wearnav recording, a Sensor Logger export zip
# (wearnav.track.load_input); anything else must be a folder (a dataset, an export or several).
INPUT_SUFFIXES = (".h5", ".zip")


def check_input(path: Path) -> None:
    """Refuse a command's input before the heavy imports (torch, the importers): it must exist,
    and a file must be one of :data:`INPUT_SUFFIXES` (a folder is read by the command)."""
    path = Path(path)
    if not path.exists():
        raise FormatError("no such file or folder", path)
    if path.is_file() and path.suffix.lower() not in INPUT_SUFFIXES:
        raise FormatError("not a recording (.h5), a dataset folder, or a Sensor Logger export (folder or .zip)", path)


def check_out_folder_path(out: Path) -> None:
    """Refuse an output folder that is a file (the command checks what the folder holds)."""
    from wearnav.outputs import check_out_folder

    check_out_folder(out, (), "", "")
