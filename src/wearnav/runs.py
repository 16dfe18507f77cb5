"""Run folders: a run is a pure function of its config → a folder named by the config's hash.

``runs/<suite>/<model>-<hash8>/`` holds ``config.yaml`` (the config plus the data's provenance,
package version and git commit), ``checkpoints/`` (best.ckpt, last.ckpt), ``metrics.json``,
``trajectories/`` and ``plots/``. A run is complete when ``metrics.json`` exists: suites skip
complete runs, so an interrupted benchmark resumes where it stopped. The results (config,
metrics, training record) are written durably: on disk before the call returns
(:func:`wearnav.core.fileio.atomic_path`).

One process at a time trains into a run folder: :func:`locked` holds the folder's lock file
``.wearnav.lock`` (an OS file lock, released when the process ends however it ends), and a second
process is refused with :class:`~wearnav.errors.BusyError`. The lock file is empty and stays; it
is neither a result (a run is still complete only with ``metrics.json``) nor part of the hash.

Only what changes the numbers enters the hash (model, data, splits, preprocessing, windows,
training hyper-parameters, seed); where a run is written, progress bars and the time budget do
not.

Decision: docs/decisions/0004-run-folders-atomic-writes-locks.md.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Protocol, TypeVar

import yaml
from filelock import FileLock, Timeout

from wearnav.core.fileio import write_text_atomic
from wearnav.core.provenance import provenance
from wearnav.core.textio import read_json, read_yaml
from wearnav.errors import BusyError, FormatError, MissingFileError, WearnavError

CONFIG = "config.yaml"
METRICS = "metrics.json"
LOCK = ".wearnav.lock"


# A config field added after runs were made: left out of the dict (so of config.yaml and of the
# run's hash) while it holds its default, so that those runs keep their folders' names.
OMIT_AT_DEFAULT = "omit_at_default"


def to_dict(cfg: Any) -> dict:
    """A (nested) dataclass as plain YAML-safe data (tuples become lists); a field whose metadata
    has :data:`OMIT_AT_DEFAULT` is left out while it holds its default."""

    def plain(v):
        if dataclasses.is_dataclass(v):
            return {
                f.name: plain(getattr(v, f.name))
                for f in dataclasses.fields(v)
                if not (f.metadata.get(OMIT_AT_DEFAULT) and getattr(v, f.name) == f.default)
            }
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


def is_blank(run: str | Path) -> bool:
    """Whether ``run`` may become a new run folder: absent, or a folder holding nothing but the
    lock file."""
    run = Path(run)
    if not run.exists():
        return True
    return run.is_dir() and all(p.name == LOCK for p in run.iterdir())


_held: dict[str, FileLock] = {}  # lock file → this process's hold on it (nested blocks share it)
_held_guard = threading.Lock()


@contextmanager
def locked(run: str | Path) -> Iterator[Path]:
    """Hold run folder ``run`` (created if absent) for this process during the block.

    Never waits: if another process holds it, raises :class:`BusyError`
    (``R: another wearnav process is using this run folder (pid N)``; the pid where the system
    tells). Re-entrant within a process, so a command may hold the folder across preparing,
    training and evaluating while ``fit`` takes it again inside.
    """
    run = Path(run)
    run.mkdir(parents=True, exist_ok=True)
    if _secondary_rank():  # the rank-0 process that started this one holds the folder
        yield run
        return
    key = os.path.realpath(run / LOCK)
    with _held_guard:
        lock = _held.get(key)
        if lock is None:
            lock = FileLock(key, timeout=0, thread_local=False)
        try:
            lock.acquire(timeout=0)
        except Timeout:
            pid = lock_holder(run)
            raise BusyError(
                "another wearnav process is using this run folder" + (f" (pid {pid})" if pid else ""), run
            ) from None
        _held[key] = lock
    try:
        yield run
    finally:
        with _held_guard:
            lock.release()
            if not lock.is_locked:
                _held.pop(key, None)


def _secondary_rank() -> bool:
    """True in a process that Lightning's DDP launcher started for another rank (it re-runs the
    command with ``LOCAL_RANK`` set; other nodes set ``NODE_RANK``): one training spread over
    several processes is one user of its run folder, so only rank 0 takes the lock."""
    return os.environ.get("LOCAL_RANK", "0") != "0" or os.environ.get("NODE_RANK", "0") != "0"


def lock_holder(run: str | Path) -> int | None:
    """The id of the process holding ``run``'s lock, where the system tells (Linux's
    ``/proc/locks``); else None."""
    try:
        st = os.stat(Path(run) / LOCK)
        table = Path("/proc/locks").read_text()
    except OSError:
        return None
    where = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    for line in table.splitlines():
        f = line.split()  # "1: FLOCK  ADVISORY  WRITE 4242 fd:01:1234567 0 EOF" ("->": a waiter)
        if len(f) >= 6 and f[1] == "FLOCK" and f[5] == where and f[4].isdigit():
            return int(f[4])
    return None


def write_config(run: str | Path, cfg: dict, extra: dict | None = None) -> Path:
    doc = {"config": cfg, "provenance": provenance(), **(extra or {})}
    return write_text_atomic(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), Path(run) / CONFIG, durable=True)


def read_config(run: str | Path) -> dict:
    path = Path(run) / CONFIG
    if not path.is_file():
        raise MissingFileError("not a run folder (no config.yaml)", Path(run))
    doc = read_yaml(path)
    if not isinstance(doc.get("config"), dict):
        raise FormatError("no 'config' mapping", path)
    return doc


class _FromDict(Protocol):
    """A config dataclass that reads itself from a mapping (``TrainConfig``, ``ClassifyConfig``)."""

    @classmethod
    def from_dict(cls: type[_ConfigT], d: dict) -> _ConfigT: ...


_ConfigT = TypeVar("_ConfigT", bound=_FromDict)


def run_folder(model: str | Path) -> Path:
    """The run folder of a model given as its run folder or one of its checkpoints
    (``RUN/checkpoints/NAME``): the commands take either."""
    p = Path(model)
    return p.parent.parent if p.is_file() else p


def read_run_config(run: str | Path, cls: type[_ConfigT]) -> _ConfigT:
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
    """``obj`` as JSON at ``path``, atomically and durably (on disk when this returns)."""
    return write_text_atomic(json.dumps(obj, indent=1, default=float), path, durable=True)


def write_metrics(run: str | Path, metrics: dict) -> Path:
    return write_json(Path(run) / METRICS, metrics)


def read_metrics(run: str | Path) -> dict:
    path = Path(run) / METRICS
    if not path.is_file():
        raise MissingFileError("run has no metrics.json yet (not evaluated)", Path(run))
    return read_json(path)
