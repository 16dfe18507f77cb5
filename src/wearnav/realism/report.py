"""The realism report: how real is the simulated walking? (Its page prints this docstring from
the second paragraph on.)

Every source is compared on walking only, device by device and placement by placement, with the
same pipeline:

1. **Walking stretches.** Labels where a dataset has them (simulator: ``activity = walk``;
   MotionSense: the ``walking`` trials; UJI: ``WALKING`` and the ``TURNING`` between two walking
   intervals, a turn taken while walking; Oxford: runs of annotated true steps less than
   :data:`MAX_STEP_GAP_S` apart). Without labels (ILC2, IPIN) :func:`detect_walking` decides,
   2-s window by window (hop 0.5 s, the centre second marked): the |acc| standard deviation
   within :data:`WALK_STD_BAND`, the |acc| spectrum peaking in the step band
   :data:`STEP_BAND_HZ` with at least 40 % of the 0.5–5 Hz power there, and the mean |gyro|
   below :data:`MAX_WALK_GYRO`; gaps shorter than a window are closed.
   Every stretch loses :data:`TRIM_S` at both ends (gait initiation and termination) and is
   cut into segments of :data:`SEGMENT_S` (the remainder kept if at least
   :data:`MIN_SEGMENT_S`). One segment is one sample of every statistic.
2. **One rate.** acc, gyro and world-frame acc (where the stream has an orientation) are
   interpolated onto a uniform 100 Hz grid and decimated to :data:`RATE_HZ` = 25 Hz with
   scipy's polyphase FIR anti-alias filter, so the 25 Hz earbuds, the 50 Hz and the 100–220 Hz
   devices all end with the same 12.5 Hz band.
3. **Statistics per segment** (:func:`segment_stats`), on the magnitude |acc| (independent of
   how the device is mounted):

   - ``acc_std``: standard deviation of |acc| (m/s²); ``gyro_mean``: mean |gyro| (rad/s);
   - ``f_dom``: frequency of the highest peak of the |acc| periodogram in 0.5–4 Hz (Hann
     window, zero-padded to 0.003 Hz);
   - ``cadence``: steps per second from the stride period, the highest peak of the |acc|
     autocorrelation at lags 0.8–1.6 s (parabolic sub-sample refinement);
   - ``step_reg``: the autocorrelation one step apart, the peak near half the stride lag
     (Moe-Nilssen & Helbostad's step regularity: 1 = identical consecutive steps);
   - ``step_cv`` and ``amp_cv``: coefficients of variation of the step-to-step periods and
     peak-to-trough amplitudes of the steps found as peaks of the 4 Hz low-passed |acc|
     (parabolic refinement of the peak times, so a 25 Hz grid does not add 40 ms jitter);
   - ``band_*``: share of the |acc| power (Welch) in the bands of :data:`BANDS` up to 12.5 Hz;
   - ``hv_ratio``: RMS horizontal over RMS vertical dynamic world-frame acceleration, where the
     stream carries an orientation.

Location fixes (:func:`fix_stats`), against the points a surveyor marked (IPIN's POSI points;
in the simulator, its truth every :data:`SIM_REFERENCE_EVERY_S`): error distribution, reported
accuracy over the actual error, outage lengths (gaps longer than :data:`OUTAGE_GAP_S`) and
jumps (consecutive fixes further apart than a walker could go, :data:`JUMP_SPEED_MPS`).

:func:`realism_report` runs it all and writes the Markdown page, the PNGs and a JSON holding
the numbers behind every table and figure.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from wearnav.core.fileio import atomic_path, write_text_atomic
from wearnav.core.provenance import __version__, git_commit
from wearnav.errors import ConfigError
from wearnav.realism.calibrate import IQR_MIN_SEGMENTS, SourceResult, compute_realism, fix_compare, summary
from wearnav.realism.fixes import FIX_STATS, JUMP_SPEED_MPS, OUTAGE_GAP_S, SIM_REFERENCE_EVERY_S
from wearnav.realism.sources import (
    CALIBRATION_COLUMNS,
    CALIBRATION_NOTES,
    CALIBRATION_TABLE,
    CLAIMED,
    FIX_REAL,
    GROUPS,
    ILC2_CALIBRATION,
    SIM_DURATION_S,
    Group,
    RealSource,
)
from wearnav.realism.stats import STAT_LABELS, STATS
from wearnav.report.plots import plot_ecdf


def _save(fig: Figure, out: Path) -> Path:
    FigureCanvasAgg(fig)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    return out


_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")


def _hist_data(results: list[SourceResult], stat: str, bins: int = 30) -> dict | None:
    vals = [r.values(stat) for r in results]
    allv = np.concatenate(vals) if vals else np.empty(0)
    if allv.size == 0:
        return None
    lo, hi = np.percentile(allv, [1, 99])
    if not hi > lo:
        lo, hi = lo - 0.5, hi + 0.5
    edges = np.linspace(lo, hi, bins + 1)
    return {
        "edges": np.round(edges, 5).tolist(),
        "density": {
            r.label: (np.round(np.histogram(np.clip(v, lo, hi), edges, density=True)[0], 5).tolist() if v.size else [])
            for r, v in zip(results, vals)
        },
    }


def _plot_group(group: Group, results: list[SourceResult], freqs: np.ndarray, out: Path) -> tuple[Path, dict]:
    stats = [s for s in STATS if any(r.values(s).size for r in results)]
    ncol = 4
    nrow = int(np.ceil((len(stats) + 1) / ncol))
    fig = Figure(figsize=(4.0 * ncol, 2.8 * nrow))
    data = {"statistics": {}, "spectrum": {"freq_hz": np.round(freqs, 4).tolist(), "psd": {}}}
    for k, stat in enumerate(stats):
        ax = fig.add_subplot(nrow, ncol, k + 1)
        h = _hist_data(results, stat)
        data["statistics"][stat] = h
        if h is None:
            continue
        for c, r in zip(_COLORS, results):
            d = h["density"][r.label]
            if d:
                ax.stairs(
                    d,
                    h["edges"],
                    color=c,
                    fill=r.kind == "sim",
                    alpha=0.35 if r.kind == "sim" else 1.0,
                    label=f"{r.label} ({r.kind})",
                )
        ax.set_title(STAT_LABELS[stat], fontsize=9)
        ax.tick_params(labelsize=7)
    ax = fig.add_subplot(nrow, ncol, len(stats) + 1)
    for c, r in zip(_COLORS, results):
        if r.psd:
            m = np.median(np.stack(r.psd), axis=0)
            data["spectrum"]["psd"][r.label] = np.round(m, 6).tolist()
            ax.semilogy(freqs, m, color=c, lw=2.0 if r.kind == "sim" else 1.2, label=r.label)
    ax.set_title("median |acc| PSD ((m/s²)²/Hz)", fontsize=9)
    ax.set_xlabel("Hz", fontsize=8)
    ax.tick_params(labelsize=7)
    handles, labels = fig.axes[0].get_legend_handles_labels()
    fig.suptitle(
        f"{group.title}: walking segments (histograms clipped to the 1st–99th percentile)", y=0.995, fontsize=10
    )
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.965), ncol=len(results), fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    return _save(fig, out), data


def _plot_fixes(res: dict[str, dict], out: Path) -> tuple[Path, dict]:
    fig = Figure(figsize=(12, 3.2))
    data: dict[str, Any] = {}
    for k, (stat, title, log) in enumerate(
        (
            ("error_m", "fix error at reference points (m)", False),
            ("acc_over_error", "reported accuracy / error", True),
            ("fix_speed", "fix-to-fix distance / time (m/s)", True),
        )
    ):
        ax = fig.add_subplot(1, 3, k + 1)
        data[stat] = {}
        for c, (label, r) in zip(_COLORS, res.items()):
            v = np.asarray(r[stat], float)
            if v.size == 0:
                continue
            plot_ecdf(ax, v, color=c, label=f"{label} (n={v.size})")
            q = np.linspace(0, 1, 101)  # the CDF as 101 quantiles keeps the JSON small
            data[stat][label] = {"quantile": q.round(2).tolist(), "x": np.round(np.quantile(v, q), 3).tolist()}
        if log:
            ax.set_xscale("log")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, out), data


def _markdown(rows: list[list[str]], head: list[str]) -> str:
    """A Markdown table of text cells (no number parsing: "1.76 [1.7, 1.8]" stays as written)."""
    return pd.DataFrame(rows, columns=head).to_markdown(index=False, disable_numparse=True)


def _fmt(x: dict) -> str:
    if not x or x.get("n", 0) == 0:
        return "—"
    return f"{x['median']:.3g} [{x['q25']:.3g}, {x['q75']:.3g}]"


def _band_count(g: dict | None) -> str:
    if g is None:
        return "—"
    e = [v for v in g["compare"].values() if "inside" in v]
    return f"{sum(v['inside'] for v in e)} of {len(e)}"


def _table(groups: dict, claimed: bool = False) -> list[str]:
    lines = []
    for key, g in groups.items():
        lines += [
            f"### {g['title']}",
            "",
            f"Simulated: {g['sim']['label']} ({g['sim']['segments']} segments of "
            f"{g['sim']['recordings']} recordings). Real: "
            + (
                ", ".join(
                    f"{r['label']} ({r['segments']} segments of {r['recordings']} recordings, walking by {r['how']})"
                    for r in g["real"]
                )
                or "none in the shipped data"
            )
            + ".",
            "",
        ]
        reals = [r["label"] for r in g["real"]]
        head = ["statistic", "simulated"] + reals + (["band (pooled real)", "in band"] if reals else [])
        rows = []
        for stat, e in g["compare"].items():
            if e["sim"].get("n", 0) == 0 and e["real"].get("n", 0) == 0:
                continue
            row = [STAT_LABELS[stat].replace("|", "\\|"), _fmt(e["sim"])]
            row += [_fmt(e["per_source"][r]) for r in reals]
            if reals:
                if "band" in e:
                    row += [
                        f"{e['band'][0]:.3g} … {e['band'][1]:.3g} ({e['band_kind']})",
                        "yes" if e["inside"] else "**no**",
                    ]
                else:
                    row += ["—", "—"]
            rows.append(row)
        lines.append(_markdown(rows, head))
        if claimed and g["real"] and key in CLAIMED:
            lines += [
                "",
                "Claimed (re-checked by tests/test_realism.py): "
                + ", ".join(STAT_LABELS[k].replace("|", "\\|") for k in CLAIMED[key])
                + ".",
            ]
        lines.append("")
    return lines


def _fix_table(fix: dict) -> list[str]:
    labels = list(fix)
    comp = fix_compare(fix)
    rows = []
    names = {
        "error_m": "error at reference points (m)",
        "acc_over_error": "reported accuracy / error",
        "fix_speed": "fix-to-fix distance / time (m/s; walking ≈ 1.3, jumps far above)",
        "outage_s": f"outage length (s, gaps > {OUTAGE_GAP_S:g} s)",
        "outage_share": "share of time in outages (per recording)",
        "jumps_per_100": f"jumps per 100 fixes (> {JUMP_SPEED_MPS:g} m/s apart, per recording)",
    }
    for k in FIX_STATS:
        row = [names[k]]
        for lab in labels:
            v = np.asarray(fix[lab].get(k, []), float)
            row.append(_fmt(summary(v)) + (f" (n={v.size})" if v.size else ""))
        e = comp[k]
        if "band" in e:
            row += [f"{e['band'][0]:.3g} … {e['band'][1]:.3g} ({e['band_kind']})", "yes" if e["inside"] else "**no**"]
        else:
            row += ["—", "—"]
        rows.append(row)
    return [_markdown(rows, ["statistic", *labels, "band (IPIN)", "in band"])]


def realism_report(
    data: Path,
    out: Path,
    work: Path,
    n_sim: int = 12,
    limit: int | None = None,
    seed: int = 0,
    before: Path | None = None,
    json_out: Path | None = None,
    progress: bool = False,
    sim_duration_s: float = SIM_DURATION_S,
    groups: tuple[Group, ...] = GROUPS,
    fix_source: RealSource | None = FIX_REAL,
) -> dict:
    """Compute everything, write ``out`` (Markdown), ``<out dir>/img/realism_*.png`` and the JSON
    (default: ``out`` with suffix .json). ``before``: an earlier JSON of this report (e.g. of the
    uncalibrated simulator) whose tables the page shows beside the current ones."""
    if n_sim < 2:
        raise ConfigError("the realism report needs at least 2 simulated walks per placement")
    out = Path(out)
    json_out = Path(json_out) if json_out else out.with_suffix(".json")
    res = compute_realism(data, work, n_sim, limit, seed, sim_duration_s, groups, fix_source, progress)
    img = out.parent / "img"
    figures = {}
    for key, results in res.pop("_figs").items():
        g = next(g for g in groups if g.key == key)
        png, fdata = _plot_group(g, results, res["_freqs"], img / f"realism_{key}.png")
        figures[key] = {"png": os.path.relpath(png, out.parent), **fdata}
    if res["fixes"] is not None:
        png, fdata = _plot_fixes(res["fixes"], img / "realism_fixes.png")
        figures["fixes"] = {"png": os.path.relpath(png, out.parent), **fdata}
    res.pop("_freqs")
    commit = git_commit()
    from wearnav.simulate.walk import SIMULATOR_VERSION

    res["provenance"] = {"wearnav": __version__, "commit": commit, "simulator_version": SIMULATOR_VERSION}
    res["figures"] = figures
    res["fix_compare"] = fix_compare(res["fixes"]) if res["fixes"] is not None else None
    write_text_atomic(json.dumps(res, indent=1, default=float) + "\n", json_out)

    cmd = (
        f"wearnav realism --data {data} --out {out} --work {work} --n-sim {n_sim}"
        + (f" --limit {limit}" if limit else "")
        + (f" --before {before}" if before else "")
    )
    lines = [
        f"_Generated by `{cmd}` (wearnav {__version__}{', commit ' + commit if commit else ''}); do not edit by hand._",
        "",
        "# How real is the simulated walking?",
        "",
        re.sub(r":(?:data|func):`([^`]+)`", r"`\1`", (__doc__ or "").split("\n\n", 1)[1].strip()),
        "",
        f"Each cell: median [25th, 75th percentile] over walking segments. **Band**: the pooled real "
        f"segments' interquartile range (±15 % of their median when fewer than {IQR_MIN_SEGMENTS}); "
        "**in band**: the simulated median lies inside it.",
        "",
        "## Calibration data",
        "",
        f"- ILC2: only `{ILC2_CALIBRATION}` (site 1, floor F1). **Odometry benchmarks must not test on "
        "ILC2 floor F1.**",
        "- IPIN 2023: only training trials 01 and 02 (all repetitions). **Odometry and EasyTrack "
        "benchmarks must not evaluate on IPIN trials 01 and 02.**",
        "- MotionSense (`wlk` trials), UJI (phone and watch), Oxford validation (all placements): "
        "used whole; no benchmark evaluates odometry on them.",
        "",
    ]
    lines += [
        "## What is calibrated against what",
        "",
        _markdown([list(r) for r in CALIBRATION_TABLE], list(CALIBRATION_COLUMNS)),
        "",
        CALIBRATION_NOTES,
        "",
    ]
    prev = json.loads(Path(before).read_text()) if before is not None else None
    counts = [
        [g["title"], *([_band_count(prev["groups"].get(key))] if prev else []), _band_count(g)]
        for key, g in res["groups"].items()
        if g["real"]
    ]
    lines += [
        "## Summary: statistics whose simulated median lies in the real band",
        "",
        _markdown(counts, ["device and placement", *(["before calibration"] if prev else []), "now"]),
    ]
    was = f", {prev.get('provenance', {}).get('simulator_version', '?')} before (from `{before}`)" if prev else ""
    lines += ["", f"Simulator version {res['provenance']['simulator_version']} now{was}.", ""]
    lines += ["## Now", ""] + _table(res["groups"], claimed=True)
    if res["fixes"] is not None:
        lines += [
            "### Location fixes",
            "",
            f"IPIN: phone GNSS at the surveyed POSI points (trials 01–02); "
            f"simulator: its fixes against its truth every {SIM_REFERENCE_EVERY_S:g} s.",
            "",
        ]
        lines += _fix_table(res["fixes"]) + [""]
    for key, f in figures.items():
        lines += [f"![{key}]({f['png']})", ""]
    if prev is not None:
        pv = prev.get("provenance", {})
        lines += [
            "## Before calibration",
            "",
            f"The same report on the simulator before calibration (from `{before}`: simulator version "
            f"{pv.get('simulator_version', '?')}, wearnav {pv.get('wearnav', '?')}).",
            "",
        ]
        lines += _table(prev["groups"])
        if prev.get("fixes"):
            lines += ["### Location fixes", ""] + _fix_table(prev["fixes"]) + [""]
    write_text_atomic("\n".join(lines).rstrip() + "\n", out)
    return res
