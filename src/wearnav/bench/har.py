"""The HAR benchmark (paper 002, Sec. III; Figs. 8–12 analogues) as suites of run configs.

Per dataset, every technique is a :class:`wearnav.train.classify.ClassifyConfig` per seed, one
run folder each (``<out>/runs/<dataset>/<technique>-<hash8>``); complete runs are skipped, so an
interrupted benchmark resumes; :mod:`wearnav.bench.executor` runs them here, in local processes or
on a Ray cluster. The report reads run folders only.

Datasets (real recordings imported from the shared data folder, and the simulator's placement
dataset, generated: :func:`wearnav.simulate.presets.plan_placement_dataset`) and their subject-independent
splits are listed in :data:`DATASETS` / :data:`wearnav.train.classify.TEST_SUBJECTS`. Techniques
that need a gyroscope (Head2, Head3) are "not applicable" on an accelerometer-only set (Oxford):
no run is made and the table says so. "world frame" needs the device orientation (MotionSense).
"""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from wearnav import runs
from wearnav.bench.executor import Execution, Job, run_jobs
from wearnav.core.fileio import write_text_atomic
from wearnav.core.textio import read_json
from wearnav.errors import ConfigError, FormatError, MissingFileError, check_names
from wearnav.stats import SIGNIFICANCE, bh_adjust, welch_p
from wearnav.trust import QUICK_NOTE

BASELINE = "har-cnn-bilstm"


@dataclass(frozen=True)
class HarDataset:
    name: str
    fmt: str  # importer
    src: str  # folder under the shared data root
    scheme: str  # split scheme (wearnav.train.classify.TEST_SUBJECTS)
    label_kind: str
    classes: tuple[str, ...]  # empty: every value in the training data
    devices: tuple[str, ...]
    gyro: bool
    orientation: bool
    quick_limit: int | None = None  # recordings imported by --quick (simulated: subjects)
    note: str = ""  # shown under the dataset's table


# The simulator's fine phone placements (wearnav.simulate.config.PHONE_HOLDS; "transition"
# windows between holds are not a class).
SIM_HOLDS = ("texting", "swinging", "call", "front_pocket", "back_pocket", "bag")
SIM_SUBJECTS, SIM_DURATION_S = 8, (60.0, 90.0)
SIM_QUICK_DURATION_S = (20.0, 25.0)

UCI_BASIC = ("WALKING", "WALKING_UPSTAIRS", "WALKING_DOWNSTAIRS", "SITTING", "STANDING", "LAYING")

DATASETS: dict[str, HarDataset] = {
    d.name: d
    for d in (
        HarDataset("motionsense", "motionsense", "motionsense", "motionsense", "activity", (), ("phone",), True, True),
        # The first 6 experiments hold users 1–3, of whom 2 is a UCI HAR test subject.
        HarDataset("uci-hapt", "uci-hapt", "uci_hapt", "uci-hapt", "activity", UCI_BASIC, ("phone",), True, False, 6),
        HarDataset(
            "uji-phone", "uji-phone-watch", "uji_phone_watch_har", "uji", "activity", (), ("phone",), True, False
        ),
        HarDataset(
            "uji-watch", "uji-phone-watch", "uji_phone_watch_har", "uji", "activity_watch", (), ("watch",), True, False
        ),
        HarDataset(
            "uji-both", "uji-phone-watch", "uji_phone_watch_har", "uji", "activity", (), ("phone", "watch"), True, False
        ),
        HarDataset(
            "oxford",
            "oxford-steps",
            "oxford_step_counter",
            "oxford",
            "placement",
            (),
            ("phone",),
            False,
            False,
            note="This copy holds two users, one recording per placement each: the models learn from user1's six "
            "recordings and are tested on user2, so a placement's device orientation is seen on one person "
            "only.",
        ),
        # Generated, not imported: wearnav.simulate.presets.plan_placement_dataset (8 walkers, 6 walks
        # each; --quick: 4 walkers, 20-25 s walks). Test walkers u4, u8.
        HarDataset(
            "sim-placement",
            "simulate-placement",
            "",
            "sim-placement",
            "placement",
            SIM_HOLDS,
            ("phone",),
            True,
            True,
            4,
        ),
    )
}


