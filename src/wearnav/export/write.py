"""``wearnav export``: a trained run's network as one ONNX or TorchScript file that carries its own
description (:mod:`wearnav.export.header`), checked against PyTorch before it is kept.

The network is traced through its :meth:`~wearnav.models.base.OdometryModel.for_export` (the same
arithmetic without CPU-only fused kernels) on an example batch, with the batch axis dynamic:
inputs ``x`` (batch, D, window, 6) float32 and ``mask`` (batch, D) float32 (1.0: the device is
present), output ``velocity`` (batch, 2) m/s for odometry or ``logits`` (batch, classes) for a
classifier. ONNX goes through ``torch.onnx.export(dynamo=True)`` (the torch.export-based
exporter; needs the ``onnx`` extra), TorchScript through ``torch.jit.trace``.

Parity check (:func:`parity`): the file is run (ONNX Runtime or TorchScript) on a seeded batch
whose masks cycle through every non-empty subset of the devices (a phone-only sample, all
devices, one missing, …), of another batch size than the traced one (:data:`PARITY_BATCH`), and
compared with the PyTorch model; a largest absolute difference above :data:`PARITY_TOL` refuses
the file.
"""

from __future__ import annotations

import contextlib
import io
import itertools
import json
import logging
import warnings
from pathlib import Path

import torch
from torch import nn

from wearnav import pretrained, runs
from wearnav.core.fileio import atomic_path
from wearnav.core.provenance import provenance
from wearnav.core.textio import read_json
from wearnav.errors import ConfigError, ValidationError
from wearnav.export.header import (
    EXTRA_FILE,
    HEADER_FORMAT,
    IMU_CHANNELS,
    KEY,
    ONNX_MISSING,
    check_out_file,
    onnxruntime,
)
from wearnav.export.runtime import load_file
from wearnav.models import registry
from wearnav.models.base import SNAP_DEG
from wearnav.models.pdr import STEP_PER_CADENCE_M_S
from wearnav.train import classify, odometry
from wearnav.train.common import run_kind

# Largest |PyTorch − exported| accepted, in the output's unit (m/s; logits for a classifier).
# Measured on the registered models: 1e-8 … 3e-7 (float32 rounding; the parity test prints it).
PARITY_TOL = 1e-4
EXAMPLE_BATCH = 2  # the traced batch (not 1: torch.export would fix a batch of 1 as a constant)
# The checked batch: another size than the traced one, and more than the 64 windows that
# Suite-IN++'s PyTorch inference runs per chunk (wearnav.models.suitein.GroupedExtractors.chunk).
PARITY_BATCH = 70
# A classifier's metrics that `wearnav classify`'s trust warnings read (wearnav.trust.did_not_learn)
TRUST_METRICS = ("accuracy", "macro_f1", "beats_trivial", "trivial", "trivial_accuracy", "test_windows")


def load_run(run: str | Path) -> tuple[nn.Module, dict]:
    """The network of an odometry or classifier run folder and its header (module docstring of
    :mod:`wearnav.export.header`); a model that is not a learned network (PDR) is refused."""
    run = Path(run)
    task, name = run_kind(run)
    if task not in ("odometry", "classify"):
        raise ConfigError(
            f"is not an odometry or classifier run ({name or 'no model'}); `wearnav export` "
            "takes the run folder of `wearnav train` or of a classifier",
            run,
        )
    assert name is not None  # run_kind names the model of an odometry or classifier run
    if not registry.get(name).learned:
        raise ConfigError(
            f"{name} is not a learned network (NumPy step detection, no weights): nothing to "
            f"export; use `--model {name}` directly",
            run,
        )
    classes = None
    cfg: odometry.TrainConfig | classify.ClassifyConfig
    if task == "odometry":
        model, cfg = odometry.load_model(run)
    else:
        model, cfg, classes = classify.load_model(run)
    training = read_json(run / odometry.TRAINING) if (run / odometry.TRAINING).is_file() else {}
    metrics = runs.read_metrics(run) if task == "classify" and runs.is_complete(run) else {}
    return model, make_header(
        task,
        cfg,
        classes,
        training,
        {k: metrics[k] for k in TRUST_METRICS if k in metrics},
        str(run),
        pretrained.track_defaults(run) if task == "odometry" else None,
    )


