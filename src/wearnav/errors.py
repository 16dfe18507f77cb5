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

    def with_source(self, source: str | Path) -> WearnavError:
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


def check_names(
    given, valid, what: str, where: str | Path | None = None, error: type[WearnavError] = ConfigError
) -> tuple[str, ...]:
    """``given`` as a tuple when every name is one of ``valid``; else a :class:`ConfigError` naming
    the unknown ones and every valid one, e.g. "unknown device(s) ['watc']; valid: phone, watch".
    The one check for names a user types (devices, splits, techniques, models, methods), made
    before any work starts. ``error``: the class raised (ConfigError for an option)."""
    given, valid = tuple(given), list(valid)
    unknown = [g for g in given if g not in valid]
    if unknown:
        raise error(f"unknown {what}(s) {unknown}; valid: {', '.join(map(str, valid)) or 'none'}", where)
    return given


def check_field_types(cfg) -> None:
    """Raise :class:`ConfigError` unless every field of dataclass ``cfg`` has its annotated type.

    For configs read back from a file (a run's config.yaml), where a hand edit or a damaged file
    may put text where a number belongs: ``int`` takes no bool, ``float`` takes an int,
    ``tuple[X, ...]`` takes a tuple of X, ``A | None`` takes None; ``Any`` takes anything.
    """
    import dataclasses
    import numbers
    import types
    import typing

    def fits(value, hint) -> bool:
        origin, args = typing.get_origin(hint), typing.get_args(hint)
        if hint is typing.Any:
            return True
        if origin in (typing.Union, types.UnionType):
            return any(fits(value, a) for a in args)
        if hint is type(None):
            return value is None
        if hint is bool:
            return isinstance(value, bool)
        if hint is int:
            return isinstance(value, numbers.Integral) and not isinstance(value, bool)
        if hint is float:
            return isinstance(value, numbers.Real) and not isinstance(value, bool)
        if origin is tuple:
            return isinstance(value, tuple) and all(fits(v, args[0]) for v in value)
        if origin is dict:
            return isinstance(value, dict) and all(isinstance(k, str) for k in value)
        return isinstance(value, origin or hint)

    hints = typing.get_type_hints(type(cfg))
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        if not fits(value, hints[f.name]):
            want = getattr(hints[f.name], "__name__", None) or str(hints[f.name]).replace("typing.", "")
            raise ConfigError(f"{f.name} must be {want}, got {value!r}")
