"""The one reading of a command's ``--model``: a run folder, one of its checkpoints, a model file of
``wearnav export`` (``.onnx``, ``.pt``), the name of a shipped model (:mod:`wearnav.pretrained`), or
the name of an untrained baseline (a registry model with ``learned=False``, e.g. ``pdr``), turned
into the model and the config that says how to feed it.

Two steps, so that a command refuses a bad ``--model`` before it imports torch (issue 38):
:func:`locate_model` reads the argument without loading anything (what it names: a path, or a
baseline's name; a typo is refused listing the shipped names and the baselines, with the nearest
suggested; the names come from the registry's table, :mod:`wearnav.models.catalogue`), and :func:`resolve_model` loads what it locates. ``track``, ``classify``, ``adapt``
and ``export`` all take their ``--model`` (``export``'s RUN) through :func:`locate_model`; a run
of the wrong kind is refused saying what it is and which command takes it
(:func:`wearnav.train.common.check_run_kind`).
"""

from __future__ import annotations

import difflib
from pathlib import Path

from wearnav import pretrained
from wearnav.errors import ConfigError, FormatError, MissingFileError
from wearnav.export.header import format_of, is_exported, onnxruntime
from wearnav.models import catalogue
from wearnav.runs import CONFIG

TASKS = ("odometry", "classify")
CHECKPOINTS_DIR = "checkpoints"  # wearnav.train.common.CHECKPOINTS (that module imports Lightning)
# difflib.get_close_matches' cutoff (its default): 'phnoe' → 'phone' scores 0.8, 'pdr' → 'phone' 0.25.
SUGGEST_CUTOFF = 0.6
SUGGEST_N = 3  # at most this many close names suggested


def untrained_baselines(task: str = "odometry") -> list[str]:
    """Registry models of ``task`` that need no training, usable by name as ``--model`` (from the
    registry's table, :mod:`wearnav.models.catalogue`: no torch)."""
    return sorted(catalogue.names(task, learned=False))


def locate_model(
    arg: str | Path | None,
    task: str | None,
    devices_in_recording=(),
    *,
    files: bool = True,
    baselines: bool = True,
) -> Path | str:
    """What ``arg`` names for a command of ``task``, without loading it (no torch, unless ``arg`` is
    neither a path nor a shipped name): None → the shipped default for ``devices_in_recording``
    (:func:`wearnav.pretrained.default_for`); an exported file (``files``: the command runs one;
    an ONNX file needs ONNX Runtime, checked here); a checkpoint inside a run's ``checkpoints/``;
    a run folder (it holds ``config.yaml``); a shipped model's name → its folder; an untrained
    baseline's name (``baselines``) → the name. ``task`` None: a model of either task (`wearnav
    export`; a checkpoint file is then refused, a run folder is any run). Anything else is one ConfigError line listing the
    names accepted, with the nearest suggested (:data:`SUGGEST_CUTOFF`)."""
    if task not in TASKS and not (task is None and arg is not None):
        raise ValueError(f"task must be odometry or classify, got {task!r}")
    if arg is None:
        assert task is not None  # the check above refuses a missing model of no task
        return pretrained.default_model(task, devices_in_recording)[0]
    p = Path(arg)
    if p.exists():
        if is_exported(p):
            if not files:
                raise ConfigError("is a file of `wearnav export`; give the run folder it was exported from", p)
            if format_of(p) == "onnx":
                onnxruntime()  # the runtime it needs, named before any work
            return p
        if p.is_file():
            if task != "odometry" or p.parent.name != CHECKPOINTS_DIR:
                raise FormatError(
                    f"a checkpoint must lie in a run folder's {CHECKPOINTS_DIR}/ (next to "
                    "config.yaml, which says how the model was trained)"
                    if task == "odometry"
                    else "not a run folder",
                    p,
                )
            if not (p.parent.parent / CONFIG).is_file():
                raise MissingFileError(f"not a run folder (no {CONFIG})", p.parent.parent)
            return p
        if not (p / CONFIG).is_file():
            raise MissingFileError(f"not a run folder (no {CONFIG})", p)
        return p
    name = str(arg)
    if name in pretrained.SHIPPED:
        return pretrained.model_path(name, task or pretrained.SHIPPED[name].task)
    shipped = [s.name for s in pretrained.installed(task)]
    base = untrained_baselines(task or "odometry")
    if name in base:
        if not baselines:
            raise ConfigError(
                f"is an untrained baseline (no run folder, no weights); this command takes a run "
                f"folder or a shipped model ({', '.join(shipped) or 'none installed'})",
                name,
            )
        return name
    known = shipped + (base if baselines else [])
    # the names suggested: those accepted, then the registered models of the task (to train first)
    near = difflib.get_close_matches(name, known, n=SUGGEST_N, cutoff=SUGGEST_CUTOFF)
    near += difflib.get_close_matches(
        name, [n for n in catalogue.names(task) if n not in known], n=SUGGEST_N - len(near), cutoff=SUGGEST_CUTOFF
    )
    what = f"shipped models: {', '.join(shipped) or 'none installed'}"
    if baselines:
        what += f"; untrained baselines usable by name: {', '.join(base) or 'none of this kind'}"
    spec = catalogue.entry(name)  # the registry's table: no torch before the refusal
    if spec is not None:  # a registered model to train first, or of another task
        if task is not None and spec.task != task:
            from wearnav.train.common import RUN_KINDS

            kind, command = RUN_KINDS.get(spec.task, (f"a {spec.task} model", "another command"))
            raise ConfigError(f"is {kind}, not {RUN_KINDS[task][0]}; use {command}", name)
        raise ConfigError(
            f"is a model that must be trained first (wearnav train {name} --data DATA --out RUN, "
            f"then --model RUN); {what}",
            name,
        )
    hint = f"; did you mean {' or '.join(map(repr, near))}?" if near else ""
    raise ConfigError(
        f"no such run folder or checkpoint (nor an exported .onnx / .pt file), nor a model name ({what}){hint}",
        name,
    )


