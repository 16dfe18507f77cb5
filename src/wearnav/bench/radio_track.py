"""`wearnav bench radio-track`: the path a user gets with a radio map built from other walks (issue 60 §5).

The user protocol: `track` is run on each held-out walk exactly as a user would run it (no start, no
site yaw, no truth), with a radio map built from *other* walks; the path is scored afterwards at the
walk's surveyed points from the second on (:func:`wearnav.bench.user_protocol.score_path`; the truth
is read only there), and its floor at them.

``ipin2023``  leave one trial out: each trial's walks (every repetition) with the radio map of the
              other trials; the phone's fixes alone, the fixes and the radio map, the radio map
              without any fix (no GNSS); beside the raw fixes at the same points. The shared copy
              has no floor plan of the venue, so there is no plan row.
``ilc2``      site 1, walks held out in ``folds`` groups over all floors: each walk with the radio map
              of the walks of the other groups (every floor: the floor comes from Wi-Fi too), no GNSS
              (the traces have none), no start; with the floor's plan (the particle filter) and without
              (the smoother). ``per_floor`` walks per floor, spread over each floor's walks.

Each row for the shipped phone model (``phone``) and PDR (``pdr``), with the learned path against PDR's
on the same walks (the difference of its median, p75 and p95, and a 90 % interval from resampling
walks: :func:`wearnav.stats.walk_bootstrap_difference`). No known-start rows: a start taken from the
surveyed points is truth in a test input, which the user protocol forbids.

Resumable: each walk's scores are one JSON under ``walks/<site>/``; the maps under ``maps/``.
"""

from __future__ import annotations

import dataclasses
import os
import platform
import shutil
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from wearnav import runs
from wearnav.bench.user_protocol import fix_point_errors, score_path
from wearnav.core.provenance import provenance
from wearnav.core.textio import read_json
from wearnav.errors import ValidationError, WearnavWarning
from wearnav.fuse.radiobuild import build as build_map
from wearnav.fuse.radiomap import RadioMapConfig, walk_group
from wearnav.recording import Recording
from wearnav.stats import difference_cells, walk_bootstrap_difference
from wearnav.track import track as track_

MODELS = ("phone", "pdr")  # the shipped phone model, and PDR beside it
RAW_FIXES = "raw phone fixes"
# IPIN's targets (issue 60): p75 ≤ 6 m, median ≤ 0.4× the raw fixes', floor right ≥ 95 %; ILC2's: median ≤ 3 m
IPIN_P75_M, IPIN_FIX_RATIO, FLOOR_RIGHT, ILC2_MEDIAN_M = 6.0, 0.4, 0.95, 3.0


@dataclasses.dataclass(frozen=True)
class Variant:
    """One way of running `track`: keep the phone's fixes, the ``plan`` argument, use the radio map."""

    label: str
    fixes: bool
    plan: str
    radio: bool


IPIN_VARIANTS = (
    Variant("fixes", True, "auto", False),
    Variant("fixes + radio map", True, "auto", True),
    Variant("radio map, no GNSS", False, "auto", True),
)
ILC2_VARIANTS = (
    Variant("radio map + plan", False, "auto", True),
    Variant("radio map, no plan", False, "none", True),
)
SITES = {"ipin2023": IPIN_VARIANTS, "ilc2": ILC2_VARIANTS}


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in text)


def _fit(recs: Sequence[Recording]) -> list[Recording]:
    """The walks a bench can score: surveyed points (≥ 3) and Wi-Fi scans."""
    return [r for r in recs if r.truth is not None and len(r.truth) >= 3 and r.wifi is not None]


def ipin_cases(recs: Sequence[Recording]) -> list[tuple[Recording, str, list[Recording]]]:
    """(held-out walk, its map's name, the map's walks): every walk, the map of the other trials."""
    fit = _fit(recs)
    group = {r.name: walk_group(r, "trial") for r in fit}
    return [(r, _slug(group[r.name]), [o for o in fit if group[o.name] != group[r.name]]) for r in fit]


def ilc2_cases(recs: Sequence[Recording], folds: int, per_floor: int) -> list[tuple[Recording, str, list[Recording]]]:
    """(held-out walk, its map's name, the map's walks): ``per_floor`` walks of each floor (spread over
    the floor's walks in name order), each with the map of the walks outside its group; walks go to
    groups in name order, round robin, so every group holds walks of every floor."""
    fit = sorted(_fit(recs), key=lambda r: r.name)
    if len(fit) < folds:
        raise ValidationError(f"ILC2: {len(fit)} walks with surveyed points and Wi-Fi, fewer than {folds} folds")
    fold_of = {r.name: i % folds for i, r in enumerate(fit)}
    cases = []
    for floor in sorted({str(r.meta.get("floor_name")) for r in fit}):
        walks = [r for r in fit if str(r.meta.get("floor_name")) == floor]
        picked = sorted({int(i) for i in np.linspace(0, len(walks) - 1, min(per_floor, len(walks)))})
        for i in picked:
            r = walks[i]
            k = fold_of[r.name]
            cases.append((r, f"fold{k}", [o for o in fit if fold_of[o.name] != k]))
    return cases


