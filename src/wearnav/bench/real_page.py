"""The page of `wearnav bench real-odometry` (:mod:`wearnav.bench.real`): results.md and results.json
from the suite's run folders, the known-start table per site, the user protocol where the site has
fixes (:mod:`wearnav.bench.user_protocol`), the error CDF and example paths."""

from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wearnav import runs
from wearnav.bench import decompose
from wearnav.bench.map_eval import MAP_LABEL, MAP_SUFFIX
from wearnav.bench.odometry import BEATS_STILL, beats_text
from wearnav.bench.real_sites import fix_errors
from wearnav.bench.user_protocol import (
    PAIRED_TEXT,
    arc_ratio,
    paired_rows,
    particle_paired_rows,
    score_path,
    site_calibration,
    user_table,
)
from wearnav.core.fileio import shown_path, write_text_atomic
from wearnav.core.textio import read_json
from wearnav.dataset import Dataset
from wearnav.fuse.placement import SiteModels, fit_site_models
from wearnav.models.base import SNAP_DEG
from wearnav.models.registry import get
from wearnav.pretrained.mix import is_mix
from wearnav.report.odometry import plot_speed_ratio
from wearnav.stats import difference_cells, walk_bootstrap_difference


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
            made = (
                f"simulator `{Path(train['data']).name}` (commit {prov.get('commit', '?')})"
                if prov.get("generator") == "wearnav.simulate"
                else f"{' + '.join(q['part'] for q in prov['parts'])} (`{Path(train['data']).name}`)"
                if is_mix(train["data"])
                else f"`{Path(train['data']).name}`"
            )
            label = f"{label} · {made}"
        labelled.append((not get(train["model"]).learned, "·" in label, label, run))
    return {label: run for *_, label, run in sorted(labelled, key=lambda x: x[:3])}


# Where a scored path's speed comes from (wearnav.train.odometry.SPEED_SOURCES) → (suffix of its
# evaluation folder ``eval_<site>``, suffix of its row label): the model as trained; its direction at
# PDR's speed (wearnav.models.pdr.PDRSpeed), with 0.67-m steps or cadence-long ones; a heading-frame
# model's speed along where the phone points (wearnav.models.base.AlongPointing).
VARIANTS = {
    "model": ("", ""),
    "pdr": ("_pdrspeed", " · PDR speed"),
    "cadence": ("_cadence", " · cadence speed"),
    "pointing": ("_pointing", " · its speed, pointing"),
    "snapped": ("_snapped", f" · cadence speed, pointing within {SNAP_DEG:g}°"),
}
# and either one placed on the building's floor plans (wearnav.bench.map_eval, issue 36): + MAP_SUFFIX, MAP_LABEL


def evaluations(folders: dict[str, Path], site: str) -> dict[str, tuple[Path, Path]]:
    """Every scored path of ``site`` by its row label: (run folder, evaluation folder); a learned
    model's hybrids (:data:`VARIANTS`) follow the model's own row."""
    out = {}
    for label, run in folders.items():
        for suffix, name in VARIANTS.values():
            for more, more_label in (("", ""), (MAP_SUFFIX, MAP_LABEL)):
                if runs.is_complete(run / f"eval_{site}{suffix}{more}"):
                    out[label + name + more_label] = (run, run / f"eval_{site}{suffix}{more}")
    return out


