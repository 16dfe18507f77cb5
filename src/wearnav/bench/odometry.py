"""The Suite-IN++ comparison (paper 000, Sec. V, Tables III–VI analogues) as a list of run configs.

A grid (:data:`GRIDS`) is a plain list of (registered model, model_args) entries; each entry ×
training seed is one run folder ``<out>/<model>-<hash8>`` (see :mod:`wearnav.runs`; the seed and
model_args are part of the hash); complete runs are skipped, so an interrupted suite resumes.
The pages (:func:`write_suite_report` here, the paper's tables in
:mod:`wearnav.bench.odometry_tables`) read run folders only.

Decision: docs/decisions/0011-odometry-grid-and-page.md.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import runs
from wearnav.bench.executor import Execution, Job, run_jobs
from wearnav.core.fileio import write_text_atomic
from wearnav.dataset import Dataset, scorable_split
from wearnav.errors import ConfigError, ValidationError
from wearnav.evaluate import evaluate_run
from wearnav.models.registry import check_models, get
from wearnav.train.odometry import (
    TrainConfig,
    build_model,
    check_devices,
    fit,
    prepare_run,
    run_hash_exclude,
    run_record,
)

DEFAULT_MODELS = ("suitein++", "suitein", "ronin", "ronin*", "pdr")
TEST_SPLITS = ("test", "test_unseen", "cross_subject")
MODES = ("STW", "PVW", "MVW", "DRW", "DLW")


# Issue #16 §4 "paper" grid, in the page's row order (Suite-IN++ first, as the paper's tables
# read): every model of Table III (* = the devices' channels concatenated),
# the phone-only ionet (one-directional: Table VI's 114.6 K; the registry's default is EasyTrack's
# Bi-LSTM) and imunet of Table IV, the ablations (1)–(5) of Table V ((6) = suitein++) and
# Suite-IN++ with the paper's row-keeping extractor (suitein++-rows). Names the registry does not
# hold yet make `--grid paper` refuse to start, naming them: edit this list to run what exists.
PAPER_GRID: list[tuple[str, dict]] = [
    ("suitein++", {}),
    ("suitein", {}),
    ("rewf", {}),
    ("deepsense*", {}),
    ("deepit*", {}),
    ("imunet*", {}),
    ("ronin*", {}),
    ("ionet*", {}),
    ("imunet", {}),
    ("ronin", {}),
    ("ionet", {"bidirectional": False}),
    ("pdr", {}),
    ("suitein++-rows", {}),
    *[(f"suitein++-abl{n}", {}) for n in range(1, 6)],
]
GRIDS: dict[str, list[tuple[str, dict]]] = {
    "default": [(m, {}) for m in DEFAULT_MODELS],
    "paper": PAPER_GRID,
}
# How a model_args item reads in a row label; others read "key=value".
ARG_LABELS: dict = {}


def row_label(model: str, model_args: dict | None = None) -> str:
    """A grid entry's row label: the model's name, plus its model_args where it has any
    ("suitein++ (mixed extractor)"), so two entries of one model get two rows."""
    if not model_args:
        return model
    parts = [ARG_LABELS.get((k, v), f"{k}={v}") for k, v in sorted(model_args.items())]
    return f"{model} ({', '.join(parts)})"


def grid_entries(models) -> list[tuple[str, dict]]:
    """``models`` as (name, model_args) entries: a name stands for (name, {})."""
    return [(m, {}) if isinstance(m, str) else (m[0], dict(m[1])) for m in models]


def suite_configs(data: str | Path, models=DEFAULT_MODELS, seeds=None, **train_kw) -> list:
    """One TrainConfig per grid entry (a model name or a (name, model_args) pair) and training
    seed, entry by entry; ``seeds`` None: the one ``seed`` of ``train_kw`` (default 0). A ``devices``
    layout naming a device no recording of ``data`` has is refused here, before any run."""
    entries = grid_entries(models)
    check_models([m for m, _ in entries], "odometry")  # every name, before any config is built
    if "devices" in train_kw:
        check_devices(Dataset.open(data), tuple(train_kw["devices"]))
    seeds = [train_kw.pop("seed", 0)] if seeds is None else list(seeds)
    if not seeds or len(set(seeds)) != len(seeds):
        raise ConfigError(f"seeds must be distinct and at least one, got {seeds}")
    return [
        TrainConfig(model=m, data=str(data), model_args=args, seed=seed, **train_kw)
        for m, args in entries
        for seed in seeds
    ]


def run_key(cfg) -> dict:
    """What names a config's run folder (``<model>-<hash8>``): its record less what is not hashed."""
    return run_hash_exclude(run_record(cfg))