@dataclass(frozen=True)
class Technique:
    name: str
    label: str
    changes: dict
    needs_gyro: bool = False
    needs_orientation: bool = False
    extra: bool = False  # beyond the paper


TECHNIQUES: tuple[Technique, ...] = (
    Technique("baseline", "baseline", {}),
    Technique("head2", "Head2", {"model": "har-head2"}, needs_gyro=True),
    Technique("head3", "Head3", {"model": "har-head3"}, needs_gyro=True),
    Technique("rot_x", "rotation x", {"expand": "rot_x"}),
    Technique("rot_y", "rotation y", {"expand": "rot_y"}),
    Technique("rot_z", "rotation z", {"expand": "rot_z"}),
    Technique("rot_all", "rotation all axes", {"expand": "rot_all"}),
    Technique("noise", "additive noise", {"expand": "noise"}),
    Technique("ma10", "moving average 10", {"denoise": 10}),
    Technique("ma25", "moving average 25", {"denoise": 25}),
    Technique("ma50", "moving average 50", {"denoise": 50}),
    Technique("rot_random", "random rotation (on the fly)", {"augment": ("rotate_random",)}, extra=True),
    Technique("world", "world-frame input", {"frame": "world"}, needs_orientation=True, extra=True),
)


def applicable(tech: Technique, ds: HarDataset) -> str | None:
    """None if ``tech`` applies to ``ds``, else why not."""
    if tech.needs_gyro and not ds.gyro:
        return "not applicable (no gyroscope)"
    if tech.needs_orientation and not ds.orientation:
        return "not applicable (no orientation)"
    return None


def check_inputs(specs: list[HarDataset], data_root: Path, out: Path, quick: bool, techniques=None) -> None:
    """Refuse what would stop the suite part-way, before anything is written: an unknown
    technique, a dataset neither imported into ``out`` yet nor found under ``data_root``."""
    if techniques is not None:
        check_names(techniques, [t.name for t in TECHNIQUES], "technique")
    for ds in specs:
        if ds.fmt == "simulate-placement" or (_data_folder(ds, out, quick) / "manifest.csv").is_file():
            continue
        if not (data_root / ds.src).exists():
            raise MissingFileError(f"no {ds.name} source here (expected {ds.src}/); see --data", data_root)


def _data_folder(ds: HarDataset, out: Path, quick: bool) -> Path:
    return out / "data" / (ds.fmt + ("-quick" if quick and ds.quick_limit else ""))


def import_data(ds: HarDataset, data_root: Path, out: Path, quick: bool) -> Path:
    """Import ``ds``'s source once into ``out/data/<fmt>[-quick]`` (reused when present); the
    simulated dataset is generated there instead (seed 0)."""
    from wearnav.importers import import_dataset

    folder = _data_folder(ds, out, quick)
    if (folder / "manifest.csv").is_file():
        return folder
    if ds.fmt == "simulate-placement":
        from wearnav.simulate.presets import simulate_placement_dataset

        assert ds.quick_limit is not None  # the simulated dataset's --quick size (walkers)
        simulate_placement_dataset(
            folder,
            subjects=ds.quick_limit if quick else SIM_SUBJECTS,
            duration_s=SIM_QUICK_DURATION_S if quick else SIM_DURATION_S,
        )
    else:
        import_dataset(ds.fmt, data_root / ds.src, folder, limit=ds.quick_limit if quick else None, progress=False)
    return folder


def baseline_config(ds: HarDataset, data: Path, **train_kw):
    """The baseline's :class:`wearnav.train.classify.ClassifyConfig` on ``ds`` imported at ``data``."""
    from wearnav.train.classify import ClassifyConfig

    return ClassifyConfig(
        model=BASELINE,
        data=str(data),
        scheme=ds.scheme,
        label_kind=ds.label_kind,
        classes=ds.classes,
        devices=ds.devices,
        **train_kw,
    )


