"""Reading wearnav's own text files (config.yaml, results.md, results.json, training.json, ...).

The one place such a file is read: whatever is wrong with it (not UTF-8, not YAML / JSON, not the
top-level mapping the caller expects, a folder or a named pipe where a file should be) becomes a
:class:`wearnav.errors.FormatError` naming the file, so a damaged file is one line and exit 2,
never an internal error. Importers read the datasets' original files through
:mod:`wearnav.importers.common` instead (compressed files, lenient decoding).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from wearnav.core.fileio import require_regular_file
from wearnav.errors import FormatError


def read_text(path: str | Path) -> str:
    """The whole of a UTF-8 text file."""
    path = require_regular_file(path)
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise FormatError(f"not a UTF-8 text file (byte {exc.start}: {exc.reason})", path) from None
    except OSError as exc:
        raise FormatError(f"cannot read ({exc.strerror or exc})", path) from None


def read_json(path: str | Path, kind: type | None = dict) -> Any:
    """A JSON file's value; with ``kind`` (default: dict), a value of another type is refused."""
    text = read_text(path)
    try:
        value = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise FormatError(f"unreadable JSON ({exc})", path) from None
    return _require(value, kind, "JSON", path)


def read_yaml(path: str | Path, kind: type | None = dict) -> Any:
    """A YAML file's value (safe loader); with ``kind`` (default: dict), another type is refused."""
    text = read_text(path)
    try:
        value = yaml.safe_load(text)
    except (yaml.YAMLError, RecursionError) as exc:
        raise FormatError(
            f"unreadable YAML ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})", path
        ) from None
    return _require(value, kind, "YAML", path)


def _require(value: Any, kind: type | None, what: str, path: str | Path) -> Any:
    if kind is not None and not isinstance(value, kind):
        names: dict[type, str] = {dict: "a mapping", list: "a list"}
        name = names.get(kind, kind.__name__)
        raise FormatError(f"the {what} is not {name} (got {type(value).__name__})", path)
    return value
