"""Odometry figures: estimated vs true trajectories, position-error CDFs, ATE box plots.

Drawn on matplotlib's Agg canvas (``Figure`` objects, no pyplot state) and written atomically,
like every figure of wearnav.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from wearnav.report.plots import plot_ecdf, save

MAX_TRAJECTORIES = 8


def _pick(rows: list[dict], trajs: dict[str, pd.DataFrame], k: int) -> list[dict]:
    """Up to ``k`` sequences, taken in turn from each walking mode so every mode is shown."""
    by_mode: dict[str, list[dict]] = {}
    for r in rows:
        if r["name"] in trajs:
            by_mode.setdefault(r["mode"], []).append(r)
    picked: list[dict] = []
    while len(picked) < k and any(by_mode.values()):
        for m in sorted(by_mode):
            if by_mode[m] and len(picked) < k:
                picked.append(by_mode[m].pop(0))
    return picked


def plot_trajectories(rows, trajs, out: Path, title: str) -> Path | None:
    picked = _pick(rows, trajs, MAX_TRAJECTORIES)
    if not picked:
        return None
    ncols = min(4, len(picked))
    nrows = -(-len(picked) // ncols)
    fig = Figure(figsize=(3.6 * ncols, 3.5 * nrows + 0.6), layout="constrained")
    for i, r in enumerate(picked):
        ax = fig.add_subplot(nrows, ncols, i + 1)
        tr = trajs[r["name"]]
        if "x_true" in tr:
            ax.plot(tr.x_true, tr.y_true, color="black", lw=1.0, label="truth")
        ax.plot(tr.x, tr.y, color="tab:red", lw=1.0, label="estimate")
        ax.plot(tr.x.iloc[0], tr.y.iloc[0], marker="*", color="tab:green", ms=10, mec="black", mew=0.5)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
        score = f"ATE {r['ate']:.2f} m" if "ate" in r else f"mean err {r.get('mean_error', float('nan')):.2f} m"
        ax.set_title(f"{r['name']}\n{r['mode']} · {score}", fontsize=8)
        if i == 0:
            ax.legend(fontsize=7)
    fig.suptitle(f"{title} (metres, start ★)", fontsize=11)
    return save(fig, out)


def plot_cdf(errors: dict[str, np.ndarray], out: Path, title: str) -> Path | None:
    """One empirical CDF of per-timestamp position error per entry (a model, or a mode)."""
    errors = {k: v for k, v in errors.items() if v.size}
    if not errors:
        return None
    fig = Figure(figsize=(6, 4), layout="constrained")
    ax = fig.add_subplot()
    for name, e in errors.items():
        plot_ecdf(ax, e, label=name)
    ax.set_xlabel("position error (m)")
    ax.set_ylabel("P(error ≤ x)")
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=10)
    return save(fig, out)


def plot_box(values: dict[str, list[float]], out: Path, title: str, ylabel: str = "ATE (m)") -> Path | None:
    values = {k: v for k, v in values.items() if len(v)}
    if not values:
        return None
    fig = Figure(figsize=(max(4.0, 0.9 * len(values) + 2), 4), layout="constrained")
    ax = fig.add_subplot()
    ax.boxplot(list(values.values()), tick_labels=list(values.keys()))
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3, axis="y")
    ax.tick_params(axis="x", labelsize=8, rotation=30)
    ax.set_title(title, fontsize=10)
    return save(fig, out)


def plot_run_split(plots: Path, split: str, result: dict, trajs: dict[str, pd.DataFrame], model: str) -> None:
    rows = result["sequences"]
    plot_trajectories(rows, trajs, plots / f"{split}_trajectories.png", f"{model} on {split}")
    by_mode: dict[str, list] = {}
    for r in rows:
        if r["name"] in trajs and "error" in trajs[r["name"]]:
            by_mode.setdefault(r["mode"] or "all", []).append(trajs[r["name"]]["error"].to_numpy())
    plot_cdf(
        {m: np.concatenate(v) for m, v in sorted(by_mode.items())},
        plots / f"{split}_error_cdf.png",
        f"{model} on {split}: position error by walking mode",
    )
    ates: dict[str, list[float]] = {}
    for r in rows:
        if "ate" in r:
            ates.setdefault(r["mode"] or "all", []).append(r["ate"])
    plot_box(dict(sorted(ates.items())), plots / f"{split}_ate_box.png", f"{model} on {split}: ATE per sequence")


def plot_cdf_panels(panels: dict[str, dict[str, np.ndarray]], out: Path, title: str) -> Path | None:
    """One panel per entry of ``panels`` (e.g. a phone placement), in it one empirical CDF of
    position error (metres) per model (Suite-IN++ Fig. 7)."""
    panels = {k: {m: e for m, e in v.items() if e.size} for k, v in panels.items()}
    panels = {k: v for k, v in panels.items() if v}
    if not panels:
        return None
    fig = Figure(figsize=(3.6 * len(panels), 3.6), layout="constrained")
    for i, (name, errors) in enumerate(panels.items()):
        ax = fig.add_subplot(1, len(panels), i + 1)
        for model, e in errors.items():
            plot_ecdf(ax, e, label=model)
        ax.set_xlabel("position error (m)")
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
        ax.set_title(name, fontsize=10)
        if i == 0:
            ax.set_ylabel("P(error ≤ x)")
            ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=11)
    return save(fig, out)


def plot_speed(panels: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]], out: Path, title: str) -> Path | None:
    """One panel per entry (e.g. a sequence), in it speed (m/s) over time (s) per curve
    (``{label: (t_s, speed_mps)}``; a curve labelled "truth" is drawn in black): Suite-IN++ Fig. 11."""
    panels = {k: v for k, v in panels.items() if v}
    if not panels:
        return None
    fig = Figure(figsize=(7.5, 2.6 * len(panels)), layout="constrained")
    for i, (name, curves) in enumerate(panels.items()):
        ax = fig.add_subplot(len(panels), 1, i + 1)
        for label, (t, v) in curves.items():
            kw = dict(color="black", lw=1.4) if label == "truth" else dict(lw=0.9)
            ax.plot(t - t[0], v, label=label, **kw)
        ax.set_ylabel("speed (m/s)")
        ax.grid(alpha=0.3)
        ax.set_title(name, fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
    ax.set_xlabel("time from the sequence's first scored sample (s)")
    fig.suptitle(title, fontsize=11)
    return save(fig, out)


def plot_speed_ratio(panels: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]], out: Path, title: str) -> Path | None:
    """One panel per site, in it each source's speed ratio (estimated / true length between
    consecutive surveyed points) against the true speed (m/s) of those segments
    (``{label: (true_speed_m_s, speed_ratio)}``): points, and the median in speed bins as a line.
    A ratio of 1 (dashed) is right; below it the path is short."""
    panels = {k: v for k, v in panels.items() if any(len(s) for s, _ in v.values())}
    if not panels:
        return None
    fig = Figure(figsize=(5.0 * len(panels), 3.8), layout="constrained")
    for i, (name, curves) in enumerate(panels.items()):
        ax = fig.add_subplot(1, len(panels), i + 1)
        for k, (label, (speed, ratio)) in enumerate(curves.items()):
            if not len(speed):
                continue
            color = f"C{k}"  # matplotlib's colour cycle: the dots and their binned median alike
            ax.scatter(speed, ratio, s=4, alpha=0.25, color=color)
            edges = np.quantile(speed, np.linspace(0, 1, 7))
            mid = 0.5 * (edges[1:] + edges[:-1])
            med = [np.median(ratio[(speed >= a) & (speed <= b)]) for a, b in zip(edges[:-1], edges[1:])]
            ax.plot(mid, med, lw=2, color=color, label=f"{label} (median {np.median(ratio):.2f})")
        ax.axhline(1.0, color="black", ls="--", lw=0.8)
        ax.set_ylim(0, 2)
        ax.set_xlabel("true speed between surveyed points (m/s)")
        ax.set_ylabel("estimated / true length")
        ax.set_title(name, fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    fig.suptitle(title, fontsize=11)
    return save(fig, out)