def suite_configs(
    ds: HarDataset, data: Path, seeds: int, techniques=None, **train_kw
) -> list[tuple[Technique, object]]:
    """(technique, config) for every applicable technique (of ``techniques``, default all) and seed."""
    if techniques is not None:
        check_names(techniques, [t.name for t in TECHNIQUES], "technique")
    out = []
    for tech in TECHNIQUES:
        if applicable(tech, ds) or (techniques is not None and tech.name not in techniques):
            continue
        for seed in range(seeds):
            out.append((tech, replace(baseline_config(ds, data, seed=seed, **train_kw), **tech.changes)))
    return out


DEFAULT_THREADS = 1


def run_job(cfg, run: Path) -> Path:
    """Train and evaluate one run folder (an executor job: a pure function of ``cfg``)."""
    from wearnav.train.classify import evaluate_run, fit, prepare_run

    prepare_run(cfg, run)
    evaluate_run(run, training=fit(cfg, run, progress=False))
    return run


def expected_cost(cfg) -> int:
    """A run's training windows relative to the baseline's: an expanded set (rotation, noise)
    trains on 2–4× the windows, so it starts first and the workers finish together."""
    from wearnav.preprocess.augment import expansion_copies

    return 1 + len(expansion_copies(cfg.expand)) if cfg.expand else 1


def run_suite(
    items, root: Path, execution: Execution = Execution(threads=DEFAULT_THREADS), echo=print
) -> dict[str, list[Path]]:
    """Train and evaluate every (technique, config) as ``execution`` says (:mod:`.executor`); skip
    complete runs. technique → folders.

    ``execution.threads``: torch intra-op threads per run (:data:`DEFAULT_THREADS` = 1). This
    model is small (batch 64, 41 LSTM steps of 64 units). Measured on the shared 2-core machine: a
    training step took 37–41 ms with 1 thread and 35–40 ms with 2 when the machine was quiet, but
    51–62 ms with 1 thread and 266–428 ms with 2 at a load average of 5.6 (two OpenMP threads
    spin-wait for each other's core); one epoch of UCI HAPT took 5.6 s with 1 thread and 9.6 s
    with 2 at a load of about 1. More throughput comes from ``execution.jobs``."""
    from wearnav.train.classify import run_folder

    folders: dict[str, list[Path]] = {}
    jobs = []
    for tech, cfg in items:
        run = run_folder(root, tech.name, cfg)
        folders.setdefault(tech.name, []).append(run)
        jobs.append(Job(run_job, cfg, run, cost=expected_cost(cfg)))
    run_jobs(jobs, execution, echo)
    return folders


def summarise(folders: dict[str, list[Path]]) -> dict[str, dict]:
    """technique → mean/std of accuracy and macro-F1 over its seeds (from metrics.json only)."""
    out = {}
    for name, runs_ in folders.items():
        ms = [runs.read_metrics(r) for r in runs_ if runs.is_complete(r)]
        if not ms:
            continue
        acc = np.array([m["accuracy"] for m in ms])
        f1 = np.array([m["macro_f1"] for m in ms])
        out[name] = {
            "accuracy_mean": float(acc.mean()),
            "accuracy_std": float(acc.std(ddof=1)) if acc.size > 1 else 0.0,
            "f1_mean": float(f1.mean()),
            "f1_std": float(f1.std(ddof=1)) if f1.size > 1 else 0.0,
            "seeds": len(ms),
            "accuracy_per_seed": acc.tolist(),
            "classes": ms[0]["classes"],
            "confusion": np.sum([m["confusion"] for m in ms], axis=0).tolist(),
            "train_wall_s": float(sum(m["training"].get("wall_s", 0.0) for m in ms)),
            "epochs": ms[0]["training"].get("epochs_run"),
            "train_windows": ms[0]["training"].get("train_windows"),
            "test_windows": ms[0]["test_windows"],
            "beats_trivial": [m.get("beats_trivial") for m in ms],  # per seed; None: not recorded
        }
    return out


