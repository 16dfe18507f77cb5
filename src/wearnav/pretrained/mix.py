"""One training set from several sources: real buildings and the simulator (issue 18 §1–2).

A model trained on one building loses to PDR in another; the shipped models train on everything
with positions. The sources disagree on frames, so each recording's truth (and fixes) is turned
into the frame its own IMU input will have — the phone's world frame after the devices' common
alignment (:func:`wearnav.preprocess.frames.align_frames`, mode ``common``) — by one constant yaw, and the
models train in that frame (``frame_align="common"``, the frame `wearnav track` feeds them):

``axis``        a real building where the phone is held in the hand, pointing ahead (ILC2, IPIN
                2023: meta ``placement`` "handheld"): one yaw for all its recordings (the phone's
                rotation vector refers to magnetic north, the survey to a floor plan), the angle
                of the phone's +y axis against the surveyed direction of walking
                (:func:`wearnav.bench.real_sites.device_axis_yaw`). The yaw that `bench real-odometry`
                fits for PDR carries PDR's own heading bias, which differs by building (ILC2: PDR
                −20.0°, the axis −1.0°; IPIN: PDR +3.3°, the axis +6.6°), and a model trained on
                the simulator alone found −11.3° and +12.1°: either would teach a mixed model a
                different rotation per building. The truth-frame estimator of :mod:`wearnav.preprocess.frames`
                does not work on surveyed points joined by straight lines (measured on 16 ILC2/IPIN
                traces: per-trace yaws 50–180° apart within a site).
``recording``   the simulator: one yaw per recording from its dense truth (each simulated device's
                orientation has its own drawn yaw offset), :func:`wearnav.preprocess.frames.truth_yaw` over
                the whole walk — the estimate of mode ``initial`` without its 10-s limit.

Turning the truth rather than the IMU keeps the recordings' sensor data byte for byte. Both yaws
use truth, which is allowed for training data only; nothing here reads what the simulator drew.
Validation recordings are chosen by a hash of the name (:func:`wearnav.dataset.is_validation_name`).

Decision: docs/decisions/0019-pretrained-mix-lobo.md.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from wearnav.core.progress import progress as report_progress
from wearnav.dataset import Dataset, DatasetWriter, is_validation_name
from wearnav.errors import ValidationError
from wearnav.preprocess import SURVEYED_TRUTH_MAX_GAP_S, PreprocessConfig, align
from wearnav.preprocess.frames import FrameConfig, _circular_mean, align_frames, truth_yaw
from wearnav.recording import Fixes, Recording, Trajectory

MIX_FRAME = "common"  # the frame the mix's truth is in, and the frame its models train in
YAW_METHODS = ("axis", "recording")


@dataclasses.dataclass(frozen=True)
class Part:
    """One source of a mix: an imported dataset folder (all of it), a name for it, and how its yaw
    is found (:data:`YAW_METHODS`)."""

    data: str
    name: str
    yaw: str = "axis"

    def __post_init__(self):
        if self.yaw not in YAW_METHODS:
            raise ValidationError(f"yaw method must be one of {', '.join(YAW_METHODS)}, got {self.yaw!r}")


def turn(rec: Recording, yaw_rad: float) -> Recording:
    """``rec`` with its truth and fixes turned by ``yaw_rad`` about the vertical (x, y only;
    counter-clockwise), so that input rotated by −yaw into the truth frame becomes: truth rotated
    by +yaw into the input's frame (:func:`wearnav.preprocess.frames.rotate_stacked`'s convention)."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)

    def xy(p):
        p = np.array(p, dtype=np.float64, copy=True)
        p[:, :2] = p[:, :2] @ np.array([[c, s], [-s, c]])
        return p

    truth = rec.truth and Trajectory(rec.truth.t, xy(rec.truth.pos), None, rec.truth.floor)
    fixes = rec.fixes and Fixes(rec.fixes.t, xy(rec.fixes.pos), rec.fixes.accuracy, rec.fixes.floor)
    return dataclasses.replace(
        rec, truth=truth, fixes=fixes, meta={**rec.meta, "truth_turned_deg": round(float(np.degrees(yaw_rad)), 3)}
    )


def recording_yaw(rec: Recording, devices: tuple[str, ...], rate: float = 25.0) -> float | None:
    """The constant yaw (rad) of ``rec``'s common frame relative to its truth, from all of its
    dense truth; None where the truth says nothing (no overlap, no motion)."""
    cfg = PreprocessConfig(
        rate=rate, devices=tuple(d for d in devices if d in rec.devices) or devices[:1], frame_align="none"
    )
    seq = align(rec, cfg)
    if seq.pos is None:
        return None
    common, _ = align_frames(seq.imu, seq.mask, seq.devices, rate, None, MIX_FRAME)
    tr = truth_yaw(common, seq.mask, seq.pos, rate, FrameConfig())
    return _circular_mean(tr.yaw, tr.info) if tr.info.any() else None


def axis_yaw(data: str | Path, rate: float = 25.0) -> dict:
    """The ``axis`` yaw of every recording of ``data`` (all are training): the phone's +y axis
    against the surveyed walking direction, and PDR's fit beside it for the record."""
    from wearnav.bench.real_sites import estimate_site_yaw  # it imports the trainer: keep it lazy

    found = estimate_site_yaw(Path(data), split=None, rate=rate)
    if found.get("phone_axis_yaw_deg") is None:
        raise ValidationError("the phone has no orientation to take its axis from", data)
    return {"yaw_deg": found["phone_axis_yaw_deg"], "pdr_yaw_deg": found["yaw_deg"], "segments": found["segments"]}


def write_mix(
    parts: list[Part], out: str | Path, devices: tuple[str, ...] = ("phone",), rate: float = 25.0, progress: bool = True
) -> Path:
    """Write the recordings of ``parts`` (their truth turned as the module docstring says) into one
    dataset folder ``out`` with ``train``/``val`` splits; ``dataset.yaml`` records every yaw."""
    out = Path(out)
    info = []
    with DatasetWriter(
        out, {"generator": "wearnav.pretrained.mix", "frame": MIX_FRAME, "truth_max_gap": SURVEYED_TRUTH_MAX_GAP_S}
    ) as w:
        for part in parts:
            ds = Dataset.open(part.data)
            names = ds.names
            site = axis_yaw(part.data, rate) if part.yaw == "axis" else None
            kept = skipped = 0
            for name in report_progress(names, desc=f"mix {part.name}", unit="rec", enabled=progress, leave=False):
                rec = ds.load(name)
                if rec.truth is None or len(rec.truth) < 2:
                    skipped += 1
                    continue
                yaw = np.radians(site["yaw_deg"]) if site is not None else recording_yaw(rec, devices, rate)
                if yaw is None:
                    skipped += 1
                    continue
                rec = turn(dataclasses.replace(rec, name=f"{part.name}-{rec.name}"), yaw)
                rec.meta["mix_source"] = part.name
                w.add(rec, split="val" if is_validation_name(rec.name) else "train")
                kept += 1
            info.append(
                {
                    "part": part.name,
                    "data": str(part.data),
                    "yaw": part.yaw,
                    "recordings": kept,
                    "skipped": skipped,
                    **({"site_yaw": site} if site else {}),
                }
            )
        w.provenance["parts"] = info
    return out


def is_mix(data: str | Path) -> bool:
    """Whether ``data`` was written by :func:`write_mix` (its models train in :data:`MIX_FRAME`)."""
    return Dataset.open(data).provenance.get("generator") == "wearnav.pretrained.mix"