@dataclasses.dataclass(frozen=True)
class OdometryJob:
    """One run of the suite: train ``cfg`` (or resume), then evaluate on ``splits``."""

    cfg: TrainConfig
    splits: tuple[str, ...]
    progress: bool = False


# Where a run of a truth-aligned training is also scored with its test input turned onto the
# truth's yaw over time (the old, optimistic test frame; issue 16 §1), to measure what the honest
# frame costs. Never read by a model or a results table other than that comparison.
DIAGNOSTIC_TRUTH_FRAME = "diagnostic-truth-frame"


def run_job(job: OdometryJob, run: Path) -> Path:
    """Train and evaluate one run folder (an executor job: a pure function of ``job``); where the
    test frame is the honest "initial" one, also score the diagnostic truth frame into
    ``run/diagnostic-truth-frame`` (first, so that a complete run has both)."""
    prepare_run(job.cfg, run)
    training = fit(job.cfg, run, progress=job.progress)
    if job.cfg.eval_config().frame_align == "initial":
        evaluate_run(
            run,
            splits=job.splits,
            progress=job.progress,
            training=training,
            preprocess={"eval_frame_align": "truth"},
            out_dir=run / DIAGNOSTIC_TRUTH_FRAME,
        )
    evaluate_run(run, splits=job.splits, progress=job.progress, training=training)
    return run


def check_configs(configs, splits=TEST_SPLITS) -> None:
    """Refuse a suite that could not finish, before its first run folder is written: a model that
    is not an odometry model, a device no recording has, or data whose test splits have no truth
    to score against (a page of runs scoring 0 sequences), or model_args the model does not take."""
    built = set()
    for cfg in configs:
        key = (cfg.model, repr(sorted(cfg.model_args.items())), len(cfg.devices), cfg.window)
        if key not in built:  # once per grid entry, not per seed
            build_model(cfg)
            built.add(key)
        spec = get(cfg.model)
        if spec.task != "odometry":
            raise ConfigError(f"{cfg.model!r} is a {spec.task} model, not an odometry model")
        ds = Dataset.open(cfg.data)
        check_devices(ds, cfg.devices)
        present = set(ds.manifest["split"].astype(str))
        use = [s for s in splits if s in present]
        if not use:
            raise ValidationError(f"none of the test splits {list(splits)} is in the dataset", cfg.data)
        for split in use:
            scorable_split(ds, split)


def run_folder(out: str | Path, cfg) -> Path:
    """The run folder of ``cfg`` in suite folder ``out``."""
    return runs.run_dir(out, cfg.model, run_key(cfg))


def run_suite(
    configs, out: str | Path, splits=TEST_SPLITS, progress: bool = True, echo=print, execution: Execution = Execution()
) -> list[Path]:
    """Train (or resume) and evaluate every config as ``execution`` says (:mod:`.executor`); skip
    complete runs. Returns the run folders, in the order of ``configs``."""
    check_configs(configs, splits)
    out = Path(out)
    jobs = []
    for cfg in configs:
        run = run_folder(out, cfg)
        present = set(Dataset.open(cfg.data).manifest["split"].astype(str))
        use = tuple(s for s in splits if s in present)  # check_configs: at least one
        jobs.append(Job(run_job, OdometryJob(cfg, use, progress and execution.in_process), run))
    return run_jobs(jobs, execution, echo)


BEATS_STILL = "beats standing still"  # best validation MSE below predicting zero velocity (wearnav.trust)


def beats_text(training: dict) -> str:
    """ "yes" / "NO" (did not learn) / "not learned" (PDR) / "—" (a run from before it was recorded)."""
    if training.get("learned") is False:
        return "not learned"
    b = training.get("beats_trivial")
    return "—" if b is None else ("yes" if b else "NO")