SIGNIFICANCE_NOTE = (
    "† = differs from the baseline beyond seed spread: Welch's t-test over per-seed accuracies, "
    f"Benjamini–Hochberg-adjusted p < {SIGNIFICANCE} over the dataset's techniques (p: raw; "
    "p_BH: adjusted)"
)


def _plot_improvement(dataset: str, summary: dict, path: Path, p_bh: dict[str, float | None]) -> Path | None:
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    from wearnav.report.plots import save

    base = summary.get("baseline")
    names = [t.name for t in TECHNIQUES if t.name != "baseline" and t.name in summary]
    if base is None or not names:
        return None
    d = [100 * (summary[n]["accuracy_mean"] - base["accuracy_mean"]) for n in names]
    fig = Figure(figsize=(7, 3.2))
    ax = fig.add_subplot()
    # error bar: the standard error of the difference of two seed means
    se = [
        100
        * np.hypot(
            summary[n]["accuracy_std"] / np.sqrt(summary[n]["seeds"]), base["accuracy_std"] / np.sqrt(base["seeds"])
        )
        for n in names
    ]
    ax.bar(range(len(names)), d, yerr=se, capsize=3, color=["tab:green" if v > 0 else "tab:red" for v in d])
    for i, n in enumerate(names):
        if (p_n := p_bh.get(n)) is not None and p_n < SIGNIFICANCE:
            ax.annotate(
                "†",
                (i, d[i] + np.copysign(se[i], d[i])),
                xytext=(0, 2 if d[i] >= 0 else -2),
                textcoords="offset points",
                ha="center",
                va="bottom" if d[i] >= 0 else "top",
            )
    ax.axhline(0, color="k", lw=0.8)
    ax.legend(
        handles=[
            Line2D(
                [],
                [],
                ls="none",
                marker="$†$",
                color="k",
                label=f"differs from the baseline (Welch's t over seeds, BH-adjusted p < {SIGNIFICANCE})",
            )
        ],
        fontsize=7,
    )
    ax.margins(y=0.15)
    ax.set_xticks(range(len(names)), names, rotation=45, ha="right")
    ax.set_ylabel("Δ accuracy vs baseline (points)\n± standard error over seeds", fontsize=8)
    ax.set_title(f"{dataset}: improvement over the baseline")
    fig.tight_layout()
    return save(fig, path)


def _plot_confusion(dataset: str, s: dict, path: Path) -> Path:
    from matplotlib.figure import Figure

    from wearnav.report.plots import save

    c = np.asarray(s["confusion"], float)
    norm = c / np.maximum(c.sum(axis=1, keepdims=True), 1)
    k = len(s["classes"])
    fig = Figure(figsize=(1.0 + 0.7 * k, 0.8 + 0.6 * k))
    ax = fig.add_subplot()
    ax.imshow(norm, cmap="Blues", vmin=0, vmax=1)
    for i in range(k):
        for j in range(k):
            ax.text(
                j,
                i,
                f"{int(c[i, j])}",
                ha="center",
                va="center",
                fontsize=7,
                color="white" if norm[i, j] > 0.5 else "black",
            )
    ax.set_xticks(range(k), s["classes"], rotation=45, ha="right", fontsize=7)
    ax.set_yticks(range(k), s["classes"], fontsize=7)
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(f"{dataset}: baseline, {s['seeds']} seed(s) summed", fontsize=9)
    fig.tight_layout()
    return save(fig, path)


IMPROVED_SIGNIFICANT = f"improved, p_BH < {SIGNIFICANCE}"
WORSE_SIGNIFICANT = f"worse, p_BH < {SIGNIFICANCE}"


