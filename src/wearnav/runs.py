"""Run folders: a run is a pure function of its config → a folder named by the config's hash.

``runs/<suite>/<model>-<hash8>/`` holds ``config.yaml`` (the config plus the data's provenance,
package version and git commit), ``checkpoints/`` (best.ckpt, last.ckpt), ``metrics.json``,
``trajectories/`` and ``plots/``. A run is complete when ``metrics.json`` exists: suites skip
complete runs, so an interrupted benchmark resumes where it stopped.

Only what changes the numbers enters the hash (model, data, splits, preprocessing, windows,
training hyper-parameters, seed); where a run is written, progress bars and the time budget do
not.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Any

import yaml

from wearnav.errors import FormatError, MissingFileError, WearnavError
from wearnav.fileio import write_text_atomic
from wearnav.provenance import provenance
from wearnav.textio import read_json, read_yaml

CONFIG = "config.yaml"
METRICS = "metrics.json"


def to_dict(cfg: Any) -> dict:
    """A (nested) dataclass as plain YAML-safe data (tuples become lists)."""
    def plain(v):
        if dataclasses.is_dataclass(v):
            return {f.name: plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        if isinstance(v, dict):
            return {str(k): plain(x) for k, x in v.items()}
        if isinstance(v, Path):
            return str(v)
        return v
    return plain(cfg)


def config_hash(cfg: dict, exclude: tuple[str, ...] = ()) -> str:
    """First 8 hex digits of the SHA-256 of the config's canonical JSON (keys sorted)."""
    d = {k: v for k, v in cfg.items() if k not in exclude}
    blob = json.dumps(d, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(blob.encode()).hexdigest()[:8]


def run_dir(root: str | Path, name: str, cfg: dict, exclude: tuple[str, ...] = ()) -> Path:
    safe = "".join(c if c.isalnum() or c in "+-_." else "_" for c in name)
    return Path(root) / f"{safe}-{config_hash(cfg, exclude)}"


def is_complete(run: str | Path) -> bool:
    return (Path(run) / METRICS).is_file()


def write_config(run: str | Path, cfg: dict, extra: dict | None = None) -> Path:
    doc = {"config": cfg, "provenance": provenance(), **(extra or {})}
    return write_text_atomic(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), Path(run) / CONFIG)


def read_config(run: str | Path) -> dict:
    path = Path(run) / CONFIG
    if not path.is_file():
        raise MissingFileError("not a run folder (no config.yaml)", Path(run))
    doc = read_yaml(path)
    if not isinstance(doc.get("config"), dict):
        raise FormatError("no 'config' mapping", path)
    return doc


def read_run_config(run: str | Path, cls: type):
    """The run's training config (``config.train`` of config.yaml) as ``cls`` (a config dataclass
    with ``from_dict``); a missing, mistyped or invalid entry is a FormatError naming the file."""
    path = Path(run) / CONFIG
    train = read_config(run)["config"].get("train")
    if not isinstance(train, dict):
        raise FormatError("no 'config.train' mapping", path)
    try:
        return cls.from_dict(train)
    except WearnavError as exc:
        raise FormatError(exc.reason, path) from None
    except (TypeError, ValueError) as exc:
        raise FormatError(f"invalid training config ({exc})", path) from None


def write_json(path: str | Path, obj: dict) -> Path:
    return write_text_atomic(json.dumps(obj, indent=1, default=float), path)


def write_metrics(run: str | Path, metrics: dict) -> Path:
    return write_json(Path(run) / METRICS, metrics)


def read_metrics(run: str | Path) -> dict:
    path = Path(run) / METRICS
    if not path.is_file():
        raise MissingFileError("run has no metrics.json yet (not evaluated)", Path(run))
    return read_json(path)
