"""`wearnav bench real-odometry --seeds 0,1,2`: the real-building suite once per seed, and one page
that says what holds across seeds (issue 34 §3).

Each seed is a whole suite (:func:`wearnav.bench.real.plan_benchmark`) in ``out/seed-<s>/`` with its
own results.md; the split data and the site yaws are prepared once, in ``out/data/``, which every
seed's folder links to. The page ``out/results.md`` gives, per site and per scored path (each model,
its PDR-speed hybrid, PDR):

- the known-start statistics of every seed and their mean and spread over seeds;
- the path minus PDR, paired by walk: the difference of the median and p75 errors with a 90 %
  interval from resampling whole walks (:func:`wearnav.stats.walk_bootstrap_difference`), each walk
  carrying its points of every seed (so the interval covers the walks, and the seeds average in);
- where the site has fixes, the same for the user protocol's smoother against PDR's smoother.

PDR is not learned: its seeds give the same path, and it is paired with each learned path as is.

Decision: docs/decisions/0026-real-bench-seeds.md.
"""

from __future__ import annotations

import dataclasses
import os
import platform
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import runs
from wearnav.bench.decompose import ALONG_TEXT, along_across_table
from wearnav.bench.executor import Execution, run_jobs
from wearnav.bench.real import RealBench, plan_benchmark
from wearnav.bench.real_page import evaluations, frame_name, suite_runs, warp_text
from wearnav.bench.user_protocol import FLOOR_COLUMN, PARTICLES, PARTICLES_LABEL, RAW_FIXES
from wearnav.core.fileio import write_text_atomic
from wearnav.core.provenance import provenance
from wearnav.core.textio import read_json
from wearnav.errors import ValidationError
from wearnav.fuse import fix_lags
from wearnav.stats import mean_sd_text, walk_bootstrap_difference

REFERENCE = "pdr"  # the path every other is paired with
SMOOTH_SUFFIX = " · smoother (`track` now)"  # the user protocol's row label of a path's smoother


def seed_folder(out: Path, seed: int) -> Path:
    return Path(out) / f"seed-{seed}"


def run_seeds(
    data: Path,
    out: Path,
    seeds: tuple[int, ...],
    bench: RealBench = RealBench(),
    execution: Execution = Execution(),
    progress: bool = True,
    echo=print,
    **plan_kw,
) -> Path:
    """Every seed's suite (resumable, one executor call for all their jobs), then the page."""
    if len(set(seeds)) < 2:
        raise ValidationError(f"--seeds needs at least two different seeds, got {list(seeds)}")
    out = Path(out)
    (out / "data").mkdir(parents=True, exist_ok=True)
    plans = []
    for s in seeds:
        folder = seed_folder(out, s)
        folder.mkdir(parents=True, exist_ok=True)
        if not (folder / "data").exists():  # the split data and site yaws are the seeds' common ground
            os.symlink(Path("..") / "data", folder / "data", target_is_directory=True)
        plans.append(
            plan_benchmark(
                data,
                folder,
                bench=dataclasses.replace(bench, seed=s),
                progress=progress,
                echo=echo,
                in_process=execution.in_process,
                **plan_kw,
            )
        )
    # seed by seed: the first seed's whole suite is done before the next one starts
    run_jobs([dataclasses.replace(j, cost=0) for p in plans for j in p.jobs], execution, echo)
    for p in plans:
        p.finish()
    return seeds_page(out, {s: seed_folder(out, s) for s in seeds}, bench)


def walk_errors(eval_dir: Path) -> dict[str, np.ndarray]:
    """A known-start evaluation's errors (m) per test walk, by the walk's name."""
    m = runs.read_metrics(eval_dir)
    return {r["name"]: np.asarray(r.get("point_errors", []), float) for r in m["splits"]["test"]["sequences"]}


def _paired(a: dict[int, dict[str, np.ndarray]], b: dict[int, dict[str, np.ndarray]]) -> dict | None:
    """``a`` minus ``b`` over the walks both scored in every seed of ``a`` (a walk's points of all
    seeds together; ``b`` taken from its own seed, or its only one)."""
    common: set[str] | None = None
    for d in (*a.values(), *b.values()):
        common = set(d) if common is None else common & set(d)
    walks = sorted(common or ())
    if len(walks) < 2:
        return None
    pick = lambda d, s: d.get(s, next(iter(d.values())))
    xa = [np.concatenate([a[s][w] for s in a]) for w in walks]
    xb = [np.concatenate([pick(b, s)[w] for s in a]) for w in walks]
    return walk_bootstrap_difference(xa, xb, quantiles=(50, 75, 95))


def _interval(d: dict | None, k: int) -> str:
    if d is None:
        return "—"
    return f"{d['difference'][k]:+.2f} [{d['low'][k]:+.2f}, {d['high'][k]:+.2f}]"