def _plot_summary(rows: list[dict], path: Path) -> Path | None:
    from matplotlib.figure import Figure

    from wearnav.report.plots import save

    if not rows:
        return None
    # as the paper's Fig. 12: bars count datasets, circles mark the maximum improvement
    fig = Figure(figsize=(7, 3.8), layout="constrained")
    ax = fig.add_subplot()
    x = np.arange(len(rows))
    ax.bar(x, [r["datasets improved"] for r in rows], 0.6, color="tab:blue", alpha=0.4, label="datasets improved")
    ax.bar(
        x,
        [r[IMPROVED_SIGNIFICANT] for r in rows],
        0.6,
        color="tab:blue",
        label=f"… of which beyond seed spread (Welch's t, BH-adjusted p < {SIGNIFICANCE})",
    )
    ax.yaxis.get_major_locator().set_params(integer=True)  # type: ignore[call-arg]  # a MaxNLocator (matplotlib's default)
    ax2 = ax.twinx()
    ax2.plot(
        x, [r["max improvement (points)"] for r in rows], "o", color="tab:orange", ms=8, label="max Δ accuracy (points)"
    )
    ax2.axhline(0, color="tab:orange", lw=0.8, ls=":")
    ax.set_xticks(x, [r["technique"] for r in rows], rotation=45, ha="right")
    ax.set_ylabel("datasets improved")
    ax2.set_ylabel("max Δ accuracy (points)")
    ax.set_title("techniques over all datasets (Fig. 12 analogue)")
    fig.legend(loc="outside lower center", ncols=3, fontsize=7)
    return save(fig, path)


BEATS_MAJORITY = "beats majority class"  # seeds whose test accuracy beat always answering it


def _beats_text(beats: list) -> str:
    """ "3/3": seeds that beat the majority class; "NO 0/3" where some did not; "—" unrecorded."""
    known = [b for b in beats if b is not None]
    if not known:
        return "—"
    return ("" if all(known) else "NO ") + f"{sum(known)}/{len(known)}"


def _p_text(p: float | None) -> str:
    return "" if p is None else f"{p:.2g}"


def _wall_text(wall_s: float | None, earlier: Sequence[dict]) -> str:
    if wall_s is None:
        return ""
    if not earlier:
        return f"; this invocation's wall time {wall_s:.0f} s"
    total = wall_s + sum(c["wall_s"] for c in earlier)
    return f"; wall time {total:.0f} s over {len(earlier) + 1} invocations (this one {wall_s:.0f} s)"


def previous_invocations(out: Path) -> list[dict]:
    """The wall times of the suite's earlier invocations, from its results.json."""
    path = Path(out) / "results.json"
    if not path.is_file():
        return []
    calls = read_json(path).get("invocations", [])
    if not isinstance(calls, list) or not all(isinstance(c, dict) for c in calls):
        raise FormatError("'invocations' is not a list of records", path)
    return calls


