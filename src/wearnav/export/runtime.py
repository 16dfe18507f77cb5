"""Running an exported model file (:mod:`wearnav.export.write`) where a PyTorch model would run.

:func:`load_exported` turns a ``.onnx`` (ONNX Runtime, the ``onnx`` extra) or ``.pt``
(TorchScript) file into what :func:`wearnav.train.resolve.resolve_model` returns for a run folder:
an object with the calls that :func:`wearnav.evaluate.predict_sequence` and
:func:`wearnav.train.classify.predict` make (``model(x, mask)``, ``predict``, ``eval``,
``parameters``) and the training config rebuilt from the file's header.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import torch

from wearnav.errors import ConfigError
from wearnav.export.header import KEY, format_of, onnx_session, parse_header, read_header
from wearnav.train.classify import ClassifyConfig
from wearnav.train.common import RUN_KINDS
from wearnav.train.odometry import TrainConfig


class ExportedModel:
    """An exported network behind the PyTorch calls wearnav makes: ``model(x, mask)`` /
    ``predict(x, mask)`` with x (B, D, L, 6), mask (B, D) → (B, outputs) float32 on the CPU;
    ``eval()`` and ``parameters()`` (none) for the callers that ask; ``runtime`` names what runs it."""

    runtime = ""

    def __call__(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:  # pragma: no cover - abstract
        raise NotImplementedError

    def predict(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        return self(x, mask)

    def eval(self) -> ExportedModel:
        return self

    def parameters(self):
        return iter(())


class OnnxModel(ExportedModel):
    """An ONNX file run by ONNX Runtime on the CPU with ``threads`` intra-op threads (None: its default)."""

    runtime = "onnxruntime"

    def __init__(self, path: str | Path, threads: int | None = None):
        self.session = onnx_session(path, threads)
        self.path = Path(path)

    def header(self) -> dict:
        return parse_header(self.session.get_modelmeta().custom_metadata_map.get(KEY), self.path)

    def __call__(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        feed = {"x": _f32(x), "mask": _f32(mask)}
        return torch.from_numpy(self.session.run(None, feed)[0])


class TorchScriptModel(ExportedModel):
    """A TorchScript file run by ``torch.jit`` on the CPU. Recent PyTorch (2.13 here) marks
    ``torch.jit`` deprecated; the warning is not shown here, and ONNX is the format to prefer."""

    runtime = "torchscript"

    def __init__(self, path: str | Path):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            self.module = torch.jit.load(str(path), map_location="cpu").eval()

    @torch.no_grad()
    def __call__(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        return self.module(x.float().cpu(), mask.float().cpu())


def _f32(t: torch.Tensor) -> np.ndarray:
    return np.ascontiguousarray(t.detach().cpu().numpy(), dtype=np.float32)


def load_file(path: str | Path, fmt: str | None = None, threads: int | None = None) -> ExportedModel:
    """The runnable model of an exported file (``fmt`` None: from its suffix)."""
    fmt = fmt or format_of(path)
    if fmt == "onnx":
        return OnnxModel(path, threads)
    if fmt == "torchscript":
        return TorchScriptModel(path)
    raise ConfigError(f"not an exported model file (.onnx or .pt): {fmt!r}", path)


def load_exported(path: str | Path, task: str, threads: int | None = None):
    """An exported file as :func:`wearnav.train.resolve.resolve_model` returns a run of ``task``:
    odometry ``(model, TrainConfig)``, classify ``(model, ClassifyConfig, classes)``; a file of
    the other task is refused saying which command takes it."""
    model = load_file(path, threads=threads)
    header = model.header() if isinstance(model, OnnxModel) else read_header(path)
    if header.get("task") != task:
        what, command = RUN_KINDS.get(str(header.get("task")), (f"a {header.get('task')} model", "another command"))
        raise ConfigError(f"is {what} ({header.get('model')}) exported, not {RUN_KINDS[task][0]}; use {command}", path)
    if task == "odometry":
        return model, TrainConfig.from_dict(header["config"])
    return model, ClassifyConfig.from_dict(header["config"]), list(header["classes"])
