"""Model registry: name → constructor, task and device layout (the one list of models).

A model family registers its constructors with :func:`register` at import; :func:`get` imports
the families listed in ``FAMILIES`` on first use, so ``wearnav models`` and training see every
model without the CLI importing torch-heavy modules up front. Adding a family: write its module
in ``wearnav/models/`` and add its name to ``FAMILIES``.

Every constructor accepts ``n_devices`` and ``window`` (samples) as keyword arguments, plus its
own hyper-parameters with defaults taken from its paper.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

from torch import nn

from wearnav.errors import ConfigError, check_names

# Modules under wearnav.models that register models when imported.
FAMILIES: tuple[str, ...] = (
    "suitein",
    "ronin",
    "pdr",
    "har",
    "easytrack",
    "ionet",
    "imunet",
    "deepit",
    "rewf",
    "deepsense",
)

TASKS = ("odometry", "classify", "noisy")
# How a model uses the devices: "multi" = per-device branches with masked fusion; "single" = one
# device (the first of the layout present); "concat" = the devices' channels side by side, zeros
# where a device is absent (the starred baselines of Suite-IN++).
LAYOUTS = ("multi", "single", "concat")


@dataclass(frozen=True)
class ModelSpec:
    name: str
    task: str
    layout: str
    build: Callable[..., nn.Module]
    description: str
    learned: bool = True
    heading_frame: bool = False  # its input must be in the device's heading frame (PreprocessConfig.heading_frame)


_REGISTRY: dict[str, ModelSpec] = {}
_loaded = False


def register(name: str, task: str, layout: str, description: str, learned: bool = True, heading_frame: bool = False):
    """Decorator: register a constructor (a class or a function returning an ``nn.Module``)."""
    if task not in TASKS:
        raise ValueError(f"task must be one of {TASKS}, got {task!r}")
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")

    def deco(fn):
        if name in _REGISTRY and _REGISTRY[name].build is not fn:
            raise ValueError(f"model {name!r} registered twice")
        _REGISTRY[name] = ModelSpec(name, task, layout, fn, description, learned, heading_frame)
        return fn

    return deco


def _load() -> None:
    global _loaded
    if not _loaded:
        for fam in FAMILIES:
            importlib.import_module(f"wearnav.models.{fam}")
        _loaded = True


def available(task: str | None = None) -> list[ModelSpec]:
    _load()
    return [s for s in _REGISTRY.values() if task is None or s.task == task]


def check_models(names, task: str | None = None) -> tuple[str, ...]:
    """``names`` when each is a registered model (of ``task``); else a ConfigError listing the valid
    ones. For a list of models typed on the command line, checked before any work."""
    return check_names(names, [s.name for s in available(task)], f"{task} model" if task else "model")


def get(name: str) -> ModelSpec:
    _load()
    if name not in _REGISTRY:
        raise ConfigError(f"unknown model {name!r}; known: {', '.join(sorted(_REGISTRY)) or 'none'}")
    return _REGISTRY[name]


def build(name: str, **kwargs) -> nn.Module:
    """Construct model ``name``; unknown hyper-parameters are a one-line ConfigError."""
    spec = get(name)
    try:
        return spec.build(**kwargs)
    except TypeError as exc:
        raise ConfigError(f"model {name!r}: {exc}") from None


def n_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
