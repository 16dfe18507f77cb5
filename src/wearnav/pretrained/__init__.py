"""Models shipped inside the package, so that `wearnav track` and `wearnav classify` work on a
stranger's recording without training first (issue 18).

Each lives in ``models/<name>/`` beside this file: a run folder as `wearnav train` writes it,
trimmed to what inference needs (``config.yaml``, ``checkpoints/best.ckpt`` with the weights
only, ``training.json``, the smoother's ``fuse_calibration.json`` for odometry) and a
``MODEL_CARD.md`` (data and licences, preprocessing, measured errors, known limits). They are
trained and installed by one command, ``wearnav pretrain`` (:mod:`wearnav.pretrained.recipe`).

``track`` without ``--model`` takes :data:`PHONE` for a phone-only recording and :data:`MULTI`
when the recording also has a watch or earbuds; ``classify`` takes :data:`ACTIVITY` (the phone's)
where the recording has a phone, else :data:`ACTIVITY_WATCH` where it has a watch.

Decisions: docs/decisions/0018-shipped-models-phone-on-simulator.md,
docs/decisions/0039-mse-whole-preset-not-shipped.md.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from wearnav.core.textio import read_json, read_yaml
from wearnav.errors import ConfigError, FormatError
from wearnav.export.header import is_exported, read_header
from wearnav.runs import run_folder

MODELS_DIR = Path(__file__).parent / "models"
CARD = "MODEL_CARD.md"
# in a shipped odometry model's folder: its known-start errors in buildings it never trained in,
# beside PDR's (wearnav.pretrained.recipe.held_out_record), and where its speed comes from ("speed",
# wearnav.train.odometry.SPEED_SOURCES); what the phone-only choice and the commands' default speed read
HELD_OUT_JSON = "held_out.json"
# how each speed source is said in a sentence (the choice's reason, the card)
SPEED_WORDS = {
    "model": "its own speed",
    "pdr": "its direction at detected steps × 0.67 m",
    "cadence": "its direction at detected steps as long as the cadence makes them",
    "pointing": "its speed along where the phone points",
    "snapped": "its direction, turned onto where the phone points wherever within 30° of it, at detected steps "
    "as long as the cadence makes them",
}
PHONE, MULTI, ACTIVITY, ACTIVITY_WATCH = "phone", "phone-watch-earbuds", "activity", "activity-watch"


@dataclasses.dataclass(frozen=True)
class Shipped:
    name: str
    task: str  # "odometry" or "classify" (wearnav.train.common.RUN_KINDS)
    devices: tuple[str, ...]
    # what it is and what it learned from; its frame, speed and loss are read from its run
    # (frame_words, recorded_speed), never restated here
    summary: str

    @property
    def path(self) -> Path:
        return MODELS_DIR / self.name

    @property
    def installed(self) -> bool:
        return any((self.path / "checkpoints").glob("*.ckpt")) and (self.path / "config.yaml").is_file()

    def size_bytes(self) -> int:
        return sum(p.stat().st_size for p in self.path.rglob("*") if p.is_file()) if self.path.is_dir() else 0


SHIPPED = {
    s.name: s
    for s in (
        Shipped(
            PHONE,
            "odometry",
            ("phone",),
            "Suite-IN++ on the phone alone, trained on the simulator only "
            "(ILC2 and IPIN 2023 are the buildings it is measured in)",
        ),
        Shipped(
            MULTI,
            "odometry",
            ("phone", "watch", "earbuds"),
            "Suite-IN++ on phone, watch and earbuds (any of them absent), trained "
            "on the simulator only (ILC2 and IPIN 2023 are the buildings it is measured in, on the phone alone)",
        ),
        Shipped(
            ACTIVITY,
            "classify",
            ("phone",),
            "CNN+BiLSTM (paper 002) on gravity-aligned phone windows, trained on every labelled source "
            "(MotionSense, UCI HAPT, UJI, Oxford, ILC2, IPIN, the simulator) in one label set; "
            "unsure windows are labelled unknown",
        ),
        Shipped(
            ACTIVITY_WATCH,
            "classify",
            ("watch",),
            "the same recipe on the watch: UJI's smartwatch and the simulator's watch (walking, sitting, other)",
        ),
    )
}


def get(name: str) -> Shipped:
    if name not in SHIPPED:
        raise ConfigError(f"no shipped model {name!r}; shipped: {', '.join(SHIPPED)}")
    return SHIPPED[name]


def installed(task: str | None = None) -> list[Shipped]:
    """The shipped models present in this installation (of ``task``)."""
    return [s for s in SHIPPED.values() if s.installed and (task is None or s.task == task)]


def default_for(task: str, devices_in_recording=()) -> Shipped:
    """The model a command uses without ``--model``: for odometry the multi-device one where the
    recording has a watch or earbuds, else the phone one; for classify the phone's activity model
    where the recording has a phone (or its devices are not known), else the watch's where it has
    a watch and that model is installed."""
    if task == "classify":
        devs = set(devices_in_recording)
        name = (
            ACTIVITY_WATCH
            if "watch" in devs and "phone" not in devs and SHIPPED[ACTIVITY_WATCH].installed
            else ACTIVITY
        )
    else:
        name = MULTI if {"watch", "earbuds"} & set(devices_in_recording) else PHONE
    spec = SHIPPED[name]
    if not spec.installed:
        raise ConfigError(
            f"this installation has no shipped model {name!r} (models/{name} is missing); "
            f"give --model RUN, or train it with `wearnav pretrain`"
        )
    return spec


TRACK_DEFAULTS = "track_defaults"  # the export header's field holding track_defaults (wearnav.export.header)


def track_defaults(model: str | Path) -> dict:
    """What `wearnav track` takes from the model at ``model`` besides its weights and training config
    (issue 56 §2): ``speed``, where its speed comes from by default (:data:`SPEED_WORDS`; what its
    :data:`HELD_OUT_JSON` records, where ``wearnav pretrain`` writes the recipe's ``speed``; else
    "model"), and ``fuse_calibration``, the smoother's calibration of its run
    (:data:`wearnav.fuse.CALIBRATION_JSON`, that :func:`wearnav.fuse.config_for` places the path with;
    None where the run has none or it is not an object). ``model``: a run folder or one of its
    checkpoints, or a file of `wearnav export`, whose header carries these under
    :data:`TRACK_DEFAULTS` (written from this function by :func:`wearnav.export.write.load_run`, so
    the file and its run cannot drift); a file exported before the header carried them gives "model"
    and the header's own ``fuse_calibration``. The speed sources' constants (30° of
    :data:`wearnav.models.base.SNAP_DEG`, the cadence's step length) are the code's, the same for
    both; the header also names them for runtimes outside wearnav."""
    from wearnav.fuse.config import CALIBRATION_JSON  # scipy: not imported before a command runs

    if is_exported(model):
        header = read_header(model)
        got = header.get(TRACK_DEFAULTS)
        got = got if isinstance(got, dict) else {"fuse_calibration": header.get("fuse_calibration")}
        speed, calibration = got.get("speed", "model"), got.get("fuse_calibration")
    else:
        folder = run_folder(model)
        speed = _run_speed(folder)
        f, calibration = folder / CALIBRATION_JSON, None
        if f.is_file():
            try:
                calibration = read_json(f)
            except FormatError:  # config_for says so and uses the smoother's defaults
                calibration = None
    return {
        "speed": _speed_or_model(speed),
        "fuse_calibration": calibration if isinstance(calibration, dict) else None,
    }


def _speed_or_model(speed) -> str:
    return speed if isinstance(speed, str) and speed in SPEED_WORDS else "model"


def _run_speed(folder: Path) -> str:
    """The speed a run folder records (its :data:`HELD_OUT_JSON`'s ``speed``), else "model"."""
    record = read_json(folder / HELD_OUT_JSON) if (folder / HELD_OUT_JSON).is_file() else {}
    return _speed_or_model(record.get("speed", "model") if isinstance(record, dict) else "model")


def recorded_speed(model: str | Path) -> str:
    """Where the speed of the model at ``model`` (a run folder or one of its checkpoints, or a file of
    `wearnav export`) comes from by default: :func:`track_defaults`' ``speed`` (for a run folder read
    without importing the smoother: ``wearnav models`` lists it); a name: "model"."""
    if not Path(model).exists():
        return "model"
    if is_exported(model):
        return track_defaults(model)["speed"]
    return _run_speed(run_folder(model))


def shipped_speeds() -> dict[str, str]:
    """Each installed shipped odometry model's default speed source (:func:`recorded_speed`: its
    :data:`HELD_OUT_JSON`), the one place `track --help`, `wearnav models` and the model cards read
    it from (issue 58 §7; tests/test_said_once.py holds the README to it)."""
    return {s.name: recorded_speed(s.path) for s in installed("odometry")}


def frame_words(heading_frame: bool, devices, reference: str | None = None) -> str:
    """The frames an odometry model on ``devices`` (those it uses, in its layout's order) works in, in
    one phrase: what `wearnav models` says of a shipped model and `track` of the model it ran (issue 58
    §7: before, one said "the phone's heading frame" and the other "frame: common", each half of it).
    Every device is turned into the ``reference`` device's world frame (the devices' common frame,
    :mod:`wearnav.preprocess.frames`; default the phone where it is among ``devices``, as
    :func:`wearnav.preprocess.frames.reference_index` picks it); a ``heading_frame`` model's windows are turned
    into the first device's heading frame (where it points, :attr:`wearnav.preprocess.PreprocessConfig.heading_frame`)
    and its velocity turned back, so its path too is in the common frame, whose yaw no one knows until
    the path is placed (on the fixes, a plan or ``--start``)."""
    devices = list(devices)
    if not devices:
        return "no device"
    ref = reference or ("phone" if "phone" in devices else devices[0])
    common = f"the {ref}'s world frame (the devices' common frame; its yaw is fixed where the path is placed)"
    if not heading_frame:
        return f"input and path in {common}"
    return f"windows in the {devices[0]}'s heading frame (where it points), the velocity turned back: path in {common}"


def shipped_frame_words(spec: Shipped) -> str:
    """:func:`frame_words` of the installed shipped odometry model ``spec``, read from its ``config.yaml``."""

    train = read_yaml(spec.path / "config.yaml").get("config", {}).get("train", {})
    return frame_words(bool(train.get("heading_frame")), train.get("devices") or spec.devices)


def phone_only_choice(has_fixes: bool = False) -> tuple[Path | str, str]:
    """What `track` and `live` use without ``--model`` for a recording with the phone alone, and why
    (issue 34): the path that measured better where the shipped phone model never trained, by what
    the user will see. A recording with fixes (``has_fixes``) is placed by the smoother, so it takes
    the shipped model where its :data:`HELD_OUT_JSON` shows the smoother's median with it at or below
    the smoother's with PDR in every building with fixes; one without fixes (or a model measured in no
    building with fixes) is placed from its start, so it takes the model where its known-start median
    is below PDR's in every building. Else step-and-heading PDR. A recording with a watch or earbuds
    keeps the learned multi-device model: no real multi-device walk here measures PDR against it, and
    on the simulator the multi-device Suite-IN++ is far ahead of PDR (Table III)."""
    spec = SHIPPED[PHONE]
    record = spec.path / HELD_OUT_JSON
    if not (spec.installed and record.is_file()):
        return "pdr", (
            "a phone-only recording: step-and-heading PDR (this installation's phone model carries no "
            "measurement in buildings it never saw); `--model phone` takes the learned model"
        )
    buildings = read_json(record)["buildings"]
    smoothed = {name: b["smoother"] for name, b in buildings.items() if b.get("smoother")}
    if has_fixes and smoothed:
        said = "; ".join(
            f"{name}: {b['model_median_m']:.2f} against PDR's {b['pdr_median_m']:.2f} m "
            f"(p75 {b['model_p75_m']:.2f} against {b['pdr_p75_m']:.2f})"
            for name, b in smoothed.items()
        )
        how = "placed on the user's own fixes by the smoother, median error at the surveyed points"
        wins = all(b["model_median_m"] <= b["pdr_median_m"] for b in smoothed.values())
        where = "every building with fixes"
    else:
        said = "; ".join(
            f"{name}: {b['model_median_m']:.2f} against PDR's {b['pdr_median_m']:.2f} m "
            f"(path length / truth {b['model_length_ratio']:.2f} against {b['pdr_length_ratio']:.2f})"
            for name, b in buildings.items()
        )
        how = "known start, median error at the surveyed points"
        wins = bool(buildings) and all(b["model_median_m"] < b["pdr_median_m"] for b in buildings.values())
        where = "every building"
    kind = "with fixes" if has_fixes else "without fixes"
    speed = recorded_speed(spec.path)
    with_speed = "" if speed == "model" else f" with {SPEED_WORDS[speed]} (`--speed model` takes its own)"
    if wins:
        return spec.path, (
            f"a phone-only recording {kind}: the shipped model {PHONE!r}{with_speed}, which measured better than "
            f"step-and-heading PDR in {where} it never trained in ({how}; {said}); `--model pdr` takes PDR"
        )
    return "pdr", (
        f"a phone-only recording {kind}: step-and-heading PDR, which measured better than the shipped phone model "
        f"in a building that model never trained in ({how}; {said}); `--model phone` takes the learned model"
    )


def default_model(task: str, devices_in_recording=(), has_fixes: bool = False) -> tuple[Path | str, str]:
    """What a command uses without ``--model`` for a recording with ``devices_in_recording`` (and
    fixes, ``has_fixes``), and why: for odometry on a phone-only recording :func:`phone_only_choice`,
    else the shipped model of :func:`default_for`."""
    if task == "odometry" and not {"watch", "earbuds"} & set(devices_in_recording):
        return phone_only_choice(has_fixes)
    spec = default_for(task, devices_in_recording)
    return (
        spec.path,
        f"the shipped model {spec.name!r} for a recording with {', '.join(devices_in_recording) or 'these devices'}",
    )


def model_path(arg, task: str, devices_in_recording=(), has_fixes: bool = False):
    """A command's ``--model`` as the path of what it names: None → :func:`default_model`; the name of
    a shipped model (where no such file or folder exists) → its folder; anything else unchanged."""
    if arg is None:
        return default_model(task, devices_in_recording, has_fixes)[0]
    if not Path(arg).exists() and str(arg) in SHIPPED:
        spec = SHIPPED[str(arg)]
        if spec.task != task:
            raise ConfigError(f"shipped model {spec.name!r} is a {spec.task} model, not {task}")
        if not spec.installed:
            raise ConfigError(f"this installation has no shipped model {spec.name!r}; train it with `wearnav pretrain`")
        return spec.path
    return arg


def shipped_name(path) -> str | None:
    """The name of the shipped model whose folder ``path`` is, else None."""
    p = Path(path)
    return next((s.name for s in SHIPPED.values() if p.exists() and p.resolve() == s.path.resolve()), None)
