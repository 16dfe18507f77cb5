"""The EasyTrack benchmark's page (:mod:`wearnav.bench.easytrack`): ADE over seeds (Fig. 3/4) with
the paper's claim checked, ATE (Fig. 7), the phone labels' noise (Table I, eqs. 5–7), CoAdapt over
the joint epochs (Fig. 5/6) and the real-data tables, written as ``<out>/results.md`` + PNGs."""

from __future__ import annotations

import dataclasses
import platform
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import metrics
from wearnav.core.fileio import write_text_atomic
from wearnav.core.provenance import provenance
from wearnav.core.textio import read_json
from wearnav.fixlabels import LabelConfig, Segments, noise_summary
from wearnav.report.plots import plot_ecdf, save
from wearnav.stats import welch_p
from wearnav.trust import QUICK_NOTE


@dataclasses.dataclass(frozen=True)
class PageConfig:
    """What the page says of the benchmark's settings: the same names as
    :class:`wearnav.bench.easytrack.BenchConfig` (which builds it), as plain data so that the page
    imports nothing of the benchmark."""

    ae_epochs: int
    pre_epochs: int
    joint_epochs: int
    km: float  # simulated walking per level
    stride_s: float | None  # overlapping segments every this many s; None: back to back
    levels: tuple[str, ...]
    methods: tuple[str, ...]
    loss: str  # the models' loss on the displacements (NoisyConfig.loss)

    @classmethod
    def of(cls, config: object) -> PageConfig:
        """The fields of any config object that has them (the benchmark passes its BenchConfig)."""
        return cls(**{f.name: getattr(config, f.name) for f in dataclasses.fields(cls)})


# the methods that select instances (CoAdapt or Co-teaching), in the order of the CoAdapt table
SELECTING = ("easytrack", "easytrack-amended", "nocnal", "coteaching")
# issue 59's per-epoch diagnostics (wearnav.train.noisy.DIAGNOSTICS) and their column heads
DIAGNOSIS = {
    "length_bias": "length bias",
    "weighting_length_bias": "weighting bias",
    "delta_scale": "δ / median error",
    "ensemble_shrinkage": "ensemble shrinkage",
}


def _last(joint: list[dict], key: str) -> float:
    v = joint[-1].get(key)
    return round(float(v), 3) if v is not None else float("nan")


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
                parts.append(
                    f"{verdict} {rival} ({100 * (e - table.loc[rival, level]):+.1f} cm"
                    + (f", p = {p:.3f}" if p is not None else "")
                    + ")"
                )
        ratio = e / gt
        parts.append(
            f"{ratio:.2f}× BaseModel-GT ({'within' if ratio <= 1.15 else 'NOT within'} 1.15×); "
            f"EasyTrack's ADE is {100 * e / mean_d:.0f} % of the mean displacement"
        )
        out.append(f"**{level}**: " + "; ".join(parts))
    return (
        "The paper's claim (EasyTrack below every other LNL and within 1.15× of BaseModel-GT), checked on these "
        "seeds (Welch's two-sided p over seeds; with 3 seeds only a large, consistent gap reaches p < 0.05):\n\n- "
        + "\n- ".join(out)
    )


def _amended(df: pd.DataFrame, levels) -> str:
    """Issue 59's bar for the amended method per level: not worse than BaseModel beyond seed spread
    (Welch's two-sided p over seeds < 0.05 with a higher mean is "worse"); the faithful one beside."""
    methods = set(df["method"])
    if not {"easytrack-amended", "basemodel"} <= methods:
        return ""
    out = []
    for level in levels:
        at = df[df["level"] == level]
        base = at[at["method"] == "basemodel"]["ade"].dropna().tolist()
        parts = []
        for m in ("easytrack-amended", "easytrack"):
            mine = at[at["method"] == m]["ade"].dropna().tolist()
            if not mine or not base:
                continue
            diff, p = float(np.mean(mine) - np.mean(base)), welch_p(mine, base)
            worse = diff > 0 and p is not None and p < 0.05
            parts.append(
                f"{m} {100 * diff:+.1f} cm against BaseModel"
                + (f" (p = {p:.3f})" if p is not None else " (one seed: no test)")
                + (": worse beyond seed spread" if worse else ": not worse beyond seed spread" if p is not None else "")
            )
        if parts:
            out.append(f"**{level}**: " + "; ".join(parts))
    if not out:
        return ""
    return (
        "Issue 59's bar for the amended CoAdapt (`easytrack-amended`): not worse than BaseModel beyond seed "
        "spread (Welch's two-sided p over seeds), the faithful EasyTrack beside it:\n\n- " + "\n- ".join(out)
    )


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


