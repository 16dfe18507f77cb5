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

The page ``<out>/results.md`` (+ PNGs) is what ``wearnav results`` stitches into docs/results.md.
"""

from __future__ import annotations

import dataclasses
import logging
import platform
import re
import time
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import metrics, runs
from wearnav.bench.executor import Execution, Job, run_jobs
from wearnav.bench.real import IPIN_TEST_TRIALS
from wearnav.errors import ConfigError, ValidationError, check_names
from wearnav.fileio import write_text_atomic
from wearnav.dataset import Dataset
from wearnav.evaluate import SPARSE_MAX_GAP, predict_sequence
from wearnav.fixlabels import LabelConfig, Segments, aligned_phone, label_dataset, noise_summary
from wearnav.models.registry import build
from wearnav.provenance import provenance
from wearnav.report.plots import plot_ecdf, save
from wearnav.simulate.presets import plan_phone_only, simulate_plan
from wearnav.textio import read_json
from wearnav.train.noisy import METHODS, NoisyConfig, fit_noisy, load_predictor, write_history
from wearnav.stats import welch_p
from wearnav.timeseries import interp_onto
from wearnav.trajectory import integrate_velocity
from wearnav.trust import QUICK_NOTE

LEVELS = ("L1", "L2", "L3")
MAIN = ("easytrack", "coteaching", "aux", "basemodel", "basemodel-gt", "ionet", "ronin")
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
    sim_seed: int = 0
    levels: tuple[str, ...] = LEVELS
    methods: tuple[str, ...] = MAIN + ABLATION
    l1_only: tuple[str, ...] = ("ionet", "ronin")  # Fig. 7 trains them on L1 only: not run at L2/L3

    def __post_init__(self) -> None:  # before any walk is simulated
        check_names(self.levels, LEVELS, "noise level")
        check_names(self.methods, METHODS, "method")

    @classmethod
    def quick(cls) -> "BenchConfig":
        return cls(km=0.25, test_walks=1, test_duration_s=(40.0, 50.0), ae_epochs=1, pre_epochs=1, joint_epochs=2,
                   levels=("L1",), methods=("easytrack", "basemodel", "coteaching", "aux", "basemodel-gt"), l1_only=())


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


def sim_segments(out: Path, bc: BenchConfig, lc: LabelConfig, echo=print) -> tuple[dict[str, Segments], Segments]:
    """Phone-labelled training segments per level and truth-labelled test segments (cached)."""

    data = out / "data"
    caches, test_cache = _caches(out, bc, lc)
    train = {}
    for level, cache in caches.items():
        if not cache.is_file():
            ds = _dataset(data / f"sim_{level}_km{bc.km:g}_s{bc.sim_seed}", plan_phone_only(level, bc.km, bc.sim_seed), echo)
            label_dataset(ds, lc).save(cache)
        train[level] = Segments.load(cache)
    if not test_cache.is_file():
        plan = plan_phone_only("L1", 0.0, bc.sim_seed, bc.test_duration_s, test=True, n=bc.test_walks)
        ds = _dataset(data / f"sim_test_n{bc.test_walks}_s{bc.sim_seed}", plan, echo)
        label_dataset(ds, lc, from_truth=True).save(test_cache)
    return train, Segments.load(test_cache)


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
        rows.append({"name": name, "ate": metrics.ate(test.node_t[nodes], est, true),
                     "length_m": float(np.sum(np.linalg.norm(np.diff(true, axis=0), axis=1)))})
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
            return {"test_ade_m": metrics.ade(np.concatenate([predict(test.x[i:i + 2048])
                                                              for i in range(0, len(test), 2048)]), test.truth)}
    tr = fit_noisy(cfg, train, folder, monitor=monitor)
    write_history(folder, tr)
    predict = load_predictor(cfg, folder, train.x.shape[1])
    m = {"method": cfg.method, "seed": cfg.seed, **{k: v for k, v in record.items() if k != "noisy"},
         "training": {k: v for k, v in tr.items() if k != "history"}}
    if test is not None and len(test):
        m["ade_m"] = metrics.ade(predict(test.x), test.truth)
        m["ate"] = _ate_rows(predict, test)
        m["ate_mean_m"] = float(np.mean([r["ate"] for r in m["ate"]])) if m["ate"] else None
        # did it learn: against standing still (zero displacement per segment) on the same segments
        m["trivial_ade_m"] = metrics.ade(np.zeros_like(test.truth), test.truth)
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
    return {"points": int(err.size), "median_m": float(np.median(err)) if err.size else None,
            "p75_m": float(np.percentile(err, 75)) if err.size else None,
            "mean_m": float(np.mean(err)) if err.size else None}


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


def real_part(data: Path, out: Path, bc: BenchConfig, lc: LabelConfig, test_routes: str | None, seeds: int,
              echo=print, execution: Execution = Execution()) -> dict:
    """Train on the training routes' GNSS labels, score at the surveyed points of the test routes.

    ``test_routes``: a regex on recording names; None: the dataset's ``test`` split where it has
    one, else :data:`IPIN_TEST_ROUTES`."""
    plan = real_plan(data, out, bc, lc, test_routes, seeds, echo)
    run_jobs(plan.jobs, execution, echo)
    return real_scores(plan, out, lc)


def real_plan(data: Path, out: Path, bc: BenchConfig, lc: LabelConfig, test_routes: str | None, seeds: int,
              echo=print) -> RealPlan:
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
        raise ValidationError(f"--test-routes {test_routes!r} must match some recordings and leave some for training", data)
    rdir = out / "real"
    cache = rdir / f"train_{runs.config_hash({'d': str(Path(data).resolve()), 'r': test_routes, 'l': dataclasses.asdict(lc)})}.npz"
    if not cache.is_file():
        view = ds._view(ds.manifest["name"].isin(train_names))
        label_dataset(view, lc).save(cache)
    train = Segments.load(cache)
    echo(f"real: {len(train)} GNSS-labelled segments from {len(train.names)} training routes; "
         f"{len(test_names)} test routes")
    jobs = []
    for method in IPIN_METHODS:
        for seed in range(seeds):
            cfg = NoisyConfig(method=method, seed=seed, ae_epochs=bc.ae_epochs, pre_epochs=bc.pre_epochs,
                              joint_epochs=bc.joint_epochs)
            record = {"noisy": dataclasses.asdict(cfg), "data": str(Path(data).resolve()), "test_routes": test_routes,
                      "labels": dataclasses.asdict(lc), "part": "real"}
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
    pdr = build("pdr", n_devices=1, window=int(round(4 * lc.rate)), rate=lc.rate)
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
        x = np.stack([seq.imu[0, s:s + N] for s in starts]).astype(np.float32)
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
                        metrics.errors_at_reference(t_nodes, est, ref_t, ref_p, SPARSE_MAX_GAP))
            row[method] = float(np.median(np.concatenate([errs[("user", method, k)][-1] for k in range(len(fns))])))
        t_c, vel, _ = predict_sequence(pdr, dataclasses.replace(seq, pos=None), pdr.window, int(round(lc.rate)))
        t_int = seq.t[seq.t >= tt[inside[0]]]
        for proto, p0 in starts_at.items():
            est = integrate_velocity(t_c, vel, t_int, p0)
            errs.setdefault((proto, "pdr", 0), []).append(metrics.errors_at_reference(t_int, est, ref_t, ref_p,
                                                                                        SPARSE_MAX_GAP))
        row["pdr"] = float(np.median(errs[("user", "pdr", 0)][-1]))
        e = metrics.errors_at_reference(rec.fixes.t, rec.fixes.pos, ref_t, ref_p, metrics.FIX_MAX_GAP_S)
        for proto in starts_at:
            errs.setdefault((proto, "gnss", 0), []).append(e)
        row["gnss"] = float(np.median(e)) if e.size else None
        per_route.append(row)
    summary = {proto: {} for proto in ("user", "known")}
    for proto in summary:
        for method in (*IPIN_METHODS, "pdr", "gnss"):
            per_seed = [np.concatenate(v) for (p, m, _), v in sorted(errs.items()) if p == proto and m == method and v]
            if per_seed:
                summary[proto][method] = {**_scores(np.concatenate(per_seed)), "seed_medians_m":
                                          [float(np.median(e)) for e in per_seed if e.size]}
    doc = {"train_routes": train_names, "test_routes": test_names, "segments": len(train),
           "train_label_km": round(float(np.sum(np.linalg.norm(train.label, axis=1))) / 1000, 2),
           "summary": summary, "per_route": per_route}
    runs.write_json(out / "real" / "real.json", doc)
    return doc


# ---- page -----------------------------------------------------------------------------------------

def _pct(share) -> str:
    return "—" if share is None else f"{100 * share:.2f}"


def _mean_sd(mean, sd, n, seeds: int) -> str:
    """A cell in cm: mean ± sd over its seeds, their count added where it is not every seed."""
    if not n or not np.isfinite(mean):
        return "—"
    cell = f"{100 * mean:.1f} ± {100 * sd:.1f}" if n > 1 and np.isfinite(sd) else f"{100 * mean:.1f}"
    return cell if int(n) == seeds else f"{cell} (n={int(n)})"


def _claim(df: pd.DataFrame, table: pd.DataFrame, mean_d: float) -> str:
    """The paper's claim per level, on these seeds: EasyTrack below BaseModel, Co-teaching and AUX
    (Welch's p over seeds, :func:`wearnav.stats.welch_p`) and within 1.15× of BaseModel-GT."""
    if not {"easytrack", "basemodel-gt"} <= set(table.index):
        return ""
    out = []
    for level in table.columns:
        seeds = {m: df[(df["method"] == m) & (df["level"] == level)]["ade"].dropna().tolist() for m in table.index}
        e, gt = table.loc["easytrack", level], table.loc["basemodel-gt", level]
        parts = []
        for rival in ("basemodel", "coteaching", "aux"):
            if rival in table.index and np.isfinite(table.loc[rival, level]):
                p = welch_p(seeds["easytrack"], seeds[rival])
                verdict = "below" if e < table.loc[rival, level] else "NOT below"
                parts.append(f"{verdict} {rival} ({100 * (e - table.loc[rival, level]):+.1f} cm"
                             + (f", p = {p:.3f}" if p is not None else "") + ")")
        ratio = e / gt
        parts.append(f"{ratio:.2f}× BaseModel-GT ({'within' if ratio <= 1.15 else 'NOT within'} 1.15×); "
                     f"EasyTrack's ADE is {100 * e / mean_d:.0f} % of the mean displacement")
        out.append(f"**{level}**: " + "; ".join(parts))
    return ("The paper's claim (EasyTrack below every other LNL and within 1.15× of BaseModel-GT), checked on these "
            "seeds (Welch's two-sided p over seeds; with 3 seeds only a large, consistent gap reaches p < 0.05):\n\n- "
            + "\n- ".join(out))


def _plots(out: Path, table: pd.DataFrame, hist: dict, train: dict[str, Segments], sim: list[dict]) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure


    links = []
    # label-noise CDF (eqs. 5-7)
    fig = Figure(figsize=(5, 3.4), layout="constrained")
    ax = fig.subplots()
    for level, seg in train.items():
        e = np.linalg.norm(seg.noise(), axis=1)
        e = e[np.isfinite(e)] * 100
        if e.size:
            plot_ecdf(ax, e, label=level)
    ax.set(xlabel="phone-label noise |d_e| (cm)", ylabel="CDF", title="label noise per level")
    ax.legend()
    ax.grid(alpha=0.3)
    links.append(save(fig, out / "label_noise_cdf.png").name)
    # Fig. 3/4: ADE per method per level
    if not table.empty:
        fig = Figure(figsize=(7.5, 3.6), layout="constrained")
        ax = fig.subplots()
        methods = list(table.index)
        levels = list(table.columns)
        w = 0.8 / max(len(methods), 1)
        for i, m in enumerate(methods):
            ax.bar(np.arange(len(levels)) + i * w, 100 * table.loc[m].to_numpy(dtype=float), w, label=m)
        ax.set_xticks(np.arange(len(levels)) + 0.4 - w / 2, levels)
        ax.set(ylabel="ADE (cm)", title="displacement error per noise level (Fig. 3/4)")
        ax.legend(fontsize=7, ncol=3)
        links.append(save(fig, out / "ade_by_level.png").name)
    # Fig. 5 and 6: R_tau / R_delta and selected noise over joint epochs (EasyTrack, seed 0)
    if hist:
        fig = Figure(figsize=(9, 3.4), layout="constrained")
        a1, a2 = fig.subplots(1, 2)
        for level, h in hist.items():
            j = [r for r in h if r["phase"] == "joint"]
            ep = np.arange(1, len(j) + 1)
            a1.plot(ep, [r["r_tau"] for r in j], "k--", lw=1, label="R_τ" if level == list(hist)[0] else None)
            a1.plot(ep, [r["r_delta"] for r in j], label=f"R_δ {level}")
            a2.plot(ep, [r["selected_noise_cm"] for r in j], label=f"selected, raw {level}")
            a2.plot(ep, [r["selected_noise_corrected_cm"] for r in j], ":", label=f"selected, CNAL-corrected {level}")
            a2.plot(ep, [r["batch_noise_cm"] for r in j], "--", lw=0.8, label=f"all {level}")
        a1.set(xlabel="joint epoch", ylabel="ratio", title="R_τ and R_δ (Fig. 5)")
        a2.set(xlabel="joint epoch", ylabel="mean label noise (cm)", title="noise of selected instances (Fig. 6)")
        a1.legend(fontsize=7)
        a2.legend(fontsize=6)
        links.append(save(fig, out / "coadapt_over_epochs.png").name)
    # Fig. 7: ATE on held-out trajectories, L1-trained
    rows = [(m["method"], r["ate"]) for m in sim if m.get("level") == "L1" for r in m.get("ate", [])]
    if rows:
        df = pd.DataFrame(rows, columns=["method", "ate"])
        order = list(dict.fromkeys(df["method"]))
        fig = Figure(figsize=(7, 3.4), layout="constrained")
        ax = fig.subplots()
        ax.boxplot([df.loc[df.method == m, "ate"].to_numpy() for m in order], tick_labels=order)
        ax.set(ylabel="ATE (m)", title="held-out trajectories, trained on L1 (Fig. 7)")
        ax.tick_params(axis="x", labelrotation=30, labelsize=7)
        links.append(save(fig, out / "ate_L1.png").name)
    return links


def _ade_curves(out: Path, sim: list[dict]) -> str | None:
    from matplotlib.figure import Figure


    curves: dict[str, dict[str, list]] = {}
    for m in sim:
        f = Path(m.get("folder", "")) / "history.json"
        if m["seed"] != 0 or not f.is_file():
            continue
        h = [r.get("test_ade_m") if isinstance(r, dict) else None for r in read_json(f, kind=list)]
        if any(v is not None for v in h):
            curves.setdefault(m["level"], {})[m["method"]] = h
    if not curves:
        return None
    fig = Figure(figsize=(4.5 * len(curves), 3.4), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(curves)))
    for ax, (level, per) in zip(axes, sorted(curves.items())):
        for method, h in per.items():
            ax.plot(np.arange(1, len(h) + 1), [np.nan if v is None else 100 * v for v in h], label=method)
        ax.set(xlabel="epoch (AE, pre-training, joint)", ylabel="held-out ADE (cm)", title=level)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return save(fig, out / "ade_over_epochs.png").name


