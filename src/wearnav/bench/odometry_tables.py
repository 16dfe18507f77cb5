"""The odometry grid's page: Suite-IN++ (paper 000) Tables III–VI and Figs. 7 and 11 from run folders.

Every cell is mean ± std over the training seeds of one grid entry (a row label, see
:func:`wearnav.bench.odometry.row_label`), each seed's number being that run's mean over
sequences. A † marks a cell where the reference model (Suite-IN++) differs from that row beyond
seed spread: Welch's t-test over the per-seed numbers, Benjamini–Hochberg-adjusted over the
rows of that column (:mod:`wearnav.stats`). Only complete runs (``metrics.json``) count; a row
with fewer seeds than asked says "n of N".

Table VI is measured here, when the page is written (same machine, same command, 1 torch
thread); MACs per window come from :func:`wearnav.bench.efficiency.macs_per_window`.

Decision: docs/decisions/0011-odometry-grid-and-page.md.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch

from wearnav import runs
from wearnav.bench.efficiency import macs_per_window, windows_per_second
from wearnav.bench.odometry import DIAGNOSTIC_TRUTH_FRAME, MODES, TEST_SPLITS, beats_text, row_label
from wearnav.core.fileio import write_text_atomic
from wearnav.core.provenance import provenance
from wearnav.errors import ValidationError, WearnavError
from wearnav.models.registry import build, get, n_parameters
from wearnav.models.suitein import ABLATIONS
from wearnav.report.odometry import plot_cdf_panels, plot_speed
from wearnav.stats import SIGNIFICANCE, bh_adjust, welch_p

log = logging.getLogger(__name__)

REFERENCE = "suitein++"  # the row every † compares against
PLACEMENTS = ("HD", "MP", "PK", "BG")  # Table IV: handheld, multi-changed, pocket, bag
PLACEMENT_SPLITS = ("test", "test_unseen")  # where a placement's sequences are (PK, BG: unseen only)
VELOCITY_MODELS = ("suitein", "suitein++")  # Fig. 11's models
VELOCITY_MODES = ("DRW", "DLW")  # Fig. 11's sequences: a device removed; stationary phases
SPEED_SMOOTH_S = 1.0  # moving mean over the speed derived from positions (Fig. 11)
BATCHES = (1, 256)  # Table VI windows/s
ABLATION_MODULES = (("Contrast.FE", "contrast"), ("Weighted.GF", "weighted"), ("Attentive.LA", "attentive"))
FRAME_RULES = {
    "initial": "one constant yaw per test/validation recording, estimated from the first 10 s of its truth",
    "truth": "the truth's time-varying yaw (a diagnostic: it removes heading drift using ground truth)",
}
MARK = " †"
MARK_NOTE = (
    f"† = Suite-IN++ differs from this row beyond seed spread: Welch's t-test over the per-seed "
    f"values, Benjamini–Hochberg-adjusted p < {SIGNIFICANCE} over the rows of that column"
)


@dataclasses.dataclass(frozen=True)
class GridRun:
    """One complete run folder of the grid: its row label, seed, training config and metrics."""

    folder: Path
    label: str
    model: str
    seed: int
    train: dict
    metrics: dict


def read_grid(folders) -> dict[str, list[GridRun]]:
    """Complete run folders grouped by row label (first-seen order), each group sorted by seed;
    incomplete folders are left out."""
    out: dict[str, list[GridRun]] = {}
    for folder in folders:
        if not runs.is_complete(folder):
            continue
        train = runs.read_config(folder)["config"]["train"]
        label = row_label(train["model"], train.get("model_args"))
        out.setdefault(label, []).append(
            GridRun(Path(folder), label, train["model"], int(train.get("seed", 0)), train, runs.read_metrics(folder))
        )
    return {k: sorted(v, key=lambda r: r.seed) for k, v in out.items()}


def cell_text(values: list[float], marked: bool = False) -> str:
    """ "m ± s" (std over seeds, ddof 1) with two decimals; one seed: "m"; none: ""."""
    if not values:
        return ""
    text = f"{np.mean(values):.2f}" + (f" ± {np.std(values, ddof=1):.2f}" if len(values) > 1 else "")
    return text + (MARK if marked else "")


def seeds_text(n: int, expected: int | None) -> str:
    return f"{n} of {expected}" if expected and n < expected else str(n)


def _finite(v) -> bool:
    return v is not None and isinstance(v, (int, float)) and math.isfinite(v)


def summary_of(run: GridRun, split: str, group: str | None = None, name: str | None = None) -> dict:
    """A run's summary on ``split``: overall, or of one ``group`` ("by_mode", "by_placement") entry."""
    res = run.metrics.get("splits", {}).get(split) or {}
    return (res.get("summary") if group is None else res.get(group, {}).get(name)) or {}