def write_page(
    out: Path,
    bc: PageConfig,
    lc: LabelConfig,
    sim: list[dict],
    train: dict[str, Segments],
    test: Segments,
    real: dict | None,
    seeds: int,
    quick: bool,
) -> Path:

    p = provenance()
    df = pd.DataFrame(
        [
            {
                "method": m["method"],
                "level": m["level"],
                "seed": m["seed"],
                "ade": m.get("ade_m"),
                "ate": m.get("ate_mean_m"),
                "s_epoch": m["training"]["s_per_epoch"],
                "min": m["training"]["wall_s"] / 60,
                "device": m["training"].get("device", "cpu"),
                "length_ratio": m.get("length_ratio", np.nan),
            }
            for m in sim
        ]
    )
    devices = ", ".join(sorted(set(df["device"]))) if not df.empty else "cpu"
    reduction = (
        f"**Reduced from the paper** (200 epochs: 5 AE + 5 per model + 190 joint; ~8.5 km per level): here "
        f"{bc.ae_epochs} AE + {bc.pre_epochs} pre-training + {bc.joint_epochs} joint epochs, "
        f"~{bc.km:g} km of simulated walking per level, {seeds} seed(s). Machine: {platform.machine()}, "
        f"trained on {devices}" + (f"; a segment starts every {bc.stride_s:g} s." if bc.stride_s else ".")
    )
    loss = (
        "Every model's loss on the displacements: the mean squared error (the paper's)."
        if bc.loss == "mse"
        else f"Every model's loss on the displacements: `{bc.loss}` "
        "(`wearnav.models.base.instance_velocity_loss`: log length and direction apart, issue 34), "
        "the paper's MSE replaced; CoAdapt ranks instances by it, CNAL and AUX keep their MSE."
    )
    title = (
        f"# EasyTrack: odometry from the phone's own location fixes (paper 004): {', '.join(bc.levels)}, "
        f"{bc.ae_epochs + bc.pre_epochs + bc.joint_epochs} epochs, ~{bc.km:g} km per level"
        + (f", {bc.loss} loss" if bc.loss != "mse" else "")
        + (f" (--quick: {QUICK_NOTE})" if quick else "")
    )
    lines = [
        title,
        "",
        f"Generated by `wearnav bench easytrack{' --quick' if quick else ''}` ({p['created']}, wearnav "
        f"{p['wearnav']} {p['commit']}).",
        "",
        reduction,
        "",
        loss,
        "",
        f"Segments of {lc.segment_s:g} s at {lc.rate:g} Hz (phone IMU in the world frame, turned onto the fixes' "
        "east/north frame from the IMU and fixes only). Test: "
        f"{len(test.names)} held-out simulated trajectories ({len(test)} segments, truth labels).",
        "",
    ]
    noise = [
        "## Phone labels per noise level (eqs. 5–7)",
        "",
        "Paper Table I: median label noise 21.6 / 27.6 / 33.5 cm, ~8.5 km per level; its Figure 1a: noise over "
        "200 cm exists. Neighbour correlation: Pearson r of consecutive segments' noise, per axis (eq. 7; the paper "
        "gives no number). Dropped: labels faster than the jump filter's "
        f"{lc.max_speed:g} m/s."
        if lc.max_speed
        else "Paper Table I: median label noise 21.6 / 27.6 / 33.5 cm.",
        "",
    ]
    nrows = []
    for level, seg in train.items():
        s = noise_summary(seg)
        nc = s["neighbour_correlation"]
        nrows.append(
            {
                "level": level,
                "segments": s["segments"],
                "walks": s["trajectories"],
                "km": s["length_km"],
                "median noise (cm)": s["label_noise_median_cm"],
                "mean (cm)": s["label_noise_mean_cm"],
                "p90 (cm)": s["label_noise_p90_cm"],
                "> 1 m (%)": _pct(s.get("label_noise_over_1m")),
                "> 2 m (%)": _pct(s.get("label_noise_over_2m")),
                "dropped (%)": _pct(s.get("dropped_share")),
                "neighbour r (x, y)": f"{nc['x']:.3f}, {nc['y']:.3f}" if nc["x"] is not None else "—",
            }
        )
    noise += [pd.DataFrame(nrows).to_markdown(index=False), ""]
    table = pd.DataFrame()
    if not df.empty:
        table = df.pivot_table(index="method", columns="level", values="ade", aggfunc="mean")
        order = [m for m in bc.methods if m in table.index]
        table = table.loc[order]
        sd = df.pivot_table(index="method", columns="level", values="ade", aggfunc="std").reindex(order)
        n = df.pivot_table(index="method", columns="level", values="ade", aggfunc="count").reindex(order)
        shown = pd.DataFrame(
            {
                f"{c} ADE (cm)": [
                    _mean_sd(table.loc[m, c], sd.loc[m, c] if c in sd else None, n.loc[m, c] if c in n else 0, seeds)
                    for m in order
                ]
                for c in table.columns
            },
            index=order,
        )
        still = next((m["trivial_ade_m"] for m in sim if "trivial_ade_m" in m), None)
        unlearned = sorted({f"{m['method']} {m['level']}" for m in sim if m.get("beats_trivial") is False})
        beats = (
            ""
            if still is None
            else f" Standing still (zero displacement per segment) scores {100 * still:.1f} cm; "
            + (f"NOT beaten by: {', '.join(unlearned)}." if unlearned else "every run beats it.")
        )
        mean_d = float(np.mean(np.linalg.norm(test.truth, axis=1))) if len(test) else float("nan")
        lines += [
            "## ADE on held-out trajectories (Fig. 3, ablation Fig. 4)",
            "",
            "Paper Figure 3 (real phone labels, DS_L1): EasyTrack 12.4 cm, BaseModel-GT 11.2, BaseModel 21.9, "
            "Co-teaching 16.5, AUX 19.3; EasyTrack 15.7 cm on DS_L3.",
            "",
            f"Mean ± sd over {seeds} seed(s) (n= where a cell has fewer), cm. {reduction}{beats} The test segments' mean true displacement is "
            f"{100 * mean_d:.1f} cm (the paper's phone labels average ~100 cm and its BaseModel-GT scores 11.2 cm, "
            "11 % of that).",
            "",
            shown.to_markdown(),
            "",
        ]
        lines += [_claim(df, table, mean_d), "", _amended(df, list(table.columns)), ""]
        ratio = df.pivot_table(index="method", columns="level", values="length_ratio", aggfunc="mean")
        if not ratio.empty:
            lines += [
                "Length ratio (held-out: predicted over true path length, mean over seeds; below 1 the model "
                "walks slow, what a selection of short segments teaches):",
                "",
                ratio.reindex([m for m in order if m in ratio.index]).round(3).to_markdown(),
                "",
            ]
        ate = df.pivot_table(index="method", columns="level", values="ate", aggfunc="mean").loc[order]
        lines += [
            "ATE (m, mean over the held-out trajectories, displacements integrated from the true start; "
            "Fig. 7 uses L1):",
            "",
            ate.round(2).to_markdown(),
            "",
            "Training time (seconds per epoch, mean over methods' non-AE epochs; minutes per run):",
            "",
            df.groupby("method")[["s_epoch", "min"]].mean().round(2).to_markdown(),
            "",
        ]
    lines += noise
    hist, selecting = {}, {}  # EasyTrack's per level (the figures); every selecting method's (the table)
    for m in sim:
        if m["method"] in SELECTING and m["seed"] == 0:
            folder = Path(m["folder"])
            if (folder / "history.json").is_file():
                selecting[(m["level"], m["method"])] = read_json(folder / "history.json", kind=None)
                if m["method"] == "easytrack":
                    hist[m["level"]] = selecting[(m["level"], m["method"])]
    if selecting:
        lines += ["## CoAdapt over the joint epochs (seed 0; Fig. 5 and 6)", ""]
        rows = []
        for (level, method), h in sorted(selecting.items(), key=lambda kv: (kv[0][0], SELECTING.index(kv[0][1]))):
            j = [r for r in h if r["phase"] == "joint"]
            if j:
                rows.append(
                    {
                        "level": level,
                        "method": method,
                        "R_τ last": round(j[-1]["r_tau"], 3),
                        "R_δ last": round(j[-1]["r_delta"], 3) if method != "coteaching" else float("nan"),
                        "R_s last": round(j[-1]["r_s"], 3),
                        "selected noise raw (cm)": round(j[-1]["selected_noise_cm"] or float("nan"), 1),
                        "selected, CNAL-corrected (cm)": round(j[-1]["selected_noise_corrected_cm"] or float("nan"), 1),
                        "all instances (cm)": round(j[-1]["batch_noise_cm"] or float("nan"), 1),
                        "selected ‖d‖ (cm)": round(j[-1].get("selected_displacement_cm") or float("nan"), 1),
                        "all ‖d‖ (cm)": round(j[-1].get("batch_displacement_cm") or float("nan"), 1),
                        "corrected labels' median noise (cm)": round(
                            j[-1].get("corrected_label_noise_median_cm", float("nan")), 1
                        ),
                        **{head: _last(j, key) for key, head in DIAGNOSIS.items()},
                    }
                )
        lines += [
            "Last joint epoch (mean label noise |d_e| of the instances each model selected for its peer, and "
            "their mean true displacement ‖d‖ beside the batch's: small-loss selection is meant to keep clean "
            "labels, but while the model's own error exceeds the label noise it keeps short, easy segments). "
            "Issue 59's diagnostics (`wearnav.train.coadapt`, mean over the last epoch's batches, from the labels "
            "alone): *length bias*, the selected labels' mean length over the batch's (below 1: short, slow "
            "segments kept); *weighting bias*, the same after the 0.1 weight on the last 20 % (below 1: the "
            "low weight falls on long segments); *δ / median error*, the paper's δ = 0.24 m over the batch's "
            "median error (~1 in the paper's regime); *ensemble shrinkage*, the mean length of the two models' "
            "average over their own (below 1: averaging shortens):",
            "",
            pd.DataFrame(rows).to_markdown(index=False),
            "",
        ]
    links = _plots(out, table, hist, train, sim)
    curve = _ade_curves(out, sim)
    if curve:
        lines += [
            "Held-out ADE after every epoch (a diagnostic only: no model or epoch is chosen by it; the "
            "paper's Fig. 1b shows BaseModel on noisy labels getting worse with epochs):",
            "",
        ]
        links.append(curve)
    lines += [f"![{Path(x).stem}]({x})" for x in links] + [""]
    if real:
        lines += [
            "## Real data: GNSS labels, scored at surveyed points",
            "",
            f"Trained on the phone-GNSS labels of {len(real['train_routes'])} training recordings "
            f"({real['segments']} segments, {real['train_label_km']} km of label path); scored at the surveyed "
            f"points of {len(real['test_routes'])} held-out recordings ({', '.join(real['test_routes'])}). "
            "Each seed is scored on its own (no ensemble); the error pools every seed's points, the seed column "
            "gives each seed's median. GNSS = the raw fix nearest in time (≤ "
            f"{metrics.FIX_MAX_GAP_S:g} s). {reduction}",
            "",
        ]
        for proto, head in (
            (
                "user",
                "User protocol: the IMU methods start at the phone's own fix at the first "
                "surveyed time and integrate (heading from the IMU turned onto the walk's own "
                "fixes); no truth is used.",
            ),
            ("known", "Diagnostic, not available to a user: the same paths started at the first surveyed point."),
        ):
            rows = [
                {
                    "method": k,
                    **{c: v[c] for c in ("points", "median_m", "p75_m", "mean_m")},
                    "seed medians (m)": ", ".join(f"{x:.2f}" for x in v["seed_medians_m"]),
                }
                for k, v in real["summary"][proto].items()
            ]
            lines += [head, "", pd.DataFrame(rows).round(2).to_markdown(index=False), ""]
            pair = [real["summary"][proto].get(m, {}).get("seed_medians_m", []) for m in real["methods"]]
            p_welch = welch_p(*pair)
            if p_welch is not None:
                lines += [f"EasyTrack vs BaseModel, per-seed medians: Welch's p = {p_welch:.3f}.", ""]
        lines += [
            "Per route (user protocol; median error over the seeds' points, m):",
            "",
            pd.DataFrame(real["per_route"]).round(2).to_markdown(index=False),
            "",
        ]
    return write_text_atomic("\n".join(lines), out / "results.md")