def comparison_table(folders, split: str = "test") -> pd.DataFrame:
    """One row per run: ATE/RTE overall and per walking mode on ``split`` (means over sequences)."""
    rows = []
    for run in folders:
        m = runs.read_metrics(run)
        res = m["splits"].get(split)
        if res is None:
            continue
        s = res["summary"]
        row = {"model": m["model"], "ATE": s.get("ate_mean"), "RTE": s.get("rte_mean"), "sequences": s.get("sequences")}
        for mode in MODES:
            bm = res["by_mode"].get(mode)
            if bm:
                row[f"{mode} ATE"] = bm.get("ate_mean")
                row[f"{mode} RTE"] = bm.get("rte_mean")
        tr = m.get("training", {})
        row["epochs"] = tr.get("epochs_run", "—" if tr.get("learned") is False else None)
        row["stopped by"] = tr.get("stopped_by", "not learned" if tr.get("learned") is False else None)
        row["train s/epoch"] = tr.get("s_per_epoch")
        row["train min"] = round(tr["wall_s"] / 60, 1) if tr.get("wall_s") is not None else None
        row["attempts"] = tr.get("attempts")
        row[BEATS_STILL] = beats_text(tr)
        rows.append(row)
    return pd.DataFrame(rows)


def errors_by_model(folders, split: str = "test") -> dict[str, np.ndarray]:
    out = {}
    for run in folders:
        m = runs.read_metrics(run)
        files = sorted((Path(run) / "trajectories" / split).glob("*.csv"))
        e = [pd.read_csv(f)["error"].to_numpy() for f in files]
        if e:
            out[m["model"]] = np.concatenate(e)
    return out


def ate_by_model(folders, split: str = "test") -> dict[str, list[float]]:
    out = {}
    for run in folders:
        m = runs.read_metrics(run)
        res = m["splits"].get(split)
        if res:
            out[m["model"]] = [r["ate"] for r in res["sequences"] if "ate" in r]
    return out


# One paragraph for a reader new to odometry (the demo's page; docs/results.md has the glossary).
METRICS_EXPLAINED = (
    "What the numbers mean: each model turns the devices' accelerometer and gyroscope into a walking "
    "path, which is compared with the simulator's true path. **ATE** (absolute trajectory error, metres) "
    "is the RMS distance between the estimated and the true position over a whole walk; **RTE** "
    "(relative trajectory error, metres) is the same over 60 s stretches, so it shows drift regardless "
    "of where the walk started; lower is better for both. STW, PVW, MVW, DRW, DLW are Suite-IN++'s "
    "walking modes (standard walking; walking while holding the phone in front, calmly or with more "
    "motion; a device removed mid-walk; walking with daily-living episodes). The models: **suitein++** "
    "(Suite-IN++, one network reading phone, watch and earbuds together), **ronin** (RoNIN, a network "
    "on each device's data in a common frame) and **pdr** (pedestrian dead reckoning: steps × stride "
    "length along the phone's heading, nothing learned) as the baseline a learned model must beat."
)


def write_suite_report(
    folders, out: str | Path, title: str, splits=TEST_SPLITS, note: str = "", command: str = "wearnav bench odometry"
) -> Path:
    """results.md + results.json + comparison PNGs (error CDF and ATE box per split) in ``out``;
    ``command``: what the page says produced it."""
    from wearnav.core.provenance import provenance
    from wearnav.report.odometry import plot_box, plot_cdf

    out = Path(out)
    lines = [
        f"# {title}",
        "",
        f"Generated by `{command}` from {len(folders)} run folders "
        f"({provenance()['created']}, wearnav {provenance()['wearnav']} {provenance()['commit']}).",
        "",
    ]
    if note:
        lines += [note, ""]
    doc = {}
    for split in splits:
        table = comparison_table(folders, split)
        if table.empty or not (pd.to_numeric(table["sequences"], errors="coerce").fillna(0) > 0).any():
            continue
        doc[split] = table.to_dict(orient="records")
        lines += [
            f"## Split `{split}`",
            "",
            "ATE and RTE in metres (mean over sequences; RTE over Δ = 60 s, "
            "scaled for shorter sequences as RoNIN does).",
            "",
            table.to_markdown(index=False, floatfmt=".2f"),
            "",
        ]
        cdf = plot_cdf(
            errors_by_model(folders, split), out / f"{split}_error_cdf.png", f"position error CDF, split {split}"
        )
        box = plot_box(ate_by_model(folders, split), out / f"{split}_ate_box.png", f"ATE per sequence, split {split}")
        lines += [f"![{p.stem}]({p.name})" for p in (cdf, box) if p] + [""]
    if not doc:
        raise ValidationError(f"no run scored a sequence on the splits {list(splits)}; nothing to report", out)
    runs.write_json(out / "results.json", doc)
    return write_text_atomic("\n".join(lines), out / "results.md")