def write_report(
    results: dict[str, dict],
    out: Path,
    note: str = "",
    wall_s: float | None = None,
    invocations: Sequence[dict] = (),
    title: str = "",
) -> Path:
    """results.md + results.json + PNGs from ``results``: dataset → technique → summary.
    ``invocations``: earlier invocations' wall times (this one's is ``wall_s``); the page gives
    their total, since a resumed benchmark trains across several."""
    import pandas as pd

    from wearnav.core.provenance import provenance

    p = provenance()
    lines = [
        "# Activity and placement recognition (paper 002 techniques)" + (f": {title}" if title else ""),
        "",
        f"Generated by `wearnav bench har` ({p['created']}, wearnav {p['wearnav']} {p['commit']}) from run "
        f"folders. Machine: {platform.machine()}, {os.cpu_count()} CPU cores" + _wall_text(wall_s, invocations) + ".",
        "",
    ]
    if note:
        lines += [note, ""]
    improve: dict[str, list[tuple[float, bool]]] = {}  # technique → (Δ accuracy, beyond seed spread) per dataset
    significance: dict[str, dict[str, dict]] = {}  # dataset → technique → raw and BH-adjusted p
    for dataset, summary in results.items():
        spec = DATASETS[dataset]
        base = summary.get("baseline")
        p_raw = {
            t.name: welch_p(summary[t.name]["accuracy_per_seed"], base["accuracy_per_seed"])
            for t in TECHNIQUES
            if base and t.name != "baseline" and t.name in summary and not applicable(t, spec)
        }
        p_bh = bh_adjust(p_raw)
        significance[dataset] = {k: {"p": p_raw[k], "p_bh": p_bh[k]} for k in p_raw}
        rows = []
        for tech in TECHNIQUES:
            why = applicable(tech, spec)
            s = summary.get(tech.name)
            if why or s is None:
                rows.append(
                    {
                        "technique": tech.label + (" *" if tech.extra else ""),
                        "accuracy %": why or "not run",
                        "macro-F1 %": "",
                        "Δ acc (points)": "",
                        "p": "",
                        "p_BH": "",
                        "Δ F1 (points)": "",
                        "seeds": 0,
                        "train s": "",
                        BEATS_MAJORITY: "",
                    }
                )
                continue
            da = df = None
            sig = False
            if base and tech.name != "baseline":
                da = 100 * (s["accuracy_mean"] - base["accuracy_mean"])
                df = 100 * (s["f1_mean"] - base["f1_mean"])
                sig = (p_tech := p_bh[tech.name]) is not None and p_tech < SIGNIFICANCE
                improve.setdefault(tech.name, []).append((da, sig))
            rows.append(
                {
                    "technique": tech.label + (" *" if tech.extra else ""),
                    "accuracy %": f"{100 * s['accuracy_mean']:.1f} ± {100 * s['accuracy_std']:.1f}",
                    "macro-F1 %": f"{100 * s['f1_mean']:.1f} ± {100 * s['f1_std']:.1f}",
                    "Δ acc (points)": "" if da is None else f"{da:+.1f}" + (" †" if sig else ""),
                    "p": _p_text(p_raw.get(tech.name)),
                    "p_BH": _p_text(p_bh.get(tech.name)),
                    "Δ F1 (points)": "" if df is None else f"{df:+.1f}",
                    "seeds": s["seeds"],
                    "train s": f"{s['train_wall_s']:.0f}",
                    BEATS_MAJORITY: _beats_text(s.get("beats_trivial", [])),
                }
            )
        info = (
            f" {base['train_windows']} training / {base['test_windows']} test windows; {base['epochs']} epochs."
            if base
            else ""
        )
        lines += [
            f"## {dataset}",
            "",
            f"Devices {', '.join(spec.devices)}; labels `{spec.label_kind}`; subject-independent split "
            f"`{spec.scheme}`.{info} Mean ± std over seeds; * = beyond the paper; {SIGNIFICANCE_NOTE}.",
            "",
            pd.DataFrame(rows).to_markdown(index=False, disable_numparse=True),
            "",
        ]
        if spec.note:
            lines += [spec.note, ""]
        for png in (
            _plot_improvement(dataset, summary, out / f"{dataset}_improvement.png", p_bh),
            _plot_confusion(dataset, base, out / f"{dataset}_confusion.png") if base else None,
        ):
            if png:
                lines += [f"![{png.stem}]({png.name})", ""]
    summary_rows = [
        {
            "technique": t.label,
            "datasets improved": sum(d > 0 for d, _ in improve[t.name]),
            IMPROVED_SIGNIFICANT: sum(d > 0 and q for d, q in improve[t.name]),
            WORSE_SIGNIFICANT: sum(d < 0 and q for d, q in improve[t.name]),
            "datasets run": len(improve[t.name]),
            "max improvement (points)": round(max(d for d, _ in improve[t.name]), 1),
        }
        for t in TECHNIQUES
        if t.name in improve
    ]
    if summary_rows:
        lines += [
            "## Summary over datasets (Fig. 12 analogue)",
            "",
            pd.DataFrame(summary_rows).to_markdown(index=False),
            "",
            f"Significance as in the tables: {SIGNIFICANCE_NOTE}.",
            "",
        ]
        png = _plot_summary(summary_rows, out / "summary.png")
        if png:
            lines += [f"![{png.stem}]({png.name})", ""]
    calls = list(invocations) + ([{"at": p["created"], "wall_s": wall_s}] if wall_s is not None else [])
    runs.write_json(
        out / "results.json",
        {"datasets": results, "significance": significance, "summary": summary_rows, "invocations": calls},
    )
    return write_text_atomic("\n".join(lines), out / "results.md")


