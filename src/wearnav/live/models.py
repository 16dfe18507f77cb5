"""The models every session of one tracking process shares, and running them on many sessions'
windows at once (issue 37): :class:`SharedModels` loads each model once, on the device chosen
once (``wearnav live --model-device``), and can load the defaults before the first session
(:meth:`SharedModels.preload`); :func:`predict_windows` and :func:`classify_windows` run the
odometry model and the activity classifier on a batch (:mod:`wearnav.live.crowd` batches a tick's
sessions; :class:`wearnav.live.tracker.LiveTracker` one session's windows)."""

from __future__ import annotations

import logging
import threading
from pathlib import Path
from typing import Any

import numpy as np
import torch

from wearnav import pretrained
from wearnav.errors import ConfigError
from wearnav.recording import CANONICAL_DEVICES
from wearnav.track import odometry_preprocess
from wearnav.train.classify import window_probs
from wearnav.train.labelling import Windows
from wearnav.train.resolve import resolve_model

log = logging.getLogger("wearnav.live")


def classify_windows(model, windows: list[Windows]) -> list[np.ndarray]:
    """The activity classifier's softmax probabilities of each of ``windows`` (several sessions'),
    in one pass (:func:`wearnav.train.classify.window_probs`), split back in order."""
    if not windows:
        return []
    parts = [w.inputs() for w in windows]
    prob = window_probs(model, torch.cat([p["x"] for p in parts]), torch.cat([p["mask"] for p in parts]))
    return np.split(prob, np.cumsum([len(p["x"]) for p in parts])[:-1])


class SharedModels:
    """The models of every session of one process, each loaded once (sessions only read them), the
    odometry models on one ``device`` chosen once: ``cpu`` (None: the default), ``cuda`` (``cuda:N``),
    or ``auto``: CUDA where there is one, else the CPU. The CPU is the default because on the one GPU
    machine where both were measured (an H100 with 16 cores), the receiver kept up 8 three-device
    walkers with the models on its CPU and only 1 with them on the GPU (docs/live-scaling.md): a
    tick's batch is a few windows. The activity classifiers stay on the CPU
    (:func:`wearnav.train.labelling.window_classes` feeds them there)."""

    def __init__(self, device: str | None = None):
        if device not in (None, "auto", "cpu", "cuda") and not str(device).startswith("cuda:"):
            raise ConfigError(f"model device: auto, cpu or cuda, got {device!r}")
        if device is None:
            device = "cpu"
        elif device == "auto":
            device = "cuda" if torch.cuda.is_available() else "cpu"
        elif device != "cpu" and not torch.cuda.is_available():
            raise ConfigError(f"model device {device}: this machine's torch sees no CUDA device")
        self.device = torch.device(device)
        self._loaded: dict[tuple[str, str], Any] = {}
        self._lock = threading.Lock()

    def resolve(self, path, task: str):
        """:func:`wearnav.train.resolve.resolve_model` of ``path`` for ``task``, loaded once."""
        key = (str(path), task)
        with self._lock:
            if key not in self._loaded:
                got = resolve_model(path, task)
                if task == "odometry" and isinstance(got[0], torch.nn.Module):
                    got = (got[0].to(self.device), *got[1:])
                self._loaded[key] = got
            return self._loaded[key]

    def preload(self, model=None, activity_model: str | Path | None = "activity") -> None:
        """Load, before any session asks, what sessions will: the odometry model of a phone-only and
        of a three-device session (``model``, or the shipped defaults, as :meth:`LiveTracker._start`
        picks them), each run once on a window of zeros on its device, and the activity classifier.
        On a GPU the first pass pays CUDA's start-up, which would otherwise land in the first
        session's first update. A model that cannot be loaded here is left to that session (whose
        page then says why)."""
        for devices, has_fixes in ((("phone",), False), (("phone",), True), (CANONICAL_DEVICES, True)):
            try:
                net, cfg = self.resolve(pretrained.model_path(model, "odometry", devices, has_fixes), "odometry")
                if isinstance(net, torch.nn.Module):
                    d = len(odometry_preprocess(cfg).devices)
                    predict_windows(net, torch.zeros(1, d, cfg.window, 6), torch.ones(1, d))
            except Exception as e:  # any failure is the first session's to report, on its page
                log.warning("preloading the %s model: %s", "+".join(devices), e)
        if activity_model is not None:
            try:
                self.resolve(pretrained.model_path(activity_model, "classify"), "classify")
            except Exception as e:  # as above
                log.warning("preloading the activity model: %s", e)


def predict_windows(model, x, mask) -> np.ndarray:
    """Velocities (N, 2) m/s of windows ``x`` (N, D, L, 6), ``mask`` (N, D), on the model's device."""
    device = next((p.device for p in model.parameters()), torch.device("cpu"))
    return model.predict(x.to(device), mask.to(device)).float().cpu().numpy()


__all__ = ["SharedModels", "classify_windows", "predict_windows"]
