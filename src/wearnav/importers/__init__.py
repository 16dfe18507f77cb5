"""Importers: one module per real format, each turning the original files into Recordings.

Every importer module defines ``read(src: Path, limit: int | None = None) -> Iterator[Recording]``
yielding recordings (at most ``limit``) from a folder, file or archive in the dataset's original
layout; ``meta["split"]`` is set only where the dataset itself defines one (IPIN's
training/validation/testing trials). Problems raise :mod:`wearnav.errors` exceptions naming the file.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType

from wearnav.core.progress import Progress
from wearnav.errors import ConfigError

FORMATS: dict[str, str] = {
    "ilc2": "wearnav.importers.ilc2",
    "ipin2023": "wearnav.importers.ipin2023",
    "motionsense": "wearnav.importers.motionsense",
    "uci-hapt": "wearnav.importers.uci_hapt",
    "uji-phone-watch": "wearnav.importers.uji_phone_watch",
    "oxford-steps": "wearnav.importers.oxford_steps",
    "sensorlogger": "wearnav.importers.sensorlogger",
}


def get_importer(fmt: str) -> ModuleType:
    if fmt not in FORMATS:
        raise ConfigError(f"unknown format {fmt!r}; known: {', '.join(FORMATS)}")
    return importlib.import_module(FORMATS[fmt])


def import_dataset(
    fmt: str, src: str | Path, out: str | Path, limit: int | None = None, progress: bool = True, **options
):
    """Read ``src`` with the ``fmt`` importer and write a dataset folder at ``out``; ``options``
    go to that importer's ``read`` (e.g. sensorlogger's ``platform``)."""
    from wearnav.dataset import Dataset, DatasetWriter

    src = Path(src)
    module = get_importer(fmt)  # each read() checks src and limit (common.check_source)
    bar = Progress(
        module.read(src, limit=limit, **options), total=limit, desc=f"import {fmt}", unit="rec", enabled=progress
    )
    try:
        made_by = {"importer": fmt, "src": str(src.resolve()), "limit": limit, **options}
        with DatasetWriter(out, made_by) as writer:
            for rec in bar:
                writer.add(rec, split=rec.meta.get("split", ""))
    except BaseException:
        bar.leave = False  # clear the bar so the error stays the only line
        raise
    finally:
        bar.close()
    return Dataset.open(out)
