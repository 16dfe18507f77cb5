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
   magnetic north, the truth to a floor plan (ILC2) or to geographic east/north (IPIN): the two
   differ by a constant yaw per site. :func:`site_yaw` takes it from the training traces only:
   PDR (not learned, so nothing is fitted to the data first) is run on each trace, and the yaw is
   the angle of Σ d_pdr · conj(d_truth) over all segments between consecutive surveyed points (a
   2-D Procrustes fit, longer segments weighing more). Every model's input is rotated by it into
   the truth frame. PDR's own heading bias goes into that angle; a learned model trained under it
   absorbs any constant yaw left over (a constant rotation commutes with the yaw augmentation).
   A learned model scored where it did not train under that angle (another building, or trained
   on other data) would inherit PDR's bias there (18° at ILC2: PDR's −19.2° against −1.0° from the
   held-flat phone's axis), so it is given its own estimate instead: the same fit of *its* paths on
   the site's training traces (:meth:`RealEval.yaw`; a site yaw from training data, no test truth).
4. **transfers to another building** with ``test_data``: the same import and grouping; the
   models trained on ``data`` are scored on its test groups, with its yaw estimated from its own
   training groups (which are used for nothing else).
5. **puts the phone's own fixes beside the models** where the data has them (IPIN): the raw
   GNSS error at the same surveyed points (nearest fix within ``metrics.FIX_MAX_GAP_S``).