def ensure_map(folder: Path, walks: Sequence[Recording], source: str, group_by: str) -> Path:
    """The radio map of ``walks`` in ``folder`` (built once)."""
    if not (folder / "card.json").is_file():
        build_map(walks, RadioMapConfig(), source=source, group_by=group_by).save(folder)
    return folder


def score_walk(rec: Recording, map_dir: Path, variants: Sequence[Variant], work: Path) -> dict[str, Any]:
    """`track` on ``rec`` for each model × variant (user protocol), scored at its surveyed points:
    per run its errors (m), floor right at each point (where the path has a floor), what placed it."""
    import pandas as pd

    truth = rec.truth
    if truth is None:
        raise ValidationError(f"{rec.name}: no surveyed points to score the path at")
    out: dict[str, Any] = {"walk": rec.name, "runs": {}}
    if rec.fixes is not None and len(rec.fixes):
        out[RAW_FIXES] = [round(float(e), 3) for e in fix_point_errors(rec)]
    inputs = work / "inputs"
    inputs.mkdir(parents=True, exist_ok=True)
    for v in variants:
        walk = rec if v.fixes else dataclasses.replace(rec, fixes=None, name=f"{rec.name}_nofix")
        src = inputs / f"{walk.name}.h5"
        if not src.is_file():
            walk.save(src)
        for model in MODELS:
            folder = work / "track" / f"{_slug(rec.name)}-{_slug(v.label)}-{model}"
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", WearnavWarning)
                summary = track_(src, model, folder, plan=v.plan, radiomap=map_dir if v.radio else None)
            table = pd.read_csv(folder / "trajectory.csv")
            row: dict[str, Any] = {"method": summary["anchoring"]["method"], "warnings": summary.get("warnings", [])}
            if "east" in table:
                t = table["t"].to_numpy()
                err, _ = score_path(t, table[["east", "north"]].to_numpy(), truth.t, truth.pos[:, :2])
                row["errors"] = [round(float(e), 3) for e in err]
                if "floor" in table and truth.floor is not None:
                    near = np.clip(np.searchsorted(t, truth.t), 0, len(t) - 1)
                    row["floor_right"] = (table["floor"].to_numpy()[near] == truth.floor).astype(int).tolist()
            row["map_used"] = bool(summary.get("map", {}).get("used", False))
            if "radiomap" in summary:
                row["radio_positions"] = summary["radiomap"].get("positions")
            out["runs"][f"{v.label} · {model}"] = row
            shutil.rmtree(folder)
    return out


def run_site(
    site: str,
    cases: list[tuple[Recording, str, list[Recording]]],
    out: Path,
    log: Callable[[str], None] = lambda _: None,
) -> list[dict[str, Any]]:
    """Every case of ``site`` scored (resumes: a walk's JSON already there is read, not rerun)."""
    variants = SITES[site]
    walks_dir, maps_dir = out / "walks" / site, out / "maps" / site
    walks_dir.mkdir(parents=True, exist_ok=True)
    done = []
    for i, (rec, map_name, train) in enumerate(cases):
        f = walks_dir / f"{_slug(rec.name)}.json"
        if not f.is_file():
            t0 = time.perf_counter()
            source = "the other trials" if site == "ipin2023" else "the walks of the other groups"
            map_dir = ensure_map(maps_dir / map_name, train, source, "trial" if site == "ipin2023" else "walk")
            scored = score_walk(rec, map_dir, variants, out / "work")
            runs.write_json(f, scored | {"map": map_name, "seconds": round(time.perf_counter() - t0, 1)})
            log(f"{site} {i + 1}/{len(cases)} {rec.name}: {time.perf_counter() - t0:.0f} s")
        done.append(read_json(f))
    shutil.rmtree(out / "work", ignore_errors=True)
    return done


def _stats(e: np.ndarray) -> dict[str, float | None]:
    if not e.size:
        return {"median_m": None, "p75_m": None, "p95_m": None}
    return {f"{k}_m": round(float(np.percentile(e, q)), 2) for k, q in (("median", 50), ("p75", 75), ("p95", 95))}


