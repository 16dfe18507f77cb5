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
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from wearnav.errors import ConfigError

MODELS_DIR = Path(__file__).parent / "models"
CARD = "MODEL_CARD.md"
PHONE, MULTI, ACTIVITY, ACTIVITY_WATCH = "phone", "phone-watch-earbuds", "activity", "activity-watch"


@dataclasses.dataclass(frozen=True)
class Shipped:
    name: str
    task: str  # "odometry" or "classify" (wearnav.train.common.RUN_KINDS)
    devices: tuple[str, ...]
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
            "Suite-IN++ on the phone alone: ILC2 site 1, IPIN 2023 Track 3 and the simulator",
        ),
        Shipped(
            MULTI,
            "odometry",
            ("phone", "watch", "earbuds"),
            "Suite-IN++ on phone, watch and earbuds (any of them absent): the same data",
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


# What `track` and `live` use without --model for a recording with the phone alone (issue 34): PDR,
# because the shipped phone recipe measured worse than it in both buildings it never trained in
# (docs/results.md, "Shipped models and leave-one-building-out": known start, median error at the
# surveyed points and path-length ratio). A recording with a watch or earbuds keeps the learned
# multi-device model: there is no real multi-device walk here to measure PDR against it on, and on
# the simulator the multi-device Suite-IN++ is far ahead of PDR (Table III).
PHONE_ONLY_DEFAULT = "pdr"
PHONE_ONLY_WHY = (
    "a phone-only recording: step-and-heading PDR, which measured better than the shipped phone model in "
    "both buildings that model's recipe never trained in (known start, median at surveyed points: IPIN "
    "4.77 vs 6.75 m, ILC2 3.75 vs 5.92 m; path length / truth 1.11 and 0.94 vs 0.64 and 0.68); "
    "`--model phone` takes the learned model"
)


def default_model(task: str, devices_in_recording=()) -> tuple[Path | str, str]:
    """What a command uses without ``--model`` for a recording with ``devices_in_recording``, and
    why: for odometry PDR on a phone-only recording (:data:`PHONE_ONLY_WHY`), else the shipped model
    of :func:`default_for`."""
    if task == "odometry" and not {"watch", "earbuds"} & set(devices_in_recording):
        return PHONE_ONLY_DEFAULT, PHONE_ONLY_WHY
    spec = default_for(task, devices_in_recording)
    return (
        spec.path,
        f"the shipped model {spec.name!r} for a recording with {', '.join(devices_in_recording) or 'these devices'}",
    )


def model_path(arg, task: str, devices_in_recording=()):
    """A command's ``--model`` as the path of what it names: None → :func:`default_for`; the name of
    a shipped model (where no such file or folder exists) → its folder; anything else unchanged."""
    if arg is None:
        return default_model(task, devices_in_recording)[0]
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
