"""The EasyTrack benchmark (paper 004, §V; issue #10): learning odometry from phone labels.

Simulator part, per noise level L1/L2/L3: phone-only walking datasets (``plan_phone_only``),
labelled by their own fixes (:mod:`wearnav.fixlabels`); every method of
:mod:`wearnav.train.noisy` is one run folder ``<out>/runs/<level>-<method>-s<seed>-<hash8>``
(complete when ``metrics.json`` exists; a killed run resumes from its ``state.pt`` at the next
epoch). Scored on held-out trajectories (the same for every level, cut from dense truth): ADE
(:func:`wearnav.metrics.ade`, Fig. 3/4) and, integrating the displacements from the true start,
ATE (:func:`wearnav.metrics.ate`, Fig. 7); from the training logs R_τ/R_δ (Fig. 5) and the label
noise of the selected instances (Fig. 6).

Real part (``--data``, a wearnav dataset with phone IMU, fixes and sparse truth such as IPIN 2023
Track 3): training routes are labelled by their own GNSS fixes (the truth is never read for
training); recordings whose name matches ``--test-routes`` are held out. On those, EasyTrack and
BaseModel (same labels, same epochs), PDR and the raw GNSS fixes are scored at the surveyed points
(median, p75 of the horizontal error); the IMU methods start at the first surveyed point, as
:mod:`wearnav.evaluate` does for sparse truth.

The page ``<out>/results.md`` (+ PNGs; :mod:`wearnav.bench.easytrack_page`) is what ``wearnav results``
stitches into docs/results.md.

Decisions: docs/decisions/0009-easytrack-training-loop-and-units.md,
docs/decisions/0014-easytrack-benchmark-findings.md,
docs/decisions/0047-easytrack-amended-and-table-v-power.md (the amended CoAdapt, ``easytrack-amended``).
"""

from __future__ import annotations

import dataclasses
import logging
import re
import time
from pathlib import Path
from typing import Any

import numpy as np

from wearnav import metrics, runs
from wearnav.bench.easytrack_page import PageConfig, write_page
from wearnav.bench.executor import Execution, Job, run_jobs
from wearnav.bench.real_sites import IPIN_TEST_TRIALS
from wearnav.core.timeseries import interp_onto
from wearnav.dataset import Dataset
from wearnav.errors import ConfigError, ValidationError, check_names
from wearnav.evaluate import SPARSE_MAX_GAP, predict_sequence
from wearnav.fixlabels import LabelConfig, Segments, aligned_phone, label_dataset
from wearnav.models.registry import build
from wearnav.simulate.presets import plan_phone_only, simulate_plan
from wearnav.train.noisy import METHODS, NoisyConfig, fit_noisy, load_predictor, write_history
from wearnav.trajectory import integrate_velocity
from wearnav.trust import QUICK_NOTE

LEVELS = ("L1", "L2", "L3")
MAIN = ("easytrack", "easytrack-amended", "coteaching", "aux", "basemodel", "basemodel-gt", "ionet", "ronin")
ABLATION = ("nocnal", "nocoadapt")
# held-out routes: the recordings of real-odometry's IPIN test trials (04/24/52, recording names
# IPIN2023_T3_TrainingTrial04_repetition01 ...); trials 01/02 (simulator calibration) train only
IPIN_TEST_ROUTES = r"Trial(" + "|".join(f"{t:02d}" for t in IPIN_TEST_TRIALS) + r")_"
IPIN_METHODS = ("easytrack", "basemodel")

log = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class BenchConfig:
    km: float = 3.0  # training walking per level
    test_walks: int = 5  # the paper tests on five trajectories
    test_duration_s: tuple[float, float] = (120.0, 180.0)
    ae_epochs: int = 5
    pre_epochs: int = 5
    joint_epochs: int = 30
    stride_s: float | None = None  # overlapping segments (fixlabels.LabelConfig.stride_s); None: back to back
    loss: str = "mse"  # every method's loss on the displacements (NoisyConfig.loss: "mse" as the paper, or "polar")
    sim_seed: int = 0
    levels: tuple[str, ...] = LEVELS
    methods: tuple[str, ...] = MAIN + ABLATION
    l1_only: tuple[str, ...] = ("ionet", "ronin")  # Fig. 7 trains them on L1 only: not run at L2/L3

    def __post_init__(self) -> None:  # before any walk is simulated
        check_names(self.levels, LEVELS, "noise level")
        check_names(self.methods, METHODS, "method")

    def noisy(self, method: str, seed: int) -> NoisyConfig:
        """The training config of one run of ``method`` with ``seed``."""
        return NoisyConfig(
            method=method,
            seed=seed,
            ae_epochs=self.ae_epochs,
            pre_epochs=self.pre_epochs,
            joint_epochs=self.joint_epochs,
            loss=self.loss,
        )

    @classmethod
    def quick(cls) -> BenchConfig:
        return cls(
            km=0.25,
            test_walks=1,
            test_duration_s=(40.0, 50.0),
            ae_epochs=1,
            pre_epochs=1,
            joint_epochs=2,
            levels=("L1",),
            methods=("easytrack", "easytrack-amended", "basemodel", "coteaching", "aux", "basemodel-gt"),
            l1_only=(),
        )


# ---- data -----------------------------------------------------------------------------------------


def _dataset(path: Path, plan, echo) -> Dataset:

    if (path / "manifest.csv").is_file():
        return Dataset.open(path)
    echo(f"simulating {len(plan)} walks → {path}")
    return simulate_plan(plan, path, {"generator": "wearnav.simulate (plan_phone_only)"}, progress=False)


def _caches(out: Path, bc: BenchConfig, lc: LabelConfig) -> tuple[dict[str, Path], Path]:
    """The labelled segments' files: training per level, and the test set."""
    data, tag = out / "data", runs.config_hash(dataclasses.asdict(lc))
    train = {level: data / f"{level}_km{bc.km:g}_s{bc.sim_seed}_{tag}_train.npz" for level in bc.levels}
    return train, data / f"test_n{bc.test_walks}_s{bc.sim_seed}_{tag}.npz"


def sim_segment_files(out: Path, bc: BenchConfig, lc: LabelConfig, echo=print) -> tuple[dict[str, Path], Path]:
    """The files of the phone-labelled training segments per level and of the truth-labelled test
    segments, simulated and labelled the first time they are asked for."""
    data = out / "data"
    caches, test_cache = _caches(out, bc, lc)
    for level, cache in caches.items():
        if not cache.is_file():
            ds = _dataset(
                data / f"sim_{level}_km{bc.km:g}_s{bc.sim_seed}", plan_phone_only(level, bc.km, bc.sim_seed), echo
            )
            label_dataset(ds, lc).save(cache)
    if not test_cache.is_file():
        plan = plan_phone_only("L1", 0.0, bc.sim_seed, bc.test_duration_s, test=True, n=bc.test_walks)
        ds = _dataset(data / f"sim_test_n{bc.test_walks}_s{bc.sim_seed}", plan, echo)
        label_dataset(ds, lc, from_truth=True).save(test_cache)
    return caches, test_cache


def sim_segments(out: Path, bc: BenchConfig, lc: LabelConfig, echo=print) -> tuple[dict[str, Segments], Segments]:
    """Phone-labelled training segments per level and truth-labelled test segments (cached)."""
    caches, test_cache = sim_segment_files(out, bc, lc, echo)
    return {level: Segments.load(cache) for level, cache in caches.items()}, Segments.load(test_cache)


# ---- runs -----------------------------------------------------------------------------------------


def _ate_rows(predict, test: Segments) -> list[dict]:
    rows = []
    for k, name in enumerate(test.names):
        idx = np.flatnonzero(test.traj == k)
        if idx.size < 2:
            continue
        d = predict(test.x[idx])
        nodes = np.concatenate([test.node0[idx[:1]], test.node1[idx]])
        true = test.node_pos[nodes]
        est = np.vstack([true[:1], true[:1] + np.cumsum(d, axis=0)])
        rows.append(
            {
                "name": name,
                "ate": metrics.ate(test.node_t[nodes], est, true),
                "length_m": float(np.sum(np.linalg.norm(np.diff(true, axis=0), axis=1))),
            }
        )
    return rows


