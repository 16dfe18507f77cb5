"""Dataset presets and :func:`simulate_dataset`.

The layout follows Suite-IN++ (Sec. V intro): subject ``u1`` walks all five modes; per mode its
recordings are split 6:2:2 into train / val / test (so every split covers every mode); u1's
recordings with the phone in a pocket (PK) or bag (BG) form ``test_unseen`` (never trained on,
Table IV); every other subject's recordings form ``cross_subject`` (Sec. V-E).

A dataset is a pure function of (preset, seed): subjects are drawn from the seed alone (so ``u1``
is the same person in every preset), each recording gets its own walk seed, stored in its meta
together with its full :class:`~wearnav.simulate.config.WalkConfig`, so any single recording can
be regenerated with ``simulate_recording(WalkConfig.from_dict(meta["config"]), meta["seed"])``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wearnav.core.progress import progress as report_progress
from wearnav.dataset import Dataset, DatasetWriter
from wearnav.errors import ConfigError
from wearnav.simulate.config import MODES, NOISE_LEVELS, SCENES, WalkConfig, sample_subject
from wearnav.simulate.walk import simulate_walk

MAIN_SUBJECT = "u1"
SPLIT_SHARES = (("train", 0.6), ("val", 0.2), ("test", 0.2))
DEFAULT_PLACEMENT = {"STW": "HD", "PVW": "MP", "MVW": "MP", "DRW": "HD", "DLW": "HD"}


@dataclass(frozen=True)
class Preset:
    """How much data to simulate. Counts are recordings; durations are drawn per recording."""

    name: str
    per_mode_main: int  # u1 recordings per mode (a multiple of 5 gives an exact 6:2:2 split)
    unseen_per_placement: int  # u1 STW recordings with the phone in a pocket, and in a bag
    cross_subjects: int  # further subjects, for the cross-subject test
    per_mode_cross: int
    duration_s: tuple[float, float]
    scene_weights: tuple[float, float, float] = (0.4, 0.35, 0.25)  # small, medium, large


PRESETS: dict[str, Preset] = {
    # tests: every mode, device and split, ~17 min of data, a few seconds to simulate
    "tiny": Preset(
        "tiny", per_mode_main=5, unseen_per_placement=1, cross_subjects=1, per_mode_cross=1, duration_s=(28.0, 36.0)
    ),
    # the demo: a few minutes per mode, ~45 min of data
    "small": Preset(
        "small", per_mode_main=5, unseen_per_placement=1, cross_subjects=2, per_mode_cross=1, duration_s=(60.0, 90.0)
    ),
    # benchmarks: five subjects, ~3.3 h, recordings of 1.5–3.5 min (the paper's average is 2.8)
    "default": Preset(
        "default",
        per_mode_main=10,
        unseen_per_placement=3,
        cross_subjects=4,
        per_mode_cross=1,
        duration_s=(90.0, 210.0),
    ),
}


@dataclass(frozen=True)
class PlannedWalk:
    config: WalkConfig
    seed: int
    split: str


def get_preset(name: str) -> Preset:
    if name not in PRESETS:
        raise ConfigError(f"unknown simulator preset {name!r} (expected one of {', '.join(PRESETS)})")
    return PRESETS[name]


def _split_labels(n: int, rng: np.random.Generator) -> list[str]:
    """n split names in shares 6:2:2 (largest-remainder rounding, val/test at least one each
    when n ≥ 3), in random order."""
    counts = {k: int(np.floor(share * n)) for k, share in SPLIT_SHARES}
    if n >= 3:
        for k in ("val", "test"):
            counts[k] = max(counts[k], 1)
    counts["train"] = n - counts["val"] - counts["test"]
    labels = [k for k, _ in SPLIT_SHARES for _ in range(counts[k])]
    return [str(x) for x in rng.permutation(labels)]


def plan_dataset(preset: str | Preset, seed: int = 0) -> list[PlannedWalk]:
    """The recordings a preset makes: configs, walk seeds and splits (nothing simulated yet)."""
    p = get_preset(preset) if isinstance(preset, str) else preset
    subj_rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
    n_subjects = 1 + p.cross_subjects
    subjects = [sample_subject(subj_rng, f"u{i + 1}") for i in range(n_subjects)]
    rng = np.random.default_rng(np.random.SeedSequence([seed, 2, sum(map(ord, p.name))]))
    scenes = list(SCENES)

    plan: list[tuple[WalkConfig, str]] = []

    def add(subject, mode, placement, index, split):
        cfg = WalkConfig(
            name=f"{subject.name}_{mode}_{placement}_{index:03d}",
            subject=subject,
            mode=mode,
            placement=placement,
            scene=str(rng.choice(scenes, p=np.asarray(p.scene_weights) / sum(p.scene_weights))),
            duration_s=round(float(rng.uniform(*p.duration_s)), 2),
            noise_level=str(rng.choice(NOISE_LEVELS)),
        )
        plan.append((cfg, split))

    main = subjects[0]
    for mode in MODES:
        for i, split in enumerate(_split_labels(p.per_mode_main, rng)):
            add(main, mode, DEFAULT_PLACEMENT[mode], i, split)
    for placement in ("PK", "BG"):
        for i in range(p.unseen_per_placement):
            add(main, "STW", placement, i, "test_unseen")
    for subject in subjects[1:]:
        for mode in MODES:
            for i in range(p.per_mode_cross):
                add(subject, mode, DEFAULT_PLACEMENT[mode], i, "cross_subject")
    return [
        PlannedWalk(cfg, int(s), split)
        for (cfg, split), s in zip(plan, np.random.SeedSequence([seed, 3]).generate_state(len(plan)))
    ]


def simulate_dataset(
    preset: str,
    out: str | Path,
    seed: int = 0,
    progress: bool = True,
    corridor_m: float | None = None,
    select: Callable[[list[PlannedWalk]], list[PlannedWalk]] | None = None,
) -> Dataset:
    """Simulate a preset into the dataset folder ``out`` and open it; ``corridor_m``: every walk carries
    a floor plan of corridors that wide along its route (:func:`wearnav.simulate.walk.corridor_plan`);
    ``select``: which of the preset's planned walks to simulate (each as the whole preset would make
    it; the rest are not simulated, and ``made_by`` says how many were)."""
    p = get_preset(preset)
    plan = plan_dataset(p, seed)
    planned = len(plan)
    if select is not None:
        plan = select(plan)
    if corridor_m is not None:
        plan = [dataclasses.replace(w, config=w.config.replace(corridor_m=corridor_m)) for w in plan]
    out = Path(out)
    made_by = {"generator": "wearnav.simulate", "preset": dataclasses.asdict(p), "seed": int(seed)}
    if corridor_m is not None:
        made_by["corridor_m"] = corridor_m
    if select is not None:
        made_by["walks_simulated"] = f"{len(plan)} of {planned}"
    with DatasetWriter(out, made_by) as writer:
        for item in report_progress(plan, desc=f"simulate {p.name}", unit="rec", enabled=progress):
            rec = simulate_walk(item.config, item.seed).recording
            rec.meta.update({"split": item.split, "preset": p.name, "dataset_seed": int(seed)})
            writer.add(rec, split=item.split)
    return Dataset.open(out)


# ---- placement recognition (issue 9: the HAR benchmark's simulated placement task) ------------

# The phone holds a single-placement walk can have (every hold except "call", which the simulator
# only makes inside multi-placement walks).
SINGLE_HOLDS = (("HD", "texting"), ("HD", "swinging"), ("PK", "front_pocket"), ("PK", "back_pocket"), ("BG", "bag"))


def plan_placement_dataset(
    subjects: int = 8, duration_s: tuple[float, float] = (60.0, 90.0), seed: int = 0
) -> list[PlannedWalk]:
    """A placement-recognition dataset: per subject (``u1`` … drawn as in :func:`plan_dataset`, so
    ``u1`` is the same person), one STW walk per single phone hold (:data:`SINGLE_HOLDS`) and one
    PVW walk with multi-placement changes (MP: the holds change with 1–2 s hand moves, "call"
    among them). Phone only. The class of a window is the recording's ``placement`` label track
    (the holds; "transition" between them). No split is written: the benchmark splits by subject
    (:data:`wearnav.train.classify.TEST_SUBJECTS` ``"sim-placement"``)."""
    if subjects < 2:
        raise ConfigError(f"a placement dataset needs at least 2 subjects (train and test), got {subjects}")
    subj_rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
    people = [sample_subject(subj_rng, f"u{i + 1}") for i in range(subjects)]
    rng = np.random.default_rng(np.random.SeedSequence([seed, 4]))
    scenes = list(SCENES)
    configs = []
    for person in people:
        walks = [("STW", placement, hold) for placement, hold in SINGLE_HOLDS] + [("PVW", "MP", None)]
        for mode, placement, hold in walks:
            configs.append(
                WalkConfig(
                    name=f"{person.name}_{mode}_{hold or placement}",
                    subject=person,
                    mode=mode,
                    placement=placement,
                    phone_hold=hold,
                    devices=("phone",),
                    scene=str(rng.choice(scenes)),
                    duration_s=round(float(rng.uniform(*duration_s)), 2),
                    noise_level=str(rng.choice(NOISE_LEVELS)),
                )
            )
    walk_seeds = np.random.SeedSequence([seed, 5]).generate_state(len(configs))
    return [PlannedWalk(cfg, int(s), "") for cfg, s in zip(configs, walk_seeds)]


def simulate_placement_dataset(
    out: str | Path,
    subjects: int = 8,
    duration_s: tuple[float, float] = (60.0, 90.0),
    seed: int = 0,
    progress: bool = False,
) -> Dataset:
    """Simulate :func:`plan_placement_dataset` into the dataset folder ``out`` and open it."""
    plan = plan_placement_dataset(subjects, duration_s, seed)
    made_by = {
        "generator": "wearnav.simulate",
        "dataset": "placement",
        "subjects": int(subjects),
        "duration_s": list(duration_s),
        "seed": int(seed),
    }
    return simulate_plan(plan, out, made_by, progress, meta={"dataset": "placement", "dataset_seed": int(seed)})


# ---- phone-only walking for EasyTrack (paper 004, §V-B) -------------------------------------------

# Phone-only recordings, walking outdoors with the phone in hand, in a trouser pocket or swinging
# (EasyTrack's users "walk freely ... holding a phone"); modes without a watch/earbuds to remove.
PHONE_ONLY_KINDS = (("STW", "HD"), ("STW", "PK"), ("PVW", "MP"), ("DLW", "HD"))


def plan_phone_only(
    level: str,
    km: float,
    seed: int = 0,
    duration_s: tuple[float, float] = (240.0, 420.0),
    test: bool = False,
    n: int | None = None,
) -> list[PlannedWalk]:
    """Phone-only walks at fix-noise ``level`` until about ``km`` of walking (at ~1.3 m/s), or ``n``
    walks; one subject per walk drawn from the seed (the paper's data come from many users).
    ``test``: held-out trajectories (split ``test``), drawn from a separate seed stream."""
    if level not in NOISE_LEVELS:
        raise ConfigError(f"unknown noise level {level!r} (expected one of {', '.join(NOISE_LEVELS)})")
    tag = 2 if test else 1
    rng = np.random.default_rng(np.random.SeedSequence([seed, 40 + tag, NOISE_LEVELS.index(level)]))
    scenes = list(SCENES)
    plan: list[PlannedWalk] = []
    dist = 0.0
    while (n is None and dist < km * 1000.0) or (n is not None and len(plan) < n):
        i = len(plan)
        mode, placement = PHONE_ONLY_KINDS[int(rng.integers(len(PHONE_ONLY_KINDS)))]
        dur = round(float(rng.uniform(*duration_s)), 2)
        cfg = WalkConfig(
            name=f"et{'T' if test else ''}_{level}_{i:04d}",
            subject=sample_subject(rng, f"s{i}"),
            mode=mode,
            placement=placement,
            devices=("phone",),
            scene=str(rng.choice(scenes, p=[0.2, 0.4, 0.4])),
            duration_s=dur,
            noise_level=level,
        )
        plan.append(PlannedWalk(cfg, int(rng.integers(2**31)), "test" if test else "train"))
        dist += 1.3 * dur
    return plan


def simulate_plan(
    plan: list[PlannedWalk], out: str | Path, made_by: dict, progress: bool = True, meta: dict | None = None
) -> Dataset:
    """Simulate planned walks into dataset folder ``out`` (``meta`` added to every recording's)."""
    with DatasetWriter(Path(out), made_by) as writer:
        for item in report_progress(plan, desc="simulate", unit="rec", enabled=progress):
            rec = simulate_walk(item.config, item.seed).recording
            rec.meta.update({"split": item.split, **(meta or {})})
            writer.add(rec, split=item.split)
    return Dataset.open(out)
