"""Reports, one module per job:

* :mod:`.plots`: figures to check a recording (signals, labels, map) or a dataset (trajectories).
* :mod:`.stats`: the numbers behind ``wearnav info`` and the tables of ``wearnav demo``.
* :mod:`.datasets_page`: the Markdown page about the shipped public datasets.
* :mod:`.odometry`: odometry figures (estimated vs true trajectories, error CDFs, ATE boxes).

Metrics (ATE, fix errors, label noise ...) are defined in :mod:`wearnav.metrics`, not here.
"""

from wearnav.metrics import FIX_MAX_GAP_S
from wearnav.report.datasets_page import SHIPPED_DATASETS, write_datasets_report
from wearnav.report.plots import (
    ACC_COLOR,
    FIX_COLOR,
    GYRO_COLOR,
    TRUTH_COLOR,
    decimate_minmax,
    plot_recording,
    plot_trajectories,
)
from wearnav.report.stats import dataset_stats, stats_markdown, walk_tables

__all__ = [
    "ACC_COLOR",
    "FIX_COLOR",
    "FIX_MAX_GAP_S",
    "GYRO_COLOR",
    "SHIPPED_DATASETS",
    "TRUTH_COLOR",
    "dataset_stats",
    "decimate_minmax",
    "plot_recording",
    "plot_trajectories",
    "stats_markdown",
    "walk_tables",
    "write_datasets_report",
]