def write_page(out: Path, bc: BenchConfig, lc: LabelConfig, sim: list[dict], train: dict[str, Segments],
               test: Segments, real: dict | None, seeds: int, quick: bool) -> Path:

    p = provenance()
    df = pd.DataFrame([{"method": m["method"], "level": m["level"], "seed": m["seed"], "ade": m.get("ade_m"),
                        "ate": m.get("ate_mean_m"), "s_epoch": m["training"]["s_per_epoch"],
                        "min": m["training"]["wall_s"] / 60, "device": m["training"].get("device", "cpu")} for m in sim])
    devices = ", ".join(sorted(set(df["device"]))) if not df.empty else "cpu"
    reduction = (f"**Reduced from the paper** (200 epochs: 5 AE + 5 per model + 190 joint; ~8.5 km per level): here "
                 f"{bc.ae_epochs} AE + {bc.pre_epochs} pre-training + {bc.joint_epochs} joint epochs, "
                 f"~{bc.km:g} km of simulated walking per level, {seeds} seed(s). Machine: {platform.machine()}, "
                 f"trained on {devices}"
                 + (f"; a segment starts every {bc.stride_s:g} s." if bc.stride_s else "."))
    title = (f"# EasyTrack: odometry from the phone's own location fixes (paper 004): {', '.join(bc.levels)}, "
             f"{bc.ae_epochs + bc.pre_epochs + bc.joint_epochs} epochs, ~{bc.km:g} km per level"
             + (f" (--quick: {QUICK_NOTE})" if quick else ""))
    lines = [title, "",
             f"Generated by `wearnav bench easytrack{' --quick' if quick else ''}` ({p['created']}, wearnav "
             f"{p['wearnav']} {p['commit']}).", "", reduction, "",
             f"Segments of {lc.segment_s:g} s at {lc.rate:g} Hz (phone IMU in the world frame, turned onto the fixes' "
             "east/north frame from the IMU and fixes only). Test: "
             f"{len(test.names)} held-out simulated trajectories ({len(test)} segments, truth labels).", ""]
    noise = ["## Phone labels per noise level (eqs. 5–7)", "",
             "Paper Table I: median label noise 21.6 / 27.6 / 33.5 cm, ~8.5 km per level; its Figure 1a: noise over "
             "200 cm exists. Neighbour correlation: Pearson r of consecutive segments' noise, per axis (eq. 7; the paper "
             "gives no number). Dropped: labels faster than the jump filter's "
             f"{lc.max_speed:g} m/s." if lc.max_speed else "Paper Table I: median label noise 21.6 / 27.6 / 33.5 cm.", ""]
    nrows = []
    for level, seg in train.items():
        s = noise_summary(seg)
        nc = s["neighbour_correlation"]
        nrows.append({"level": level, "segments": s["segments"], "walks": s["trajectories"], "km": s["length_km"],
                      "median noise (cm)": s["label_noise_median_cm"], "mean (cm)": s["label_noise_mean_cm"],
                      "p90 (cm)": s["label_noise_p90_cm"], "> 1 m (%)": _pct(s.get("label_noise_over_1m")),
                      "> 2 m (%)": _pct(s.get("label_noise_over_2m")), "dropped (%)": _pct(s.get("dropped_share")),
                      "neighbour r (x, y)": f"{nc['x']:.3f}, {nc['y']:.3f}" if nc["x"] is not None else "—"})
    noise += [pd.DataFrame(nrows).to_markdown(index=False), ""]
    table = pd.DataFrame()
    if not df.empty:
        table = df.pivot_table(index="method", columns="level", values="ade", aggfunc="mean")
        order = [m for m in (*MAIN, *ABLATION) if m in table.index]
        table = table.loc[order]
        sd = df.pivot_table(index="method", columns="level", values="ade", aggfunc="std").reindex(order)
        n = df.pivot_table(index="method", columns="level", values="ade", aggfunc="count").reindex(order)
        shown = pd.DataFrame({f"{c} ADE (cm)": [_mean_sd(table.loc[m, c], sd.loc[m, c] if c in sd else None,
                                                          n.loc[m, c] if c in n else 0, seeds) for m in order]
                              for c in table.columns}, index=order)
        still = next((m["trivial_ade_m"] for m in sim if "trivial_ade_m" in m), None)
        unlearned = sorted({f"{m['method']} {m['level']}" for m in sim if m.get("beats_trivial") is False})
        beats = ("" if still is None else f" Standing still (zero displacement per segment) scores {100 * still:.1f} cm; "
                 + (f"NOT beaten by: {', '.join(unlearned)}." if unlearned else "every run beats it."))
        mean_d = float(np.mean(np.linalg.norm(test.truth, axis=1))) if len(test) else float("nan")
        lines += ["## ADE on held-out trajectories (Fig. 3, ablation Fig. 4)", "",
                  "Paper Figure 3 (real phone labels, DS_L1): EasyTrack 12.4 cm, BaseModel-GT 11.2, BaseModel 21.9, "
                  "Co-teaching 16.5, AUX 19.3; EasyTrack 15.7 cm on DS_L3.", "",
                  f"Mean ± sd over {seeds} seed(s) (n= where a cell has fewer), cm. {reduction}{beats} The test segments' mean true displacement is "
                  f"{100 * mean_d:.1f} cm (the paper's phone labels average ~100 cm and its BaseModel-GT scores 11.2 cm, "
                  "11 % of that).", "", shown.to_markdown(), ""]
        lines += [_claim(df, table, mean_d), ""]
        ate = df.pivot_table(index="method", columns="level", values="ate", aggfunc="mean").loc[order]
        lines += ["ATE (m, mean over the held-out trajectories, displacements integrated from the true start; "
                  "Fig. 7 uses L1):", "", ate.round(2).to_markdown(), "",
                  "Training time (seconds per epoch, mean over methods' non-AE epochs; minutes per run):", "",
                  df.groupby("method")[["s_epoch", "min"]].mean().round(2).to_markdown(), ""]
    lines += noise
    hist = {}
    for m in sim:
        if m["method"] == "easytrack" and m["seed"] == 0:
            folder = Path(m["folder"])
            if (folder / "history.json").is_file():
                hist[m["level"]] = read_json(folder / "history.json", kind=None)
    if hist:
        lines += ["## CoAdapt over the joint epochs (EasyTrack, seed 0; Fig. 5 and 6)", ""]
        rows = []
        for level, h in hist.items():
            j = [r for r in h if r["phase"] == "joint"]
            if j:
                rows.append({"level": level, "R_τ last": round(j[-1]["r_tau"], 3), "R_δ last": round(j[-1]["r_delta"], 3),
                             "selected noise raw (cm)": round(j[-1]["selected_noise_cm"] or float("nan"), 1),
                             "selected, CNAL-corrected (cm)": round(j[-1]["selected_noise_corrected_cm"] or float("nan"), 1),
                             "all instances (cm)": round(j[-1]["batch_noise_cm"] or float("nan"), 1),
                             "selected ‖d‖ (cm)": round(j[-1].get("selected_displacement_cm") or float("nan"), 1),
                             "all ‖d‖ (cm)": round(j[-1].get("batch_displacement_cm") or float("nan"), 1),
                             "corrected labels' median noise (cm)": round(j[-1].get("corrected_label_noise_median_cm",
                                                                                     float("nan")), 1)})
        lines += ["Last joint epoch (mean label noise |d_e| of the instances each model selected for its peer, and "
                  "their mean true displacement ‖d‖ beside the batch's: small-loss selection is meant to keep clean "
                  "labels, but while the model's own error exceeds the label noise it keeps short, easy segments):", "",
                  pd.DataFrame(rows).to_markdown(index=False), ""]
    links = _plots(out, table, hist, train, sim)
    curve = _ade_curves(out, sim)
    if curve:
        lines += ["Held-out ADE after every epoch (a diagnostic only: no model or epoch is chosen by it; the "
                  "paper's Fig. 1b shows BaseModel on noisy labels getting worse with epochs):", ""]
        links.append(curve)
    lines += [f"![{Path(x).stem}]({x})" for x in links] + [""]
    if real:
        lines += ["## Real data: GNSS labels, scored at surveyed points", "",
                  f"Trained on the phone-GNSS labels of {len(real['train_routes'])} training recordings "
                  f"({real['segments']} segments, {real['train_label_km']} km of label path); scored at the surveyed "
                  f"points of {len(real['test_routes'])} held-out recordings ({', '.join(real['test_routes'])}). "
                  "Each seed is scored on its own (no ensemble); the error pools every seed's points, the seed column "
                  "gives each seed's median. GNSS = the raw fix nearest in time (≤ "
                  f"{metrics.FIX_MAX_GAP_S:g} s). {reduction}", ""]
        for proto, head in (("user", "User protocol: the IMU methods start at the phone's own fix at the first "
                                     "surveyed time and integrate (heading from the IMU turned onto the walk's own "
                                     "fixes); no truth is used."),
                            ("known", "Diagnostic, not available to a user: the same paths started at the first "
                                      "surveyed point.")):
            rows = [{"method": k, **{c: v[c] for c in ("points", "median_m", "p75_m", "mean_m")},
                     "seed medians (m)": ", ".join(f"{x:.2f}" for x in v["seed_medians_m"])}
                    for k, v in real["summary"][proto].items()]
            lines += [head, "", pd.DataFrame(rows).round(2).to_markdown(index=False), ""]
            pair = [real["summary"][proto].get(m, {}).get("seed_medians_m", []) for m in IPIN_METHODS]
            p = welch_p(*pair)
            if p is not None:
                lines += [f"EasyTrack vs BaseModel, per-seed medians: Welch's p = {p:.3f}.", ""]
        lines += ["Per route (user protocol; median error over the seeds' points, m):", "",
                  pd.DataFrame(real["per_route"]).round(2).to_markdown(index=False), ""]
    return write_text_atomic("\n".join(lines), out / "results.md")