def known_start_table(seed_docs: dict[int, dict], seed_evals: dict[int, dict[str, Path]], site: str) -> pd.DataFrame:
    """Per path: each seed's median / p75 / length ratio (known start), their mean ± sd over the
    seeds, and the path minus PDR paired by walk (median, p75, with 90 % walk-bootstrap intervals)."""
    labels: list[str] = []
    for doc in seed_docs.values():
        labels += [r["method"] for r in doc["sites"][site]["table"] if r["method"] not in labels]
    errors = {
        label: {s: walk_errors(ev[label]) for s, ev in seed_evals.items() if label in ev}
        for label in labels
        if any(label in ev for ev in seed_evals.values())
    }
    rows = []
    for label in labels:
        per_seed = [
            next((r for r in doc["sites"][site]["table"] if r["method"] == label), None) for doc in seed_docs.values()
        ]
        got = [r for r in per_seed if r is not None]
        paired = _paired(errors[label], errors[REFERENCE]) if label in errors and REFERENCE in errors else None
        rows.append(
            {
                "path": label,
                "seeds": len(got),
                "median (m)": mean_sd_text([r["median (m)"] for r in got]),
                "p75 (m)": mean_sd_text([r["p75 (m)"] for r in got]),
                "p95 (m)": mean_sd_text([r["p95 (m)"] for r in got]),
                "length ratio": mean_sd_text([r["length ratio"] for r in got]),
                "arc ratio": mean_sd_text([r["arc ratio"] for r in got if "arc ratio" in r]),
                "minus PDR, median (m)": "—" if label == REFERENCE else _interval(paired, 0),
                "minus PDR, p75 (m)": "—" if label == REFERENCE else _interval(paired, 1),
                "median (m) per seed": " / ".join(f"{r['median (m)']:.2f}" for r in got),
            }
        )
    return pd.DataFrame(rows)


def smoother_table(
    seed_docs: dict[int, dict],
    site: str,
    key: str = "smooth",
    suffix: str = SMOOTH_SUFFIX,
    column: str = "smoother of",
) -> pd.DataFrame | None:
    """The user protocol's smoother (or, by ``key``/``suffix``, another of its paths: the particle filter)
    per model over the seeds, minus PDR's same path and minus the raw fixes, paired by walk."""
    ups = {s: d["sites"][site].get("user_protocol") for s, d in seed_docs.items()}
    ups = {s: u for s, u in ups.items() if u and any(key in r for r in u["runs"].values())}
    if not ups:
        return None
    labels: list[str] = []
    for u in ups.values():
        labels += [k for k in u["runs"] if k not in labels and key in u["runs"][k]]

    def walks(label: str, path: str) -> dict[int, dict[str, np.ndarray]]:
        return {
            s: {w: np.asarray(e, float) for w, e in u["runs"][label][path]["by_trace"].items()}
            for s, u in ups.items()
            if label in u["runs"] and path in u["runs"][label]
        }

    by_trace = {label: walks(label, key) for label in labels}
    rows = []
    for label in labels:
        found = [
            next((r for r in u["table"] if r["path"] == label + suffix), None)
            for u in ups.values()
            if label in u["runs"]
        ]
        stats = [r for r in found if r is not None]
        paired = _paired(by_trace[label], by_trace[REFERENCE]) if REFERENCE in by_trace else None
        raw = _paired(by_trace[label], walks(label, RAW_FIXES))
        rows.append(
            {
                column: label,
                "seeds": len(stats),
                "median (m)": mean_sd_text([r["median (m)"] for r in stats]),
                "p75 (m)": mean_sd_text([r["p75 (m)"] for r in stats]),
                "p95 (m)": mean_sd_text([r["p95 (m)"] for r in stats]),
                "length ratio": mean_sd_text([r["length ratio"] for r in stats]),
                "minus PDR's, median (m)": "—" if label == REFERENCE else _interval(paired, 0),
                "minus PDR's, p75 (m)": "—" if label == REFERENCE else _interval(paired, 1),
                "minus raw fixes, median (m)": _interval(raw, 0),
                "minus raw fixes, p95 (m)": _interval(raw, 2),
                **(
                    {FLOOR_COLUMN: mean_sd_text([r[FLOOR_COLUMN] for r in stats if FLOOR_COLUMN in r])}
                    if any(FLOOR_COLUMN in r for r in stats)
                    else {}
                ),
            }
        )
    return pd.DataFrame(rows)


SEEDS_TEXT = (
    "Each seed is a whole suite with its own page; *mean ± sd* over the seeds. *Minus "
    "PDR*: the path's error quantile minus PDR's on the same walks (below 0: better than PDR), in "
    "brackets a 90 % interval from resampling whole walks, each walk carrying its points of every "
    "seed (:func:`wearnav.stats.walk_bootstrap_difference`); an interval across 0 means these walks "
    "cannot tell the two apart. *Length ratio*: the median over walks of the path's length through "
    "the surveyed times over the truth's (1 is right); *arc ratio*: of the path's own length over the "
    "truth's polyline (below 1 the path is slow, however it wanders; — on pages made before it)."
)