def epochs_for_steps(spec: HarDataset, data: Path, steps: int, batch: int = 64) -> int:
    """Epochs that give the baseline about ``steps`` gradient steps on ``spec``'s (un-augmented)
    training windows: the paper sets epochs per dataset "depending on convergence and running
    time" (Sec. II-A); a step budget makes that rule explicit. Expanded sets (rotation, noise) train
    for the same epochs, so they take 2–4× the steps, as adding data to the training set does."""
    from wearnav.dataset import Dataset
    from wearnav.train.classify import _windows, sequences, split_view

    cfg = baseline_config(spec, data)
    n = len(_windows(sequences(split_view(Dataset.open(data), spec.scheme, "train"), cfg), cfg, spec.classes))
    return max(1, round(steps / max(1, -(-n // batch))))


def run_benchmark(
    data_root: Path,
    out: Path,
    datasets=None,
    seeds: int = 3,
    execution: Execution = Execution(threads=DEFAULT_THREADS),
    quick: bool = False,
    epochs: int | None = None,
    techniques=None,
    max_minutes: float | None = None,
    echo=print,
    steps: int | None = None,
) -> Path:
    """Import, train, evaluate and report. ``quick``: UCI HAPT's first 6 experiments, 1 epoch,
    at most 128 training windows per run, 1 seed unless ``seeds`` says otherwise. ``steps``
    (instead of ``epochs``): each dataset's epochs from :func:`epochs_for_steps`."""
    if steps is not None and epochs is not None:
        raise ConfigError("give --epochs or --steps, not both")
    t0 = time.perf_counter()
    earlier = previous_invocations(out)
    names = list(datasets or (("uci-hapt",) if quick else DATASETS))
    check_names(names, DATASETS, "HAR dataset")
    check_inputs([DATASETS[n] for n in names], Path(data_root), Path(out), quick, techniques)
    kw = {"epochs": epochs or (1 if quick else 30), "max_minutes": max_minutes}
    if quick:
        echo(f"--quick: {QUICK_NOTE} (a tiny subset, {kw['epochs']} epoch(s))")
        kw["max_train_windows"] = 128
    results = {}
    for name in names:
        spec = DATASETS[name]
        data = import_data(spec, Path(data_root), Path(out), quick)
        if steps is not None:
            kw["epochs"] = epochs_for_steps(spec, data, steps)
        echo(f"{name}: {data}, {kw['epochs']} epochs")
        folders = run_suite(
            suite_configs(spec, data, seeds, techniques, **kw), Path(out) / "runs" / name, execution, echo
        )
        results[name] = summarise(folders)
    wall = time.perf_counter() - t0
    budget = (
        f"epochs per dataset for about {steps} baseline steps (listed per dataset)"
        if steps is not None
        else f"{kw['epochs']} epochs"
    )
    note = (
        f"Training: Adam lr 1e-3, batch 64, {budget}"
        + (f" or {max_minutes:g} min per run" if max_minutes else "")
        + ", last-epoch weights (no validation split, "
        "as the paper); windows of 128 samples at 50 Hz with 50 % overlap; device-frame input. Sizes the paper "
        "omits (ours): Bi-LSTM 64 units per direction, last states as the summary, max-pool stride 3, ReLU after "
        "FC 256. Noise σ (eq. 12): 0.1 × the pooled std of the training windows' acc (resp. gyro) channels."
        + (
            f" QUICK RUN ({QUICK_NOTE}): a tiny subset and few steps, for testing the pipeline, not a result."
            if quick
            else ""
        )
    )
    title = (
        f"{len(names)} datasets, {seeds} seed(s), "
        + (f"~{steps} baseline steps per dataset" if steps is not None else f"{kw['epochs']} epochs")
        + (f" (--quick: {QUICK_NOTE})" if quick else "")
    )
    return write_report(results, Path(out), note, wall, earlier, title)
