"""Whether to trust a tracked path (`wearnav track`, and the live receiver as a session arrives):
one line per reason not to, each with what to do, from :mod:`wearnav.trust`'s findings: devices
the recording lacks, a rate / placement / gravity direction unlike the model's training data, a
model that did not beat standing still (:func:`input_warnings`), and a result implausible for
walking (:func:`walk_warnings`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from wearnav import runs, trust
from wearnav.errors import ConfigError, FormatError
from wearnav.evaluate import predict_sequence
from wearnav.export.header import is_exported, read_header
from wearnav.models import registry
from wearnav.models.pdr import PDR
from wearnav.recording import Recording
from wearnav.textio import read_json
from wearnav.train.odometry import TRAINING


def run_training_record(model_path: str | Path) -> dict:
    """The run's ``training.json`` for a run folder or its checkpoint, or the copy an exported model
    file carries in its header; ``{}`` where it has none or cannot be read (the warnings then say
    that the training data is unknown: tracking goes on)."""
    p = Path(model_path)
    if is_exported(p):
        record = read_header(p).get("training")
        return record if isinstance(record, dict) else {}
    run = runs.run_folder(p)
    try:
        record = read_json(run / TRAINING) if (run / TRAINING).is_file() else {}
    except FormatError:
        return {}
    return record if isinstance(record, dict) else {}


def input_warnings(model_path, cfg, rec: Recording) -> list[str]:
    """The reasons not to trust a path that the input alone gives (one line each, with what to do),
    for learned models only (an untrained baseline such as PDR has no training data, and uses the
    first device the recording has): devices the recording lacks, a rate / placement / gravity
    direction unlike the training data's (a rate only where the recording is slower than the
    model's, :func:`wearnav.trust.rate_outside`), or a model that did not beat standing still. The live receiver
    gives these as the session's first half minute arrives (:mod:`wearnav.live.tracker`)."""
    out: list[str] = []
    if not registry.get(cfg.model).learned:  # PDR: no training data, any one device will do
        return out
    if (m := trust.missing_devices(cfg.devices, rec.devices)) is not None:
        out.append(f"{m}: {trust.TRACK_DEVICES_ADVICE}")
    record = run_training_record(model_path)
    facts = trust.recording_facts(rec, cfg.devices, cfg.window / cfg.rate)
    known = record.get("training_data")
    known = known if isinstance(known, dict) else None
    out += [f"{f}: {trust.TRACK_DOMAIN_ADVICE}" for f in trust.domain_findings(facts, known, cfg.rate)]
    if (m := trust.did_not_learn(record)) is not None:
        out.append(f"{m}: {trust.LEARN_ADVICE}")
    return out


def walk_warnings(cfg, seq, vel: np.ndarray, length_m: float) -> list[str]:
    """A result implausible for walking: PDR's step detector on the same windows as the model's
    velocities ``vel`` over the whole walk of ``length_m`` (none where the window is too short for
    PDR)."""
    try:
        pdr = PDR(n_devices=len(cfg.devices), window=cfg.window, rate=cfg.rate)
    except ConfigError:  # a window too short for PDR's step detector: no walking check
        return []
    _, pdr_vel, _ = predict_sequence(pdr, seq, cfg.window, cfg.stride)
    step_rate_hz = np.linalg.norm(pdr_vel, axis=1) / pdr.step_length
    steps = float(np.sum(step_rate_hz) * cfg.stride / cfg.rate)  # windows tile time at the stride
    findings = trust.implausible_walk(np.linalg.norm(vel, axis=1), step_rate_hz, length_m, steps)
    return [f"{f}: {trust.TRACK_RESULT_ADVICE}" for f in findings]


def trust_warnings(
    model_path, cfg, rec: Recording, seq, t_c: np.ndarray, vel: np.ndarray, length_m: float
) -> list[str]:
    """One line per reason not to trust the path, each with what to do: :func:`input_warnings`
    (devices, domain, did the model learn) and :func:`walk_warnings` (implausible for walking)."""
    return input_warnings(model_path, cfg, rec) + walk_warnings(cfg, seq, vel, length_m)


__all__ = ["input_warnings", "run_training_record", "trust_warnings", "walk_warnings"]
