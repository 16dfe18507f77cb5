"""Ctrl-C and SIGTERM during training: stop between two batches, end as the CLI promises.

Lightning handles both signals its own way, and loses the exit code on the way: it catches
KeyboardInterrupt in ``trainer.fit`` and calls ``sys.exit(1)``; its SignalConnector turns SIGTERM
into ``SIGTERMException``, a ``SystemExit`` with no code (exit 0). :func:`stop_between_batches`
wraps ``trainer.fit`` so that a signal is only noted when it arrives (never in the middle of a
step or a checkpoint write), the :class:`StopOnSignal` callback raises at the next batch
boundary, and whatever Lightning turns it into leaves ``fit`` as ``KeyboardInterrupt`` (Ctrl-C)
or :class:`wearnav.errors.Terminated` (SIGTERM): ``wearnav.cli.main`` maps them to exit 130 and
143. ``checkpoints/last.ckpt`` is the last finished epoch's, so the run resumes from it (and
replays the interrupted epoch exactly; see :mod:`wearnav.train.common`). A second Ctrl-C stops at
once.
"""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from lightning.pytorch.callbacks import Callback

from wearnav.core.interrupts import raise_lost_interrupt
from wearnav.errors import Terminated


class StopOnSignal(Callback):
    """Raises the noted signal's exception at the next batch (train or validation) boundary."""

    def __init__(self) -> None:
        self.pending: int | None = None

    def note(self, signum: int, frame=None) -> None:
        if self.pending == signum == signal.SIGINT:  # asked twice: stop now
            raise KeyboardInterrupt
        self.pending = signum

    def check(self) -> None:
        # a signal the CLI's handler raised inside a finalizer before fit began (loading the data:
        # h5py frees objects there) was kept, not delivered (wearnav.core.interrupts): it stops here,
        # not when the run ends (a `wearnav train --max-time 2` went on for minutes after its SIGTERM)
        raise_lost_interrupt()
        if self.pending == signal.SIGINT:
            raise KeyboardInterrupt
        if self.pending == signal.SIGTERM:
            raise Terminated("terminated (SIGTERM)")

    def on_train_start(self, trainer, pl_module) -> None:
        self.check()

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        self.check()

    def on_validation_batch_end(self, trainer, pl_module, outputs, batch, batch_idx, dataloader_idx=0) -> None:
        self.check()


@contextmanager
def stop_between_batches(trainer) -> Iterator[None]:
    """Run ``trainer.fit`` (or another entry point) inside: SIGINT / SIGTERM stop it between
    batches and leave as KeyboardInterrupt / Terminated (see the module docstring)."""
    # Lightning logs "Received SIGTERM" at INFO on stderr: the CLI's one line says it already.
    logging.getLogger("lightning.pytorch.trainer.connectors.signal_connector").setLevel(logging.WARNING)
    stopper = StopOnSignal()
    trainer.callbacks.append(stopper)
    main = threading.current_thread() is threading.main_thread()
    old = {s: signal.signal(s, stopper.note) for s in (signal.SIGINT, signal.SIGTERM)} if main else {}
    try:
        yield
    except SystemExit as exc:  # Lightning's sys.exit(1) after Ctrl-C, its SIGTERMException
        if stopper.pending == signal.SIGINT:
            raise KeyboardInterrupt from None
        if stopper.pending == signal.SIGTERM or type(exc).__name__ == "SIGTERMException":
            raise Terminated("terminated (SIGTERM)") from None
        raise
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
        trainer.callbacks.remove(stopper)
    stopper.check()  # a signal that came after the last batch still stops the command