def seeds_page(out: Path, folders: dict[int, Path], bench: RealBench) -> Path:
    """``out/results.md`` and ``results.json`` from the seeds' suites (:func:`run_seeds`)."""
    docs = {s: read_json(f / "results.json") for s, f in folders.items() if (f / "results.json").is_file()}
    if not docs:
        raise ValidationError("no seed of this suite has a results.json yet", out)
    first = next(iter(docs.values()))
    src = first["sites"]["main"]["split"]["source"]
    trained = Path(bench.train_data).name if bench.train_data else src
    tested = " and ".join(site["split"]["source"] for site in first["sites"].values())
    # augmentations beyond the default yaw (which the heading frame drops), named in the title
    extra = [a for a in bench.augment if a != "rotate_yaw"]
    learned = (
        [f"on {' + '.join(bench.devices)} (the phone alone in the buildings)"] if bench.devices != ("phone",) else []
    )
    learned += [f"in {frame_name(bench.devices)}"] if bench.heading_frame else []
    learned += [f"with the `{bench.vel_loss}` loss"] if bench.vel_loss != "mse" else []
    lagged = fix_lags(c for d in docs.values() for c in d["sites"].get("main", {}).get("calibration", {}).values())
    p = provenance()
    lines = [
        f"# Odometry in real buildings over {len(docs)} seeds: trained on `{trained}`, tested on {tested}"
        + (f", the learned models {' '.join(learned)}" if learned else "")
        + (f", augmented with {', '.join(f'`{a}`' for a in extra)}" if extra else "")
        + warp_text(bench.speed_warp)
        + (", the fixes read at the site's lag" if lagged else "")
        + f" ({bench.epochs} epoch{'' if bench.epochs == 1 else 's'} at most)",
        "",
        f"Generated by `wearnav bench real-odometry --seeds` ({p['created']}, wearnav {p['wearnav']} {p['commit']}) "
        f"on {platform.machine()}, {os.cpu_count()} CPUs, from the seeds' suite folders.",
        "",
        f"Seeds {', '.join(map(str, docs))} (suites {', '.join(f'`{folders[s].name}`' for s in docs)}); every "
        f"other setting as each seed's page says (at most {bench.epochs} epochs, velocity loss `{bench.vel_loss}`"
        + (
            f", the learned models' windows in {frame_name(bench.devices)} without random yaw"
            if bench.heading_frame
            else ""
        )
        + ").",
        "",
        SEEDS_TEXT,
        "",
    ]
    doc: dict = {"seeds": list(docs), "bench": dataclasses.asdict(bench), "sites": {}}
    for site in first["sites"]:
        evals = {
            s: {
                label: ev
                for label, (_, ev) in evaluations(
                    suite_runs(folders[s], str(folders[s] / "data" / "main")), site
                ).items()
            }
            for s in docs
        }
        ks = known_start_table(docs, evals, site)
        labels = [label for label in ks["path"] if any(label in ev for ev in evals.values())]
        split = along_across_table(
            {
                label: [(ev[label], folders[s] / "data" / site) for s, ev in evals.items() if label in ev]
                for label in labels
            }
        )
        sm = smoother_table(docs, site)
        pf = smoother_table(docs, site, PARTICLES, " · " + PARTICLES_LABEL, "particle filter of")
        doc["sites"][site] = {
            "known_start": ks.to_dict(orient="records"),
            "along_across": None if split is None else split.to_dict(orient="records"),
            "smoother": None if sm is None else sm.to_dict(orient="records"),
            "particle_filter": None if pf is None else pf.to_dict(orient="records"),
        }
        where = "held-out groups" if site == "main" else "another building, never trained on"
        lines += [f"## {first['sites'][site]['split']['source']} ({where})", "", "Known start:", ""]
        lines += [ks.to_markdown(index=False), ""]
        if split is not None:
            lines += [ALONG_TEXT.format(seeds="; mean ± sd over the seeds"), "", split.to_markdown(index=False), ""]
        if sm is not None:
            lags = fix_lags(c for d in docs.values() for c in d["sites"][site].get("calibration", {}).values())
            lag = (
                f" Each fix read as where the walker was {' / '.join(f'{v:g}' for v in lags)} s before its time "
                "stamp (the fixes' lag on the site's training walks, `wearnav.fuse.fix_lag_of`; `track --fix-lag`)."
                if lags
                else ""
            )
            lines += [
                "User protocol (no truth), the smoother (`track`'s default):" + lag,
                "",
                sm.to_markdown(index=False),
                "",
            ]
        if pf is not None:
            lines += [
                "User protocol, the particle filter with fixes, beacons and the barometer (issue 36; *floor "
                "right*: share of surveyed points on the right floor):",
                "",
                pf.to_markdown(index=False),
                "",
            ]
    runs.write_json(out / "results.json", doc)
    return write_text_atomic("\n".join(lines), out / "results.md")
