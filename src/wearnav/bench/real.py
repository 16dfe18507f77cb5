"""Odometry measured in real buildings: `wearnav bench real-odometry` (issue 8 §3, issue 11 §3).

Real indoor recordings have no dense truth, only surveyed points: ILC2's waypoints (phone held
flat in front) and IPIN 2023's POSI points (hand-held phone, with the phone's own GNSS fixes).
The benchmark

1. **splits by place, not by trace.** A dataset's recordings are grouped by a meta key (ILC2: the
   floor; IPIN: the route, i.e. the trial whose repetitions walk the same path); the named test
   groups are held out entirely, the rest is training, one recording in five of it (by a hash of
   its name) validation. Defaults avoid what the simulator was calibrated on (ILC2 floor F1, IPIN
   trials 01–02: :mod:`wearnav.realism`), which may be trained on but never tested on.
2. **joins the surveyed points by straight lines** for the training targets (the competitions'
   own assumption between waypoints; truth is interpolated across gaps up to
   ``TRUTH_MAX_GAP_S``). Evaluation uses the surveyed points only: each test trace starts at
   its first point and is scored at every later one (:func:`wearnav.evaluate.evaluate_sequence`).
3. **estimates one yaw per site from its training traces.** The phone's rotation vector refers to
   magnetic north, the truth to a floor plan (ILC2) or to geographic east/north (IPIN): the two differ
   by a constant yaw per site. :func:`wearnav.bench.real_sites.site_yaw` takes it from the training
   traces only, with PDR (not learned): the angle of Σ d_pdr · conj(d_truth) over all segments between
   consecutive surveyed points (a 2-D Procrustes fit), which turns every model's input into the truth
   frame. PDR's own heading bias goes into that angle; a learned model trained under it
   absorbs any constant yaw left over (a constant rotation commutes with the yaw augmentation).
   A learned model scored where it did not train under that angle gets its own estimate, the
   same fit of *its* paths on the site's training traces (:meth:`RealEval.yaw`), as does every
   model that is not learned.
4. **transfers to another building** with ``test_data``: the same import and grouping; the
   models trained on ``data`` are scored on its test groups, with its yaw estimated from its own
   training groups (which are used for nothing else).
5. **puts the phone's own fixes beside the models** where the data has them (IPIN): the raw
   GNSS error at the same surveyed points (nearest fix within ``metrics.FIX_MAX_GAP_S``).
6. **scores the path a user gets** where the data has fixes (issue 25): the user protocol of
   :mod:`wearnav.bench.user_protocol` (no start point, no site yaw; the path placed on the
   recording's own fixes by first-fix anchoring, a rigid fit, or the smoother), beside the
   known-start protocol of steps 2–3, which is named as such in the report. Each model's
   smoother is calibrated where it is used (:func:`wearnav.bench.user_protocol.site_calibration`:
   the odometry's random walk and the σ scale), stored in its run folder.

Steps 1, 3 and 5 live in :mod:`wearnav.bench.real_sites`, the page in :mod:`wearnav.bench.real_page`;
this module runs the suite.

Optionally ``train_data`` (a simulated dataset) trains the learned models instead of the real
training floors: the sim-to-real test of issue 11. Everything is a run folder; complete runs
are skipped, so the benchmark resumes. Decisions: docs/decisions/0010-real-buildings-splits-and-site-yaw.md,
docs/decisions/0032-sim-only-transfers-best.md.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any, TypedDict

from wearnav import runs
from wearnav.bench.executor import Execution, Job, run_jobs
from wearnav.bench.map_eval import has_plans, map_aware_eval, map_dir
from wearnav.bench.real_page import VARIANTS, suite_runs, write_report
from wearnav.bench.real_sites import TRUTH_MAX_GAP_S, estimate_site_yaw, fix_errors, prepare_data
from wearnav.core.textio import read_json
from wearnav.errors import ConfigError
from wearnav.evaluate import evaluate_run
from wearnav.models.registry import check_models, get
from wearnav.preprocess import augment as augmentations
from wearnav.preprocess import check_speed_warp
from wearnav.pretrained.mix import MIX_FRAME, is_mix
from wearnav.recording import CANONICAL_DEVICES
from wearnav.train.odometry import (
    POINTING_SPEEDS,
    SPEED_SOURCES,
    TrainConfig,
    fit,
    prepare_run,
    run_hash_exclude,
    run_record,
)

DEFAULT_MODELS = ("ronin", "suitein++", "pdr")


# ---- the suite ----------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class RealBench:
    """What decides a real-building benchmark (saved with its results)."""

    models: tuple[str, ...] = DEFAULT_MODELS
    epochs: int = 100
    patience: int = 10
    max_minutes: float | None = None
    seed: int = 0
    lr: float | None = 1e-3  # as the simulator comparison (`wearnav bench odometry --lr 1e-3`); None: paper values
    window: int = 100
    stride: int = 10
    train_data: str | None = None  # a simulated dataset or a mix (wearnav.pretrained.mix) to train on instead
    augment: tuple[str, ...] = ("rotate_yaw",)  # the learned models' batch augmentations (wearnav.preprocess.augment)
    vel_loss: str = "mse"  # the learned models' velocity loss (wearnav.models.base.velocity_loss)
    # the learned models' windows in the phone's heading frame (PreprocessConfig.heading_frame; issue
    # 34), without the random yaw of ``augment``
    heading_frame: bool = False
    speed_warp: tuple[float, ...] = ()  # the learned models' training also played this much faster (TrainConfig)
    # the learned models' devices: the real walks carry the phone alone, so any other device is
    # absent (masked) where they are scored; more than the phone only with simulated ``train_data``
    devices: tuple[str, ...] = ("phone",)

    def __post_init__(self) -> None:
        check_models(self.models, "odometry")
        check_speed_warp(self.speed_warp)  # before any data is prepared
        for name in self.augment:
            augmentations.get(name)  # an unknown one: one line now, not at the first training batch
        if set(self.devices) - set(CANONICAL_DEVICES) or len(set(self.devices)) < len(self.devices):
            raise ConfigError(f"devices {'+'.join(self.devices)}: each of {', '.join(CANONICAL_DEVICES)} at most once")
        if "phone" not in self.devices or (self.devices != ("phone",) and self.train_data is None):
            raise ConfigError(
                f"devices {'+'.join(self.devices)}: the real walks carry the phone alone; "
                "more devices than the phone only with a simulated train_data"
            )


def _train_config(model: str, data: str, yaw: float, bench: RealBench, elsewhere: bool):
    kw: dict[str, Any] = dict(
        model=model,
        data=data,
        devices=bench.devices if get(model).learned else ("phone",),
        epochs=bench.epochs,
        patience=bench.patience,
        max_minutes=bench.max_minutes,
        seed=bench.seed,
        window=bench.window,
        stride=bench.stride,
        lr=bench.lr,
        augment=bench.augment,
        vel_loss=bench.vel_loss,
    )
    if bench.heading_frame and get(model).learned:
        kw.update(heading_frame=True, augment=tuple(a for a in bench.augment if a != "rotate_yaw"))
    if bench.speed_warp and get(model).learned:
        kw.update(speed_warp=bench.speed_warp)
    if elsewhere and is_mix(data):  # several sources, truth turned into each input's common frame
        return TrainConfig(**kw, frame_align=MIX_FRAME, truth_max_gap=TRUTH_MAX_GAP_S)
    if elsewhere:  # the simulator's own truth frame and dense truth
        return TrainConfig(**kw)
    return TrainConfig(**kw, frame_align="none", truth_max_gap=TRUTH_MAX_GAP_S, yaw_deg=yaw)


class PlanPlace(TypedDict, total=False):
    """Where a suite's data come from and what it holds out (:func:`plan_benchmark`'s keywords)."""

    test_data: Path | None
    fmt: str | None
    test_fmt: str | None
    group_by: str | None
    test_groups: tuple[str, ...] | None
    test_group_by: str | None
    test_test_groups: tuple[str, ...] | None


@dataclasses.dataclass(frozen=True)
class RealEval:
    """Where a trained model is scored: a site's prepared ``data``, its yaw (PDR's), the output
    folder; ``own_yaw``: turn the input by the model's own estimate of the site's yaw instead."""

    data: str
    yaw_deg: float
    out_dir: Path
    own_yaw: bool = False
    plans: bool = False  # the site's recordings carry floor plans: score the map-aware path too

    def yaw(self, run: Path, speed: str = "model") -> float:
        """The yaw the test input is turned by: PDR's, or the model's own (module docstring, step 3),
        estimated once on the site's training traces and kept beside the evaluation. A path along
        where the phone points (``speed`` "pointing", or "snapped" onto it) always takes its own, as
        ``pdr-pointing`` does: the heading frame's windows do not depend on the yaw, so what the model
        learned under PDR's is its speed only."""
        if not self.own_yaw and speed not in POINTING_SPEEDS:
            return self.yaw_deg
        f = run / f"site_yaw_{variant_dir(self.out_dir, speed).name}.json"
        if not f.is_file():
            runs.write_json(f, {**estimate_site_yaw(Path(self.data), run=run, speed=speed), "data": self.data})
        return float(read_json(f)["yaw_deg"])