def results_table(sites: dict, folders: dict[str, Path], site: str) -> tuple[pd.DataFrame, dict]:
    """One row per model, its PDR-speed hybrid, and the raw fixes: errors at the surveyed points of
    the test traces."""
    rows, errors = [], {}
    for label, (run, ev) in evaluations(folders, site).items():
        m = runs.read_metrics(ev)
        if not m:
            continue
        res = m["splits"]["test"]
        # the pooled per-point statistics are evaluate's summary; the errors themselves feed the CDF
        errors[label] = np.concatenate(
            [np.asarray(r.get("point_errors", []), float) for r in res["sequences"]] or [np.empty(0)]
        )
        summary = res["summary"]
        tr = m.get("training", {})
        # the path's own site yaw (a pointing path's is its own), else the model's, else PDR's
        own = [run / f"site_yaw_{ev.name.removesuffix(MAP_SUFFIX)}.json", run / f"site_yaw_eval_{site}.json"]
        yaw = next((read_json(f)["yaw_deg"] for f in own if f.is_file()), sites[site]["yaw"]["yaw_deg"])
        rows.append(
            {
                "method": label,
                "site yaw (°)": yaw,
                "traces": summary["sequences"],
                "points": summary.get("points", 0),
                **{k: summary.get(k, float("nan")) for k in ("error_mean", "error_p50", "error_p75", "error_p95")},
                **dict(zip(("length ratio", "arc ratio"), length_ratios(ev, sites[site]["data"]))),
                "epochs": tr.get("epochs_run", "—"),
                "train min": round(tr["wall_s"] / 60, 1) if tr.get("wall_s") else "—",
                BEATS_STILL: beats_text(tr),
            }
        )
    fx = sites[site].get("fixes")
    if fx:
        errors["raw phone fixes"] = np.asarray(fx["point_errors"])
        rows.append(
            {
                "method": "raw phone fixes",
                "site yaw (°)": "—",
                "traces": fx["sequences"],
                "points": fx["points"],
                **{k: v for k, v in fx.items() if k.startswith("error_")},
                "length ratio": float("nan"),
                "arc ratio": float("nan"),
                "epochs": "—",
                "train min": "—",
                BEATS_STILL: "—",
            }
        )
    df = pd.DataFrame(rows)
    if not df.empty:
        df = df.rename(
            columns={
                "error_mean": "mean (m)",
                "error_p50": "median (m)",
                "error_p75": "p75 (m)",
                "error_p95": "p95 (m)",
            }
        )
    return df, errors


MAP_TEXT = (
    "Map-aware rows (*· map-aware*, :mod:`wearnav.bench.map_eval`, issue 36): the same known-start path "
    "placed on the trace's floor plan by the particle filter of :mod:`wearnav.fuse.particles` (walls as "
    "constraints; start at the first surveyed point, heading offset 0 ± {h:g}°, {s}, "
    "{n} particles, constants chosen on ILC2's training floors B1/F1/F3 with PDR), scored at the same points. "
    "Below, each map-aware row minus its map-less row, paired by walk (90 % interval from resampling "
    "whole walks; below 0: the plan helps):"
)


def _map_section(evals: dict[str, tuple[Path, Path]]) -> list[str]:
    """The map-aware rows' note and their walk-paired difference from the map-less rows."""
    rows, cfg = [], None
    for label, (_, ev) in evals.items():
        if not label.endswith(MAP_LABEL) or label[: -len(MAP_LABEL)] not in evals:
            continue
        m, base = runs.read_metrics(ev), runs.read_metrics(evals[label[: -len(MAP_LABEL)]][1])
        cfg = m.get("map_aware", {}).get("config", cfg)
        by = {r["name"]: r["point_errors"] for r in m["splits"]["test"]["sequences"] if r.get("point_errors")}
        ref = {r["name"]: r["point_errors"] for r in base["splits"]["test"]["sequences"] if r.get("point_errors")}
        names = [n for n in by if n in ref]
        if len(names) < 2:
            continue
        d = walk_bootstrap_difference([by[n] for n in names], [ref[n] for n in names])
        rows.append(
            {
                "map-aware minus map-less": label[: -len(MAP_LABEL)],
                "walks": d["walks"],
                **difference_cells(d),
            }
        )
    if not rows or cfg is None:
        return []
    scale = (
        f"the odometry's scale fixed at {cfg['walls_only_scale']:g} (the walls its only evidence)"
        if cfg.get("walls_only_scale")
        else f"log-scale ± {cfg['scale_log_sigma']:g}"
    )
    text = MAP_TEXT.format(h=cfg["start_heading_sigma_deg"], s=scale, n=cfg["particles"])
    return [text, "", pd.DataFrame(rows).to_markdown(index=False), ""]