def make_header(
    task: str,
    cfg,
    classes: list[str] | None = None,
    training: dict | None = None,
    metrics: dict | None = None,
    source_run: str = "",
    track_defaults: dict | None = None,
) -> dict:
    """The header of a model of ``task`` trained with ``cfg`` (TrainConfig / ClassifyConfig);
    ``track_defaults``: what `wearnav track` takes from the run besides its weights and config
    (:func:`wearnav.pretrained.track_defaults`: the default speed source, the smoother's
    calibration), carried whole so that `track` reads the file as it reads the run (issue 56 §2)."""
    D = len(cfg.devices)
    frame = "world (gravity on +z)" if task == "odometry" else f"{cfg.frame} (ClassifyConfig.frame)"
    out = (
        {"name": "velocity", "shape": ["batch", 2], "units": "m/s, horizontal x and y of the input's frame"}
        if task == "odometry"
        else {"name": "logits", "shape": ["batch", len(classes or ())], "units": "unnormalised log-probabilities"}
    )
    return {
        "format": HEADER_FORMAT,
        "task": task,
        "model": cfg.model,
        "devices": list(cfg.devices),
        "window": cfg.window,
        "rate_hz": cfg.rate,
        "stride": getattr(cfg, "stride", None),
        "inputs": {
            "x": {
                "shape": ["batch", D, cfg.window, IMU_CHANNELS],
                "dtype": "float32",
                "units": "per device acc x y z (m/s²) then gyro x y z (rad/s)",
                "frame": frame,
            },
            "mask": {"shape": ["batch", D], "dtype": "float32", "units": "1.0 where the device is present"},
        },
        "output": out,
        "config": runs.to_dict(cfg),
        "classes": classes,
        "training": training or {},
        "metrics": metrics or {},
        pretrained.TRACK_DEFAULTS: track_defaults,
        # the calibration where files exported before track_defaults existed kept it (read by fuse.config_for)
        "fuse_calibration": (track_defaults or {}).get("fuse_calibration"),
        "speed_constants": speed_constants((track_defaults or {}).get("speed")) if task == "odometry" else None,
        "source_run": source_run,
        "provenance": provenance(),
        "torch": torch.__version__,
    }


def speed_constants(speed: str | None) -> dict:
    """The constants behind a speed source (:data:`wearnav.train.odometry.SPEED_SOURCES`), named in the
    header for a runtime outside wearnav that rebuilds it: the sentence saying what it does, the
    angle within which the phone's pointing is taken (:data:`wearnav.models.base.SNAP_DEG`) and the
    step length per unit cadence (:data:`wearnav.models.pdr.STEP_PER_CADENCE_M_S`). wearnav's `track`
    uses its own code's (the same for the file and its run)."""
    speed = speed or "model"
    return {
        "speed": speed,
        "description": pretrained.SPEED_WORDS.get(speed, speed),
        "snap_deg": SNAP_DEG if speed == "snapped" else None,
        "step_per_cadence_m_s": STEP_PER_CADENCE_M_S if speed in ("cadence", "snapped") else None,
    }


