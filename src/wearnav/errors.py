"""Errors raised on bad input. Each names the file (when known) and what is wrong, in one line.

The CLI catches :class:`WearnavError`, prints ``str(err)`` and exits with code 2.
"""

from __future__ import annotations

from pathlib import Path


class WearnavError(Exception):
    """Base class: ``source`` is the file or folder at fault (may be None), ``reason`` says why."""

    def __init__(self, reason: str, source: str | Path | None = None):
        # Messages quote other libraries' errors (pandas' parser errors span lines); the promise
        # is one line, so every run of whitespace becomes one space.
        self.reason = one_line(str(reason))
        self.source = None if source is None else str(source)
        super().__init__(str(self))

    def __str__(self) -> str:
        return f"{self.source}: {self.reason}" if self.source else self.reason

    def with_source(self, source: str | Path) -> "WearnavError":
        """The same error attributed to ``source`` (kept if one is already set)."""
        if self.source is None:
            self.source = str(source)
            self.args = (str(self),)
        return self


def one_line(text: str) -> str:
    """``text`` with every run of whitespace (newlines included) collapsed to one space."""
    return " ".join(text.split())


class ValidationError(WearnavError):
    """Values are wrong: shapes, non-finite numbers, unsorted time, implausible units."""


class FormatError(WearnavError):
    """A file is not in the expected format: unreadable, corrupt, missing or renamed columns."""


class MissingFileError(WearnavError):
    """A file or folder that was named does not exist."""


class ConfigError(WearnavError):
    """A configuration value or command-line option is invalid."""


class BusyError(WearnavError):
    """Another process holds what this one needs (a run folder being trained into)."""


class WearnavWarning(UserWarning):
    """Input was accepted with a caveat the user must know (e.g. a file that looks cut short)."""


class Terminated(BaseException):
    """The process was asked to stop (SIGTERM: a cluster time limit, ``docker stop``).

    A BaseException like KeyboardInterrupt, so that only cleanup code (``finally``, ``with``)
    sees it, never an ``except Exception`` meant for bad data.
    """