def length_ratios(eval_dir: Path, data: str) -> tuple[float, float]:
    """Medians over the test traces of the path's length ratio through its positions at the
    surveyed times (:func:`wearnav.bench.user_protocol.score_path`: chords) and of its own arc over
    the truth's polyline (:func:`wearnav.bench.user_protocol.arc_ratio`: below 1 the path is slow,
    however it wanders), from the trajectories an evaluation wrote; 1 is right."""
    chords, arcs = [], []
    for w in decompose.scored_walks(eval_dir, data):
        chords.append(score_path(w.t, w.xy, w.truth.t, w.truth.pos[:, :2])[1])
        arcs.append(arc_ratio(w.t, w.xy, w.truth.t, w.truth.pos[:, :2]))

    def median(v: list[float]) -> float:
        return round(float(np.nanmedian(v)), 3) if np.isfinite(v).any() else float("nan")

    return median(chords), median(arcs)


def frame_name(devices) -> str:
    """Whose heading frame a suite's learned models take: the first of their devices present, so the
    phone's on the real walks, which carry it alone (``preprocess._carrier_heading``)."""
    first = tuple(devices or ("phone",))[0]
    return (
        "the phone's heading frame"
        if first == "phone"
        else f"the heading frame of the {first} (the phone's on the real walks)"
    )


def warp_text(speed_warp) -> str:
    """The speed time-warp expansion (RealBench.speed_warp) as a page says it, or nothing."""
    if not speed_warp:
        return ""
    return ", trained also on the walks played " + " and ".join(f"{k:g}×" for k in speed_warp) + " as fast"