def run_one(cfg: NoisyConfig, train: Segments, test: Segments | None, folder: Path, record: dict) -> dict:
    """Train (or resume) and score one run folder; returns its metrics."""
    if runs.is_complete(folder):
        return runs.read_metrics(folder)
    folder.mkdir(parents=True, exist_ok=True)
    runs.write_config(folder, record)
    t0 = time.perf_counter()
    monitor = None
    if test is not None and len(test):

        def monitor(predict):
            return {
                "test_ade_m": metrics.ade(
                    np.concatenate([predict(test.x[i : i + 2048]) for i in range(0, len(test), 2048)]), test.truth
                )
            }

    tr = fit_noisy(cfg, train, folder, monitor=monitor)
    write_history(folder, tr)
    predict = load_predictor(cfg, folder, train.x.shape[1])
    m = {
        "method": cfg.method,
        "seed": cfg.seed,
        **{k: v for k, v in record.items() if k != "noisy"},
        "training": {k: v for k, v in tr.items() if k != "history"},
    }
    if test is not None and len(test):
        pred = predict(test.x)
        m["ade_m"] = metrics.ade(pred, test.truth)
        m["ate"] = _ate_rows(predict, test)
        m["ate_mean_m"] = float(np.mean([r["ate"] for r in m["ate"]])) if m["ate"] else None
        # did it learn: against standing still (zero displacement per segment) on the same segments
        m["trivial_ade_m"] = metrics.ade(np.zeros_like(test.truth), test.truth)
        # does it walk slow (issue 59: small-loss selection that keeps short segments teaches so)?
        m["length_ratio"] = float(np.linalg.norm(pred, axis=1).sum() / np.linalg.norm(test.truth, axis=1).sum())
        m["beats_trivial"] = bool(m["ade_m"] < m["trivial_ade_m"])
    runs.write_metrics(folder, m)
    score = f"ADE {m['ade_m']:.3f} m" if "ade_m" in m else "trained"
    log.info(f"{folder.name}: {score}, {tr['s_per_epoch']:.2f} s/epoch, {time.perf_counter() - t0:.0f} s")
    return m


@dataclasses.dataclass(frozen=True)
class EasyJob:
    """One run: ``cfg`` trained on the segments in file ``train``, scored on those in ``test``."""

    cfg: NoisyConfig
    train: Path
    test: Path | None
    record: dict


def run_job(job: EasyJob, folder: Path) -> Path:
    """An executor job: :func:`run_one` on the segments the job names."""
    run_one(job.cfg, Segments.load(job.train), Segments.load(job.test) if job.test else None, folder, job.record)
    return folder


# ---- real data (IPIN 2023 or any dataset with fixes and sparse truth) -----------------------------


def _scores(err: np.ndarray) -> dict:
    return {
        "points": int(err.size),
        "median_m": float(np.median(err)) if err.size else None,
        "p75_m": float(np.percentile(err, 75)) if err.size else None,
        "mean_m": float(np.mean(err)) if err.size else None,
    }


def route_pattern(text: str) -> re.Pattern:
    """``--test-routes`` compiled; a malformed regular expression is a ConfigError."""
    try:
        return re.compile(text)
    except (re.error, RecursionError, OverflowError) as exc:
        raise ConfigError(f"--test-routes {text!r} is not a regular expression ({exc})") from None


@dataclasses.dataclass
class RealPlan:
    """The real part's runs (``jobs``) and what scoring them needs."""

    data: Path
    test_routes: str
    train_names: list[str]
    test_names: list[str]
    train: Segments
    jobs: list[Job]


def real_part(
    data: Path,
    out: Path,
    bc: BenchConfig,
    lc: LabelConfig,
    test_routes: str | None,
    seeds: int,
    echo=print,
    execution: Execution = Execution(),
) -> dict:
    """Train on the training routes' GNSS labels, score at the surveyed points of the test routes.

    ``test_routes``: a regex on recording names; None: the dataset's ``test`` split where it has
    one, else :data:`IPIN_TEST_ROUTES`."""
    plan = real_plan(data, out, bc, lc, test_routes, seeds, echo)
    run_jobs(plan.jobs, execution, echo)
    return real_scores(plan, out, lc)


