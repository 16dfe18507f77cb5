"""Ctrl-C and SIGTERM that Python could not deliver: kept, and raised again at the next safe point.

A signal handler runs between two bytecodes of the main thread, wherever that thread is. When
it is inside a finalizer (a weakref callback such as ``WeakValueDictionary``'s, which h5py's
objects trigger as they are freed, or a ``__del__``), the exception the handler raises
(:class:`~wearnav.errors.Terminated` from ``wearnav.cli.main``'s SIGTERM handler,
``KeyboardInterrupt`` from Ctrl-C) cannot propagate: Python prints ``Exception ignored in:
<function WeakValueDictionary…>`` and carries on, and the command would finish as if never
stopped (exit 0). Inside :func:`noting_lost_interrupts` such an exception is kept instead (and
nothing is printed), and :func:`raise_lost_interrupt` raises it again where the code can stop
cleanly: before each recording a dataset writer adds, before it moves the dataset into place,
and when a command returns.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager

from wearnav.errors import Terminated

_lost: list[BaseException] = []  # interrupts raised where they could not propagate, oldest first
_depth: list[None] = []  # one per noting_lost_interrupts block open (the writer's inside the CLI's)


def note_interrupt(exc: BaseException) -> None:
    """Keep ``exc`` (a Terminated or KeyboardInterrupt) for :func:`raise_lost_interrupt`; a handler
    that must not raise (e.g. while the command line is still loading) calls it directly."""
    _lost.append(exc)


def note_sigterm(signum: int | None = None, frame: object = None) -> None:
    """A SIGTERM handler that only notes the signal (as :class:`Terminated`), raising nothing."""
    note_interrupt(Terminated("terminated (SIGTERM)"))


def raise_lost_interrupt() -> None:
    """Raise the first interrupt kept since the last call (Ctrl-C before SIGTERM when both were),
    as a fresh exception of its type; nothing when none was."""
    if _lost:
        first = next((e for e in _lost if isinstance(e, KeyboardInterrupt)), _lost[0])
        _lost.clear()
        raise type(first)(*first.args)


def _is_interrupt(exc_type: type[BaseException] | None) -> bool:
    return exc_type is not None and issubclass(exc_type, (KeyboardInterrupt, Terminated))


@contextmanager
def noting_lost_interrupts() -> Iterator[None]:
    """Within: an interrupt raised where Python cannot propagate it (``sys.unraisablehook``) is kept
    for :func:`raise_lost_interrupt` and not printed; anything else goes to the previous hook.
    Leaving the outermost such block forgets what was kept and not raised (a command that failed
    otherwise meanwhile has ended; the next one in this process starts clean)."""
    previous = sys.unraisablehook
    _depth.append(None)

    def hook(unraisable) -> None:
        if _is_interrupt(unraisable.exc_type):
            note_interrupt(unraisable.exc_value or unraisable.exc_type())
        else:
            previous(unraisable)

    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous
        _depth.pop()
        if not _depth:
            _lost.clear()


__all__ = ["note_interrupt", "note_sigterm", "noting_lost_interrupts", "raise_lost_interrupt"]
