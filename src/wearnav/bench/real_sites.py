"""The sites of `wearnav bench real-odometry` (:mod:`wearnav.bench.real`): each building's data split by
place (step 1 there), its yaw between the phone's magnetic-north frame and the truth's, estimated by
PDR from its training traces (step 3), and the phone's own fixes' error at its surveyed points
(step 5).

Decisions: docs/decisions/0010-real-buildings-splits-and-site-yaw.md, docs/decisions/0029-heading-frame.md."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from wearnav import runs
from wearnav.bench.user_protocol import fix_point_errors
from wearnav.core.progress import progress as report_progress
from wearnav.core.rotations import from_wxyz
from wearnav.core.textio import read_json
from wearnav.dataset import Dataset, is_validation_name
from wearnav.errors import ConfigError, ValidationError
from wearnav.evaluate import predict_sequence
from wearnav.models.registry import build
from wearnav.preprocess import SURVEYED_TRUTH_MAX_GAP_S, load_sequences
from wearnav.train.odometry import TrainConfig, load_model
from wearnav.trajectory import integrate_velocity

TRUTH_MAX_GAP_S = SURVEYED_TRUTH_MAX_GAP_S
# IPIN 2023 Track 3's held-out routes (meta ``trial``), for every benchmark on IPIN (this one, the
# user protocol, `bench easytrack`'s real part): three of the eleven routes, none of them the
# simulator's calibration trials 01–02.
IPIN_TEST_TRIALS = (4, 24, 52)
# Grouping and held-out groups per source; neither holds data the simulator was calibrated on.
SITE_DEFAULTS: dict[str, tuple[str, tuple[str, ...]]] = {
    "ilc2": ("floor_name", ("F2", "F4")),
    "ipin2023": ("trial", tuple(str(t) for t in IPIN_TEST_TRIALS)),
}
CALIBRATION = {"ilc2": ("floor_name", {"F1"}), "ipin2023": ("trial", {"1", "2"})}
PERCENTILES = (50, 75, 95)


# ---- data ---------------------------------------------------------------------------------------


def _group(meta: dict, key: str, name: str) -> str:
    if key not in meta:
        raise ValidationError(f"recording {name} has no meta key {key!r} to group by")
    return str(meta[key])


def split_of(name: str, group: str, test_groups: set[str]) -> str:
    """``test`` for the held-out groups; else ``val`` for one recording in VAL_EVERY (by a hash of
    its name: :func:`wearnav.dataset.is_validation_name`), else ``train``."""
    if group in test_groups:
        return "test"
    return "val" if is_validation_name(name) else "train"


def prepare_data(
    src: str | Path,
    out: str | Path,
    fmt: str | None = None,
    group_by: str | None = None,
    test_groups: tuple[str, ...] | None = None,
    progress: bool = True,
) -> tuple[Path, dict]:
    """Write ``src`` (an imported dataset folder, or an original-format folder read with importer
    ``fmt``) to ``out`` with splits by place. Returns the folder and what was decided."""
    from wearnav.dataset import DatasetWriter
    from wearnav.importers import get_importer

    src, out = Path(src), Path(out)
    if (src / "manifest.csv").is_file():
        ds = Dataset.open(src)
        recs, source = (ds.load(n) for n in ds.names), str(ds.manifest["source"].iloc[0]) if len(ds) else ""
    elif fmt is None:
        raise ConfigError(f"{src} is not an imported dataset (no manifest.csv): name its --format")
    else:
        recs, source = get_importer(fmt).read(src), fmt
    key, groups = SITE_DEFAULTS.get(source, (None, None))
    key, groups = group_by or key, tuple(test_groups) if test_groups else groups
    if key is None or not groups:
        raise ConfigError(f"no default grouping for source {source!r}: give --group-by and --test-groups")
    wanted = {"src": str(src.resolve()), "importer": fmt, "group_by": key, "test_groups": list(groups)}
    info_path = out / "split.json"
    if info_path.is_file() and (out / "manifest.csv").is_file():
        info = read_json(info_path)
        if {k: info.get(k) for k in wanted} == wanted:
            return out, info
    counts: dict[str, dict[str, int]] = {}
    calib_key, calib = CALIBRATION.get(source, (None, set()))
    with DatasetWriter(out, {"generator": "wearnav.bench.real", **wanted}) as w:
        for rec in report_progress(recs, desc=f"prepare {src.name}", unit="rec", enabled=progress, leave=False):
            g = _group(rec.meta, key, rec.name)
            split = split_of(rec.name, g, set(groups))
            if split == "test" and calib_key and str(rec.meta.get(calib_key)) in calib:
                raise ConfigError(
                    f"test group {g!r} holds data the simulator was calibrated on "
                    f"({calib_key} {sorted(calib)}); choose other --test-groups"
                )
            counts.setdefault(g, {}).setdefault(split, 0)
            counts[g][split] += 1
            w.add(rec, split=split)
    missing = set(groups) - set(counts)
    if missing:
        raise ValidationError(
            f"test groups {sorted(missing)} are not in the data ({key} values: {sorted(counts)})", src
        )
    info = {**wanted, "source": source, "groups": counts}
    runs.write_json(info_path, info)
    return out, info


# ---- the site's yaw ---------------------------------------------------------------------------


def segment_products(seqs, window: int = 100, stride: int = 10, model=None) -> np.ndarray:
    """d_model · conj(d_truth) per segment between consecutive surveyed points (complex), over the
    sequences ``seqs`` (Aligned, world frame, no yaw applied); ``model`` None: PDR."""
    out = []
    for seq in seqs:
        net = (
            model
            if model is not None
            else build("pdr", n_devices=len(seq.devices), window=window, rate=seq.rate).eval()
        )
        t_c, vel, _ = predict_sequence(net, seq, window, stride)
        rec = seq.recording
        if t_c.size < 2 or rec is None or rec.truth is None:
            continue
        tt, tp = rec.truth.t, rec.truth.pos[:, :2]
        k = (tt >= seq.t[0]) & (tt <= seq.t[-1])
        if k.sum() < 2:
            continue
        est = integrate_velocity(t_c, vel, tt[k], tp[k][0])
        de, dt = np.diff(est, axis=0), np.diff(tp[k], axis=0)
        out.append((de[:, 0] + 1j * de[:, 1]) * np.conj(dt[:, 0] + 1j * dt[:, 1]))
    return np.concatenate(out) if out else np.empty(0, complex)


def device_axis_yaw(seqs, device: str = "phone", axis=(0.0, 1.0, 0.0)) -> float | None:
    """A cross-check valid only for a device held flat and pointing ahead (ILC2's phones): the yaw
    of its ``axis`` in the world frame against each segment's truth direction, Σ over segments of
    at least 1 m (degrees); None without orientation."""
    p = []
    for seq in seqs:
        rec = seq.recording
        s = rec.devices.get(device) if rec is not None else None
        if s is None or s.quat is None or rec.truth is None:
            continue
        fwd = from_wxyz(s.quat).apply(axis)
        h = fwd[:, 0] + 1j * fwd[:, 1]
        h = h / np.maximum(np.abs(h), 1e-9)
        tt, tp = rec.truth.t, rec.truth.pos[:, :2]
        for a in range(len(tt) - 1):
            k = (s.t >= tt[a]) & (s.t <= tt[a + 1])
            d = tp[a + 1] - tp[a]
            if k.sum() >= 10 and np.hypot(*d) >= 1.0:
                p.append(h[k].mean() * np.conj(d[0] + 1j * d[1]))
    return round(float(np.degrees(np.angle(np.sum(p)))), 2) if p else None


def site_yaw(seqs, window: int = 100, stride: int = 10, model=None) -> dict:
    """The yaw (degrees) of the input's world frame relative to the truth frame, from PDR (or
    ``model``) on training traces (module docstring, step 3), with its spread."""
    p = segment_products(seqs, window, stride, model)
    if p.size == 0:
        raise ValidationError("no segments between surveyed points to estimate the site's yaw from")
    yaw = float(np.angle(np.sum(p)))
    dev = np.degrees(np.abs(np.angle(p * np.exp(-1j * yaw))))
    unit = p / np.maximum(np.abs(p), 1e-12)
    return {
        "yaw_deg": round(float(np.degrees(yaw)), 2),
        "segments": int(p.size),
        "traces": len(seqs),
        "median_abs_dev_deg": round(float(np.median(dev)), 1),
        "resultant_length": round(float(np.abs(unit.mean())), 3),
        "phone_axis_yaw_deg": device_axis_yaw(seqs),
    }


def estimate_site_yaw(
    data: Path,
    split: str | None = "train",
    devices=("phone",),
    rate: float = 25.0,
    progress: bool = False,
    run: Path | None = None,
    speed: str = "model",
) -> dict:
    """:func:`site_yaw` of the ``split`` traces (None: all) of dataset ``data`` (no yaw applied, no
    frame alignment), by PDR or by the model of ``run`` (a run folder: its rate, window and stride;
    ``speed`` as :func:`wearnav.train.odometry.load_model`'s); ``progress``: report the traces' loading
    (:mod:`wearnav.core.progress`)."""
    model, window, stride = None, 100, 10
    cfg = TrainConfig(
        model="pdr",
        data=str(data),
        devices=tuple(devices),
        rate=rate,
        frame_align="none",
        truth_max_gap=TRUTH_MAX_GAP_S,
    )
    if run is not None:  # the model's own preprocessing (its heading frame too), no yaw
        model, tcfg = load_model(run, speed=speed)
        window, stride = tcfg.window, tcfg.stride
        cfg = dataclasses.replace(tcfg, data=str(data), frame_align="none", truth_max_gap=TRUTH_MAX_GAP_S, yaw_deg=0.0)
    ds = Dataset.open(data)
    found = site_yaw(load_sequences(ds.split(split) if split else ds, cfg, progress), window, stride, model)
    by = "pdr" if run is None else "the model itself" if speed == "model" else f"the model itself, speed {speed}"
    return {**found, "by": by}


# ---- the phone's own fixes --------------------------------------------------------------------


def fix_errors(data: Path, split: str = "test") -> dict | None:
    """Raw fix error at the surveyed points of ``split`` (nearest fix within metrics.FIX_MAX_GAP_S), each
    trace from its second point on, as the models are scored; None without fixes."""
    view = Dataset.open(data).split(split)
    errs = []
    for name in view.names:
        rec = view.load(name)
        if rec.fixes is None or rec.truth is None or len(rec.fixes) == 0:
            continue
        errs.append(fix_point_errors(rec))
    if not errs:
        return None
    e = np.concatenate(errs)
    return {
        "sequences": len(errs),
        "points": int(e.size),
        **_point_stats(e),
        "point_errors": [round(float(x), 3) for x in e],
    }


def _point_stats(e: np.ndarray) -> dict:
    if e.size == 0:
        return {"error_mean": float("nan"), **{f"error_p{p}": float("nan") for p in PERCENTILES}}
    return {"error_mean": float(e.mean()), **{f"error_p{p}": float(np.percentile(e, p)) for p in PERCENTILES}}