def real_plan(
    data: Path, out: Path, bc: BenchConfig, lc: LabelConfig, test_routes: str | None, seeds: int, echo=print
) -> RealPlan:
    """The real part's training labels (cached) and one job per method × seed."""

    ds = Dataset.open(data)
    names = list(ds.names)
    if test_routes is None and (ds.manifest["split"].astype(str) == "test").any():
        test_routes = "split:test"
        test_names = ds.manifest.loc[ds.manifest["split"].astype(str) == "test", "name"].tolist()
    else:
        test_routes = test_routes or IPIN_TEST_ROUTES
        pat = route_pattern(test_routes)
        test_names = [n for n in names if pat.search(n)]
    train_names = [n for n in names if n not in set(test_names)]
    if not test_names or not train_names:
        raise ValidationError(
            f"--test-routes {test_routes!r} must match some recordings and leave some for training", data
        )
    rdir = out / "real"
    cache = (
        rdir
        / f"train_{runs.config_hash({'d': str(Path(data).resolve()), 'r': test_routes, 'l': dataclasses.asdict(lc)})}.npz"
    )
    if not cache.is_file():
        view = ds._view(ds.manifest["name"].isin(train_names))
        label_dataset(view, lc).save(cache)
    train = Segments.load(cache)
    echo(
        f"real: {len(train)} GNSS-labelled segments from {len(train.names)} training routes; "
        f"{len(test_names)} test routes"
    )
    jobs = []
    for method in IPIN_METHODS:
        for seed in range(seeds):
            cfg = bc.noisy(method, seed)
            record = {
                "noisy": cfg.record(),
                "data": str(Path(data).resolve()),
                "test_routes": test_routes,
                "labels": dataclasses.asdict(lc),
                "part": "real",
            }
            folder = runs.run_dir(rdir / "runs", f"{method}-s{seed}", record)
            jobs.append(Job(run_job, EasyJob(cfg, cache, None, record), folder))
    return RealPlan(Path(data), test_routes, train_names, test_names, train, jobs)


def real_scores(plan: RealPlan, out: Path, lc: LabelConfig) -> dict:
    """Score the real part's trained runs, PDR and the raw fixes at the test routes' surveyed points."""

    ds, train, test_names, train_names = Dataset.open(plan.data), plan.train, plan.test_names, plan.train_names
    preds: dict[str, list] = {}
    for job in plan.jobs:
        preds.setdefault(job.config.cfg.method, []).append(load_predictor(job.config.cfg, job.folder, train.x.shape[1]))
    N = lc.samples
    pdr_window = int(round(4 * lc.rate))
    pdr = build("pdr", n_devices=1, window=pdr_window, rate=lc.rate)
    errs: dict[tuple, list] = {}  # (protocol, method, seed) → error arrays per route
    per_route = []
    for name in test_names:
        rec = ds.load(name)
        if rec.truth is None or len(rec.truth) < 2:
            continue
        seq = aligned_phone(rec, lc)
        tt, tp = rec.truth.t, rec.truth.pos[:, :2]
        inside = np.flatnonzero((tt >= seq.t[0]) & (tt <= seq.t[-1] - N / lc.rate))
        if inside.size < 2:
            continue
        s0 = int(np.searchsorted(seq.t, tt[inside[0]]))
        starts = np.arange(s0, seq.t.size - N, N)
        x = np.stack([seq.imu[0, s : s + N] for s in starts]).astype(np.float32)
        t_nodes = np.concatenate([seq.t[starts], [seq.t[starts[-1] + N]]])
        ref_t, ref_p = tt[inside[1:]], tp[inside[1:]]
        if rec.fixes is None or len(rec.fixes) < 2:
            continue  # the user protocol starts from the phone's own fix
        own, _ = interp_onto(tt[inside[:1]], rec.fixes.t, rec.fixes.pos[:, :2], max_gap=np.inf)
        starts_at = {"user": own[0], "known": tp[inside[0]]}
        row = {"route": name, "points": int(ref_t.size)}
        for method, fns in preds.items():
            for k, f in enumerate(fns):
                d = f(x)
                for proto, p0 in starts_at.items():
                    est = np.vstack([p0, p0 + np.cumsum(d, axis=0)])
                    errs.setdefault((proto, method, k), []).append(
                        metrics.errors_at_reference(t_nodes, est, ref_t, ref_p, SPARSE_MAX_GAP)
                    )
            row[method] = float(np.median(np.concatenate([errs[("user", method, k)][-1] for k in range(len(fns))])))
        t_c, vel, _ = predict_sequence(pdr, dataclasses.replace(seq, pos=None), pdr_window, int(round(lc.rate)))
        t_int = seq.t[seq.t >= tt[inside[0]]]
        for proto, p0 in starts_at.items():
            est = integrate_velocity(t_c, vel, t_int, p0)
            errs.setdefault((proto, "pdr", 0), []).append(
                metrics.errors_at_reference(t_int, est, ref_t, ref_p, SPARSE_MAX_GAP)
            )
        row["pdr"] = float(np.median(errs[("user", "pdr", 0)][-1]))
        e = metrics.errors_at_reference(rec.fixes.t, rec.fixes.pos, ref_t, ref_p, metrics.FIX_MAX_GAP_S)
        for proto in starts_at:
            errs.setdefault((proto, "gnss", 0), []).append(e)
        row["gnss"] = float(np.median(e)) if e.size else None
        per_route.append(row)
    summary: dict[str, dict[str, Any]] = {proto: {} for proto in ("user", "known")}
    for proto in summary:
        for method in (*IPIN_METHODS, "pdr", "gnss"):
            per_seed = [np.concatenate(v) for (p, m, _), v in sorted(errs.items()) if p == proto and m == method and v]
            if per_seed:
                summary[proto][method] = {
                    **_scores(np.concatenate(per_seed)),
                    "seed_medians_m": [float(np.median(e)) for e in per_seed if e.size],
                }
    doc = {
        "methods": list(IPIN_METHODS),
        "train_routes": train_names,
        "test_routes": test_names,
        "segments": len(train),
        "train_label_km": round(float(np.sum(np.linalg.norm(train.label, axis=1))) / 1000, 2),
        "summary": summary,
        "per_route": per_route,
    }
    runs.write_json(out / "real" / "real.json", doc)
    return doc