6. **scores the path a user gets** where the data has fixes (issue 25): the user protocol of
   :mod:`wearnav.bench.user_protocol` (no start point, no site yaw; the path placed on the
   recording's own fixes by first-fix anchoring, a rigid fit, or the smoother), beside the
   known-start protocol of steps 2–3, which is named as such in the report. Each model's
   smoother is calibrated on its validation walks first (the odometry's random walk,
   :func:`wearnav.fuse.odometry_walk_sigma`), stored in its run folder for `track`.

Optionally ``train_data`` (a simulated dataset) trains the learned models instead of the real
training floors: the sim-to-real test of issue 11. Everything is a run folder; complete runs
are skipped, so the benchmark resumes.
"""

from __future__ import annotations

import dataclasses
import os
import platform
import time
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import runs
from wearnav.bench.executor import Execution, Job, run_jobs
from wearnav.bench.user_protocol import (PAIRED_TEXT, fix_point_errors, paired_rows, score_path, site_calibration,
                                         user_table)
from wearnav.bench.odometry import BEATS_STILL, beats_text
from wearnav.dataset import Dataset, is_validation_name
from wearnav.errors import ConfigError, ValidationError
from wearnav.evaluate import evaluate_run, predict_sequence
from wearnav.fileio import shown_path, write_text_atomic
from wearnav.models.registry import build, check_models, get
from wearnav.pretrained.mix import MIX_FRAME, is_mix
from wearnav.preprocess import SURVEYED_TRUTH_MAX_GAP_S, load_sequences
from wearnav.progress import progress as report_progress
from wearnav.rotations import from_wxyz
from wearnav.train.odometry import TrainConfig, fit, load_model, prepare_run, run_hash_exclude, run_record
from wearnav.trajectory import integrate_velocity
from wearnav.textio import read_json

DEFAULT_MODELS = ("ronin", "suitein++", "pdr")
TRUTH_MAX_GAP_S = SURVEYED_TRUTH_MAX_GAP_S
# IPIN 2023 Track 3's held-out routes (meta ``trial``), for every benchmark on IPIN (this one, the
# user protocol, `bench easytrack`'s real part): three of the eleven routes, none of them the
# simulator's calibration trials 01–02.
IPIN_TEST_TRIALS = (4, 24, 52)
# Grouping and held-out groups per source; neither holds data the simulator was calibrated on.
SITE_DEFAULTS: dict[str, tuple[str, tuple[str, ...]]] = {
    "ilc2": ("floor_name", ("F2", "F4")),
    "ipin2023": ("trial", tuple(str(t) for t in IPIN_TEST_TRIALS)),
}
CALIBRATION = {"ilc2": ("floor_name", {"F1"}), "ipin2023": ("trial", {"1", "2"})}
PERCENTILES = (50, 75, 95)


# ---- data ---------------------------------------------------------------------------------------

def _group(meta: dict, key: str, name: str) -> str:
    if key not in meta:
        raise ValidationError(f"recording {name} has no meta key {key!r} to group by")
    return str(meta[key])


def split_of(name: str, group: str, test_groups: set[str]) -> str:
    """``test`` for the held-out groups; else ``val`` for one recording in VAL_EVERY (by a hash of
    its name: :func:`wearnav.dataset.is_validation_name`), else ``train``."""
    if group in test_groups:
        return "test"
    return "val" if is_validation_name(name) else "train"


def prepare_data(src: str | Path, out: str | Path, fmt: str | None = None, group_by: str | None = None,
                 test_groups: tuple[str, ...] | None = None, progress: bool = True) -> tuple[Path, dict]:
    """Write ``src`` (an imported dataset folder, or an original-format folder read with importer
    ``fmt``) to ``out`` with splits by place. Returns the folder and what was decided."""
    from wearnav.dataset import DatasetWriter
    from wearnav.importers import get_importer

    src, out = Path(src), Path(out)
    if (src / "manifest.csv").is_file():
        ds = Dataset.open(src)
        recs, source = (ds.load(n) for n in ds.names), str(ds.manifest["source"].iloc[0]) if len(ds) else ""
    elif fmt is None:
        raise ConfigError(f"{src} is not an imported dataset (no manifest.csv): name its --format")
    else:
        recs, source = get_importer(fmt).read(src), fmt
    key, groups = SITE_DEFAULTS.get(source, (None, None))
    key, groups = group_by or key, tuple(test_groups) if test_groups else groups
    if key is None or not groups:
        raise ConfigError(f"no default grouping for source {source!r}: give --group-by and --test-groups")
    wanted = {"src": str(src.resolve()), "importer": fmt, "group_by": key, "test_groups": list(groups)}
    info_path = out / "split.json"
    if info_path.is_file() and (out / "manifest.csv").is_file():
        info = read_json(info_path)
        if {k: info.get(k) for k in wanted} == wanted:
            return out, info
    counts: dict[str, dict[str, int]] = {}
    calib_key, calib = CALIBRATION.get(source, (None, set()))
    with DatasetWriter(out, {"generator": "wearnav.bench.real", **wanted}) as w:
        for rec in report_progress(recs, desc=f"prepare {src.name}", unit="rec", enabled=progress, leave=False):
            g = _group(rec.meta, key, rec.name)
            split = split_of(rec.name, g, set(groups))
            if split == "test" and calib_key and str(rec.meta.get(calib_key)) in calib:
                raise ConfigError(f"test group {g!r} holds data the simulator was calibrated on "
                                  f"({calib_key} {sorted(calib)}); choose other --test-groups")
            counts.setdefault(g, {}).setdefault(split, 0)
            counts[g][split] += 1
            w.add(rec, split=split)
    missing = set(groups) - set(counts)
    if missing:
        raise ValidationError(f"test groups {sorted(missing)} are not in the data ({key} values: "
                              f"{sorted(counts)})", src)
    info = {**wanted, "source": source, "groups": counts}
    runs.write_json(info_path, info)
    return out, info


# ---- the site's yaw ---------------------------------------------------------------------------

def segment_products(seqs, window: int = 100, stride: int = 10, model=None) -> np.ndarray:
    """d_model · conj(d_truth) per segment between consecutive surveyed points (complex), over the
    sequences ``seqs`` (Aligned, world frame, no yaw applied); ``model`` None: PDR."""
    out = []
    for seq in seqs:
        net = model if model is not None else build("pdr", n_devices=len(seq.devices), window=window,
                                                     rate=seq.rate).eval()
        t_c, vel, _ = predict_sequence(net, seq, window, stride)
        rec = seq.recording
        if t_c.size < 2 or rec is None or rec.truth is None:
            continue
        tt, tp = rec.truth.t, rec.truth.pos[:, :2]
        k = (tt >= seq.t[0]) & (tt <= seq.t[-1])
        if k.sum() < 2:
            continue
        est = integrate_velocity(t_c, vel, tt[k], tp[k][0])
        de, dt = np.diff(est, axis=0), np.diff(tp[k], axis=0)
        out.append((de[:, 0] + 1j * de[:, 1]) * np.conj(dt[:, 0] + 1j * dt[:, 1]))
    return np.concatenate(out) if out else np.empty(0, complex)


def device_axis_yaw(seqs, device: str = "phone", axis=(0.0, 1.0, 0.0)) -> float | None:
    """A cross-check valid only for a device held flat and pointing ahead (ILC2's phones): the yaw
    of its ``axis`` in the world frame against each segment's truth direction, Σ over segments of
    at least 1 m (degrees); None without orientation."""
    p = []
    for seq in seqs:
        rec = seq.recording
        s = rec.devices.get(device) if rec is not None else None
        if s is None or s.quat is None or rec.truth is None:
            continue
        fwd = from_wxyz(s.quat).apply(axis)
        h = fwd[:, 0] + 1j * fwd[:, 1]
        h = h / np.maximum(np.abs(h), 1e-9)
        tt, tp = rec.truth.t, rec.truth.pos[:, :2]
        for a in range(len(tt) - 1):
            k = (s.t >= tt[a]) & (s.t <= tt[a + 1])
            d = tp[a + 1] - tp[a]
            if k.sum() >= 10 and np.hypot(*d) >= 1.0:
                p.append(h[k].mean() * np.conj(d[0] + 1j * d[1]))
    return round(float(np.degrees(np.angle(np.sum(p)))), 2) if p else None


def site_yaw(seqs, window: int = 100, stride: int = 10, model=None) -> dict:
    """The yaw (degrees) of the input's world frame relative to the truth frame, from PDR (or
    ``model``) on training traces (module docstring, step 3), with its spread."""
    p = segment_products(seqs, window, stride, model)
    if p.size == 0:
        raise ValidationError("no segments between surveyed points to estimate the site's yaw from")
    yaw = float(np.angle(np.sum(p)))
    dev = np.degrees(np.abs(np.angle(p * np.exp(-1j * yaw))))
    unit = p / np.maximum(np.abs(p), 1e-12)
    return {"yaw_deg": round(float(np.degrees(yaw)), 2), "segments": int(p.size), "traces": len(seqs),
            "median_abs_dev_deg": round(float(np.median(dev)), 1),
            "resultant_length": round(float(np.abs(unit.mean())), 3),
            "phone_axis_yaw_deg": device_axis_yaw(seqs)}


def estimate_site_yaw(data: Path, split: str | None = "train", devices=("phone",), rate: float = 25.0,
                      progress: bool = False, run: Path | None = None) -> dict:
    """:func:`site_yaw` of the ``split`` traces (None: all) of dataset ``data`` (no yaw applied, no
    frame alignment), by PDR or by the model of ``run`` (a run folder: its rate, window and stride);
    ``progress``: report the traces' loading (:mod:`wearnav.progress`)."""
    model, window, stride = None, 100, 10
    if run is not None:
        model, tcfg = load_model(run)
        devices, rate, window, stride = tcfg.devices, tcfg.rate, tcfg.window, tcfg.stride
    cfg = TrainConfig(model="pdr", data=str(data), devices=tuple(devices), rate=rate, frame_align="none",
                      truth_max_gap=TRUTH_MAX_GAP_S)
    ds = Dataset.open(data)
    found = site_yaw(load_sequences(ds.split(split) if split else ds, cfg, progress), window, stride, model)
    return {**found, "by": "pdr" if run is None else "the model itself"}


# ---- the phone's own fixes --------------------------------------------------------------------

def fix_errors(data: Path, split: str = "test") -> dict | None:
    """Raw fix error at the surveyed points of ``split`` (nearest fix within metrics.FIX_MAX_GAP_S), each
    trace from its second point on, as the models are scored; None without fixes."""
    view = Dataset.open(data).split(split)
    errs = []
    for name in view.names:
        rec = view.load(name)
        if rec.fixes is None or rec.truth is None or len(rec.fixes) == 0:
            continue
        errs.append(fix_point_errors(rec))
    if not errs:
        return None
    e = np.concatenate(errs)
    return {"sequences": len(errs), "points": int(e.size), **_point_stats(e),
            "point_errors": [round(float(x), 3) for x in e]}


def _point_stats(e: np.ndarray) -> dict:
    if e.size == 0:
        return {"error_mean": float("nan"), **{f"error_p{p}": float("nan") for p in PERCENTILES}}
    return {"error_mean": float(e.mean()), **{f"error_p{p}": float(np.percentile(e, p)) for p in PERCENTILES}}


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
    augment: tuple[str, ...] = ("rotate_yaw",)  # the learned models' batch augmentations (wearnav.augment)

    def __post_init__(self) -> None:
        check_models(self.models, "odometry")  # before any data is prepared


def _train_config(model: str, data: str, yaw: float, bench: RealBench, elsewhere: bool):
    kw = dict(model=model, data=data, devices=("phone",), epochs=bench.epochs, patience=bench.patience,
              max_minutes=bench.max_minutes, seed=bench.seed, window=bench.window, stride=bench.stride,
              lr=bench.lr, augment=bench.augment)
    if elsewhere and is_mix(data):  # several sources, truth turned into each input's common frame
        return TrainConfig(**kw, frame_align=MIX_FRAME, truth_max_gap=TRUTH_MAX_GAP_S)
    if elsewhere:  # the simulator's own truth frame and dense truth
        return TrainConfig(**kw)
    return TrainConfig(**kw, frame_align="none", truth_max_gap=TRUTH_MAX_GAP_S, yaw_deg=yaw)


@dataclasses.dataclass(frozen=True)
class RealEval:
    """Where a trained model is scored: a site's prepared ``data``, its yaw (PDR's), the output
    folder; ``own_yaw``: turn the input by the model's own estimate of the site's yaw instead."""

    data: str
    yaw_deg: float
    out_dir: Path
    own_yaw: bool = False

    def yaw(self, run: Path) -> float:
        """The yaw the test input is turned by: PDR's, or the model's own (module docstring, step 3),
        estimated once on the site's training traces and kept beside the evaluation."""
        if not self.own_yaw:
            return self.yaw_deg
        f = run / f"site_yaw_{self.out_dir.name}.json"
        if not f.is_file():
            runs.write_json(f, {**estimate_site_yaw(Path(self.data), run=run), "data": self.data})
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
        pre = {"frame_align": "none", "truth_max_gap": TRUTH_MAX_GAP_S, "yaw_deg": e.yaw(run)}
        evaluate_run(run, data=e.data, splits=("test",), progress=job.progress, training=training,
                     preprocess=pre, out_dir=e.out_dir)
    return run


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
        return write_report(self.out, self.sites, suite_runs(self.out, self.sites["main"]["data"]), self.bench, wall)


def plan_benchmark(data: Path, out: Path, test_data: Path | None = None, fmt: str | None = None,
                   test_fmt: str | None = None, group_by: str | None = None, test_groups=None,
                   test_group_by: str | None = None, test_test_groups=None, bench: RealBench = RealBench(),
                   progress: bool = True, echo=print, in_process: bool = True) -> Plan:
    """Prepare the data, estimate the site yaws and list a job per model (:func:`run_job`)."""
    out = Path(out)
    t_start = time.perf_counter()
    sites = {}
    main, info = prepare_data(data, out / "data" / "main", fmt, group_by, test_groups, progress)
    sites["main"] = {"data": str(main), "split": info}
    if test_data is not None:
        other, oinfo = prepare_data(test_data, out / "data" / "other", test_fmt, test_group_by,
                                    test_test_groups, progress)
        sites["other"] = {"data": str(other), "split": oinfo}
    for name, site in sites.items():
        cached = out / "data" / name / "site_yaw.json"
        if not cached.is_file():
            echo(f"{name}: estimating the site's yaw from its training traces (PDR) ...")
            runs.write_json(cached, estimate_site_yaw(Path(site["data"]), progress=progress))
        site["yaw"] = read_json(cached)
        echo(f"{name}: site yaw {site['yaw']['yaw_deg']:+.1f}° from {site['yaw']['segments']} segments")
        site["fixes"] = fix_errors(Path(site["data"]))
    yaw = sites["main"]["yaw"]["yaw_deg"]
    jobs = []
    for model in bench.models:
        elsewhere = bool(bench.train_data) and get(model).learned
        cfg = _train_config(model, bench.train_data if elsewhere else str(main), yaw, bench, elsewhere)
        run = runs.run_dir(out / "runs", model, run_hash_exclude(run_record(cfg)))
        # a learned model scored where it did not train under PDR's site yaw is given its own
        # estimate of the site's yaw (PDR's heading bias differs by building: 18° at ILC2)
        evals = tuple(RealEval(site["data"], site["yaw"]["yaw_deg"], run / f"eval_{s}",
                               own_yaw=get(model).learned and (elsewhere or s != "main"))
                      for s, site in sites.items())
        jobs.append(Job(run_job, RealJob(cfg, evals, progress and in_process), run,
                        marks=tuple(e.out_dir for e in evals)))
    return Plan(out, sites, jobs, bench, t_start)


def run_benchmark(data: Path, out: Path, test_data: Path | None = None, fmt: str | None = None,
                  test_fmt: str | None = None, group_by: str | None = None, test_groups=None,
                  test_group_by: str | None = None, test_test_groups=None, bench: RealBench = RealBench(),
                  progress: bool = True, echo=print, execution: Execution = Execution()) -> Path:
    """Prepare the data, estimate the site yaws, train/evaluate every model (as ``execution``
    says, :mod:`.executor`), write results.md."""
    plan = plan_benchmark(data, out, test_data, fmt, test_fmt, group_by, test_groups, test_group_by,
                          test_test_groups, bench, progress, echo, execution.in_process)
    run_jobs(plan.jobs, execution, echo)
    return plan.finish()


def suite_runs(out: Path, main_data: str) -> dict[str, Path]:
    """Every run folder of the suite by its row label: the model's name when it was trained on
    the building's own training groups (or is not learned), "model · simulator `<data>`" when it
    was trained on another dataset (sim-to-real runs share the suite, so one table holds both)."""
    labelled = []
    for run in sorted(Path(out, "runs").glob("*/")):
        if not (run / runs.CONFIG).is_file():
            continue
        train = runs.read_config(run)["config"]["train"]
        label = train["model"]
        if get(train["model"]).learned and Path(train["data"]).resolve() != Path(main_data).resolve():
            prov = Dataset.open(train["data"]).provenance
            made = (f"simulator `{Path(train['data']).name}` (commit {prov.get('commit', '?')})"
                    if prov.get("generator") == "wearnav.simulate" else
                    f"{' + '.join(q['part'] for q in prov['parts'])} (`{Path(train['data']).name}`)"
                    if is_mix(train["data"]) else f"`{Path(train['data']).name}`")
            label = f"{label} · {made}"
        labelled.append((not get(train["model"]).learned, "·" in label, label, run))
    return {label: run for *_, label, run in sorted(labelled, key=lambda x: x[:3])}


def results_table(sites: dict, folders: dict[str, Path], site: str) -> tuple[pd.DataFrame, dict]:
    """One row per model (and the raw fixes): errors at the surveyed points of the test traces."""
    rows, errors = [], {}
    for label, run in folders.items():
        m = runs.read_metrics(run / f"eval_{site}") if runs.is_complete(run / f"eval_{site}") else None
        if not m:
            continue
        res = m["splits"]["test"]
        # the pooled per-point statistics are evaluate's summary; the errors themselves feed the CDF
        errors[label] = np.concatenate([np.asarray(r.get("point_errors", []), float) for r in res["sequences"]]
                                       or [np.empty(0)])
        summary = res["summary"]
        tr = m.get("training", {})
        own = run / f"site_yaw_eval_{site}.json"
        yaw = read_json(own)["yaw_deg"] if own.is_file() else sites[site]["yaw"]["yaw_deg"]
        rows.append({"method": label, "site yaw (°)": yaw, "traces": summary["sequences"], "points": summary.get("points", 0),
                     **{k: summary.get(k, float("nan")) for k in ("error_mean", "error_p50", "error_p75", "error_p95")},
                     "length ratio": length_ratio(run / f"eval_{site}", sites[site]["data"]),
                     "epochs": tr.get("epochs_run", "—"), "train min": round(tr["wall_s"] / 60, 1) if tr.get("wall_s") else "—",
                     BEATS_STILL: beats_text(tr)})
    fx = sites[site].get("fixes")
    if fx:
        errors["raw phone fixes"] = np.asarray(fx["point_errors"])
        rows.append({"method": "raw phone fixes", "site yaw (°)": "—", "traces": fx["sequences"], "points": fx["points"],
                     **{k: v for k, v in fx.items() if k.startswith("error_")}, "length ratio": float("nan"), "epochs": "—", "train min": "—",
                     BEATS_STILL: "—"})
    df = pd.DataFrame(rows)
    if not df.empty:
        df = df.rename(columns={"error_mean": "mean (m)", "error_p50": "median (m)", "error_p75": "p75 (m)",
                                "error_p95": "p95 (m)"})
    return df, errors


def length_ratio(eval_dir: Path, data: str) -> float:
    """Median over the test traces of the path's length through its positions at the surveyed
    times over the truth's (:func:`wearnav.bench.user_protocol.score_path`; 1 is right, below 1 the
    path is short), from the trajectories an evaluation wrote."""
    ds, ratios = Dataset.open(data), []
    for f in sorted((eval_dir / "trajectories" / "test").glob("*.csv")):
        df = pd.read_csv(f)
        if f.stem in ds.names and len(df) > 1:
            truth = ds.load(f.stem).truth
            ratios.append(score_path(df["t"].to_numpy(), df[["x", "y"]].to_numpy(), truth.t, truth.pos[:, :2])[1])
    return round(float(np.nanmedian(ratios)), 3) if np.isfinite(ratios).any() else float("nan")


def write_report(out: Path, sites: dict, folders: dict[str, Path], bench: RealBench, wall_s: float) -> Path:
    import torch

    from wearnav.provenance import provenance
    from wearnav.report.odometry import plot_cdf

    p = provenance()
    src = sites['main']['split']['source']
    title = (f"Odometry in real buildings: trained on {src}" if not bench.train_data else
             f"Odometry in real buildings: trained on `{Path(bench.train_data).name}`, tested on {src}")
    lines = [f"# {title}", "",
             f"Generated by `wearnav bench real-odometry` ({p['created']}, wearnav {p['wearnav']} {p['commit']}); "
             f"this invocation {wall_s / 60:.1f} min of wall time (each run's own training minutes are in its row) on "
             f"{platform.machine()}, {os.cpu_count()} CPUs, "
             f"torch {torch.__version__}, CPU only, shared with other work while it ran.", "",
             "Errors in metres at the surveyed points of the held-out test traces: every trace starts at its "
             "first point and is scored at each later one (no reset). Training targets join the surveyed "
             "points by straight lines (the competitions' assumption between waypoints); nothing is "
             "tuned on the test groups. Phone only, 25 Hz, world frame rotated by the site's yaw "
             "(estimated by PDR from training traces only).", "",
             f"Training: at most {bench.epochs} epochs, early stopping on validation velocity MSE (patience "
             f"{bench.patience})" + (f", at most {bench.max_minutes:g} min per model" if bench.max_minutes else "")
             + (f", Adam lr {bench.lr:g}" if bench.lr else ", each model's paper learning rate")
             + f", seed {bench.seed}, one run per row (the epochs and minutes each got are in its row).", "",
             "Sim-to-real: a row named `model · simulator ...` is that model trained on the simulated "
             "dataset only (phone only, the simulator's own truth frame, dense truth) and scored here "
             "like the others; beside it the same model trained on the building's training groups, "
             "and PDR (not learned).", ""]
    doc = {"bench": dataclasses.asdict(bench), "wall_s": round(wall_s, 1), "sites": {}}
    for site, s in sites.items():
        info = s["split"]
        test = [g for g, c in info["groups"].items() if "test" in c]
        train = [g for g, c in info["groups"].items() if "test" not in c]
        n = {k: sum(c.get(k, 0) for c in info["groups"].values()) for k in ("train", "val", "test")}
        head = ("Another building, never trained on" if site != "main" else "Held-out groups of the training building"
                if not bench.train_data else "Held-out groups (a learned row trained elsewhere says where)")
        lines += [f"## {head}: `{info['source']}`", "",
                  f"Source `{shown_path(info['src'])}`, grouped by `{info['group_by']}`: test {', '.join(sorted(test))} "
                  f"({n['test']} traces); " + (f"training groups {', '.join(sorted(train))} ({n['train']} train, "
                  f"{n['val']} validation traces)." if site == "main" else
                  f"its other groups ({n['train'] + n['val']} traces) serve only to estimate its yaw."),
                  f"Site yaw {s['yaw']['yaw_deg']:+.1f}° from {s['yaw']['segments']} segments of "
                  f"{s['yaw']['traces']} training traces (median |deviation| {s['yaw']['median_abs_dev_deg']}°)"
                  + (f"; cross-check, valid only for a phone held flat and pointing ahead: its +y axis gives "
                     f"{s['yaw']['phone_axis_yaw_deg']:+.1f}° (the difference is PDR's own heading bias, "
                     "which a learned model absorbs)." if s["yaw"].get("phone_axis_yaw_deg") is not None else "."), ""]
        table, errors = results_table(sites, folders, site)
        doc["sites"][site] = {"split": info, "yaw": s["yaw"], "table": table.to_dict(orient="records")}
        if table.empty:
            lines += ["(no complete runs yet)", ""]
            continue
        lines += ["Known-start protocol (each trace starts at its true first point, input turned by the site "
                  "yaw: a floor, not available to a user). A learned row scored where it did not train under "
                  "PDR's yaw uses its own estimate from the same training traces (*site yaw* column):", "", table.to_markdown(index=False, floatfmt=".2f"), ""]
        if s.get("fixes"):
            # each model's smoother is calibrated where it is used (user_protocol.site_calibration)
            cal = doc["sites"][site]["calibration"] = {
                label: site_calibration(run, site, s["data"], _trained_on(run))
                for label, run in folders_with_eval(folders, site).items()}
            rows, raw = user_table(folders_with_eval(folders, site), s["data"], s["fixes"],
                                   calibration=cal)
            paired = paired_rows(raw)
            doc["sites"][site]["user_protocol"] = {"table": rows, "paired": paired, "runs": raw}
            lines += [USER_PROTOCOL_TEXT, "", pd.DataFrame(rows).to_markdown(index=False, floatfmt=".2f"), ""]
            if paired:
                lines += [PAIRED_TEXT, "", pd.DataFrame(paired).to_markdown(index=False), ""]
            lines += _user_protocol_elsewhere(folders_with_eval(folders, site), s["data"], cal,
                                              doc["sites"][site]["user_protocol"])
        cdf = plot_cdf(errors, out / f"{site}_error_cdf.png", f"error at surveyed points, {info['source']} test")
        traj = _plot_examples(folders, site, out / f"{site}_trajectories.png", info["source"])
        lines += [f"![{q.stem}]({q.name})" for q in (cdf, traj) if q] + [""]
    runs.write_json(out / "results.json", doc)
    return write_text_atomic("\n".join(lines), out / "results.md")


USER_PROTOCOL_TEXT = (
    "User protocol (issue 25: no truth at all, neither the start point nor the site yaw; "
    ":mod:`wearnav.bench.user_protocol`): each model's path integrated from (0, 0) in the phone's own "
    "world frame and placed on the recording's own location fixes by first-fix anchoring (today's "
    "`track` until now), one rigid fit to all fixes, or the smoother (:mod:`wearnav.fuse`, `track`'s "
    "default). Errors at the same surveyed points; *length ratio*: median over walks of the path's "
    "length through its positions at the surveyed times over the truth's (1 is right); *inside σ's 68 % "
    "radius*: the share of the smoother's points whose error is inside 1.515 times the σ `track` "
    "writes for them (0.68 where that σ is right, less where it is too small).")


def _user_protocol_elsewhere(folders: dict[str, Path], data: str, cal: dict, doc: dict) -> list[str]:
    """The user protocol again on the site's training walks, for the models that never trained on
    them (PDR, a model from another building): three times the walks of the held-out routes, though
    not held out from the smoother's settings (chosen on IPIN's training walks) or its calibration
    (:func:`site_calibration`). Adds ``train_walks`` to ``doc``; returns the page's lines."""
    others = {k: run for k, run in folders.items() if _trained_on(run) is None
              or Path(_trained_on(run)).resolve() != Path(data).resolve()}
    fixes = fix_errors(Path(data), "train") if others else None
    if not fixes:
        return []
    rows, raw = user_table(others, data, fixes, "train",
                           calibration={k: cal[k] for k in others})
    paired = paired_rows(raw)
    doc["train_walks"] = {"table": rows, "paired": paired}
    return [f"The same on the site's {fixes['sequences']} training walks, for the models that never trained "
            "on them: not held out from the smoother's settings or its calibration, which were chosen and "
            "measured on such walks, but three times as many walks:", "",
            pd.DataFrame(rows).to_markdown(index=False, floatfmt=".2f"), "",
            pd.DataFrame(paired).to_markdown(index=False) if paired else "", ""]


def _trained_on(run: Path) -> str | None:
    """The data a learned run trained on; None for a model that is not learned."""
    train = runs.read_config(run)["config"]["train"]
    return train["data"] if get(train["model"]).learned and train.get("data") else None


def folders_with_eval(folders: dict[str, Path], site: str) -> dict[str, Path]:
    """The runs of ``folders`` scored on ``site`` (complete evaluation)."""
    return {label: run for label, run in folders.items() if runs.is_complete(run / f"eval_{site}")}


def _plot_examples(folders: dict[str, Path], site: str, path: Path, source: str, k: int = 4) -> Path | None:
    """Estimated paths of every model on the first ``k`` test traces, waypoints as dots."""
    from matplotlib.figure import Figure

    from wearnav.report.plots import save

    names = None
    for run in folders.values():
        d = run / f"eval_{site}" / "trajectories" / "test"
        if d.is_dir():
            names = sorted(p.stem for p in d.glob("*.csv"))[:k]
            break
    if not names:
        return None
    fig = Figure(figsize=(3.8 * len(names), 4.0), layout="constrained")
    for i, name in enumerate(names):
        ax = fig.add_subplot(1, len(names), i + 1)
        drawn = False
        for model, run in folders.items():
            f = run / f"eval_{site}" / "trajectories" / "test" / f"{name}.csv"
            if not f.is_file():
                continue
            tr = pd.read_csv(f)
            if not drawn:
                ax.plot(tr.x_true, tr.y_true, color="black", lw=1.0, ls=":", label="waypoints, straight")
                drawn = True
            ax.plot(tr.x, tr.y, lw=1.0, label=model)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
        ax.set_title(name[-28:], fontsize=8)
        if i == 0:
            ax.legend(fontsize=7)
    fig.suptitle(f"{source}: held-out test traces (metres)", fontsize=11)
    return save(fig, path)
