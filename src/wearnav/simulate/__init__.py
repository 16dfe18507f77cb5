"""The built-in flexiwear-bodynet simulator: phone (100 Hz), watch on the left wrist (100 Hz) and
earbuds (25 Hz) on a walking body, with truth, noisy location fixes and interval labels.

Physics first: devices ride on body segments (head, forearm, hand, thigh, torso) driven by a gait
model; their IMUs measure the specific force Rᵀ(a − g) and body rate of that motion, then add
consumer-grade sensor errors. Walking modes, placements and splits follow Suite-IN++; the
phone-fix noise follows EasyTrack (see :mod:`.fixes`).

Modules, in data-flow order: ``config`` (what to simulate), ``scenario`` (events in time),
``path`` (route and gait timing), ``body`` (segments), ``placement`` (device poses), ``imu``
(sensor model), ``fixes`` (location fixes), ``walk`` (one recording), ``presets`` (datasets).

>>> from wearnav.simulate import WalkConfig, simulate_recording
>>> rec = simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=60), seed=1)
"""

from wearnav.simulate.config import (
    DEVICES,
    MODES,
    NOISE_LEVELS,
    PHONE_HOLDS,
    PLACEMENTS,
    SCENES,
    SubjectParams,
    WalkConfig,
    sample_subject,
)
from wearnav.simulate.fixes import LABEL_NOISE_MEDIAN_M, FixNoise, simulate_fixes
from wearnav.simulate.imu import IMU_SPECS, ImuSpec, TrueImu
from wearnav.simulate.presets import PRESETS, Preset, get_preset, plan_dataset, simulate_dataset
from wearnav.simulate.walk import SimulatedWalk, simulate_recording, simulate_walk

__all__ = [
    "DEVICES",
    "IMU_SPECS",
    "LABEL_NOISE_MEDIAN_M",
    "MODES",
    "NOISE_LEVELS",
    "PHONE_HOLDS",
    "PLACEMENTS",
    "PRESETS",
    "SCENES",
    "FixNoise",
    "ImuSpec",
    "Preset",
    "SimulatedWalk",
    "SubjectParams",
    "TrueImu",
    "WalkConfig",
    "get_preset",
    "plan_dataset",
    "sample_subject",
    "simulate_dataset",
    "simulate_fixes",
    "simulate_recording",
    "simulate_walk",
]
