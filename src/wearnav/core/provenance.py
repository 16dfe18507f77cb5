"""What produced a result: package version, git commit, time — written next to every output."""

from __future__ import annotations

import datetime as _dt
import subprocess
from pathlib import Path

__version__ = "0.1.0"  # the package's version, as pyproject.toml's [project] version; wearnav.__version__


def git_commit() -> str:
    """Short commit of the source tree wearnav runs from ('' outside a git checkout)."""
    try:
        r = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            timeout=5,
            cwd=Path(__file__).resolve().parent,
        )
        return r.stdout.strip() if r.returncode == 0 else ""
    except (OSError, subprocess.SubprocessError):
        return ""


def provenance() -> dict:
    return {
        "wearnav": __version__,
        "commit": git_commit(),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }
