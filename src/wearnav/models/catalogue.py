"""The registry's models as a table read without torch (issue 58 §7): name, task, device layout,
whether it is learned, whether its input is the heading frame, parameter count, description.

:mod:`wearnav.models.registry` stays the one list of models (each family registers its
constructors on import, which loads torch and scipy: ~2-3 s). The commands that only need the
names (``wearnav models``, a ``--model`` checked before any work, the untrained baselines usable by
name) read :data:`CATALOGUE_JSON` instead, written from the registry by :func:`generate`;
``tests/test_models_catalogue.py`` fails when the file and the registry differ, and
``python -m wearnav.models.catalogue`` rewrites it. Parameters are counted as ``wearnav models``
always counted them: the model built with its defaults for three devices and 100-sample windows
(None where it cannot be built so).
"""

from __future__ import annotations

import dataclasses
import json
from functools import cache
from pathlib import Path

from wearnav.core.fileio import write_text_atomic

CATALOGUE_JSON = Path(__file__).with_name("catalogue.json")
# the build arguments of the parameter count (what `wearnav models` has always shown)
COUNT_DEVICES, COUNT_WINDOW = 3, 100


@dataclasses.dataclass(frozen=True)
class Entry:
    name: str
    task: str
    layout: str
    learned: bool
    heading_frame: bool
    parameters: int | None
    description: str


@cache
def read() -> tuple[Entry, ...]:
    """Every registered model of the package, in the registry's order, from :data:`CATALOGUE_JSON`."""
    return tuple(Entry(**row) for row in json.loads(CATALOGUE_JSON.read_text())["models"])


def names(task: str | None = None, learned: bool | None = None) -> list[str]:
    """The registered models' names (of ``task``; only the learned or untrained ones)."""
    return [e.name for e in read() if (task is None or e.task == task) and (learned is None or e.learned == learned)]


def entry(name: str) -> Entry | None:
    """The registered model ``name``, None where there is none."""
    return next((e for e in read() if e.name == name), None)


def generate() -> list[dict]:
    """The table from the registry itself (imports every family: torch): the models the package's own
    families register (not those a test or a user registers at run time)."""
    from wearnav.models import registry

    family = {spec.name: spec.build.__module__.removeprefix("wearnav.models.") for spec in registry.available()}
    ours = [s for s in registry.available() if family[s.name] in registry.FAMILIES]
    rows = []
    # in FAMILIES' order, each family's in its own (the registry's order is the import order)
    for spec in sorted(ours, key=lambda s: registry.FAMILIES.index(family[s.name])):
        try:
            n: int | None = registry.n_parameters(spec.build(n_devices=COUNT_DEVICES, window=COUNT_WINDOW))
        except Exception:  # a model that cannot be built with defaults is still listed
            n = None
        rows.append(
            dataclasses.asdict(
                Entry(spec.name, spec.task, spec.layout, spec.learned, spec.heading_frame, n, spec.description)
            )
        )
    return rows


def write(path: Path = CATALOGUE_JSON) -> Path:
    """Write :func:`generate`'s table to ``path``."""

    text = json.dumps({"generated_by": "python -m wearnav.models.catalogue", "models": generate()}, indent=1)
    return write_text_atomic(text + "\n", path)


if __name__ == "__main__":
    print(write())