def write_report(out: Path, sites: dict, folders: dict[str, Path], bench: dict, wall_s: float) -> Path:
    """results.md and results.json; ``bench`` is the suite's config as plain data (``dataclasses.asdict`` of
    :class:`wearnav.bench.real.RealBench`: train_data, epochs, patience, max_minutes, lr, seed are read)."""
    import torch

    from wearnav.core.provenance import provenance
    from wearnav.report.odometry import plot_cdf

    p = provenance()
    src = sites["main"]["split"]["source"]
    title = (
        f"Odometry in real buildings: trained on {src}"
        if not bench["train_data"]
        else f"Odometry in real buildings: trained on `{Path(bench['train_data']).name}`, tested on {src}"
    ) + (f", the learned models in {frame_name(bench.get('devices'))}" if bench.get("heading_frame") else "")
    title += f", the `{bench['vel_loss']}` loss" if bench.get("vel_loss", "mse") != "mse" else ""
    title += warp_text(bench.get("speed_warp"))
    if bench.get("models") and not any(get(m).learned for m in bench["models"]):  # nothing was trained
        title = f"Odometry in real buildings, untrained baselines only ({', '.join(bench['models'])}): {src}"
    lines = [
        f"# {title}",
        "",
        f"Generated by `wearnav bench real-odometry` ({p['created']}, wearnav {p['wearnav']} {p['commit']}); "
        f"this invocation {wall_s / 60:.1f} min of wall time (each run's own training minutes are in its row) on "
        f"{platform.machine()}, {os.cpu_count()} CPUs, "
        f"torch {torch.__version__}, CPU only, shared with other work while it ran.",
        "",
        "Errors in metres at the surveyed points of the held-out test traces: every trace starts at its "
        "first point and is scored at each later one (no reset). Training targets join the surveyed "
        "points by straight lines (the competitions' assumption between waypoints); nothing is "
        "tuned on the test groups. Phone only, 25 Hz, world frame rotated by the site's yaw "
        "(estimated by PDR from training traces only).",
        "",
        f"Training: at most {bench['epochs']} epochs, early stopping on validation velocity MSE (patience "
        f"{bench['patience']})"
        + (f", at most {bench['max_minutes']:g} min per model" if bench["max_minutes"] else "")
        + (f", Adam lr {bench['lr']:g}" if bench["lr"] else ", each model's paper learning rate")
        + f", velocity loss `{bench.get('vel_loss', 'mse')}`"
        + (
            f", the learned models' windows in {frame_name(bench.get('devices'))} (`--heading-frame`) without random yaw"
            if bench.get("heading_frame")
            else ""
        )
        + warp_text(bench.get("speed_warp"))
        + f", seed {bench['seed']}, one run per row (the epochs and minutes each got are in its row).",
        "",
        "Sim-to-real: a row named `model · simulator ...` is that model trained on the simulated "
        "dataset only (phone only, the simulator's own truth frame, dense truth) and scored here "
        "like the others; beside it the same model trained on the building's training groups, "
        "and PDR (not learned).",
        "",
    ]
    doc: dict[str, Any] = {"bench": dict(bench), "wall_s": round(wall_s, 1), "sites": {}}
    for site, s in sites.items():
        info = s["split"]
        test = [g for g, c in info["groups"].items() if "test" in c]
        train = [g for g, c in info["groups"].items() if "test" not in c]
        n = {k: sum(c.get(k, 0) for c in info["groups"].values()) for k in ("train", "val", "test")}
        head = (
            "Another building, never trained on"
            if site != "main"
            else "Held-out groups of the training building"
            if not bench["train_data"]
            else "Held-out groups (a learned row trained elsewhere says where)"
        )
        lines += [
            f"## {head}: `{info['source']}`",
            "",
            f"Source `{shown_path(info['src'])}`, grouped by `{info['group_by']}`: test {', '.join(sorted(test))} "
            f"({n['test']} traces); "
            + (
                f"training groups {', '.join(sorted(train))} ({n['train']} train, {n['val']} validation traces)."
                if site == "main"
                else f"its other groups ({n['train'] + n['val']} traces) serve only to estimate its yaw."
            ),
            f"Site yaw {s['yaw']['yaw_deg']:+.1f}° from {s['yaw']['segments']} segments of "
            f"{s['yaw']['traces']} training traces (median |deviation| {s['yaw']['median_abs_dev_deg']}°)"
            + (
                f"; cross-check, valid only for a phone held flat and pointing ahead: its +y axis gives "
                f"{s['yaw']['phone_axis_yaw_deg']:+.1f}° (the difference is PDR's own heading bias, "
                "which a learned model absorbs)."
                if s["yaw"].get("phone_axis_yaw_deg") is not None
                else "."
            ),
            "",
        ]
        table, errors = results_table(sites, folders, site)
        doc["sites"][site] = {"split": info, "yaw": s["yaw"], "table": table.to_dict(orient="records")}
        if table.empty:
            lines += ["(no complete runs yet)", ""]
            continue
        lines += [
            "Known-start protocol (each trace starts at its true first point, input turned by the site "
            "yaw: a floor, not available to a user). A learned row scored where it did not train under "
            "PDR's yaw uses its own estimate from the same training traces (*site yaw* column). *Length "
            "ratio*: median over walks of the path's length through its positions at the surveyed times "
            "over the truth's (1 is right; a path that wanders between the points also comes out short); "
            "*arc ratio*: of the path's own length over the truth's polyline through the same points (a "
            "lower bound of the walked distance: below 1 the path is slow, however it wanders):",
            "",
            table.to_markdown(index=False, floatfmt=".2f"),
            "",
        ]
        lines += _map_section(evaluations(folders, site))
        split = decompose.along_across_table(
            {label: [(ev, s["data"])] for label, (_, ev) in evaluations(folders, site).items()}
        )
        if split is not None:
            lines += [decompose.ALONG_TEXT.format(seeds=""), "", split.to_markdown(index=False), ""]
        lines += _decomposition(evaluations(folders, site), s["data"], out / f"{site}_speed_ratio.png", info["source"])
        if s.get("fixes"):
            scored = {
                label: run for label, (run, _) in evaluations(folders, site).items() if not label.endswith(MAP_LABEL)
            }
            speeds = {
                label: src for label in scored for src, (_, end) in VARIANTS.items() if end and label.endswith(end)
            }
            # each model's smoother is calibrated where it is used (user_protocol.site_calibration)
            cal = doc["sites"][site]["calibration"] = {
                label: site_calibration(run, site, s["data"], _trained_on(run), speeds.get(label, "model"))
                for label, run in scored.items()
            }
            models = site_models(s["data"])
            rows, raw = user_table(scored, s["data"], s["fixes"], calibration=cal, speeds=speeds, site=models)
            paired = paired_rows(raw)
            doc["sites"][site]["user_protocol"] = {"table": rows, "paired": paired, "runs": raw}
            lines += [
                USER_PROTOCOL_TEXT,
                "",
                *_fix_lag_line(cal),
                pd.DataFrame(rows).to_markdown(index=False, floatfmt=".2f"),
                "",
            ]
            if paired:
                lines += [PAIRED_TEXT, "", pd.DataFrame(paired).to_markdown(index=False), ""]
            if particle := particle_paired_rows(raw):
                doc["sites"][site]["user_protocol"]["particle_paired"] = particle
                doc["sites"][site]["site_models"] = models.to_dict() if models is not None else None
                lines += [PARTICLE_TEXT, "", pd.DataFrame(particle).to_markdown(index=False), ""]
            lines += _user_protocol_elsewhere(scored, s["data"], cal, doc["sites"][site]["user_protocol"], speeds)
        cdf = plot_cdf(errors, out / f"{site}_error_cdf.png", f"error at surveyed points, {info['source']} test")
        traj = _plot_examples(folders, site, out / f"{site}_trajectories.png", info["source"])
        lines += [f"![{q.stem}]({q.name})" for q in (cdf, traj) if q] + [""]
    runs.write_json(out / "results.json", doc)
    return write_text_atomic("\n".join(lines), out / "results.md")


