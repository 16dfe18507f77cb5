"""Every experiment by name: the one registry of the configurations that answer the results page's
questions, and of the variants measured and not shipped (issue 58 §4).

An :class:`Experiment` is a command line held as data (a ``wearnav`` command, or a script of
``scripts/``), the questions of :data:`wearnav.bench.questions.QUESTIONS` its page answers (or
``history`` where its page left for ``docs/history.md``), whether it is the shipped configuration,
and the decision record that says why. A :class:`Data` is a dataset variant the commands read
(``{data}/NAME``), with the command that writes it. ``wearnav bench experiment NAME`` makes the
missing data and runs the command; ``--list`` prints the table (:func:`table`). The commands are
the existing ones: nothing here trains or scores.

Placeholders in a command: ``{out}`` the suite folder, ``{data}`` the folder of the named
datasets, ``{shared}`` the public datasets' root, ``{jobs}`` runs at once, ``{path}`` (in a
:class:`Data`'s command) the folder it writes. This module imports nothing heavy: ``--list``
answers at once.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from wearnav.errors import ConfigError

SHIPPED, MEASURED = "shipped", "measured, not shipped"
STATUSES = (SHIPPED, MEASURED)
HISTORY = "history"  # an experiment whose page left the results page (docs/history.md)
PYTHON = "python"  # a command's first word for a script of scripts/ (run with this interpreter)


@dataclass(frozen=True)
class Data:
    """A dataset variant under ``{data}/NAME``: what it is, and the command that writes it
    (``{path}``: its folder); ``made_by`` where no command here makes it."""

    name: str
    purpose: str
    command: tuple[str, ...] = ()
    needs: tuple[str, ...] = ()  # the variants its command reads
    made_by: str = ""


@dataclass(frozen=True)
class Experiment:
    """A named configuration: its command line (placeholders as the module docstring says), the
    question ids it answers (or :data:`HISTORY`), :data:`STATUSES`, its decision record (``NNNN``)."""

    name: str
    purpose: str
    command: tuple[str, ...]
    answers: tuple[str, ...]
    status: str
    decision: str = ""
    data: tuple[str, ...] = ()  # the Data it reads (made first where missing)


_SHARED_IPIN, _SHARED_ILC2 = "{shared}/ipin2023_track3", "{shared}/ilc2_indoor_location"

DATA: tuple[Data, ...] = (
    Data("ipin", "IPIN 2023 Track 3, every trial", ("import", "ipin2023", _SHARED_IPIN, "--out", "{path}")),
    Data("ilc2", "ILC2 site 1, every floor", ("import", "ilc2", _SHARED_ILC2, "--out", "{path}")),
    Data("sim", "the simulator's `default` preset, seed 0", ("simulate", "--preset", "default", "--out", "{path}")),
    Data("small", "the simulator's `small` preset, seed 0", ("simulate", "--preset", "small", "--out", "{path}")),
    Data(
        "mix-noipin",
        "ILC2 and `sim`, each recording's truth in its input's frame",
        (PYTHON, "scripts/mix_dataset.py", "{path}", "ilc2={data}/ilc2", "sim={data}/sim:recording"),
        ("ilc2", "sim"),
    ),
    Data(
        "mix-noilc2",
        "IPIN 2023 and `sim`, each recording's truth in its input's frame",
        (PYTHON, "scripts/mix_dataset.py", "{path}", "ipin={data}/ipin", "sim={data}/sim:recording"),
        ("ipin", "sim"),
    ),
    Data(
        "sim-hd",
        "`sim`'s walks with the phone in the hand",
        (PYTHON, "scripts/subset_dataset.py", "{data}/sim", "{path}", "--placement", "HD"),
        ("sim",),
    ),
    Data(
        "sim-walkers",
        "phone-only simulated walks, one simulated person each",
        (PYTHON, "scripts/simulate_walkers.py", "{path}"),
    ),
    Data(
        "sim-hd2",
        "`sim` with a renamed copy of each hand-held training walk",
        made_by="by hand, once (docs/decisions/0032-sim-only-transfers-best.md); no command here makes it",
    ),
)

# bench real-odometry as the shipped phone recipe's suites run it: Suite-IN++ beside PDR, 8 epochs,
# in the heading frame (no random yaw), three seeds
_REAL = ("bench", "real-odometry", "--out", "{out}", "--jobs", "{jobs}", "--models", "suitein++,pdr")
_HEADING = ("--heading-frame", "--augment", "")
_SEEDS = ("--seeds", "0,1,2")
_SIM_TO_REAL = ("--data", "{data}/ipin", "--test-data", "{data}/ilc2")
_ODOMETRY = ("bench", "odometry", "--data", "{data}/small", "--out", "{out}", "--jobs", "{jobs}", "--epochs", "12")
_PRETRAIN = ("pretrain", "--data", "{shared}", "--out", "{out}", "--work", "{data}", "--jobs", "{jobs}")

EXPERIMENTS: tuple[Experiment, ...] = (
    Experiment(
        "pretrained",
        "train, measure and install-ready every shipped model (the README's `wearnav pretrain`)",
        _PRETRAIN,
        ("shipped-phone", "shipped-multi", "users-path"),
        SHIPPED,
        "0018",
    ),
    Experiment(
        "pretrain-phone",
        "the shipped `phone` model: Suite-IN++ on the simulator, polar loss, phone's heading frame",
        (*_PRETRAIN, "--models", "phone"),
        ("shipped-phone", "users-path"),
        SHIPPED,
        "0040",
    ),
    Experiment(
        "pretrain-multi-mse",
        "the shipped `phone-watch-earbuds` model: the same on three devices with the MSE",
        (*_PRETRAIN, "--models", "phone-watch-earbuds"),
        ("shipped-multi",),
        SHIPPED,
        "0042",
    ),
    Experiment(
        "seeds-simonly-snapped-polar-heading",
        "the shipped phone recipe over three seeds, every speed source scored",
        (
            *_REAL,
            *_SIM_TO_REAL,
            "--train-data",
            "{data}/sim",
            "--epochs",
            "8",
            "--vel-loss",
            "polar",
            *_HEADING,
            *_SEEDS,
        ),
        ("seeds-phone",),
        SHIPPED,
        "0040",
        ("ipin", "ilc2", "sim"),
    ),
    Experiment(
        "seeds-multi-mse",
        "the shipped three-device recipe over three seeds (the phone alone in the buildings)",
        (
            *_REAL,
            *_SIM_TO_REAL,
            "--train-data",
            "{data}/sim",
            "--devices",
            "phone,watch,earbuds",
            "--epochs",
            "8",
            "--vel-loss",
            "mse",
            *_HEADING,
            *_SEEDS,
        ),
        ("seeds-multi",),
        SHIPPED,
        "0042",
        ("ipin", "ilc2", "sim"),
    ),
    Experiment(
        "fusion-phone",
        "the shipped `phone` model, the fixes and the smoother against the simulator's dense truth",
        ("bench", "fusion", "--data", "{data}/small", "--out", "{out}", "--model", "phone"),
        ("sim-fusion",),
        SHIPPED,
        "0020",
        ("small",),
    ),
    Experiment(
        "fusion",
        "the README's `bench fusion`: PDR, the fixes and the smoother on the simulator",
        ("bench", "fusion", "--data", "{data}/sim", "--out", "{out}"),
        ("sim-fusion",),
        MEASURED,
        "0020",
        ("sim",),
    ),
    Experiment(
        "adapt",
        "adapting the shipped `phone` model (never trained on IPIN) to IPIN's training fixes",
        ("bench", "adapt", "--model", "phone", "--data", "{data}/ipin", "--out", "{out}"),
        ("adapt",),
        MEASURED,
        "0017",
        ("ipin",),
    ),
    Experiment(
        "seeds-lobo-ipin-polar-heading",
        "trained on ILC2 and the simulator (`mix-noipin`), scored in IPIN 2023",
        (*_REAL, "--data", "{data}/ipin", "--train-data", "{data}/mix-noipin", "--epochs", "8")
        + ("--vel-loss", "polar", *_HEADING, *_SEEDS),
        ("lobo-ipin",),
        MEASURED,
        "0019",
        ("ipin", "mix-noipin"),
    ),
    Experiment(
        "lobo-ipin-polar",
        "the README's leave-one-building-out command: `mix-noipin`, polar loss, world frame",
        (*_REAL, "--data", "{data}/ipin", "--train-data", "{data}/mix-noipin", "--epochs", "8")
        + ("--vel-loss", "polar", *_SEEDS),
        ("lobo-ipin",),
        MEASURED,
        "0019",
        ("ipin", "mix-noipin"),
    ),
    Experiment(
        "seeds-lobo-ilc2-polar-heading",
        "trained on IPIN 2023 and the simulator (`mix-noilc2`), scored in ILC2",
        (*_REAL, "--data", "{data}/ilc2", "--train-data", "{data}/mix-noilc2", "--epochs", "8")
        + ("--vel-loss", "polar", *_HEADING, *_SEEDS),
        ("lobo-ilc2",),
        MEASURED,
        "0019",
        ("ilc2", "mix-noilc2"),
    ),
    Experiment(
        "seeds-ipin-polar-heading",
        "trained on IPIN 2023's own training trials, scored at its held-out ones",
        (*_REAL, "--data", "{data}/ipin", "--epochs", "30", "--vel-loss", "polar", *_HEADING, *_SEEDS),
        ("in-building",),
        MEASURED,
        "0029",
        ("ipin",),
    ),
    Experiment(
        "odometry",
        "Suite-IN++ Tables III–VI: every model of the paper's grid, world frame, MSE",
        (*_ODOMETRY, "--grid", "paper", *_SEEDS),
        ("sim-tables",),
        MEASURED,
        "0011",
        ("small",),
    ),
    Experiment(
        "odometry-small-suitein-mse-heading",
        "Table III for the shipped three-device recipe (MSE, the phone's heading frame)",
        (*_ODOMETRY, "--models", "suitein++", "--heading-frame", *_SEEDS),
        ("sim-tables-shipped",),
        SHIPPED,
        "0042",
        ("small",),
    ),
    Experiment(
        "demo",
        "`make demo`: Suite-IN++, RoNIN and PDR on the simulator's `small` preset",
        ("demo", "--out", "{out}"),
        ("demo",),
        MEASURED,
    ),
    Experiment(
        "frame-alignment",
        "each device's yaw error after the common-frame alignment, on `small`",
        (PYTHON, "scripts/frame_alignment_report.py", "small", "--seed", "0", "--out", "{out}/results.md"),
        ("frame-alignment",),
        SHIPPED,
        "0002",
    ),
    Experiment(
        "har-lodo",
        "the shipped activity models' recipe, leave one dataset out, and the final models",
        ("bench", "har-lodo", "--data", "{shared}", "--out", "{out}", "--jobs", "{jobs}", "--final"),
        ("activity",),
        SHIPPED,
        "0045",
    ),
    Experiment(
        "har",
        "paper 002's techniques on 7 datasets, 3 seeds, ~700 baseline steps each",
        ("bench", "har", "--data", "{shared}", "--out", "{out}", "--jobs", "{jobs}", "--steps", "700"),
        ("har-techniques",),
        MEASURED,
        "0030",
    ),
    Experiment(
        "easytrack",
        "EasyTrack (paper 004): L1–L3 simulated labels, ~8.5 km each, and IPIN's GNSS",
        ("bench", "easytrack", "--data", "{data}/ipin", "--out", "{out}", "--jobs", "{jobs}", "--km", "8.5"),
        ("easytrack",),
        MEASURED,
        "0014",
        ("ipin",),
    ),
    Experiment(
        "easytrack-base",
        "why BaseModel-GT is far from the paper's: one input change at a time",
        ("bench", "easytrack-base", "--out", "{out}", "--jobs", "{jobs}"),
        ("easytrack-base",),
        MEASURED,
        "0014",
    ),
    Experiment(
        "live-bench-phone-batched",
        "one `wearnav live` server's capacity, phone-only walkers, tracking batched",
        ("live", "bench", "--out", "{out}", "--walkers", "8,16,32", "--devices", "phone"),
        ("live",),
        SHIPPED,
        "0028",
    ),
    Experiment(
        "live-bench",
        "the README's `live bench`: phone-only and three-device walkers, two tracker processes",
        ("live", "bench", "--out", "{out}", "--walkers", "8,16,32", "--devices", "phone,all", "--trackers", "2"),
        ("live",),
        SHIPPED,
        "0028",
    ),
    Experiment(
        "efficiency-h100",
        "Table VI on a GPU: batches 1, 256, 4096, batch 1 compiled and as a CUDA graph",
        ("bench", "efficiency", "--out", "{out}", "--device", "cuda", "--batches", "1,256,4096", "--faster-b1"),
        ("efficiency",),
        MEASURED,
    ),
    Experiment(
        "efficiency",
        "Table VI on this machine's CPU (the README's `bench efficiency`)",
        ("bench", "efficiency", "--out", "{out}"),
        ("efficiency",),
        MEASURED,
    ),
    # variants measured and not shipped, whose pages left for docs/history.md
    Experiment(
        "sim-hd",
        "the phone recipe trained on `sim`'s hand-held walks alone (fails with the phone in a pocket)",
        (*_REAL, *_SIM_TO_REAL, "--train-data", "{data}/sim-hd", "--epochs", "8", "--vel-loss", "polar")
        + (*_HEADING, *_SEEDS),
        (HISTORY,),
        MEASURED,
        "0038",
        ("ipin", "ilc2", "sim-hd"),
    ),
    Experiment(
        "sim-hd2",
        "the phone recipe with the hand-held walks weighted twice",
        (*_REAL, *_SIM_TO_REAL, "--train-data", "{data}/sim-hd2", "--epochs", "8", "--vel-loss", "polar")
        + (*_HEADING, *_SEEDS),
        (HISTORY,),
        MEASURED,
        "0032",
        ("ipin", "ilc2", "sim-hd2"),
    ),
    Experiment(
        "sim-walkers",
        "the phone recipe trained on many simulated walkers' gaits",
        (*_REAL, *_SIM_TO_REAL, "--train-data", "{data}/sim-walkers", "--epochs", "8", "--vel-loss", "polar")
        + (*_HEADING, *_SEEDS),
        (HISTORY,),
        MEASURED,
        "0032",
        ("ipin", "ilc2", "sim-walkers"),
    ),
    Experiment(
        "speed-warp",
        "the phone recipe also trained on its walks played 0.8× and 1.25× as fast",
        (*_REAL, *_SIM_TO_REAL, "--train-data", "{data}/sim", "--epochs", "8", "--vel-loss", "polar")
        + (*_HEADING, *_SEEDS, "--speed-warp", "0.8,1.25"),
        (HISTORY,),
        MEASURED,
        "0032",
        ("ipin", "ilc2", "sim"),
    ),
    Experiment(
        "mse-heading",
        "the phone recipe with the MSE instead of the polar loss",
        (*_REAL, *_SIM_TO_REAL, "--train-data", "{data}/sim", "--epochs", "8", "--vel-loss", "mse")
        + (*_HEADING, *_SEEDS),
        (HISTORY,),
        MEASURED,
        "0039",
        ("ipin", "ilc2", "sim"),
    ),
    Experiment(
        "multi-earbuds-drop",
        "the three-device recipe in the earbuds' heading frame, devices dropped in training",
        (*_REAL, *_SIM_TO_REAL, "--train-data", "{data}/sim", "--devices", "earbuds,phone,watch", "--epochs", "8")
        + ("--vel-loss", "mse", "--heading-frame", "--augment", "drop_devices", *_SEEDS),
        (HISTORY,),
        MEASURED,
        "0041",
        ("ipin", "ilc2", "sim"),
    ),
    Experiment(
        "easytrack-amended",
        "issue 59 at a reduced scale: BaseModel, the faithful and the amended EasyTrack, CNAL alone; L1, ~3 km, 30 joint epochs",
        (
            "bench",
            "easytrack",
            "--out",
            "{out}",
            "--levels",
            "L1",
            "--methods",
            "basemodel,easytrack,easytrack-amended,nocoadapt",
            "--km",
            "3",
            "--joint-epochs",
            "30",
            "--seeds",
            "5",
        ),
        ("easytrack-amended",),
        MEASURED,
        "0047",
    ),
    Experiment(
        "map-lofo",
        "the map-aware path in ILC2 site 1, every constant chosen on the other floors (the shipped phone model)",
        ("bench", "map-lofo", "--data", "{data}/ilc2", "--out", "{out}"),
        ("map-lofo",),
        SHIPPED,
        "0046",
        ("ilc2",),
    ),
    Experiment(
        "radio-track",
        "the user's path with a radio map of other walks: IPIN 2023 each trial held out, ILC2 walks held out in 5 groups (20 a floor)",
        ("bench", "radio-track", "--ipin", "{data}/ipin", "--ilc2", "{data}/ilc2", "--out", "{out}"),
        ("radio-track",),
        SHIPPED,
        "0049",
        ("ipin", "ilc2"),
    ),
)

_PLACEHOLDER = re.compile(r"\{(\w+)\}")
_DATA_ARG = re.compile(r"\{data\}/([\w-]+)")


def get(name: str) -> Experiment:
    """The experiment named ``name``; an unknown name is one line listing the names."""
    for exp in EXPERIMENTS:
        if exp.name == name:
            return exp
    raise ConfigError(f"no experiment {name!r}; one of {', '.join(e.name for e in EXPERIMENTS)}")


def data_variant(name: str) -> Data:
    for d in DATA:
        if d.name == name:
            return d
    raise ConfigError(f"no dataset variant {name!r}; one of {', '.join(d.name for d in DATA)}")


def fill(command: tuple[str, ...], **values: str) -> list[str]:
    """``command`` with its placeholders replaced by ``values`` (every one must be given)."""

    def one(m: re.Match) -> str:
        if m.group(1) not in values:
            raise ConfigError(f"no value for {{{m.group(1)}}} in {' '.join(command)}")
        return values[m.group(1)]

    return [_PLACEHOLDER.sub(one, arg) for arg in command]


def data_read(command: tuple[str, ...]) -> tuple[str, ...]:
    """The dataset variants a command reads (its ``{data}/NAME`` arguments), in order."""
    return tuple(dict.fromkeys(m.group(1) for arg in command for m in _DATA_ARG.finditer(arg)))


def data_steps(exp: Experiment, data: Path) -> list[Data]:
    """The dataset variants ``exp`` reads that are not under ``data`` yet (no ``manifest.csv``),
    those they are made from first; one line where one has no command that makes it."""
    steps: list[Data] = []

    def need(name: str) -> None:
        d = data_variant(name)
        if d in steps or (Path(data) / name / "manifest.csv").is_file():
            return
        if not d.command:
            raise ConfigError(f"{name}: made {d.made_by}; put it in {Path(data) / name} first")
        for other in d.needs:
            need(other)
        steps.append(d)

    for name in exp.data:
        need(name)
    return steps


def table() -> str:
    """The registry as ``--list`` prints it: one line per experiment, then the dataset variants."""
    w = max(len(e.name) for e in EXPERIMENTS)
    a = max(len(", ".join(e.answers)) for e in EXPERIMENTS)
    lines = [f"{'experiment':{w}s}  {'answers':{a}s}  {'status':21s}  decision  purpose"]
    for e in EXPERIMENTS:
        answers, decision = ", ".join(e.answers), e.decision or "—"
        lines.append(f"{e.name:{w}s}  {answers:{a}s}  {e.status:21s}  {decision:8s}  {e.purpose}")
    lines += ["", "dataset variants ({data}/NAME, made where missing):"]
    lines += [f"  {d.name:12s} {d.purpose}" for d in DATA]
    return "\n".join(lines)
