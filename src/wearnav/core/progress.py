"""Progress of long work, the one helper every loop reports through.

On a terminal (stderr a TTY) it draws a tqdm bar; anywhere else (CI, ``nohup``, a pipe, a log
file) a bar's carriage returns would stay behind as fragments, so it writes a log line instead
(``log.info`` on the ``wearnav.core.progress`` logger, which ``wearnav.cli`` prints on stderr) at
most every ``interval_s`` seconds: what, done/total, elapsed and an estimate of the time left.
``interval_s`` defaults to :data:`INTERVAL_S`, or ``$WEARNAV_PROGRESS_INTERVAL_S`` where set (a
test sets it small).

>>> for rec in progress(names, desc="import ilc2", unit="rec"):
...     ...
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Iterable, Iterator

log = logging.getLogger(__name__)

INTERVAL_S = 30.0  # issue 22: without a terminal, a line at least every 30 s
INTERVAL_ENV = "WEARNAV_PROGRESS_INTERVAL_S"


def interval_s() -> float:
    """Seconds between two log lines: ``$WEARNAV_PROGRESS_INTERVAL_S``, else :data:`INTERVAL_S`."""
    try:
        return max(0.0, float(os.environ.get(INTERVAL_ENV, INTERVAL_S)))
    except ValueError:
        return INTERVAL_S


def on_terminal() -> bool:
    """Whether a bar can be drawn (stderr is a terminal)."""
    return sys.stderr.isatty()


def eta_line(
    desc: str, done: float, total: float | None, elapsed_s: float, unit: str = "", done_here: float | None = None
) -> str:
    """``desc: 3/10 rec, 12 s elapsed, about 28 s left`` (no estimate without a total or before
    the first item is done). ``done_here``: how many of ``done`` this call did in ``elapsed_s``
    (a resumed loop starts at more than 0); default ``done``.

    >>> eta_line("import", 3, 10, 12.0, "rec")
    'import: 3/10 rec, 12 s elapsed, about 28 s left'
    """
    count = f"{done:g}/{total:g}" if total else f"{done:g}"
    text = f"{desc}: {count}{' ' + unit if unit else ''}, {elapsed_s:.0f} s elapsed"
    here = done if done_here is None else done_here
    if total and here > 0:
        text += f", about {elapsed_s * max(total - done, 0) / here:.0f} s left"
    return text


class Progress:
    """A tqdm-like counter: iterate over it, or call :meth:`update`; :meth:`close` at the end.

    ``enabled=False`` reports nothing. ``leave``: keep the finished bar on the terminal.
    """

    def __init__(
        self,
        iterable: Iterable | None = None,
        total: float | None = None,
        desc: str = "",
        unit: str = "it",
        enabled: bool = True,
        leave: bool = True,
        initial: float = 0,
        interval: float | None = None,
    ):
        if total is None and iterable is not None and hasattr(iterable, "__len__"):
            total = len(iterable)  # type: ignore[arg-type]
        self.iterable, self.total, self.desc, self.unit = iterable, total, desc, unit
        self.enabled, self.leave = enabled, leave
        self.interval = interval_s() if interval is None else interval
        self.done = self.start = initial
        self.t0 = self.last = time.monotonic()
        self.bar = None
        if enabled and on_terminal():
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, desc=desc, unit=unit, leave=leave, initial=initial)

    def __iter__(self) -> Iterator:
        for item in self.iterable if self.iterable is not None else ():
            yield item
            self.update()

    def update(self, n: float = 1) -> None:
        self.done += n
        if self.bar is not None:
            self.bar.update(n)
            return
        now = time.monotonic()
        if self.enabled and now - self.last >= self.interval:
            self.last = now
            log.info(eta_line(self.desc, self.done, self.total, now - self.t0, self.unit, self.done - self.start))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.leave = self.leave
            self.bar.close()


def progress(
    iterable: Iterable,
    total: float | None = None,
    desc: str = "",
    unit: str = "it",
    enabled: bool = True,
    leave: bool = True,
) -> Iterator:
    """Iterate over ``iterable`` reporting progress (a bar on a terminal, else log lines)."""
    p = Progress(iterable, total, desc, unit, enabled, leave)
    try:
        yield from p
    finally:
        p.close()
