"""What an exported model carries about itself, and how it is read back.

One JSON object, the *header*, travels inside the file (no sidecar):

* ONNX (``.onnx``): the model's ``metadata_props`` entry ``wearnav`` (readable with
  ``onnxruntime.InferenceSession(path).get_modelmeta().custom_metadata_map["wearnav"]``);
* TorchScript (``.pt``): the archive's extra file ``wearnav.json``
  (``torch.jit.load(path, _extra_files={"wearnav.json": ""})``).

Its fields: ``format`` (:data:`HEADER_FORMAT`); ``task`` ("odometry" or "classify"); ``model``
(registry name); ``devices`` (the input's device axis, in order), ``window`` (samples),
``rate_hz``, ``stride`` (samples between windows); ``inputs`` and ``output`` (names, shapes and
units); ``config`` (the run's whole training config, as config.yaml's ``train`` holds it:
:class:`wearnav.train.odometry.TrainConfig` or :class:`wearnav.train.classify.ClassifyConfig`);
``classes`` (classifiers: the label of each logit); ``training`` (the run's training.json:
whether it beat its trivial baseline, what data it saw, for ``wearnav track``'s warnings);
``metrics`` (classifiers: test accuracy against the majority class); ``track_defaults`` (odometry:
every default that ``wearnav track`` takes from the run besides its weights and config, gathered by
:func:`wearnav.pretrained.track_defaults` for the run and read back by it for the file, so that the
file and its run give the same path (issue 56 §2): ``speed``, where the speed comes from, e.g. the
shipped phone model's "snapped", and ``fuse_calibration``, the smoother's calibration,
``fuse_calibration.json``, null where the run has none); ``fuse_calibration`` (the same calibration
again, where files exported before ``track_defaults`` kept it; :func:`wearnav.fuse.config_for` reads
it); ``speed_constants`` (odometry: what the default speed source does and its constants, the
pointing's snap angle and the step length per unit cadence, for a runtime outside wearnav);
``source_run``;
``provenance`` (wearnav version, commit, time) and ``torch`` (the exporting version).
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

from wearnav.errors import ConfigError, FormatError, one_line

HEADER_FORMAT = 1
KEY = "wearnav"  # ONNX metadata_props key
EXTRA_FILE = "wearnav.json"  # TorchScript extra file
FORMATS = {"onnx": ".onnx", "torchscript": ".pt"}  # format → file suffix
IMU_CHANNELS = 6  # per device in x: acc x y z (m/s²), gyro x y z (rad/s)
ONNX_EXTRA = "onnx"  # pyproject's optional dependencies for ONNX Runtime
ONNX_MISSING = (
    f"running or exporting an ONNX model needs onnx and onnxruntime: install wearnav[{ONNX_EXTRA}] "
    f"(pip install 'wearnav[{ONNX_EXTRA}]')"
)


def format_of(path: str | Path) -> str | None:
    """The export format a file name says (its suffix), else None."""
    suffix = Path(path).suffix.lower()
    return next((f for f, s in FORMATS.items() if s == suffix), None)


def is_exported(path: str | Path) -> bool:
    """Whether ``path`` is a file with an export suffix (``.onnx``, ``.pt``)."""
    return Path(path).is_file() and format_of(path) is not None


def check_out_file(fmt: str, out: str | Path) -> None:
    """Refuse an export's ``out`` before any work: an unknown ``fmt``, a name without the
    format's suffix (`wearnav track --model` tells formats by it), or a folder."""
    if fmt not in FORMATS:
        raise ConfigError(f"unknown export format {fmt!r}; one of {', '.join(FORMATS)}")
    out = Path(out)
    if out.suffix.lower() != FORMATS[fmt]:
        raise ConfigError(
            f"a {fmt} file's name ends in {FORMATS[fmt]} (`wearnav track --model` tells formats by it)", out
        )
    if out.is_dir():
        raise ConfigError("is a folder; --out names the file to write", out)


def onnxruntime():
    """The ``onnxruntime`` module, or a ConfigError naming the extra that installs it."""
    try:
        import onnxruntime as ort
    except ImportError:
        raise ConfigError(ONNX_MISSING) from None
    return ort


def read_header(path: str | Path) -> dict:
    """The header of an exported model file (module docstring); FormatError when it has none."""
    path = Path(path)
    fmt = format_of(path)
    if fmt == "onnx":
        return parse_header(onnx_session(path).get_modelmeta().custom_metadata_map.get(KEY), path)
    if fmt != "torchscript":
        raise FormatError(f"not an exported model (suffix one of {', '.join(FORMATS.values())})", path)
    try:
        with zipfile.ZipFile(path) as z:
            member = next((n for n in z.namelist() if n.endswith(f"/extra/{EXTRA_FILE}")), None)
            return parse_header(z.read(member).decode() if member else None, path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise FormatError(f"not a TorchScript archive: {exc}", path) from None


def onnx_session(path: str | Path, threads: int | None = None):
    """An ONNX Runtime CPU session of ``path`` with ``threads`` intra-op threads (None: its
    default); a file it cannot read is one FormatError line."""
    ort = onnxruntime()
    opts = ort.SessionOptions()
    if threads:
        opts.intra_op_num_threads, opts.inter_op_num_threads = threads, 1
    try:
        return ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own classes (Fail, InvalidProtobuf, ...)
        raise FormatError(f"not a readable ONNX model: {one_line(str(exc)) or type(exc).__name__}", path) from None


def parse_header(text: str | None, path: str | Path) -> dict:
    """The header from its JSON ``text`` (None: the file has none), checked for its format."""
    if not text:
        raise FormatError("carries no wearnav header (was it written by `wearnav export`?)", path)
    try:
        header = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FormatError(f"its wearnav header is not JSON: {exc}", path) from None
    if not isinstance(header, dict) or header.get("format") != HEADER_FORMAT:
        got = header.get("format") if isinstance(header, dict) else "?"
        raise FormatError(f"header format {got} is not {HEADER_FORMAT} (exported by another wearnav version)", path)
    return header
