"""`wearnav track`: a recording in, its path out. :mod:`wearnav.track.run` tracks (the model, the
odometry, the outputs); :mod:`~wearnav.track.files` names the outputs, :mod:`~wearnav.track.write`
places the path and writes them, :mod:`~wearnav.track.maps` the map-aware path,
:mod:`~wearnav.track.trust` whether to trust it.

``from wearnav.track import track`` reads :mod:`wearnav.track.run` on first use, so the light
modules here (``files``) load without torch: the command line names its outputs and refuses a
misspelt model before anything heavy is imported.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from wearnav.track.run import (
        ANCHOR_S,
        devices_used,
        load_input,
        model_line,
        odometry,
        odometry_preprocess,
        path_times,
        track,
    )

__all__ = [
    "track",
    "load_input",
    "odometry",
    "odometry_preprocess",
    "path_times",
    "devices_used",
    "model_line",
    "ANCHOR_S",
]


def __getattr__(name: str) -> Any:
    """A name of :mod:`wearnav.track.run`, imported on first use (module docstring)."""
    if name in __all__:
        return getattr(importlib.import_module("wearnav.track.run"), name)
    raise AttributeError(f"module 'wearnav.track' has no attribute {name!r}")
