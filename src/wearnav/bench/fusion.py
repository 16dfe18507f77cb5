"""`wearnav bench fusion` (issue 25 §2): the smoother against the simulator's dense truth, per walking
mode, beside the odometry alone and the fixes alone; its seconds per hour of walk; and the live
receiver's fixed-lag smoother timed on one long simulated walk. The smoother is calibrated on the
dataset's training walks (:func:`wearnav.bench.user_protocol.calibration_of`), which are not scored."""

from __future__ import annotations

import dataclasses
import os
import platform
import time
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import fuse, pretrained, runs
from wearnav.bench.user_protocol import calibration_of, error_stats
from wearnav.core.fileio import write_text_atomic
from wearnav.core.provenance import provenance
from wearnav.dataset import Dataset
from wearnav.errors import ConfigError
from wearnav.evaluate import predict_sequence
from wearnav.fuse.live import IncrementalFuser
from wearnav.models.registry import build
from wearnav.preprocess import align
from wearnav.simulate.config import MODES, WalkConfig
from wearnav.simulate.walk import simulate_recording
from wearnav.train.resolve import resolve_model
from wearnav.trajectory import integrate_velocity

SIM_POINT_EVERY_S = 5.0  # the simulator's dense truth, thinned to a point this often to calibrate on
ODO_ORACLE = "odometry alone (oracle rigid fit to truth)"
ODO_FIRST = "odometry alone (first-fix anchoring)"
FIXES_ALONE = "fixes alone"
SMOOTHER = "smoother"
SIM_PATHS = (ODO_ORACLE, ODO_FIRST, FIXES_ALONE, SMOOTHER)


def _untrained(model: str):
    """The fusion benches' odometry by name, phone only, in the phone's own world frame, and its
    config: an untrained baseline (PDR), a shipped model (``phone``) or a phone-only run folder."""
    arg = pretrained.model_path(model, "odometry")
    net, tcfg = resolve_model(arg, "odometry")  # a learned model by name is refused: shipped or a folder only
    if not Path(str(arg)).exists():
        tcfg = dataclasses.replace(tcfg, devices=("phone",))
        net = build_untrained(model, tcfg)
    elif tuple(tcfg.devices) != ("phone",):
        raise ConfigError(f"the fusion bench runs the phone alone; {model} uses {', '.join(tcfg.devices)}")
    return net, dataclasses.replace(tcfg, frame_align="none", yaw_deg=0.0)


def _odometry_words(model: str) -> str:
    """How a page names the odometry of :func:`_untrained`."""
    arg = pretrained.model_path(model, "odometry")
    if not Path(str(arg)).exists():
        return f"untrained `{model}`"
    name = pretrained.shipped_name(arg)
    return f"the shipped model `{name}`" if name else f"the model of run `{arg}`"


def _odometry(rec, net, tcfg) -> tuple[np.ndarray, np.ndarray]:
    """``net``'s path of one recording (from (0, 0) in the phone's world frame) at its aligned times."""
    seq = align(rec, tcfg.preprocess_config())
    t_c, vel, _ = predict_sequence(net, seq, tcfg.window, tcfg.stride)
    t = seq.t[(seq.t >= t_c[0]) & (seq.t <= t_c[-1])]
    return t, integrate_velocity(t_c, vel, t, np.zeros(2))


def simulated_errors(rec, net, tcfg, cfg: fuse.FuseConfig = fuse.FuseConfig()) -> tuple[dict, float, float]:
    """For one simulated recording (dense truth and fixes): the errors (m) against truth at 1-s
    samples per path of :data:`SIM_PATHS`, the smoother's seconds and the walk's seconds. The
    odometry is ``net`` (phone only, from (0, 0) in the phone's world frame); ``odometry alone``
    is given its best rotation + translation onto the *truth* over the whole walk (an oracle no
    user has, so a generous bound for it) and, as a user gets it, first-fix anchoring; the fixes
    alone are linear between fixes."""

    t, xy = _odometry(rec, net, tcfg)
    tt = np.arange(t[0], t[-1], 1.0)
    truth = np.stack([np.interp(tt, rec.truth.t, rec.truth.pos[:, j]) for j in range(2)], axis=1)
    fx = rec.fixes
    odo = fuse.rigid_anchor(t, xy, tt, truth, np.full(tt.size, 1.0)).xy
    first = fuse.first_fix_anchor(t, xy, fx.t, fx.pos[:, :2], fx.accuracy).xy
    t0 = time.perf_counter()
    sm = fuse.smooth(t, xy, fx.t, fx.pos[:, :2], fx.accuracy, cfg).xy
    smooth_s = time.perf_counter() - t0
    fixes_at = np.stack([np.interp(tt, fx.t, fx.pos[:, j]) for j in range(2)], axis=1)
    errs = {}
    for label, path_t, path in (
        (ODO_ORACLE, t, odo),
        (ODO_FIRST, t, first),
        (SMOOTHER, t, sm),
        (FIXES_ALONE, tt, fixes_at),
    ):
        at = np.stack([np.interp(tt, path_t, path[:, j]) for j in range(2)], axis=1)
        errs[label] = np.linalg.norm(at - truth, axis=1)
    return errs, smooth_s, float(t[-1] - t[0])