def example_inputs(header: dict, batch: int = EXAMPLE_BATCH, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """Seeded inputs of the header's shapes with every device present."""
    g = torch.Generator().manual_seed(seed)
    D, L = len(header["devices"]), header["window"]
    return torch.randn(batch, D, L, IMU_CHANNELS, generator=g), torch.ones(batch, D)


def parity_inputs(
    n_devices: int, window: int, batch: int = PARITY_BATCH, seed: int = 1
) -> tuple[torch.Tensor, torch.Tensor]:
    """At least ``batch`` seeded windows (gravity-sized offset on acc z) whose masks cycle through
    every non-empty subset of the devices (phone only, all, one missing, …)."""
    subsets = [s for k in range(1, n_devices + 1) for s in itertools.combinations(range(n_devices), k)]
    subsets *= -(-batch // len(subsets))
    mask = torch.zeros(len(subsets), n_devices)
    for i, s in enumerate(subsets):
        mask[i, list(s)] = 1.0
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(len(mask), n_devices, window, IMU_CHANNELS, generator=g)
    x[..., 2] += 9.81
    return x, mask


def parity(model: nn.Module, exported, x: torch.Tensor, mask: torch.Tensor) -> float:
    """Largest |model(x, mask) − exported(x, mask)| over the batch."""
    with torch.no_grad():
        ref = model.eval()(x, mask)
    return float((ref - exported(x, mask)).abs().max())


def export_model(model: nn.Module, header: dict, fmt: str, out: str | Path, check: bool = True) -> dict:
    """Write ``model`` as ``fmt`` (:data:`FORMATS`) to ``out`` with ``header`` inside; with
    ``check``, run the written file on :func:`parity_inputs` first and refuse it (nothing kept)
    when it differs from PyTorch by more than :data:`PARITY_TOL`. Returns what was written:
    ``path``, ``format``, ``bytes``, ``max_abs_diff`` (None unchecked), ``tolerance``."""
    check_out_file(fmt, out)
    out = Path(out)
    traced = model.for_export() if hasattr(model, "for_export") else model.eval()  # type: ignore[operator]  # hasattr checked
    x, mask = example_inputs(header)
    diff = None
    with atomic_path(out) as tmp:
        (_write_onnx if fmt == "onnx" else _write_torchscript)(traced, x, mask, header, tmp)
        if check:
            diff = parity(model, load_file(tmp, fmt), *parity_inputs(len(header["devices"]), header["window"]))
            if not diff <= PARITY_TOL:
                raise ValidationError(
                    f"the {fmt} export differs from PyTorch by {diff:.3g} (> {PARITY_TOL:g}): not written", out
                )
    return {"path": str(out), "format": fmt, "bytes": out.stat().st_size, "max_abs_diff": diff, "tolerance": PARITY_TOL}


def export_run(run: str | Path, fmt: str, out: str | Path) -> dict:
    """``wearnav export``: the run's network to ``out`` (:func:`export_model`); adds ``model``
    and ``task`` to what that returns."""
    model, header = load_run(run)
    return {"model": header["model"], "task": header["task"], **export_model(model, header, fmt, out)}


@contextlib.contextmanager
def _quiet():
    """Silence the exporters' chatter (tracer warnings, torch.onnx's progress lines and logs)."""
    logger = logging.getLogger("torch.onnx")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            yield
    finally:
        logger.setLevel(level)


def _write_onnx(module: nn.Module, x: torch.Tensor, mask: torch.Tensor, header: dict, path: Path) -> None:
    onnxruntime()
    try:
        import onnx
        import onnxscript  # noqa: F401  (the dynamo exporter's dependency: fail here with the extra's name)
    except ImportError:
        raise ConfigError(ONNX_MISSING) from None
    batch = torch.export.Dim("batch")
    with _quiet(), torch.no_grad():
        program = torch.onnx.export(
            module,
            (x, mask),
            input_names=["x", "mask"],
            output_names=[header["output"]["name"]],
            dynamic_shapes=({0: batch}, {0: batch}),
            dynamo=True,
        )
    assert program is not None  # dynamo=True returns the ONNXProgram
    proto = program.model_proto
    proto.doc_string = f"wearnav {header['task']} model {header['model']}; metadata_props['{KEY}']: JSON header"
    entry = proto.metadata_props.add()
    entry.key, entry.value = KEY, json.dumps(header)
    onnx.save_model(proto, str(path))


def _write_torchscript(module: nn.Module, x: torch.Tensor, mask: torch.Tensor, header: dict, path: Path) -> None:
    with _quiet(), torch.no_grad():
        traced = torch.jit.trace(module, (x, mask), check_trace=False)
    torch.jit.save(traced, str(path), _extra_files={EXTRA_FILE: json.dumps(header)})
