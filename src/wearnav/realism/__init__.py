"""How real is the simulated walking? Gait and sensor statistics of simulated and real recordings.

One module per job, imports running downward:

- :mod:`.gait`: walking stretches (labels or a detector), one common rate, analysis segments;
- :mod:`.stats`: the statistics and |acc| PSD of a segment, and of every segment of a recording;
- :mod:`.fixes`: location fixes against surveyed reference points;
- :mod:`.sources`: the placements compared, their simulated walkers and real recordings;
- :mod:`.calibrate`: summaries, the real calibration bands and the comparison as a whole;
- :mod:`.report`: figures, tables and the page (its docstring spells out the method).
"""

from wearnav.realism.calibrate import (
    IQR_MIN_SEGMENTS,
    SMALL_SET_TOLERANCE,
    SourceResult,
    band_of,
    compare,
    compute_realism,
    fix_compare,
    summary,
    weighted_quantiles,
)
from wearnav.realism.fixes import FIX_STATS, JUMP_SPEED_MPS, OUTAGE_GAP_S, SIM_REFERENCE_EVERY_S, fix_stats
from wearnav.realism.gait import (
    MAX_STEP_GAP_S,
    MAX_WALK_GYRO,
    MIN_SEGMENT_S,
    RATE_HZ,
    SEGMENT_S,
    STEP_BAND_HZ,
    TRIM_S,
    WALK_STD_BAND,
    WALK_WINDOW_S,
    detect_walking,
    labelled_walking,
    resample,
    segments,
    walking_stretches,
)
from wearnav.realism.report import realism_report
from wearnav.realism.sources import (
    CALIBRATION_COLUMNS,
    CALIBRATION_NOTES,
    CALIBRATION_TABLE,
    CLAIMED,
    FIX_REAL,
    GROUPS,
    ILC2_CALIBRATION,
    IPIN_CALIBRATION,
    SIM_DURATION_S,
    Group,
    RealSource,
    open_real,
    simulate_realism_walks,
)
from wearnav.realism.stats import (
    BANDS,
    F_DOM_BAND_HZ,
    STAT_LABELS,
    STATS,
    STRIDE_LAGS_S,
    recording_segments,
    segment_stats,
    spectrum,
)

__all__ = [
    "BANDS",
    "CALIBRATION_COLUMNS",
    "CALIBRATION_NOTES",
    "CALIBRATION_TABLE",
    "CLAIMED",
    "FIX_REAL",
    "FIX_STATS",
    "F_DOM_BAND_HZ",
    "GROUPS",
    "Group",
    "ILC2_CALIBRATION",
    "IPIN_CALIBRATION",
    "IQR_MIN_SEGMENTS",
    "JUMP_SPEED_MPS",
    "MAX_STEP_GAP_S",
    "MAX_WALK_GYRO",
    "MIN_SEGMENT_S",
    "OUTAGE_GAP_S",
    "RATE_HZ",
    "RealSource",
    "SEGMENT_S",
    "SIM_DURATION_S",
    "SIM_REFERENCE_EVERY_S",
    "SMALL_SET_TOLERANCE",
    "STATS",
    "STAT_LABELS",
    "STEP_BAND_HZ",
    "STRIDE_LAGS_S",
    "SourceResult",
    "TRIM_S",
    "WALK_STD_BAND",
    "WALK_WINDOW_S",
    "band_of",
    "compare",
    "compute_realism",
    "detect_walking",
    "fix_compare",
    "fix_stats",
    "labelled_walking",
    "open_real",
    "realism_report",
    "recording_segments",
    "resample",
    "segment_stats",
    "segments",
    "simulate_realism_walks",
    "spectrum",
    "summary",
    "walking_stretches",
    "weighted_quantiles",
]