@dataclasses.dataclass(frozen=True)
class RealJob:
    cfg: TrainConfig
    evals: tuple[RealEval, ...]
    progress: bool = False


def run_job(job: RealJob, run: Path) -> Path:
    """Train one model (or resume) and score it on every site's test traces (an executor job)."""
    prepare_run(job.cfg, run)
    training = fit(job.cfg, run, progress=job.progress)
    for e in job.evals:
        for speed in scored_as(job.cfg):
            out_dir = variant_dir(e.out_dir, speed)
            if runs.is_complete(out_dir) and (not e.plans or runs.is_complete(map_dir(out_dir))):
                continue  # scored by an earlier run of the suite (a resumed one that adds a path)
            pre = {"frame_align": "none", "truth_max_gap": TRUTH_MAX_GAP_S, "yaw_deg": e.yaw(run, speed)}
            evaluate_run(
                run,
                data=e.data,
                splits=("test",),
                progress=job.progress,
                training=training,
                preprocess=pre,
                out_dir=out_dir,
                speed=speed,
            )
            if e.plans:  # the same paths placed on the building's floor plans (issue 36)
                map_aware_eval(out_dir, e.data, progress=job.progress)
    return run


def scored_as(cfg: TrainConfig) -> tuple[str, ...]:
    """Where the speeds of a model's scored paths come from (issue 34; ``load_model``'s ``speed``):
    as trained; a learned model also as the hybrids with PDR's speed (0.67-m steps, and steps as
    long as the cadence makes them), and one in the heading frame also as its speed along where the
    phone points and as the cadence hybrid turned onto the phone's pointing where near it."""
    if not get(cfg.model).learned:
        return ("model",)
    return tuple(s for s in SPEED_SOURCES if cfg.heading_frame or s not in POINTING_SPEEDS)