def summarise(site: str, walks: list[dict[str, Any]]) -> dict[str, Any]:
    """Per run label (variant · model): walks placed, points, median / p75 / p95, floor right; the raw
    fixes; the learned path against PDR's on the same walks (walk bootstrap); the targets."""
    labels = [f"{v.label} · {m}" for v in SITES[site] for m in MODELS]
    rows: dict[str, dict[str, Any]] = {}
    for label in labels:
        runs_ = [w["runs"][label] for w in walks if label in w["runs"]]
        errs = [np.asarray(r["errors"]) for r in runs_ if "errors" in r]
        floors = [np.asarray(r["floor_right"]) for r in runs_ if "floor_right" in r]
        e = np.concatenate(errs) if errs else np.empty(0)
        rows[label] = {
            "walks": len(runs_),
            "placed": len(errs),
            "points": int(e.size),
            **_stats(e),
            "floor_right": round(float(np.concatenate(floors).mean()), 3) if floors else None,
            "map_used": sum(bool(r.get("map_used")) for r in runs_),
        }
    raw = [np.asarray(w[RAW_FIXES]) for w in walks if RAW_FIXES in w]
    if raw:
        rows[RAW_FIXES] = {"walks": len(raw), "placed": len(raw), "points": int(sum(r.size for r in raw))}
        rows[RAW_FIXES] |= _stats(np.concatenate(raw)) | {"floor_right": None, "map_used": 0}
    versus: dict[str, Any] = {}
    for v in SITES[site]:
        a, b = f"{v.label} · phone", f"{v.label} · pdr"
        pairs = [
            (w["runs"][a]["errors"], w["runs"][b]["errors"])
            for w in walks
            if "errors" in w["runs"].get(a, {}) and "errors" in w["runs"].get(b, {})
        ]
        if len(pairs) >= 2:
            versus[v.label] = walk_bootstrap_difference([p[0] for p in pairs], [p[1] for p in pairs])
    return {"rows": rows, "learned_vs_pdr": versus, "targets": targets(site, rows)}