def run_benchmark(
    out: str | Path,
    quick: bool = False,
    seeds: int = 1,
    execution: Execution = Execution(),
    data: str | Path | None = None,
    test_routes: str | None = None,
    bc: BenchConfig | None = None,
    echo=print,
) -> Path:
    out = Path(out)
    bc = bc or (BenchConfig.quick() if quick else BenchConfig())
    if quick:
        echo(f"--quick: {QUICK_NOTE} (tiny data, 1–2 epochs per phase)")
    lc = LabelConfig(stride_s=bc.stride_s)
    plan = real_plan(Path(data), out, bc, lc, test_routes, seeds, echo) if data else None
    caches, test_cache = sim_segment_files(out, bc, lc, echo)
    todo = _todo(out, bc, seeds, lc)
    jobs = [
        Job(run_job, EasyJob(cfg, caches[level], test_cache, record), folder) for cfg, level, folder, record in todo
    ]
    run_jobs((plan.jobs if plan else []) + jobs, execution, echo)  # one pool: real and simulator runs side by side
    real = real_scores(plan, out, lc) if plan else None
    sim = [{**runs.read_metrics(job.folder), "folder": str(job.folder)} for job in jobs]
    train, test = sim_segments(out, bc, lc, echo)
    return write_page(out, PageConfig.of(bc), lc, sim, train, test, real, seeds, quick)


def _todo(out: Path, bc: BenchConfig, seeds: int, lc: LabelConfig) -> list[tuple]:
    """(config, level, folder, record) of every simulator run, seed by seed (an interrupted suite has
    whole seeds of every cell first)."""
    res = []
    for seed in range(seeds):
        for level in bc.levels:
            for method in bc.methods:
                if level != "L1" and method in bc.l1_only:
                    continue
                cfg = bc.noisy(method, seed)
                record = {
                    "noisy": cfg.record(),
                    "level": level,
                    "km": bc.km,
                    "sim_seed": bc.sim_seed,
                    "test_walks": bc.test_walks,
                    "labels": dataclasses.asdict(lc),
                    "part": "sim",
                }
                res.append((cfg, level, runs.run_dir(out / "runs", f"{level}-{method}-s{seed}", record), record))
    return res
