"""Output folders of the commands that write into a folder the user names (``track``, ``classify``).

Two promises: a failed call changes nothing (no half-written set of files, no empty folder
left behind), and a file wearnav did not write is never replaced. Each command keeps a marker
file in its output folder (``track.json``, ``classify.json``: what was done, and the list
``files`` it wrote); a file of the same name as one the command writes, in a folder without that
marker, is the user's, and the call is refused. Files are written into a staging folder inside
the output folder and moved into place only when the command has succeeded; files the previous
call listed and this one did not write are removed (``track``: the folder never mixes two calls;
``classify`` adds each call's recordings instead).

The commands that write a whole dataset folder (``import``, ``simulate``) replace only what
wearnav wrote (:class:`wearnav.dataset.DatasetWriter`), and even that only when asked:
:func:`check_new_dataset` refuses a folder that already holds a dataset unless ``--overwrite``.
"""

from __future__ import annotations

import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from wearnav.errors import ConfigError
from wearnav.textio import read_json


def check_out_folder(out: str | Path, names: Iterable[str], marker: str, command: str) -> None:
    """Refuse ``out`` if it is not a folder, or holds one of ``names`` without ``marker`` beside it
    (a file ``command`` did not write). Call it before any work, and again before writing."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError("exists and is not a folder; choose another --out", out)
    if not out.is_dir() or (out / marker).is_file():
        return
    for name in names:
        if (out / name).exists() or (out / name).is_symlink():
            raise ConfigError(f"holds {name}, which `wearnav {command}` did not write (no {marker} beside "
                              "it); choose another --out", out)


def check_new_dataset(out: str | Path, overwrite: bool, command: str) -> None:
    """Refuse to write a new dataset over one that ``out`` already holds, unless ``overwrite``.

    A folder that is absent or empty is fine; one holding a wearnav dataset needs ``overwrite``
    (the user's recordings would be replaced); anything else is refused later by
    :class:`wearnav.dataset.DatasetWriter` whatever ``overwrite`` says. Call it before any work.
    """
    from wearnav.dataset import MANIFEST, PROVENANCE

    out = Path(out)
    if overwrite or not out.is_dir() or not any(out.iterdir()):
        return
    if (out / MANIFEST).is_file() or (out / PROVENANCE).is_file():
        n = sum(1 for _ in out.glob("*.h5"))
        raise ConfigError(f"already holds a wearnav dataset ({n} recordings); add --overwrite to replace it, "
                          f"or choose another --out for `wearnav {command}`", out)


def _previous_files(out: Path, marker: str) -> list[str]:
    try:
        files = read_json(out / marker).get("files", [])
    except Exception:  # an unreadable marker of ours: nothing to tidy, it is replaced below
        return []
    return [f for f in files if isinstance(f, str) and "/" not in f and f not in ("", ".", "..")] \
        if isinstance(files, list) else []


@contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back for a few renames (delivered when the block ends)."""
    held = {signal.SIGINT, signal.SIGTERM}
    can = hasattr(signal, "pthread_sigmask") and threading.current_thread() is threading.main_thread()
    old = signal.pthread_sigmask(signal.SIG_BLOCK, held) if can else None
    try:
        yield
    finally:
        if can:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)


@contextmanager
def staged_output(out: str | Path, marker: str, command: str, replace: bool = True) -> Iterator[Path]:
    """Yield a staging folder; when the block succeeds, every file written there moves into
    ``out`` (``marker`` last), after :func:`check_out_folder` on their names; with ``replace``,
    the files the previous call listed in its marker and this one did not write are removed.
    When it fails, the staging folder goes, and so do ``out`` and its parents if this call
    created them."""
    out = Path(out)
    check_out_folder(out, (), marker, command)
    created = [p for p in (out, *out.parents) if not p.exists()]
    out.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{marker}.", suffix=".partial", dir=out))
    try:
        yield stage
        names = sorted(p.name for p in stage.iterdir())
        check_out_folder(out, names, marker, command)
        stale = [f for f in _previous_files(out, marker) if f not in names and f != marker] if replace else []
        with _signals_held():  # Ctrl-C / SIGTERM wait until the folder is whole again
            for name in sorted(names, key=lambda n: n == marker):  # the marker last: it vouches for the rest
                os.replace(stage / name, out / name)
            for name in stale:
                (out / name).unlink(missing_ok=True)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        for folder in created:  # innermost first; only what is still empty
            try:
                folder.rmdir()
            except OSError:
                break
        raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)