def targets(site: str, rows: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """Issue 60's done-when lines for ``site``: the figure, the target, met or not."""
    out: list[dict[str, Any]] = []

    def add(what: str, value: float | None, target: float, below: bool = True) -> None:
        met = value is not None and (value <= target if below else value >= target)
        out.append({"target": what, "value": value, "limit": target, "met": bool(met)})

    def best(keys: Sequence[str], col: str) -> float | None:
        vals = [rows[k][col] for k in keys if k in rows and rows[k][col] is not None]
        return min(vals) if vals else None

    if site == "ipin2023":
        fused = ("fixes + radio map · phone",)
        add("p75 ≤ 6.0 m (fixes + radio map, shipped model)", best(fused, "p75_m"), IPIN_P75_M)
        raw = rows.get(RAW_FIXES, {}).get("median_m")
        med = best(fused, "median_m")
        ratio = round(med / raw, 3) if med is not None and raw else None
        add("median ≤ 0.4× the raw fixes' (ratio)", ratio, IPIN_FIX_RATIO)
        add("floor right ≥ 95 % of the points", rows.get(fused[0], {}).get("floor_right"), FLOOR_RIGHT, below=False)
    else:
        add(
            "median ≤ 3 m, no start, no GNSS, radio map + plan (shipped model)",
            rows.get("radio map + plan · phone", {}).get("median_m"),
            ILC2_MEDIAN_M,
        )
    learned = "fixes + radio map" if site == "ipin2023" else "radio map + plan"
    a, b = rows.get(f"{learned} · phone", {}), rows.get(f"{learned} · pdr", {})
    if a.get("median_m") is not None and b.get("median_m") is not None:
        add(f"learned ≤ PDR at the median ({learned}; learned − PDR, m)", round(a["median_m"] - b["median_m"], 2), 0.0)
    return out


SITE_TITLES = {
    "ipin2023": "IPIN 2023, each trial held out (the radio map of the other trials)",
    "ilc2": "ILC2 site 1, walks held out in groups (the radio map of the other groups' walks, every floor)",
}


def page(summary: dict[str, Any], meta: dict[str, Any]) -> str:
    """results.md of the suite."""
    p = provenance()
    lines = [
        "# The user's path with a radio map from other walks (issue 60 §5)",
        "",
        f"Generated by `wearnav bench radio-track` ({p['created']}, wearnav {p['wearnav']} {p['commit']}); "
        f"{platform.machine()}, {os.cpu_count()} cores, one process; {meta['track_s'] / 60:.0f} min of `track` "
        "runs and map builds in all (summed over the walks' runs, which may span sessions).",
        "",
        "User protocol: `track` run as a user would (no start, no site yaw, no truth) with a radio map built "
        "from other walks; scored at each walk's surveyed points from the second on, the floor at them. "
        "`phone`: the shipped phone model (trained on the simulator only); `pdr`: step detection × 0.67 m. "
        "No known-start rows: a start taken from the survey is truth in a test input. The weight of radio "
        "positions beside GNSS (`RADIO_BESIDE_FIXES`) was chosen on IPIN's trials, each left out in turn: "
        "docs/decisions/0049-radio-map-bench-floor-weights.md gives that choice's score on the trials left out. "
        "A radio position's σ is calibrated by groups beside GNSS and by the map's one scale without it "
        "(every ILC2 row): chosen on IPIN's rows without GNSS, before ILC2 was scored with it "
        "(docs/decisions/0050-radio-sigma-without-gnss.md).",
    ]
    for site, s in summary.items():
        lines += [
            "",
            f"## {SITE_TITLES[site]}",
            "",
            "| path | walks | placed | points | median (m) | p75 (m) | p95 (m) | floor right | plan used |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for label, r in s["rows"].items():
            cells = [r.get(k) for k in ("median_m", "p75_m", "p95_m")]
            fr = "—" if r["floor_right"] is None else f"{r['floor_right']:.3f}"
            lines.append(
                f"| {label} | {r['walks']} | {r['placed']} | {r['points']} | "
                + " | ".join("—" if c is None else f"{c:.2f}" for c in cells)
                + f" | {fr} | {r['map_used']} |"
            )
        if s["learned_vs_pdr"]:
            lines += [
                "",
                "The shipped model against PDR on the same walks (learned − PDR, m; 90 % interval by walk bootstrap; "
                "below 0: the learned path is better):",
                "",
                "| evidence | walks | median (m) | p75 (m) | p95 (m) |",
                "|---|---:|---|---|---|",
            ]
            for label, d in s["learned_vs_pdr"].items():
                lines.append(f"| {label} | {d['walks']} | " + " | ".join(difference_cells(d).values()) + " |")
        lines += ["", "| target (issue 60) | measured | limit | met |", "|---|---:|---:|---|"]
        for t in s["targets"]:
            v = "—" if t["value"] is None else f"{t['value']:g}"
            lines.append(f"| {t['target']} | {v} | {t['limit']:g} | {'✓' if t['met'] else '✗'} |")
    lines += ["", "![error CDFs](radio_track.png)", ""]
    return "\n".join(lines)


def plot(summary: dict[str, Any], walks: dict[str, list[dict[str, Any]]], path: Path) -> None:
    """Each site's error CDF per path (the shipped model solid, PDR dashed, the raw fixes grey)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(summary), figsize=(6.5 * len(summary), 4.5), squeeze=False)
    for ax, site in zip(axes[0], summary):
        for label in summary[site]["rows"]:
            if label == RAW_FIXES:
                e = np.concatenate([np.asarray(w[RAW_FIXES]) for w in walks[site] if RAW_FIXES in w])
                style: dict[str, Any] = {"color": "0.5", "lw": 1.5}
            else:
                e = np.concatenate(
                    [
                        np.asarray(w["runs"][label]["errors"])
                        for w in walks[site]
                        if "errors" in w["runs"].get(label, {})
                    ]
                    or [np.empty(0)]
                )
                style = {"ls": "--" if label.endswith("pdr") else "-"}
            if e.size:
                ax.plot(np.sort(e), np.arange(1, e.size + 1) / e.size, label=label, **style)
        ax.set_xlim(0, 25)
        ax.set_xlabel("error at surveyed points (m)")
        ax.set_ylabel("share of points")
        ax.set_title(site)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run_suite(
    out: str | Path,
    ipin: Sequence[Recording] = (),
    ilc2: Sequence[Recording] = (),
    folds: int = 5,
    per_floor: int = 20,
    log: Callable[[str], None] = lambda _: None,
) -> dict[str, Any]:
    """The suite (module docstring) into ``out``: ``walks/``, ``maps/``, ``metrics.json``, ``results.md``,
    ``radio_track.png``; returns the summary."""
    out = Path(out)
    t0 = time.perf_counter()
    walks: dict[str, list[dict[str, Any]]] = {}
    if ipin:
        walks["ipin2023"] = run_site("ipin2023", ipin_cases(ipin), out, log)
    if ilc2:
        walks["ilc2"] = run_site("ilc2", ilc2_cases(ilc2, folds, per_floor), out, log)
    if not walks:
        raise ValidationError("radio-track needs IPIN 2023 and/or ILC2 walks with surveyed points and Wi-Fi")
    summary = {site: summarise(site, w) for site, w in walks.items()}
    track_s = sum(float(w.get("seconds", 0.0)) for ws in walks.values() for w in ws)
    meta = {"folds": folds, "per_floor": per_floor, "wall_s": round(time.perf_counter() - t0, 1), "track_s": track_s}
    runs.write_metrics(out, {"suite": "radio-track", **meta, "summary": summary})
    plot(summary, walks, out / "radio_track.png")
    (out / "results.md").write_text(page(summary, meta))
    return summary
