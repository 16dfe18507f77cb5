"""Atomic file writes: nothing half-written is ever left under the final name."""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from wearnav.errors import FormatError, MissingFileError


def _umask_mode() -> int:
    """0o666 minus the process umask: the mode an ordinary open() would give a new file."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; when the block succeeds it is renamed to ``path``
    (with ordinary file permissions), when it fails it is deleted."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, _umask_mode())  # mkstemp creates 0600
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_text_atomic(text: str, path: str | Path) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def require_regular_file(path: str | Path) -> Path:
    """``path`` if it is a regular file (symlinks followed); else a one-line error.

    Opening a named pipe, socket or device would block or read endless data, so anything that
    is not a plain file is refused before it is opened.
    """
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise MissingFileError("no such file", path) from None
    except OSError as exc:
        raise FormatError(f"cannot access ({exc.strerror or exc})", path) from None
    if stat.S_ISDIR(mode):
        raise FormatError("is a folder, expected a file", path)
    if not stat.S_ISREG(mode):
        raise FormatError("not a regular file (a named pipe, socket or device?); refusing to read it", path)
    return path