def _fix_lag_line(calibrations: dict[str, dict]) -> list[str]:
    """What the smoother took as the fixes' lag (:func:`wearnav.fuse.fix_lag_of` on the walks each
    calibration came from: the site's training walks), a line and a blank; none where no
    calibration measured one."""
    found = [c for c in calibrations.values() if c.get("fix_lag_s") is not None]
    if not found:
        return []
    c = found[0]
    return [
        f"The smoother reads each fix as where the walker was {c['fix_lag_s']:g} s before its time stamp: the "
        f"fixes' lag on the {c.get('split', 'training')} walks (`wearnav.fuse.fix_lag_of`, {c['fix_lag_walks']} "
        f"walks: their median error {c['fix_median_m_at_0']:.2f} m at 0 s, {c['fix_median_m_at_lag']:.2f} m "
        "at that lag), as `track --fix-lag` does (`track`'s default reads them as stamped, as the raw fixes' row "
        "does).",
        "",
    ]


PARTICLE_TEXT = (
    "The particle filter (:func:`wearnav.fuse.placement.place`, issue 36) places the same odometry by the "
    "walk's fixes (Student-t), its BLE beacon readings (a log-distance path-loss model with a floor loss "
    "and per-phone gains, :mod:`wearnav.fuse.beacons`) and its floor from the barometer "
    "(:mod:`wearnav.fuse.floors`, the start floor chosen without truth), all fitted on the site's "
    "training walks only (*floor right*: its share of surveyed points on the right floor). Its "
    "difference from the raw fixes and from the smoother, paired by walk (below 0: it is better):"
)


def site_models(data: str) -> SiteModels | None:
    """The site's beacon and floor models fitted on its training walks (:func:`wearnav.fuse.placement.fit_site_models`),
    cached beside the prepared data as ``site_models.json``; None where its recordings have neither
    beacons nor a barometer."""
    cached = Path(data) / "site_models.json"
    if cached.is_file():
        d = read_json(cached)
        return None if d.get("none") else SiteModels.from_dict(d)
    ds = Dataset.open(data).split("train")
    first = ds.load(ds.names[0]) if ds.names else None
    if first is None or (first.beacons is None and first.pressure is None):
        runs.write_json(cached, {"none": "no beacon readings and no barometer in the site's recordings"})
        return None
    models = fit_site_models(ds)
    runs.write_json(cached, models.to_dict())
    return models