def summary_of_rows(run: GridRun, split: str) -> list[dict]:
    """A run's per-sequence rows on ``split`` (name, mode, placement, ate, ...)."""
    return (run.metrics.get("splits", {}).get(split) or {}).get("sequences", [])


def marked_table(
    grid: dict[str, list[GridRun]], labels: list[str], columns: dict, expected: int | None, reference: str = REFERENCE
) -> tuple[pd.DataFrame, dict]:
    """Rows ``labels``; per column ``name: fn(run) -> number | None``, mean ± std over seeds and a
    † where ``reference`` differs beyond seed spread (BH over the rows of that column). Returns
    the table and, per column, each row's per-seed values with raw and adjusted p."""
    values = {c: {lab: [v for r in grid[lab] if _finite(v := fn(r))] for lab in labels} for c, fn in columns.items()}
    stats: dict = {}
    for c, per in values.items():
        ref = per.get(reference, [])
        p = {lab: welch_p(v, ref) for lab, v in per.items() if lab != reference and v and ref}
        adj = bh_adjust(p)
        stats[c] = {lab: {"values": per[lab], "p": p.get(lab), "p_bh": adj.get(lab)} for lab in labels}
    rows = []
    for lab in labels:
        row = {"model": lab}
        for c in columns:
            pb = stats[c][lab]["p_bh"]
            row[c] = cell_text(values[c][lab], pb is not None and pb < SIGNIFICANCE)
        rows.append({**row, "seeds": seeds_text(len(grid[lab]), expected)})
    return pd.DataFrame(rows), stats


def _metric(split: str, key: str, group: str | None = None, name: str | None = None) -> Callable[[GridRun], Any]:
    """``fn(run)``: the run's summary ``key`` on ``split`` (of one ``group`` entry where given)."""
    return lambda r: summary_of(r, split, group, name).get(key)


def table3_columns(split: str) -> dict:
    cols: dict[str, Callable[[GridRun], Any]] = {
        "ATE": lambda r: summary_of(r, split).get("ate_mean"),
        "RTE": lambda r: summary_of(r, split).get("rte_mean"),
    }
    for mode in MODES:
        cols[f"{mode} ATE"] = _metric(split, "ate_mean", "by_mode", mode)
        cols[f"{mode} RTE"] = _metric(split, "rte_mean", "by_mode", mode)
    return cols


def placement_summary(run: GridRun, placement: str) -> dict:
    """A run's summary of one phone placement, from the first split of :data:`PLACEMENT_SPLITS` that has it."""
    for split in PLACEMENT_SPLITS:
        s = summary_of(run, split, "by_placement", placement)
        if s:
            return s
    return {}


def phone_only(label: str, grid: dict[str, list[GridRun]]) -> bool:
    """Whether a row's model reads the phone only (registry layout "single"); unknown models: no."""
    try:
        return get(grid[label][0].model).layout == "single"
    except WearnavError:  # a run of a model this checkout does not register
        return False


def efficiency_row(run: GridRun, threads: int = 1, min_run_time_s: float = 0.2) -> dict:
    """Table VI for one row: params, MACs per window and inference windows/s at :data:`BATCHES`
    (medians), measured now on ``threads`` torch threads with the run's model, window and
    model_args (3 devices in, as the efficiency suite measures)."""
    window, n_devices = int(run.train.get("window", 100)), 3
    model = build(run.model, n_devices=n_devices, window=window, **(run.train.get("model_args") or {}))
    old = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        row = {
            "model": run.label,
            "params": n_parameters(model),
            "MMACs per window": macs_per_window(model, n_devices, window) / 1e6,
        }
        for b in BATCHES:
            row[f"windows/s b{b}"] = windows_per_second(model, b, min_run_time_s, n_devices, window)[0]
    finally:
        torch.set_num_threads(old)
    return row


