"""What the ``wearnav`` command's modules share (:mod:`wearnav.cli`, :mod:`wearnav.cli_bench`):
option values, JSON output, and the one line an interrupted command ends with."""

from __future__ import annotations

import json
from enum import Enum
from pathlib import Path
from typing import overload

import typer

from wearnav.importers import FORMATS

# Options with a fixed set of values that both modules take (wearnav.cli explains the enums).
# (members from FORMATS at run time, which mypy cannot list: it sees an Enum without members)
ImportFormat = Enum("ImportFormat", {f: f for f in FORMATS}, type=str)  # type: ignore[misc]


class Recipe(str, Enum):
    """How a run is optimised (wearnav.train.odometry.RECIPES)."""

    fast = "fast"
    paper = "paper"


RECIPE_HELP = (
    "fast: Adam lr 1e-3, 1-epoch warm-up, cosine decay over --epochs (learns in a short run); "
    "paper: the model's published schedule (Suite-IN++: lr 1e-4 constant; needs ~100 epochs)."
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
    is :mod:`wearnav.progress`'s)."""
    return True


def split_list(text: str) -> tuple[str, ...]:
    """A comma-separated option (devices, splits, methods) as its items."""
    return tuple(d.strip() for d in text.split(",") if d.strip())