def resolve_model(arg: str | Path | None, task: str, devices_in_recording=(), speed: str | None = None):
    """The model behind ``arg`` (:func:`locate_model`) for a command of ``task``.

    Odometry: ``(model, TrainConfig)``; classify: ``(model, ClassifyConfig, class names)``. A run
    folder gives its best weights for odometry, a checkpoint its own, an exported model file is
    run by ONNX Runtime or TorchScript with its config from the file's header
    (:func:`wearnav.export.runtime.load_exported`); an untrained baseline is built with the
    default :class:`wearnav.train.odometry.TrainConfig` (25 Hz, 100-sample windows, the first of
    phone, watch, earbuds that the recording has). An odometry model's speed comes from ``speed``
    (:func:`wearnav.train.odometry.with_speed`), by default from what its run records
    (:func:`wearnav.pretrained.recorded_speed`: the shipped phone model's recipe says "snapped"; a file of
    `wearnav export` carries its run's, :func:`wearnav.pretrained.track_defaults`)."""
    from wearnav.export.runtime import load_exported
    from wearnav.train import classify, odometry
    from wearnav.train.common import BEST, check_run_kind

    where = locate_model(arg, task, devices_in_recording)
    if task == "odometry":
        speed = speed if speed is not None else pretrained.recorded_speed(where)
    if isinstance(where, str):  # an untrained baseline's name
        cfg = odometry.TrainConfig(model=where, data="")  # untrained: no data behind it
        model = odometry.with_speed(odometry.build_model(cfg), cfg, speed or "model")
        model.eval()
        return model, cfg
    if is_exported(where):
        got = load_exported(where, task)
        return (odometry.with_speed(got[0], got[1], speed or "model"), got[1]) if task == "odometry" else got
    if where.is_file():  # a checkpoint inside its run folder
        check_run_kind(where.parent.parent, task)
        return odometry.load_model(where.parent.parent, which=where.name, speed=speed or "model")
    if task == "odometry":
        return odometry.load_model(where, which=BEST, speed=speed or "model")
    return classify.load_model(where)
