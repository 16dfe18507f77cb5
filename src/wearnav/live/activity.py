"""The live activity label's input: the windows the activity classifier sees at an update, as
``classify`` cuts them (:func:`wearnav.train.labelling.class_windows`): the session's latest window and
the ``context_windows // 2`` before it, aligned from the tail of the update's Recording.

:func:`label_windows` does it for one session; :func:`label_job` and :func:`label_windows_many` for many
at once (issue 61 §2: every due session's input aligned in one call, :func:`wearnav.preprocess.batch.align_many`).
:class:`wearnav.live.tracker.LiveTracker` decides when a label is due and keeps the label.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from wearnav.errors import ValidationError
from wearnav.live.buffer import derived, sliced
from wearnav.preprocess import PreprocessConfig, clock, common_span
from wearnav.preprocess.augment import moving_average
from wearnav.preprocess.batch import align_many
from wearnav.preprocess.windows import WindowConfig, WindowDataset
from wearnav.recording import Recording
from wearnav.train.labelling import Windows, class_windows

EDGE_S = 2.0  # input aligned before the windows: the filters' edges
# what label_windows_many aligns for one session: class_windows' recording, preprocessing and clock (s)
Job = tuple[Recording, PreprocessConfig, np.ndarray]


def label_input(classifier: tuple, rec: Recording, covered: float) -> Recording | None:
    """The part of ``rec`` the label at ``covered`` (s) needs: the windows deciding it and the filters'
    edges; None where a device of ``classifier`` (model, config, classes) is missing."""
    model, cfg, _ = classifier
    k = getattr(model, "context_windows", 1)
    span = (cfg.window + (k // 2) * max(1, cfg.window // 2)) / cfg.rate
    part = _tail(rec, covered - span - EDGE_S)
    return part if all(d in part.devices for d in cfg.devices) else None


def label_windows(classifier: tuple, rec: Recording, covered: float) -> Windows | None:
    """The windows of one session's label, by ``class_windows`` itself; None where the input is too short."""
    part = label_input(classifier, rec, covered)
    if part is None:
        return None
    try:
        w = class_windows(classifier[0], classifier[1], part, last=1)
    except ValidationError:  # too little of a device yet (align's span checks)
        return None
    return w if w.keep else None


def label_job(classifier: tuple, rec: Recording, covered: float) -> Job | None:
    """What :func:`label_windows_many` aligns for one session (``class_windows``' recording,
    preprocessing and clock), or None where the input is too short for a label."""
    part = label_input(classifier, rec, covered)
    if part is None:
        return None
    pcfg = classifier[1].preprocess_config()
    try:
        t = clock(*common_span(part, pcfg.devices, pcfg.edge_tolerance), pcfg.rate)
    except ValidationError:  # too little of a device yet (align's span checks)
        return None
    return (part, pcfg, t) if t.size >= 2 else None


def label_windows_many(work: list[tuple[tuple, Job] | None]) -> list[Windows | None]:
    """:func:`label_windows` of every (classifier, :func:`label_job`) pair, their inputs aligned at once,
    then windowed as ``class_windows`` windows them (None where the pair is None)."""
    due = [i for i, pair in enumerate(work) if pair is not None]
    out: list[Windows | None] = [None] * len(work)
    for i, seq in zip(due, align_many([pair[1] for pair in work if pair is not None])):
        pair = work[i]
        assert pair is not None  # i is due
        model, cfg, _ = pair[0]
        if cfg.denoise > 1:
            seq = dataclasses.replace(seq, imu=moving_average(seq.imu, cfg.denoise, axis=1).astype(seq.imu.dtype))
        wds = WindowDataset([seq], WindowConfig(window=cfg.window, stride=max(1, cfg.window // 2), target=None))
        k = getattr(model, "context_windows", 1)
        index = np.arange(max(0, len(wds) - 1 - k // 2), len(wds))
        w = Windows(seq, wds, index, min(1, len(wds)))
        out[i] = w if w.keep else None
    return out


def _tail(rec: Recording, t_from: float) -> Recording:
    """``rec``'s device streams from ``t_from`` on (no fixes)."""
    devices = {}
    for name, s in rec.devices.items():
        k = s.t >= t_from
        if k.sum() >= 2:
            devices[name] = sliced(s, k)  # a slice of a checked stream, not checked again
    return derived(rec, devices, None) if devices else derived(rec, dict(rec.devices), None)