def speed_of(t: np.ndarray, xy: np.ndarray, smooth_s: float = SPEED_SMOOTH_S) -> np.ndarray:
    """Speed (m/s) from positions (N, 2) at times ``t`` (s): central differences, then a moving
    mean over ``smooth_s`` (shorter at the ends)."""
    if len(t) < 3:
        return np.zeros(len(t))
    v = np.linalg.norm(np.gradient(xy, t, axis=0), axis=1)
    k = max(1, int(round(smooth_s / float(np.median(np.diff(t))))))
    if k == 1:
        return v
    box = np.ones(k)
    return np.convolve(v, box, mode="same") / np.convolve(np.ones_like(v), box, mode="same")  # no edge dip


def velocity_panels(grid: dict[str, list[GridRun]], models=VELOCITY_MODELS, split: str = "test") -> dict:
    """Fig. 11: per mode of :data:`VELOCITY_MODES`, the first sequence (by name) that every one of
    ``models`` (their lowest seed) scored, with true and predicted speed over time."""
    present = [m for m in models if m in grid]
    if not present:
        return {}
    panels = {}
    for mode in VELOCITY_MODES:
        names = None
        for m in present:
            seqs = {r["name"] for r in summary_of_rows(grid[m][0], split) if r.get("mode") == mode and "ate" in r}
            names = seqs if names is None else names & seqs
        for name in sorted(names or ()):
            files = {m: grid[m][0].folder / "trajectories" / split / f"{name}.csv" for m in present}
            if not all(f.is_file() for f in files.values()):
                continue
            curves = {}
            for m, f in files.items():
                tr = pd.read_csv(f)
                t = tr["t"].to_numpy()
                if "truth" not in curves:
                    curves["truth"] = (t, speed_of(t, tr[["x_true", "y_true"]].to_numpy()))
                curves[f"{m} (seed {grid[m][0].seed})"] = (t, speed_of(t, tr[["x", "y"]].to_numpy()))
            panels[f"{mode}: {name} (split {split})"] = curves
            break
    return panels


def placement_errors(grid: dict[str, list[GridRun]], labels: list[str]) -> dict[str, dict[str, np.ndarray]]:
    """Fig. 7: per phone placement, each row's per-timestamp position errors pooled over its seeds."""
    out: dict[str, dict[str, np.ndarray]] = {p: {} for p in PLACEMENTS}
    for lab in labels:
        pooled: dict[str, list[np.ndarray]] = {p: [] for p in PLACEMENTS}
        for r in grid[lab]:
            for split in PLACEMENT_SPLITS:
                for row in summary_of_rows(r, split):
                    f = r.folder / "trajectories" / split / f"{row['name']}.csv"
                    if row.get("placement") in pooled and f.is_file():
                        tr = pd.read_csv(f)
                        if "error" in tr:
                            pooled[row["placement"]].append(tr["error"].to_numpy())
        for p, e in pooled.items():
            if e:
                out[p][lab] = np.concatenate(e)
    return out


def _distinct(grid, key: str) -> list:
    return sorted({repr(r.train.get(key)) for rs in grid.values() for r in rs})


def rules_text(grid: dict[str, list[GridRun]]) -> list[str]:
    """The test-frame rule and the training budget as the runs' configs record them."""
    rules = sorted({str(r.train.get("eval_frame_align")) for rs in grid.values() for r in rs})
    said = []
    for rule in rules:
        if rule == "None":
            frame = sorted({str(r.train.get("frame_align")) for rs in grid.values() for r in rs})
            said.append(
                f"not recorded (runs from before `eval_frame_align`): test input aligned as "
                f"training (`frame_align` {', '.join(frame)}"
                + (f": {FRAME_RULES['truth']}" if frame == ["truth"] else "")
                + ")"
            )
        else:
            said.append(f"`{rule}`: {FRAME_RULES.get(rule, 'see TrainConfig.eval_frame_align')}")
    budget = []
    for key in ("epochs", "patience", "max_minutes", "lr", "batch", "recipe"):
        vals = _distinct(grid, key)
        if vals != ["None"]:
            budget.append(f"{key} {' / '.join(v.strip(chr(39)) for v in vals)}")
    seeds = sorted({r.seed for rs in grid.values() for r in rs})
    return [
        f"**Test frame rule**: {'; '.join(said)}.",
        "",
        f"**Training budget** (the same for every model unless two values are listed): {', '.join(budget)} "
        "(None: the model's paper value); early stopping on validation velocity MSE; training seeds "
        f"{', '.join(map(str, seeds))}.",
    ]


