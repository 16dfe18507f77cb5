"""`python -m wearnav` is the `wearnav` command (the installed `wearnav` script calls :func:`main`)."""

import signal
import threading

from wearnav.core.interrupts import note_sigterm


def main() -> None:
    """Note a SIGTERM that comes while the command line loads (its libraries take a second or
    two), then run it: ``wearnav.cli.main`` ends with its one line and exit 143 for a noted one
    as for one that comes later. Only the interpreter's own start is left to the default action."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, note_sigterm)
    from wearnav.cli import main as cli_main  # the command line's libraries: loaded after the handler

    cli_main()


if __name__ == "__main__":
    main()
