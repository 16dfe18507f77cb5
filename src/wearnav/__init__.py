"""wearnav: inertial odometry and activity recognition from everyday wearables."""

from wearnav.dataset import Dataset, DatasetWriter
from wearnav.provenance import __version__
from wearnav.recording import DeviceStream, Fixes, Recording, Trajectory, make_labels

__all__ = ["Dataset", "DatasetWriter", "DeviceStream", "Fixes", "Recording", "Trajectory", "make_labels", "__version__"]