DECOMPOSITION_TEXT = (
    "Why, per walk (:mod:`wearnav.bench.decompose`): the known-start paths split into speed and heading "
    "between consecutive surveyed points. *Speed ratio*: the path's length over the truth's on each "
    "segment (1 is right, below 1 the path is short); *heading error*: the angle between their "
    "directions. A source short at every walking speed errs in scale, one with a wide heading error "
    "in direction."
)


def _decomposition(scored: dict[str, tuple[Path, Path]], data: str, figure: Path, source: str) -> list[str]:
    """The page's speed/heading split of every scored path (:mod:`wearnav.bench.decompose`): the
    summary, the speed ratio by walking speed and by device, and the speed-ratio figure."""
    segments = {label: decompose.eval_segments(ev, data) for label, (_, ev) in scored.items()}
    segments = {k: v for k, v in segments.items() if len(v)}
    if not segments:
        return []
    fig = plot_speed_ratio(
        {source: {k: (v["true_speed_m_s"].to_numpy(), v["speed_ratio"].to_numpy()) for k, v in segments.items()}},
        figure,
        f"speed ratio against true speed, {source} test (known start)",
    )
    return [
        DECOMPOSITION_TEXT,
        "",
        decompose.summary(segments).to_markdown(index=False),
        "",
        "Median speed ratio by the true speed of the segment (segments in brackets):",
        "",
        decompose.by_speed(segments).to_markdown(index=False),
        "",
        "Median speed ratio / median |heading error| by the phone that recorded the walk:",
        "",
        decompose.by_device(segments).to_markdown(index=False),
        "",
    ] + ([f"![{fig.stem}]({fig.name})", ""] if fig else [])


USER_PROTOCOL_TEXT = (
    "User protocol (issue 25: no truth at all, neither the start point nor the site yaw; "
    ":mod:`wearnav.bench.user_protocol`): each model's path integrated from (0, 0) in the phone's own "
    "world frame and placed on the recording's own location fixes by first-fix anchoring (today's "
    "`track` until now), one rigid fit to all fixes, or the smoother (:mod:`wearnav.fuse`, `track`'s "
    "default). Errors at the same surveyed points; *length ratio*: median over walks of the path's "
    "length through its positions at the surveyed times over the truth's (1 is right); *inside σ's 68 % "
    "radius*: the share of the smoother's points whose error is inside 1.515 times the σ `track` "
    "writes for them (0.68 where that σ is right, less where it is too small)."
)


def _user_protocol_elsewhere(
    folders: dict[str, Path], data: str, cal: dict, doc: dict, speeds: dict[str, str]
) -> list[str]:
    """The user protocol again on the site's training walks, for the models that never trained on
    them (PDR, a model from another building): three times the walks of the held-out routes, though
    not held out from the smoother's settings (chosen on IPIN's training walks) or its calibration
    (:func:`site_calibration`). Adds ``train_walks`` to ``doc``; returns the page's lines."""
    others = {
        k: run
        for k, run in folders.items()
        if (trained := _trained_on(run)) is None or Path(trained).resolve() != Path(data).resolve()
    }
    fixes = fix_errors(Path(data), "train") if others else None
    if not fixes:
        return []
    rows, raw = user_table(others, data, fixes, "train", calibration={k: cal[k] for k in others}, speeds=speeds)
    paired = paired_rows(raw)
    doc["train_walks"] = {"table": rows, "paired": paired}
    return [
        f"The same on the site's {fixes['sequences']} training walks, for the models that never trained "
        "on them: not held out from the smoother's settings or its calibration, which were chosen and "
        "measured on such walks, but three times as many walks:",
        "",
        pd.DataFrame(rows).to_markdown(index=False, floatfmt=".2f"),
        "",
        pd.DataFrame(paired).to_markdown(index=False) if paired else "",
        "",
    ]


def _trained_on(run: Path) -> str | None:
    """The data a learned run trained on; None for a model that is not learned."""
    train = runs.read_config(run)["config"]["train"]
    return train["data"] if get(train["model"]).learned and train.get("data") else None


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