def training_table(grid: dict[str, list[GridRun]], labels: list[str], expected: int | None) -> pd.DataFrame:
    rows = []
    for lab in labels:
        tr = [r.metrics.get("training", {}) for r in grid[lab]]
        epochs = [t["epochs_run"] for t in tr if _finite(t.get("epochs_run"))]
        wall = [t["wall_s"] / 60 for t in tr if _finite(t.get("wall_s"))]
        stopped = sorted({str(t.get("stopped_by")) for t in tr if t.get("stopped_by")})
        beats = [beats_text(t) for t in tr]
        rows.append(
            {
                "model": lab,
                "seeds": seeds_text(len(tr), expected),
                "epochs run": cell_text(epochs) if epochs else "—",
                "stopped by": ", ".join(stopped) or "—",
                "train min": cell_text(wall) if wall else "—",
                "beats standing still": f"{beats.count('yes')} of {len(beats)}"
                if "not learned" not in beats
                else "not learned",
            }
        )
    return pd.DataFrame(rows)


def test_frame_table(grid: dict[str, list[GridRun]], labels: list[str], splits=TEST_SPLITS) -> pd.DataFrame:  # noqa: PT028  a table of the test frame, not a pytest test
    """Per row label and split: mean ATE over seeds in the honest test frame and in the diagnostic
    truth frame (``<run>/diagnostic-truth-frame``, :func:`wearnav.bench.odometry.run_job`), over the
    seeds that have both; empty where no run has the diagnostic."""
    rows = []
    for lab in labels:
        row: dict = {"model": lab}
        for split in splits:
            pairs: list[tuple[float, float]] = []
            for r in grid[lab]:
                diag = r.folder / DIAGNOSTIC_TRUTH_FRAME
                if not runs.is_complete(diag):
                    continue
                d = (runs.read_metrics(diag).get("splits", {}).get(split) or {}).get("summary", {}).get("ate_mean")
                h = summary_of(r, split).get("ate_mean")
                if _finite(d) and _finite(h):
                    pairs.append((float(h), float(d)))  # type: ignore[arg-type]  # _finite: numbers
            if pairs:
                h, d = np.mean(pairs, axis=0)
                row |= {f"{split} honest": h, f"{split} diagnostic": d, f"{split} Δ": h - d}
        if len(row) > 1:
            rows.append(row)
    return pd.DataFrame(rows)


