"""The one reading of a command's ``--model``: a run folder, one of its checkpoints, a model file of
``wearnav export`` (``.onnx``, ``.pt``), or the name of an untrained baseline (a registry model
with ``learned=False``, e.g. ``pdr``), turned into the model and the config that says how to
feed it.

``wearnav track`` and ``wearnav classify`` take their ``--model`` through :func:`resolve_model`; a
run of the wrong kind is refused saying what it is and which command takes it
(:func:`wearnav.train.common.check_run_kind`).
"""

from __future__ import annotations

from pathlib import Path

from wearnav.errors import ConfigError, FormatError
from wearnav.export.header import is_exported
from wearnav.export.runtime import load_exported
from wearnav.models import registry
from wearnav.train import classify, odometry
from wearnav.train.common import BEST, CHECKPOINTS, RUN_KINDS, check_run_kind


def untrained_baselines(task: str = "odometry") -> list[str]:
    """Registry models of ``task`` that need no training, usable by name as ``--model``."""
    return sorted(s.name for s in registry.available(task) if not s.learned)


def resolve_model(arg: str | Path, task: str):
    """The model behind ``arg`` for a command of ``task`` (``odometry`` or ``classify``).

    Odometry: ``(model, TrainConfig)``; classify: ``(model, ClassifyConfig, class names)``. An
    existing path is a run folder (best weights for odometry), a checkpoint inside its
    ``checkpoints/``, or an exported model file (:func:`wearnav.export.runtime.load_exported`: run
    by ONNX Runtime or TorchScript, its config from the file's header); otherwise ``arg`` must
    name an untrained baseline of ``task``, built with the default
    :class:`wearnav.train.odometry.TrainConfig` (25 Hz, 100-sample windows, the first of phone,
    watch, earbuds that the recording has). Anything else is a ConfigError naming what is accepted.
    """
    if task not in RUN_KINDS or task == "noisy":
        raise ValueError(f"task must be odometry or classify, got {task!r}")
    p = Path(arg)
    if is_exported(p):
        return load_exported(p, task)
    if p.exists():
        if p.is_file():
            if task != "odometry" or p.parent.name != CHECKPOINTS:
                raise FormatError(
                    f"a checkpoint must lie in a run folder's {CHECKPOINTS}/ (next to "
                    "config.yaml, which says how the model was trained)"
                    if task == "odometry"
                    else "not a run folder",
                    p,
                )
            check_run_kind(p.parent.parent, task)
            return odometry.load_model(p.parent.parent, which=p.name)
        if task == "odometry":
            return odometry.load_model(p, which=BEST)
        return classify.load_model(p)
    return _by_name(str(arg), task)


def _by_name(name: str, task: str):
    baselines = untrained_baselines(task)
    hint = (
        f"untrained baselines usable by name: {', '.join(baselines)}"
        if baselines
        else "no model of this kind works untrained"
    )
    try:
        spec = registry.get(name)
    except ConfigError:
        raise ConfigError(
            f"no such run folder or checkpoint (nor an exported .onnx / .pt file), nor a model name ({hint})", name
        ) from None
    if spec.task != task:
        what, command = RUN_KINDS.get(spec.task, (f"a {spec.task} model", "another command"))
        raise ConfigError(f"is {what}, not {RUN_KINDS[task][0]}; use {command}", name)
    if spec.learned or task != "odometry":
        raise ConfigError(
            f"is a model that must be trained first (wearnav train {name} --data DATA --out RUN, "
            f"then --model RUN); {hint}",
            name,
        )
    cfg = odometry.TrainConfig(model=name, data="")  # untrained: no data behind it
    model = odometry.build_model(cfg)
    model.eval()
    return model, cfg
