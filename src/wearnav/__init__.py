"""wearnav: inertial odometry and activity recognition from everyday wearables."""

from wearnav.dataset import Dataset, DatasetWriter
from wearnav.recording import DeviceStream, Fixes, Recording, Trajectory, make_labels

__version__ = "0.1.0"

__all__ = ["Dataset", "DatasetWriter", "DeviceStream", "Fixes", "Recording", "Trajectory", "make_labels", "__version__"]