def write_grid_report(
    folders,
    out: str | Path,
    title: str = "Odometry comparison (Suite-IN++ Tables III–VI)",
    expected_seeds: int | None = None,
    note: str = "",
    command: str = "wearnav bench odometry",
    splits=TEST_SPLITS,
    measure: bool = True,
) -> Path:
    """results.md + results.json + fig7_placement_cdf.png / fig11_speed.png in ``out`` from the
    complete ones of ``folders``; ``measure``: Table VI (timed now)."""

    out = Path(out)
    grid = read_grid(folders)
    if not grid:
        raise ValidationError("no complete run folder (metrics.json) to report", out)
    labels = list(grid)
    prov = provenance()
    n_done = sum(len(v) for v in grid.values())
    seeds = sorted({r.seed for rs in grid.values() for r in rs})
    lines = [
        f"# {title}",
        "",
        f"Generated by `{command}` from {n_done} complete run folders "
        f"({prov['created']}, wearnav {prov['wearnav']} {prov['commit']}): {expected_seeds or len(seeds)} seeds "
        f"per model asked, training seeds {', '.join(map(str, seeds))} complete.",
        "",
    ]
    if note:
        lines += [note, ""]
    lines += [
        *rules_text(grid),
        "",
        f'Cells: mean ± std over training seeds (each seed: the mean over sequences), metres. {MARK_NOTE}. `seeds`: complete runs ("n of N" '
        "while a row is unfinished).",
        "",
    ]
    doc: dict = {"rows": labels, "tables": {}}

    abl = {n: (REFERENCE if n == 6 else f"suitein++-abl{n}") for n in ABLATIONS}  # Table V's rows
    ablation_rows = set(abl.values()) - {REFERENCE}  # Table V only
    lines += ["## Training", "", training_table(grid, labels, expected_seeds).to_markdown(index=False), ""]

    for split in splits:
        cols = table3_columns(split)
        have = [lab for lab in labels if any(summary_of(r, split) for r in grid[lab]) and lab not in ablation_rows]
        if not have:
            continue
        table, st = marked_table(grid, have, cols, expected_seeds)
        table = table.loc[:, (table != "").any(axis=0)]
        doc["tables"][f"III {split}"] = st
        lines += [
            f"## Table III: split `{split}`",
            "",
            "ATE and RTE (Δ = 60 s) overall and per walking mode (ablation variants: Table V).",
            "",
            table.to_markdown(index=False),
            "",
        ]

    frame = test_frame_table(grid, [lab for lab in labels if lab not in ablation_rows], splits)
    if not frame.empty:
        doc["tables"]["test frame"] = frame.to_dict(orient="records")
        lines += [
            "## What the honest test frame costs",
            "",
            "ATE (mean over seeds) with the test input in the honest frame (one constant yaw from the "
            "first 10 s of truth) and in the old diagnostic frame (turned onto the truth's yaw over time, "
            "removing heading drift with ground truth), same trained weights; Δ = honest − diagnostic.",
            "",
            frame.to_markdown(index=False, floatfmt=".2f"),
            "",
        ]

    t4 = [lab for lab in labels if lab == REFERENCE or phone_only(lab, grid)]
    cols4 = {}
    for p in PLACEMENTS:
        cols4[f"{p} ATE"] = lambda r, p=p: placement_summary(r, p).get("ate_mean")
        cols4[f"{p} RTE"] = lambda r, p=p: placement_summary(r, p).get("rte_mean")
    if t4:
        table, st = marked_table(grid, t4, cols4, expected_seeds)
        table = table.loc[:, (table != "").any(axis=0)]
        doc["tables"]["IV"] = st
        lines += [
            "## Table IV: phone-only models vs multi-device Suite-IN++ per phone placement",
            "",
            "HD handheld, MP multi-changed (split `test`), PK pocket, BG bag (split `test_unseen`: "
            "placements no training walk has). Phone-only: models reading the phone alone.",
            "",
            table.to_markdown(index=False),
            "",
        ]
        fig7 = plot_cdf_panels(
            placement_errors(grid, t4),
            out / "fig7_placement_cdf.png",
            "position error CDF per phone placement (Fig. 7), seeds pooled",
        )
        if fig7:
            lines += [f"![Fig. 7]({fig7.name})", ""]

    t5 = [lab for lab in abl.values() if lab in grid]
    if len(t5) > 1:
        cols5: dict[str, Callable[[GridRun], Any]] = {f"{s} ATE": _metric(s, "ate_mean") for s in splits}
        cols5["test RTE"] = lambda r: summary_of(r, "test").get("rte_mean")
        table, st = marked_table(grid, t5, cols5, expected_seeds)
        table = table.loc[:, (table != "").any(axis=0)]
        marks = pd.DataFrame(
            [
                {"variant": f"({n})", **{col: "✓" if ABLATIONS[n][key] else "" for col, key in ABLATION_MODULES}}
                for n, lab in abl.items()
                if lab in grid
            ]
        )
        table = pd.concat([marks, table], axis=1)
        doc["tables"]["V"] = st
        lines += [
            "## Table V: ablations",
            "",
            "(6) = Suite-IN++; ✓ = the module is on.",
            "",
            table.to_markdown(index=False),
            "",
        ]

    if measure:
        rows = []
        for lab in labels:
            try:
                rows.append(efficiency_row(grid[lab][0]))
            except WearnavError as exc:  # e.g. a run of a model this checkout does not register
                log.warning("Table VI: %s left out: %s", lab, exc)
        eff = pd.DataFrame(rows)
        doc["tables"]["VI"] = rows
        lines += [
            "## Table VI: efficiency",
            "",
            "Measured by this command on this machine, 1 torch thread: trainable parameters; "
            "MMACs = 10⁶ multiply-accumulates of one forward pass on one window (3 devices × the "
            "run's window × 6 channels): FLOPs/2 of `torch.utils.flop_counter` for matrix products and "
            "convolutions, every LSTM/GRU counted analytically (4 or 3 gates × (in·h + h·h) per step); inference windows/s at batch 1 and 256 (median of "
            "`blocked_autorange` blocks). The machine is shared: timings vary with load.",
            "",
            eff.to_markdown(index=False, floatfmt=".4g"),
            "",
        ]

    fig11 = plot_speed(velocity_panels(grid), out / "fig11_speed.png", "true vs predicted speed (Fig. 11)")
    if fig11:
        lines += [
            "## Fig. 11: predicted vs true speed",
            "",
            f"Speed from the trajectory files' positions (central differences, {SPEED_SMOOTH_S:g} s moving "
            "mean): the first `test` sequence of each mode that both models scored.",
            "",
            f"![Fig. 11]({fig11.name})",
            "",
        ]
    runs.write_json(out / "results.json", doc)
    return write_text_atomic("\n".join(lines), out / "results.md")