def variant_dir(eval_dir: Path, speed: str) -> Path:
    """Where a model's evaluation with the speed source ``speed`` goes, beside its own ``eval_<site>``."""
    return eval_dir.with_name(eval_dir.name + VARIANTS[speed][0])


@dataclasses.dataclass
class Plan:
    """A real-building suite ready to run: its folder, sites (data, split, yaw, fixes), jobs."""

    out: Path
    sites: dict
    jobs: list
    bench: RealBench
    t_start: float

    def finish(self) -> Path:
        """Write results.md once the jobs have run (:func:`write_report`)."""
        wall = time.perf_counter() - self.t_start
        return write_report(
            self.out, self.sites, suite_runs(self.out, self.sites["main"]["data"]), dataclasses.asdict(self.bench), wall
        )


def plan_benchmark(
    data: Path,
    out: Path,
    test_data: Path | None = None,
    fmt: str | None = None,
    test_fmt: str | None = None,
    group_by: str | None = None,
    test_groups=None,
    test_group_by: str | None = None,
    test_test_groups=None,
    bench: RealBench = RealBench(),
    progress: bool = True,
    echo=print,
    in_process: bool = True,
) -> Plan:
    """Prepare the data, estimate the site yaws and list a job per model (:func:`run_job`)."""
    out = Path(out)
    t_start = time.perf_counter()
    sites: dict[str, dict[str, Any]] = {}
    main, info = prepare_data(data, out / "data" / "main", fmt, group_by, test_groups, progress)
    sites["main"] = {"data": str(main), "split": info}
    if test_data is not None:
        other, oinfo = prepare_data(
            test_data, out / "data" / "other", test_fmt, test_group_by, test_test_groups, progress
        )
        sites["other"] = {"data": str(other), "split": oinfo}
    for name, site in sites.items():
        cached = out / "data" / name / "site_yaw.json"
        if not cached.is_file():
            echo(f"{name}: estimating the site's yaw from its training traces (PDR) ...")
            runs.write_json(cached, estimate_site_yaw(Path(site["data"]), progress=progress))
        site["yaw"] = read_json(cached)
        echo(f"{name}: site yaw {site['yaw']['yaw_deg']:+.1f}° from {site['yaw']['segments']} segments")
        site["fixes"] = fix_errors(Path(site["data"]))
        site["plans"] = has_plans(site["data"])
    yaw = sites["main"]["yaw"]["yaw_deg"]
    jobs = []
    for model in bench.models:
        elsewhere = bool(bench.train_data) and get(model).learned
        cfg = _train_config(
            model, bench.train_data if elsewhere and bench.train_data else str(main), yaw, bench, elsewhere
        )
        run = runs.run_dir(out / "runs", model, run_hash_exclude(run_record(cfg)))
        # PDR's estimate of the site's yaw is PDR's heading bias (it differs by building: 18° at
        # ILC2), so only PDR and a model trained under it there take it; any other is given its own
        evals = tuple(
            RealEval(
                site["data"],
                site["yaw"]["yaw_deg"],
                run / f"eval_{s}",
                own_yaw=(elsewhere or s != "main") if get(model).learned else model != "pdr",
                plans=site["plans"],
            )
            for s, site in sites.items()
        )
        scored = [(variant_dir(e.out_dir, speed), e) for speed in scored_as(cfg) for e in evals]
        marks = tuple(d for d, _ in scored) + tuple(map_dir(d) for d, e in scored if e.plans)
        jobs.append(Job(run_job, RealJob(cfg, evals, progress and in_process), run, marks=marks))
    return Plan(out, sites, jobs, bench, t_start)


def run_benchmark(
    data: Path,
    out: Path,
    test_data: Path | None = None,
    fmt: str | None = None,
    test_fmt: str | None = None,
    group_by: str | None = None,
    test_groups=None,
    test_group_by: str | None = None,
    test_test_groups=None,
    bench: RealBench = RealBench(),
    progress: bool = True,
    echo=print,
    execution: Execution = Execution(),
) -> Path:
    """Prepare the data, estimate the site yaws, train/evaluate every model (as ``execution``
    says, :mod:`.executor`), write results.md."""
    plan = plan_benchmark(
        data,
        out,
        test_data,
        fmt,
        test_fmt,
        group_by,
        test_groups,
        test_group_by,
        test_test_groups,
        bench,
        progress,
        echo,
        execution.in_process,
    )
    run_jobs(plan.jobs, execution, echo)
    return plan.finish()
