"""wearnav: inertial odometry and activity recognition from everyday wearables."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from wearnav.core.provenance import __version__

if TYPE_CHECKING:
    from wearnav.dataset import Dataset, DatasetWriter
    from wearnav.recording import DeviceStream, Fixes, Recording, Trajectory, make_labels

# Loaded on first use, so that `import wearnav` (and `python -m wearnav`, which imports it first)
# is quick: the command line takes its SIGTERM handler before pandas and h5py load (__main__.py).
_LAZY = {
    "Dataset": "wearnav.dataset",
    "DatasetWriter": "wearnav.dataset",
    "DeviceStream": "wearnav.recording",
    "Fixes": "wearnav.recording",
    "Recording": "wearnav.recording",
    "Trajectory": "wearnav.recording",
    "make_labels": "wearnav.recording",
}


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'wearnav' has no attribute {name!r}")


__all__ = ["Dataset", "DatasetWriter", "DeviceStream", "Fixes", "Recording", "Trajectory", "make_labels", "__version__"]
