"""One activity label set for every labelled source (issue 35), and each source's mapping onto it.

The shipped activity model trains on every labelled recording in ``../shared/data`` and the
simulator's walks at once; each source names its activities its own way, so they are mapped here,
as data, onto :data:`LABELS`. ``None`` in a mapping: windows of that label are not used (neither a
class nor "other"). The table below is what the model card prints (:func:`mapping_table`), and
``tests/test_activity_labels.py`` checks every source's keys against its importer's own label
names, so a renamed label upstream fails there, not silently here.

Sources without activity labels whose recordings are walks throughout (:data:`WHOLE_RECORDING`):

* ILC2 site 1 and IPIN 2023 Track 3: surveyors walking with the phone in the hand. Every window is
  ``walking`` except, in IPIN, the spans between two surveyed points on different floors (how the
  walker changed floor, stairs, lift or escalator, is not in the data, so those spans are left
  out, not guessed); ILC2's traces each stay on one floor.
* Oxford step counter (validation part): walks with step ground truth in seven carrying positions,
  accelerometer only (the model's gyroscope channels are zero for it, as for any phone without one).

Their first and last :data:`EDGE_TRIM_S` seconds are left out: the walker may still be standing.
"""

from __future__ import annotations

import pandas as pd

# The one label set (issue 35 §1). "vehicle" is part of the set so that a future source with car,
# bus or train rides maps onto it; no source here has it, so no model trained here predicts it
# (a ride should come out as ``unknown``, :mod:`wearnav.train.classify`).
WALKING, STAIRS_UP, STAIRS_DOWN, RUNNING = "walking", "stairs_up", "stairs_down", "running"
STANDING, SITTING, LYING, VEHICLE, OTHER = "standing", "sitting", "lying", "vehicle", "other"
LABELS = (WALKING, STAIRS_UP, STAIRS_DOWN, RUNNING, STANDING, SITTING, LYING, VEHICLE, OTHER)
# What classify writes for a window the model is unsure of or whose input is unlike its training data.
UNKNOWN = "unknown"

# source → (label kind in the imported recordings, {source label → one of LABELS or None})
MAPPINGS: dict[str, tuple[str, dict[str, str | None]]] = {
    # wearnav.importers.motionsense.ACTIVITIES (values)
    "motionsense": (
        "activity",
        {
            "walking": WALKING,
            "upstairs": STAIRS_UP,
            "downstairs": STAIRS_DOWN,
            "jogging": RUNNING,
            "standing": STANDING,
            "sitting": SITTING,
        },
    ),
    # UCI HAPT activity_labels.txt (the importer keeps the names as written there)
    "uci-hapt": (
        "activity",
        {
            "WALKING": WALKING,
            "WALKING_UPSTAIRS": STAIRS_UP,
            "WALKING_DOWNSTAIRS": STAIRS_DOWN,
            "SITTING": SITTING,
            "STANDING": STANDING,
            "LAYING": LYING,
            "STAND_TO_SIT": OTHER,
            "SIT_TO_STAND": OTHER,
            "SIT_TO_LIE": OTHER,
            "LIE_TO_SIT": OTHER,
            "STAND_TO_LIE": OTHER,
            "LIE_TO_STAND": OTHER,
        },
    ),
    # UJI phone + watch (a timed-up-and-go protocol, wearnav.importers.uji_phone_watch): TURNING is
    # the 180° turn walked between the two straight walks, made in steps, so it counts as walking.
    "uji-phone": (
        "activity",
        {"SEATED": SITTING, "STANDING_UP": OTHER, "WALKING": WALKING, "TURNING": WALKING, "SITTING_DOWN": OTHER},
    ),
    "uji-watch": (
        "activity_watch",
        {"SEATED": SITTING, "STANDING_UP": OTHER, "WALKING": WALKING, "TURNING": WALKING, "SITTING_DOWN": OTHER},
    ),
    # the simulator's activity track (wearnav.simulate.scenario.Scenario.label_rows): walking bouts,
    # stops, and sit / squat episodes with their transitions
    "sim": (
        "activity",
        {
            "walk": WALKING,
            "stand": STANDING,
            "sit": SITTING,
            "squat": OTHER,
            "stand_to_sit": OTHER,
            "sit_to_stand": OTHER,
            "stand_to_squat": OTHER,
            "squat_to_stand": OTHER,
        },
    ),
}

# Sources labelled walking throughout (module docstring): source → the label every window gets.
WHOLE_RECORDING: dict[str, str] = {"ilc2": WALKING, "ipin": WALKING, "oxford": WALKING}
# Seconds left out at each end of a whole-recording source's walk (a walker standing before the
# first step or after the last): a few strides.
EDGE_TRIM_S = 3.0

SOURCE_NOTES = {
    "motionsense": "iPhone 6s, front trouser pocket, 24 subjects",
    "uci-hapt": "Samsung Galaxy S II on the waist, 30 subjects; transitions as other",
    "uji-phone": "phone in a pocket (4 orientations), timed up-and-go; TURNING (walked) as walking",
    "uji-watch": "the same executions' smartwatch",
    "sim": "the simulator's walks (hand, pocket, bag), stops, sit and squat episodes",
    "ilc2": "hand-held walks, labelled walking throughout",
    "ipin": "hand-held walks, labelled walking except floor changes (left out)",
    "oxford": "walks in 7 carrying positions, accelerometer only, labelled walking throughout",
}


def unify(source: str, label: str) -> str | None:
    """``label`` of ``source`` in :data:`LABELS` (None: not used). Unknown source or label: KeyError."""
    if source in WHOLE_RECORDING:
        return WHOLE_RECORDING[source]
    return MAPPINGS[source][1][label]


def mapping_table() -> pd.DataFrame:
    """One row per (source, source label): the card's harmonisation table."""
    rows = [
        {"source": s, "source label": k, "label": v if v is not None else "(left out)"}
        for s, (_, m) in MAPPINGS.items()
        for k, v in m.items()
    ]
    rows += [{"source": s, "source label": "(whole recording)", "label": v} for s, v in WHOLE_RECORDING.items()]
    return pd.DataFrame(rows)