def simulator_rows(
    model: str = "pdr",
    duration_s: float = 300.0,
    walks_per_mode: int = 2,
    noise_level: str = "L3",
    seed: int = 0,
    cfg: fuse.FuseConfig = fuse.FuseConfig(),
    modes: tuple[str, ...] | None = None,
) -> list[dict]:
    """:func:`simulated_errors` per walking mode on walks simulated here (``walks_per_mode`` of
    ``duration_s`` each; the simulator's correlated fix error with multipath jumps,
    :mod:`wearnav.simulate.fixes`); ``modes`` (default: all) the walking modes."""

    net, tcfg = _untrained(model)
    rows = []
    for mode in modes or MODES:
        errs: dict[str, list] = {p: [] for p in SIM_PATHS}
        for k in range(walks_per_mode):
            placement = "MP" if mode in ("PVW", "MVW") else "HD"
            rec = simulate_recording(
                WalkConfig(
                    name=f"{mode}_{k}", mode=mode, placement=placement, duration_s=duration_s, noise_level=noise_level
                ),
                seed=seed + 1000 * k + MODES.index(mode),
            )
            for label, e in simulated_errors(rec, net, tcfg, cfg)[0].items():
                errs[label].append(e)
        for label in SIM_PATHS:
            rows.append(
                {"mode": mode, "path": label, "walks": walks_per_mode, **error_stats(np.concatenate(errs[label]))}
            )
    return rows


def fusion_table(
    data: str | Path, model: str = "pdr", split: str | None = None, cfg: fuse.FuseConfig | None = None
) -> dict:
    """:func:`simulated_errors` over the recordings of a simulated dataset (``split``: one split, or
    all but the training walks), per walking mode (the manifest's ``mode``) and over all: rows of
    median / p75 / p95 / mean error (m) per path, and the smoother's seconds per hour of walk.
    ``cfg`` None: the smoother calibrated where it is used, as on a real site
    (:func:`calibration_of` on the dataset's training walks, never scored); the defaults where it
    has none. Recordings without truth or with fewer than two fixes are skipped and counted."""
    ds = Dataset.open(data)
    net, tcfg = _untrained(model)
    splits = sorted(set(ds.manifest["split"]))
    calibration = None
    if cfg is None:
        if "train" in splits and split != "train":
            train = ds.split("train")
            calibration = calibration_of(
                ((rec, *_odometry(rec, net, tcfg)) for rec in map(train.load, train.names) if rec.truth is not None),
                SIM_POINT_EVERY_S,
            )
            splits.remove("train")
        cfg = fuse.calibrated(fuse.FuseConfig(), calibration)
    view = ds.split(split) if split else ds.split(*splits)
    per_mode: dict[str, dict[str, list]] = {}
    smooth_s = walk_s = 0.0
    skipped = 0
    for name in view.names:
        rec = view.load(name)
        if rec.truth is None or rec.fixes is None or len(rec.fixes) < 2:
            skipped += 1
            continue
        errs, s, w = simulated_errors(rec, net, tcfg, cfg)
        smooth_s, walk_s = smooth_s + s, walk_s + w
        mode = str(rec.meta.get("mode", "?"))
        for label, e in errs.items():
            per_mode.setdefault(mode, {p: [] for p in SIM_PATHS})[label].append(e)
    rows = []
    for mode in sorted(per_mode) + (["all"] if per_mode else []):
        groups = [per_mode[mode]] if mode != "all" else list(per_mode.values())
        for label in SIM_PATHS:
            e = np.concatenate([x for g in groups for x in g[label]])
            rows.append(
                {
                    "mode": mode,
                    "path": label,
                    "walks": sum(len(g[label]) for g in groups),
                    "samples": int(e.size),
                    **{k: round(v, 2) for k, v in error_stats(e).items()},
                }
            )
    prov = ds.provenance
    preset = prov.get("preset")
    return {
        "rows": rows,
        "model": model,
        "split": split or ", ".join(splits),
        "skipped": skipped,
        "calibration": calibration,
        "simulator": {"preset": preset.get("name") if isinstance(preset, dict) else preset, "seed": prov.get("seed")},
        "walk_s": round(walk_s, 1),
        "smooth_s": round(smooth_s, 3),
        "smooth_s_per_hour": round(smooth_s / walk_s * 3600.0, 3) if walk_s else None,
        "config": dataclasses.asdict(cfg),
    }


