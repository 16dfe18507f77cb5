"""`wearnav track`: the walking path of a user's own recording, from a trained odometry model.

Steps: read the input (a Sensor Logger export folder or zip, a wearnav ``.h5`` recording, or a
dataset folder and a recording name), align the devices the model was trained on into one
horizontal frame (:mod:`wearnav.frames`, mode "common": a user's recording has no truth, so the
frame is the reference device's), predict a velocity per window (the run's window and rate),
integrate from (0, 0) at the first window centre (:func:`wearnav.trajectory.integrate_velocity`),
and write into the output folder:

``trajectory.csv``
    ``t`` (s since the recording's start; ``unix_time`` too where the recording keeps its start,
    ``meta["t0_unix_ns"]``), ``x``, ``y`` (m, in the common frame of the reference
    device), one 0/1 column per model device (present in the window whose centre is nearest), and
    where the recording has location fixes ``east``, ``north`` (m, the anchored path, below).
``trajectory.png``
    The path with its start and end, and per-device presence over time.
``trajectory.geojson``
    Only when the recording has fixes and a lat/lon origin (``meta["origin_lat"/"origin_lon"]``,
    written by the importers that project lat/lon with :func:`wearnav.geo.latlon_to_local`): the
    anchored path as a LineString and the fixes as Points (with time and accuracy), in WGS-84
    lon/lat, converted back by :func:`wearnav.geo.local_to_latlon` (``east``, ``north`` are their
    WGS-84 east-north-up metres about that origin).
``track.json``
    What was done: model, run, devices used and present, frame reference, anchoring fit, and
    ``warnings`` (one line each; also shown on the console), e.g. a recording imported with an
    older lat/lon projection (:func:`wearnav.geo.needs_reimport`), or a reason not to trust the
    path (:func:`trust_warnings`, :mod:`wearnav.trust`): devices the recording lacks, a rate,
    placement or gravity direction unlike the model's training data, a model that did not beat
    standing still, a path implausible for walking.

Anchoring: the common frame has an arbitrary yaw and the path starts at (0, 0); the yaw and offset
that map it onto the fixes are the weighted least-squares 2-D rotation + translation (Procrustes
without scale, Umeyama 1991) between the path at the fix times and the fixes, over the fixes of the
first ``ANCHOR_S`` seconds, each weighted by 1/accuracy² (fixes without an accuracy get the median
weight). Where the path spreads less than ``MIN_ANCHOR_SPREAD_M`` (weighted RMS about its centre)
over those fixes the yaw is not observable, so later fixes are added until it does (or all are
used); ``track.json`` reports the fixes used, the weighted RMS residual and a 1-σ yaw uncertainty
≈ residual / (spread · √n) (the angular error of a rotation fitted to n points at that spread). Only the first fixes are used so that the path drifts
freely afterwards: the map shows the odometry, not the GNSS track.
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import geo, trust
from wearnav.errors import ConfigError, FormatError, ValidationError, WearnavWarning
from wearnav.fileio import atomic_path, write_text_atomic
from wearnav.outputs import check_out_folder, staged_output
from wearnav.recording import Recording
from wearnav.textio import read_json
from wearnav.train.resolve import resolve_model

ANCHOR_S = 60.0
MIN_ANCHOR_SPREAD_M = 5.0
TRAJ_FORMAT = "%.4f"
TRACK_JSON = "track.json"  # the marker: a folder holding it was written by `wearnav track`
TRACK_FILES = ("trajectory.csv", "trajectory.png", "trajectory.geojson", TRACK_JSON)


# ---- input -------------------------------------------------------------------------------------

def load_input(src: str | Path, name: str | None = None, platform: str | None = None) -> Recording:
    """The recording to track: a ``.h5`` recording, a dataset folder (``name`` picks one; the only
    one if omitted), or a Sensor Logger export (folder, zip, or folder of several with ``name``)."""
    from wearnav.dataset import MANIFEST, Dataset
    from wearnav.importers import sensorlogger

    src = Path(src)
    if not src.exists():
        raise FormatError("no such file or folder", src)
    if src.is_file() and src.suffix.lower() == ".h5":
        return Recording.load(src)
    if src.is_dir() and (src / MANIFEST).is_file():
        ds = Dataset.open(src)
        if name is None:
            if len(ds) != 1:
                raise ConfigError(f"the dataset holds {len(ds)} recordings; pick one with --name "
                                  f"(e.g. {', '.join(ds.names[:3])})", src)
            name = ds.names[0]
        return ds.load(name)
    # A Sensor Logger export: zips are extracted into a temporary folder that the importer removes.
    recs = list(sensorlogger.read(src, platform=platform))
    if name is not None:
        recs = [r for r in recs if r.name == name]
        if not recs:
            raise ValidationError(f"no export named {name!r} here", src)
    if len(recs) != 1:
        raise ConfigError(f"holds {len(recs)} Sensor Logger exports; pick one with --name "
                          f"({', '.join(r.name for r in recs[:5])})", src)
    return recs[0]


# ---- anchoring ---------------------------------------------------------------------------------

def anchor_to_fixes(t: np.ndarray, xy: np.ndarray, fix_t: np.ndarray, fix_pos: np.ndarray,
                    fix_accuracy: np.ndarray) -> dict:
    """Rotation + translation (see module docstring) mapping path ``xy`` (at times ``t``) onto
    the first fixes. Returns ``yaw`` (rad), ``offset`` (2,), the fixes used and the fit's residual;
    raises ValidationError when fewer than two fixes lie under the path."""
    inside = np.flatnonzero((fix_t >= t[0]) & (fix_t <= t[-1]))
    if inside.size < 2:
        raise ValidationError("fewer than two location fixes lie inside the tracked span")
    p_all = np.stack([np.interp(fix_t[inside], t, xy[:, k]) for k in range(2)], axis=1)
    q_all = fix_pos[inside, :2]
    acc = fix_accuracy[inside]
    w_all = np.where(np.isfinite(acc) & (acc > 0), 1.0 / np.maximum(acc, 0.5) ** 2, np.nan)
    w_all = np.where(np.isfinite(w_all), w_all, np.nanmedian(w_all) if np.isfinite(w_all).any() else 1.0)
    n = max(2, int(np.sum(fix_t[inside] <= fix_t[inside[0]] + ANCHOR_S)))
    while True:
        p, q, w = p_all[:n], q_all[:n], w_all[:n]
        pc = p - np.average(p, axis=0, weights=w)
        spread = float(np.sqrt(np.average(np.sum(pc ** 2, axis=1), weights=w)))
        if spread >= MIN_ANCHOR_SPREAD_M or n == len(p_all):
            break
        n += 1
    qc = q - np.average(q, axis=0, weights=w)
    # 2-D Procrustes: the angle maximising Σ w q·R(θ)p
    cross = np.sum(w * (pc[:, 0] * qc[:, 1] - pc[:, 1] * qc[:, 0]))
    dot = np.sum(w * np.sum(pc * qc, axis=1))
    yaw = float(np.arctan2(cross, dot))
    rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    offset = np.average(q, axis=0, weights=w) - rot @ np.average(p, axis=0, weights=w)
    resid = (p @ rot.T + offset) - q
    return {"yaw": yaw, "offset": offset, "fixes_used": int(n),
            "span_s": float(fix_t[inside[n - 1]] - fix_t[inside[0]]), "path_spread_m": spread,
            "rms_residual_m": (rms := float(np.sqrt(np.average(np.sum(resid ** 2, axis=1), weights=w)))),
            "yaw_std_deg": float(np.degrees(rms / max(spread, 1e-9) / np.sqrt(n)))}


def apply_anchor(xy: np.ndarray, fit: dict) -> np.ndarray:
    yaw = fit["yaw"]
    rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    return xy @ rot.T + fit["offset"]


def geojson(path_ll: tuple[np.ndarray, np.ndarray], fixes_ll: tuple[np.ndarray, np.ndarray],
            fix_t: np.ndarray, fix_accuracy: np.ndarray, props: dict) -> dict:
    """A FeatureCollection: the path as a LineString, each fix as a Point (RFC 7946: lon, lat)."""
    def coords(lat, lon):
        return [[round(float(a), 8), round(float(b), 8)] for a, b in zip(lon, lat)]
    feats = [{"type": "Feature", "geometry": {"type": "LineString", "coordinates": coords(*path_ll)},
              "properties": {"kind": "path", **props}}]
    for (lon, lat), t, a in zip(coords(*fixes_ll), fix_t, fix_accuracy):
        feats.append({"type": "Feature", "geometry": {"type": "Point", "coordinates": [lon, lat]},
                      "properties": {"kind": "fix", "t": round(float(t), 3),
                                     "accuracy_m": None if not np.isfinite(a) else round(float(a), 2)}})
    return {"type": "FeatureCollection", "features": feats}


# ---- can the path be trusted? (wearnav.trust) --------------------------------------------------

def run_training_record(model_path: str | Path) -> dict:
    """The run's ``training.json`` for a run folder or its checkpoint; ``{}`` where it has none or
    cannot be read (the warnings then say that the training data is unknown: tracking goes on)."""
    from wearnav.train.odometry import TRAINING

    p = Path(model_path)
    run = p.parent.parent if p.is_file() else p
    try:
        record = read_json(run / TRAINING) if (run / TRAINING).is_file() else {}
    except FormatError:
        return {}
    return record if isinstance(record, dict) else {}


def trust_warnings(model_path, cfg, rec: Recording, seq, t_c: np.ndarray, vel: np.ndarray,
                   length_m: float) -> list[str]:
    """One line per reason not to trust the path, each with what to do: devices the recording
    lacks, a rate / placement / gravity direction unlike the training data's (learned models), a
    model that did not beat standing still, and a result implausible for walking (PDR's step
    detector on the same windows)."""
    from wearnav.evaluate import predict_sequence
    from wearnav.models import registry
    from wearnav.models.pdr import PDR

    out = []
    if (m := trust.missing_devices(cfg.devices, rec.devices)) is not None:
        out.append(f"{m}: {trust.TRACK_DEVICES_ADVICE}")
    if registry.get(cfg.model).learned:
        record = run_training_record(model_path)
        facts = trust.recording_facts(rec, cfg.devices, cfg.window / cfg.rate)
        known = record.get("training_data")
        known = known if isinstance(known, dict) else None
        out += [f"{f}: {trust.TRACK_DOMAIN_ADVICE}" for f in trust.domain_findings(facts, known)]
        if (m := trust.did_not_learn(record)) is not None:
            out.append(f"{m}: {trust.LEARN_ADVICE}")
    try:
        pdr = PDR(n_devices=len(cfg.devices), window=cfg.window, rate=cfg.rate)
    except ConfigError:  # a window too short for PDR's step detector: no walking check
        return out
    _, pdr_vel, _ = predict_sequence(pdr, seq, cfg.window, cfg.stride)
    step_rate_hz = np.linalg.norm(pdr_vel, axis=1) / pdr.step_length
    steps = float(np.sum(step_rate_hz) * cfg.stride / cfg.rate)  # windows tile time at the stride
    findings = trust.implausible_walk(np.linalg.norm(vel, axis=1), step_rate_hz, length_m, steps)
    return out + [f"{f}: {trust.TRACK_RESULT_ADVICE}" for f in findings]


# ---- the command -------------------------------------------------------------------------------

def track(src: str | Path, model_path: str | Path, out: str | Path, name: str | None = None,
          platform: str | None = None, progress: bool = False) -> dict:
    """Track one recording (see module docstring); returns what ``track.json`` holds."""
    from wearnav.evaluate import predict_sequence
    from wearnav.preprocess import align
    from wearnav.trajectory import integrate_velocity

    out = Path(out)
    check_out_folder(out, TRACK_FILES, TRACK_JSON, "track")  # before any work
    model, cfg = resolve_model(model_path, "odometry")  # a run folder, checkpoint or `pdr`
    rec = load_input(src, name, platform)
    usable = [d for d in cfg.devices if d in rec.devices]
    if not usable:
        raise ValidationError(f"no IMU stream the model can use: it was trained on "
                              f"{', '.join(cfg.devices)}; the recording has {', '.join(rec.devices) or 'none'}",
                              src)
    pcfg = dataclasses.replace(cfg.preprocess_config(), frame_align="common")
    seq = align(rec, pcfg)
    t_c, vel, present = predict_sequence(model, seq, cfg.window, cfg.stride, progress=progress)
    if t_c.size < 2:
        raise ValidationError(f"too short to track: {seq.t[-1] - seq.t[0]:.1f} s of common data, the "
                              f"model needs windows of {cfg.window / cfg.rate:g} s", src)
    t = seq.t[(seq.t >= t_c[0]) & (seq.t <= t_c[-1])]
    xy = integrate_velocity(t_c, vel, t, np.zeros(2))
    nearest = np.clip(np.searchsorted(t_c, t), 0, len(t_c) - 1)
    prev = np.clip(nearest - 1, 0, len(t_c) - 1)
    nearest = np.where(np.abs(t_c[prev] - t) < np.abs(t_c[nearest] - t), prev, nearest)
    table = pd.DataFrame({"t": t, "x": xy[:, 0], "y": xy[:, 1]})
    if "t0_unix_ns" in rec.meta:
        table.insert(1, "unix_time", rec.meta["t0_unix_ns"] * 1e-9 + t)
    for k, dev in enumerate(seq.devices):
        table[dev] = (present[nearest, k] > 0).astype(int)
    share = {dev: round(float((present[:, k] > 0).mean()), 3) for k, dev in enumerate(seq.devices)}
    frame = seq.meta.get("frame", {})
    summary: dict = {
        "recording": rec.name, "source": str(src), "model": cfg.model, "run": str(model_path),
        "model_devices": list(cfg.devices), "devices_in_recording": list(rec.devices),
        "devices_used": usable, "device_share_of_windows": share,
        "rate_hz": cfg.rate, "window": cfg.window, "stride": cfg.stride,
        "frame": frame.get("frame", "none"), "frame_reference": frame.get("reference"),
        "duration_s": round(float(t[-1] - t[0]), 2),
        "length_m": round(float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1))), 2),
        "end_xy_m": [round(float(v), 3) for v in xy[-1]],
        "warnings": [],
    }
    if (stale := geo.needs_reimport(rec.meta, has_fixes=rec.fixes is not None)) is not None:
        summary["warnings"].append(f"{rec.name}: {stale}")
    summary["warnings"] += [f"{rec.name}: {w}" for w in trust_warnings(model_path, cfg, rec, seq, t_c, vel,
                                                                        summary["length_m"])]
    for w in summary["warnings"]:
        warnings.warn(WearnavWarning(w))
    with staged_output(out, TRACK_JSON, "track") as stage:
        _write_track(stage, out, table, t, xy, rec, cfg, seq, summary)
    return summary


def _write_track(stage: Path, out: Path, table: pd.DataFrame, t: np.ndarray, xy: np.ndarray, rec: Recording,
                 cfg, seq, summary: dict) -> None:
    """Anchor on the fixes and write the files into ``stage`` (moved to ``out`` afterwards)."""
    anchored = None
    fx = rec.fixes
    if fx is not None and len(fx) >= 2:
        try:
            fit = anchor_to_fixes(t, xy, fx.t, fx.pos[:, :2], fx.accuracy)
        except ValidationError as exc:
            summary["anchoring"] = f"not anchored: {exc.reason}"
        else:
            anchored = apply_anchor(xy, fit)
            table["east"], table["north"] = anchored[:, 0], anchored[:, 1]
            summary["anchoring"] = {"yaw_deg": round(float(np.degrees(fit["yaw"])), 2),
                                    "offset_m": [round(float(v), 3) for v in fit["offset"]],
                                    **{k: (round(v, 3) if isinstance(v, float) else v)
                                       for k, v in fit.items() if k not in ("yaw", "offset")},
                                    "method": f"weighted (1/accuracy²) least-squares rotation + translation "
                                              f"over the fixes of the first {ANCHOR_S:g} s"}
            lat0, lon0 = rec.meta.get("origin_lat"), rec.meta.get("origin_lon")
            if lat0 is not None and lon0 is not None:
                gj = geojson(geo.local_to_latlon(anchored, float(lat0), float(lon0)),
                             geo.local_to_latlon(fx.pos[:, :2], float(lat0), float(lon0)),
                             fx.t, fx.accuracy, {"recording": rec.name, "model": cfg.model})
                write_text_atomic(json.dumps(gj), stage / "trajectory.geojson")
                summary["geojson"] = str(out / "trajectory.geojson")
            else:
                summary["geojson"] = "not written: the recording's fixes have no lat/lon origin"
    with atomic_path(stage / "trajectory.csv") as tmp:
        table.to_csv(tmp, index=False, float_format=TRAJ_FORMAT)
    plot_track(table, seq.devices, anchored, fx, summary, stage / "trajectory.png")
    summary["files"] = ["trajectory.csv", "trajectory.png", TRACK_JSON] + (
        ["trajectory.geojson"] if (stage / "trajectory.geojson").is_file() else [])
    write_text_atomic(json.dumps(summary, indent=2, default=str), stage / TRACK_JSON)


def plot_track(table: pd.DataFrame, devices: tuple[str, ...], anchored, fixes, summary: dict,
               out: Path) -> Path:
    """The path (anchored on the fixes where there are some) with start and end, and per-device
    presence over time."""
    from matplotlib.figure import Figure

    from wearnav.report.plots import save

    fig = Figure(figsize=(7.5, 8.5), layout="constrained")
    ax, ax_dev = fig.subplots(2, 1, height_ratios=[5, 1])
    xy = anchored if anchored is not None else table[["x", "y"]].to_numpy()
    if anchored is not None:
        ax.scatter(fixes.pos[:, 0], fixes.pos[:, 1], s=8, c="tab:red", alpha=0.6, label="location fixes")
    ax.plot(xy[:, 0], xy[:, 1], color="tab:blue", lw=1.2, label=f"path ({summary['model']})")
    ax.plot(*xy[0], "o", color="tab:green", ms=8, label="start")
    ax.plot(*xy[-1], "s", color="black", ms=7, label="end")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)" if anchored is not None else "x (m, common frame)")
    ax.set_ylabel("north (m)" if anchored is not None else "y (m, common frame)")
    ax.set_title(f"{summary['recording']}: {summary['length_m']:.0f} m in {summary['duration_s']:.0f} s; "
                 f"devices used: {', '.join(summary['devices_used'])}", fontsize=9)
    ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.3)
    t = table["t"].to_numpy()
    for k, dev in enumerate(devices):
        on = table[dev].to_numpy().astype(float)
        ax_dev.fill_between(t, k + 0.1, k + 0.1 + 0.8 * on, step="mid", color=f"C{k}", alpha=0.7)
    ax_dev.set_yticks(np.arange(len(devices)) + 0.5, devices)
    ax_dev.set_ylim(0, len(devices))
    ax_dev.set_xlabel("time (s)")
    ax_dev.set_title("device present per window", fontsize=9)
    return save(fig, out)


__all__ = ["track", "load_input", "anchor_to_fixes", "apply_anchor", "ANCHOR_S"]