def run_benchmark(out: str | Path, quick: bool = False, seeds: int = 1, execution: Execution = Execution(),
                  data: str | Path | None = None, test_routes: str | None = None, bc: BenchConfig | None = None,
                  echo=print) -> Path:
    out = Path(out)
    bc = bc or (BenchConfig.quick() if quick else BenchConfig())
    if quick:
        echo(f"--quick: {QUICK_NOTE} (tiny data, 1–2 epochs per phase)")
    lc = LabelConfig(stride_s=bc.stride_s)
    plan = real_plan(Path(data), out, bc, lc, test_routes, seeds, echo) if data else None
    train, test = sim_segments(out, bc, lc, echo)
    caches, test_cache = _caches(out, bc, lc)
    todo = _todo(out, bc, seeds, lc)
    jobs = [Job(run_job, EasyJob(cfg, caches[level], test_cache, record), folder) for cfg, level, folder, record in todo]
    run_jobs((plan.jobs if plan else []) + jobs, execution, echo)  # one pool: real and simulator runs side by side
    real = real_scores(plan, out, lc) if plan else None
    sim = [{**runs.read_metrics(job.folder), "folder": str(job.folder)} for job in jobs]
    return write_page(out, bc, lc, sim, train, test, real, seeds, quick)


def _todo(out: Path, bc: BenchConfig, seeds: int, lc: LabelConfig) -> list[tuple]:
    """(config, level, folder, record) of every simulator run, seed by seed (an interrupted suite has
    whole seeds of every cell first)."""
    res = []
    for seed in range(seeds):
        for level in bc.levels:
            for method in bc.methods:
                if level != "L1" and method in bc.l1_only:
                    continue
                cfg = NoisyConfig(method=method, seed=seed, ae_epochs=bc.ae_epochs, pre_epochs=bc.pre_epochs,
                                  joint_epochs=bc.joint_epochs)
                record = {"noisy": dataclasses.asdict(cfg), "level": level, "km": bc.km, "sim_seed": bc.sim_seed,
                          "test_walks": bc.test_walks, "labels": dataclasses.asdict(lc), "part": "sim"}
                res.append((cfg, level, runs.run_dir(out / "runs", f"{level}-{method}-s{seed}", record), record))
    return res