def _live_lines(live: dict) -> list[str]:
    return [
        "## The live receiver's smoother (fixed lag)",
        "",
        f"One simulated standard walk of {live['walk_min']} min (odometry at {live['odometry_hz']} Hz, "
        f"{live['fixes']} fixes), fed to `wearnav.fuse.live.IncrementalFuser` ({live['lag_s']:g}-s window) in time "
        f"order and solved every {live['every_s']:g} s: {live['updates']} updates, "
        f"**{live['ms_per_update_median']} ms per update** (median; p95 {live['ms_per_update_p95']} ms; "
        f"{live['ms_first_tenth_median']} ms in the walk's first tenth after the first window, "
        f"{live['ms_last_tenth_median']} ms in its last; solver evaluations per update "
        f"{live['solver_evaluations_first_tenth']} and {live['solver_evaluations_last_tenth']}), where the batch smoother over the whole walk took "
        f"{live['batch_s']} s. Its final path lies {live['gap_to_batch_median_m']} m (median; p95 "
        f"{live['gap_to_batch_p95_m']} m) from the batch smoother's; median error against truth "
        f"{live['live_error_median_m']} m (batch {live['batch_error_median_m']} m).",
        "",
    ]


def fixed_lag_run(
    rec, net, tcfg, cfg: fuse.FuseConfig = fuse.FuseConfig(), lag_s: float = 300.0, every_s: float = 10.0
) -> dict:
    """The live receiver's smoother (:class:`wearnav.fuse.live.IncrementalFuser`) on one simulated
    recording: odometry and fixes fed in time order, the path asked for every ``every_s`` seconds.
    Returns the seconds per update (median, p95, and the medians over the first tenth after the
    first window and over the last tenth: equal when the cost does not grow with the walk), and
    the final path's median / p95 distance from the batch smoother's and both errors against truth."""

    t, xy = _odometry(rec, net, tcfg)
    fx = rec.fixes
    order = np.argsort(fx.t, kind="stable")
    ft, fp, acc = fx.t[order], fx.pos[order, :2], fx.accuracy[order]
    inc = IncrementalFuser(cfg, lag_s=lag_s)
    times, evals, fi, next_s = [], [], 0, t[0] + every_s
    for k in range(t.size):
        inc.add_odometry(t[k], xy[k])
        while fi < ft.size and ft[fi] <= t[k]:
            inc.add_fix(ft[fi], fp[fi, 0], fp[fi, 1], acc[fi])
            fi += 1
        if t[k] >= next_s or k == t.size - 1:
            next_s += every_s
            t0 = time.perf_counter()
            live = inc.result()
            times.append(time.perf_counter() - t0)
            evals.append(live.info.get("solver_evaluations", 0))
    t0 = time.perf_counter()
    batch = fuse.smooth(t, xy, ft, fp, acc, cfg)
    batch_s = time.perf_counter() - t0
    truth = np.stack([np.interp(t, rec.truth.t, rec.truth.pos[:, j]) for j in range(2)], axis=1)
    gap = np.linalg.norm(live.xy - batch.xy, axis=1)
    e_live, e_batch = np.linalg.norm(live.xy - truth, axis=1), np.linalg.norm(batch.xy - truth, axis=1)
    ms = np.asarray(times) * 1e3
    tenth = max(1, ms.size // 10)
    i0 = min(ms.size - 1, int(lag_s // every_s) + 1)
    first, ev = ms[i0:][:tenth], np.asarray(evals, float)
    return {
        "walk_min": round(float(t[-1] - t[0]) / 60.0, 1),
        "odometry_hz": round(float((t.size - 1) / (t[-1] - t[0])), 1),
        "fixes": int(ft.size),
        "lag_s": lag_s,
        "every_s": every_s,
        "updates": int(ms.size),
        "method": live.method,
        "ms_per_update_median": round(float(np.median(ms)), 1),
        "ms_per_update_p95": round(float(np.percentile(ms, 95)), 1),
        "ms_first_tenth_median": round(float(np.median(first)), 1),
        "ms_last_tenth_median": round(float(np.median(ms[-tenth:])), 1),
        "solver_evaluations_first_tenth": round(float(np.mean(ev[i0:][:tenth])), 1),
        "solver_evaluations_last_tenth": round(float(np.mean(ev[-tenth:])), 1),
        "batch_s": round(batch_s, 3),
        "gap_to_batch_median_m": round(float(np.median(gap)), 2),
        "gap_to_batch_p95_m": round(float(np.percentile(gap, 95)), 2),
        "live_error_median_m": round(float(np.median(e_live)), 2),
        "batch_error_median_m": round(float(np.median(e_batch)), 2),
    }


def live_walk(minutes: float, model: str = "pdr", seed: int = 0, cfg: fuse.FuseConfig = fuse.FuseConfig()) -> dict:
    """:func:`fixed_lag_run` on one simulated standard walk of ``minutes`` (the simulator's fixes)."""

    net, tcfg = _untrained(model)
    rec = simulate_recording(WalkConfig(name="live", mode="STW", placement="HD", duration_s=60.0 * minutes), seed=seed)
    return fixed_lag_run(rec, net, tcfg, cfg)


def write_fusion_page(table: dict, data: str | Path, out: str | Path, live: dict | None = None) -> Path:
    """results.md + results.json in ``out`` for :func:`fusion_table`'s ``table`` (and
    :func:`live_walk`'s result, where given)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runs.write_json(out / "results.json", {**table, "data": str(data), "live": live})
    p = provenance()
    df = pd.DataFrame(table["rows"])
    wide = df.pivot_table(index="mode", columns="path", values="median (m)", sort=False)[list(SIM_PATHS)]
    overall = df[df["mode"] == "all"].drop(columns=["mode"])
    cpu = platform.processor() or platform.machine()
    lines = [
        "# Fusion on the simulator: odometry, fixes and the smoother"
        + (f" (odometry `{table['model']}`)" if table["model"] != "pdr" else ""),
        "",
        f"Generated by `wearnav bench fusion` ({p['created']}, wearnav {p['wearnav']} {p['commit']}) on "
        f"`{Path(data).name}` ({table['split']} recordings; {table['walk_s'] / 60:.1f} min of walk"
        + (f", {table['skipped']} skipped: no truth or fewer than two fixes" if table["skipped"] else "")
        + (
            f"; simulator preset `{sim['preset']}`, seed {sim['seed']}"
            if (sim := table["simulator"])["seed"] is not None
            else ""
        )
        + "); "
        f"{cpu}, {os.cpu_count()} CPUs, one process. "
        f"Odometry: {_odometry_words(table['model'])}, phone only, integrated from (0, 0) in the phone's world frame. "
        "Errors are against the simulator's dense truth at 1-s samples. "
        f"*{ODO_ORACLE}*: the odometry given its best rotation + translation onto the truth over the "
        "whole walk (an oracle no user has, so a generous bound); "
        f"*{ODO_FIRST}*: placed on the first minute's fixes, as `track --anchor first-fixes`; "
        f"*{FIXES_ALONE}*: the simulated phone fixes (correlated error, multipath jumps), linear between fixes; "
        f"*{SMOOTHER}*: `wearnav.fuse.smooth`, as `track` gives it (no truth used), "
        + (
            f"its odometry random walk ({cal['odometry_walk_m_per_sqrt_s']} m/√s) and σ scale "
            f"({cal['sigma_scale']}) calibrated on the dataset's training walks ({cal['walks']}), which are "
            "not scored (`wearnav.bench.user_protocol.calibration_of`)."
            if (cal := table.get("calibration"))
            else "with its default settings (no training walks to calibrate on)."
        ),
        "",
        "## Every walk (m)",
        "",
        overall.to_markdown(index=False, floatfmt=".2f"),
        "",
        f"The smoother took {table['smooth_s']:.2f} s for {table['walk_s'] / 60:.1f} min of walk: "
        f"**{table['smooth_s_per_hour']} s per hour of walk** (one process; the machine is shared).",
        "",
        *(_live_lines(live) if live else []),
        "## Median error per walking mode (m)",
        "",
        wide.to_markdown(floatfmt=".2f"),
        "",
        "## Every statistic",
        "",
        df.to_markdown(index=False, floatfmt=".2f"),
        "",
    ]
    return write_text_atomic("\n".join(lines), out / "results.md")


def build_untrained(model: str, tcfg):
    """An untrained baseline (PDR) for phone-only input at the config's window and rate."""

    return build(model, n_devices=len(tcfg.devices), window=tcfg.window, rate=tcfg.rate).eval()


__all__ = [
    "simulator_rows",
    "fusion_table",
    "write_fusion_page",
    "simulated_errors",
    "fixed_lag_run",
    "live_walk",
    "SIM_PATHS",
]
