"""`wearnav bench adapt`: the adaptation table of issue 18 §3, on IPIN 2023.

A base model never trained on IPIN is adapted (:mod:`wearnav.adapt`) on the training trials'
GNSS fixes only (no POSI point is read) and scored at the held-out trials' POSI points
(:data:`wearnav.bench.real_sites.IPIN_TEST_TRIALS`), beside the un-adapted model, PDR and the raw GNSS,
in two protocols:

1. **known start + site yaw**, as `bench real-odometry` scores (:func:`wearnav.evaluate.evaluate_run`;
   the site yaw from PDR on the training trials, :func:`wearnav.bench.real_sites.estimate_site_yaw`);
2. **the user protocol** (:func:`wearnav.bench.user_protocol.user_protocol`): no truth at all,
   the path placed on the walk's own fixes by the smoother or one rigid fit.

Each with the per-walk path-length ratio (1 is right). The default method is chosen on the
training trials only: each method adapts on the fixes of the training trials' ``train`` split and
is scored at the POSI points of every training trial (protocol 1's median; the walks it adapted
on, as a user tracks their own walks, and the ``val`` walks it did not see, both shown); the
held-out trials play no part in the choice.
"""

from __future__ import annotations

import dataclasses
import os
import platform
import re
import shutil
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import runs
from wearnav.adapt import METHODS, AdaptConfig, adapt
from wearnav.adapt.segments import walk_segments
from wearnav.bench.real_sites import TRUTH_MAX_GAP_S, estimate_site_yaw, fix_errors, prepare_data
from wearnav.bench.user_protocol import calibrate, median_ratio, raw_fix_length_ratio, score_path, user_protocol
from wearnav.core.fileio import shown_path, write_text_atomic
from wearnav.core.provenance import provenance
from wearnav.core.textio import read_json
from wearnav.dataset import Dataset
from wearnav.evaluate import evaluate_run
from wearnav.preprocess import interpolate_position
from wearnav.recording import Recording
from wearnav.train.odometry import ADAPTATION, TrainConfig, fit, load_model, prepare_run

UNADAPTED, PDR, RAW = "un-adapted", "PDR", "raw GNSS"
ANCHORS = ("smooth", "rigid")  # the user protocol's anchorings shown (wearnav.fuse.ANCHORS)


def _label(method: str) -> str:
    return f"adapted ({method})"


def _recordings(data: Path, splits: tuple[str, ...]) -> Iterator[Recording]:
    ds = Dataset.open(data)
    for split in splits:
        view = ds.split(split)
        for name in view.names:
            yield view.load(name)


def _stats(e: np.ndarray) -> dict:
    e = np.asarray(e, float)
    if e.size == 0:
        return {"points": 0, "median (m)": float("nan"), "p75 (m)": float("nan"), "p95 (m)": float("nan")}
    return {
        "points": int(e.size),
        "median (m)": round(float(np.median(e)), 2),
        "p75 (m)": round(float(np.percentile(e, 75)), 2),
        "p95 (m)": round(float(np.percentile(e, 95)), 2),
    }


def scored(run: Path, data: Path, splits: tuple[str, ...], yaw_deg: float, out_dir: Path) -> dict[str, tuple]:
    """Protocol 1 per split of ``splits``: (errors at the POSI points, each walk's length ratio)."""
    pre = {"frame_align": "none", "truth_max_gap": TRUTH_MAX_GAP_S, "yaw_deg": yaw_deg}
    m = evaluate_run(run, data=data, splits=splits, progress=False, preprocess=pre, out_dir=out_dir)
    ds, out = Dataset.open(data), {}
    for split in splits:
        errors, ratios = [], []
        for r in m["splits"][split]["sequences"]:
            if "point_errors" not in r:
                continue
            errors.append(np.asarray(r["point_errors"], float))
            traj = pd.read_csv(out_dir / "trajectories" / split / f"{r['name']}.csv")
            truth = ds.load(r["name"]).truth
            assert truth is not None  # a scored recording has truth
            ratios.append(score_path(traj["t"].to_numpy(), traj[["x", "y"]].to_numpy(), truth.t, truth.pos[:, :2])[1])
        out[split] = (np.concatenate(errors) if errors else np.empty(0), ratios)
    return out


def pooled(parts: list[tuple]) -> dict:
    """Walks, POSI-point statistics and the median length ratio over :func:`scored`'s parts."""
    ratios = [x for _, r in parts for x in r]
    return {"walks": len(ratios), **_stats(np.concatenate([e for e, _ in parts])), "length ratio": median_ratio(ratios)}


def fix_label_bias(model: Path, data: Path, splits: tuple[str, ...]) -> dict:
    """A diagnostic of the labels, never used to adapt: per segment that `wearnav adapt` would use
    on ``splits``, the length of the fixes' displacement over the truth's (the POSI points joined
    by straight lines, the competition's own assumption between them)."""
    _, tcfg = load_model(model)
    ratio = []
    for rec in _recordings(data, splits):
        w = walk_segments(rec, tcfg)
        if w is None or rec.truth is None:
            continue
        p = interpolate_position(rec.truth.t, rec.truth.pos[:, :2], np.concatenate([w.t0, w.t1]), max_gap=np.inf)
        d = np.linalg.norm(p[len(w) :] - p[: len(w)], axis=1)
        ok = np.isfinite(d) & (d > 1.0)
        ratio.append(np.linalg.norm(w.d_fix[ok], axis=1) / d[ok])
    r = np.concatenate(ratio) if ratio else np.empty(0)
    return {
        "segments": int(r.size),
        "median": round(float(np.median(r)), 3) if r.size else None,
        "iqr": [round(float(q), 3) for q in np.percentile(r, [25, 75])] if r.size else None,
    }


def user(run: Path, data: Path, split: str) -> dict[str, dict]:
    """Protocol 2 on ``split``, per anchoring of :data:`ANCHORS`; the smoother's odometry random walk
    and σ scale calibrated on the site's training walks (as `bench real-odometry` does for a model that did not
    train on them: :func:`wearnav.bench.user_protocol.site_calibration`), not kept in the run."""
    res = user_protocol(run, data, split, calibration=calibrate(run, data, "train"))
    return {
        a: {
            "walks": len(res[a]["length_ratio"]),
            **_stats(np.asarray(res[a]["errors"])),
            "length ratio": median_ratio(res[a]["length_ratio"]),
        }
        for a in ANCHORS
    }


def _adapted(model: Path, data: Path, splits: tuple[str, ...], run: Path, cfg: AdaptConfig) -> dict:
    """Adapt (unless ``run`` holds this adaptation of ``model`` already: one of another base is
    replaced) and return its ``adaptation.json``."""
    if (run / ADAPTATION).is_file():
        base = runs.read_config(run).get("adapted_from", {}).get("run")
        if base == str(Path(model).resolve()):
            return read_json(run / ADAPTATION)
        shutil.rmtree(run)
    return adapt(_recordings(data, splits), model, run, cfg)


def adapt_table(
    model: str | Path,
    data: str | Path,
    out: str | Path,
    fmt: str | None = None,
    cfg: AdaptConfig = AdaptConfig(),
    progress: bool = False,
) -> dict:
    """The adaptation table (module docstring) into ``out`` (results.md, results.json, the split
    data, the adapted runs and their evaluations); returns what results.json holds."""
    t_start = time.perf_counter()
    model, out = Path(model), Path(out)
    data_dir, info = prepare_data(data, out / "data", fmt, progress=progress)
    yaw_file = out / "data" / "site_yaw.json"
    if not yaw_file.is_file():
        runs.write_json(yaw_file, estimate_site_yaw(data_dir, "train"))
    yaw = read_json(yaw_file)
    yaw_deg = float(yaw["yaw_deg"])
    doc: dict = {
        "model": str(model),
        "data": str(data),
        "split": info,
        "site_yaw": yaw,
        "config": dataclasses.asdict(cfg),
        "seconds": {},
    }

    # the default's choice: adapt on the training trials' train split, score at the POSI points of
    # every training trial (train: the walks adapted on, as a user tracks them; val: walks not)
    t0 = time.perf_counter()
    choice: dict = {"all": {}, "train": {}, "val": {}}
    records = {}
    for m in (None, *METHODS):
        run, label = (model, UNADAPTED) if m is None else (out / "choice" / m, _label(m))
        if m is not None:
            records[m] = _adapted(model, data_dir, ("train",), run, dataclasses.replace(cfg, method=m))
        parts = scored(run, data_dir, ("train", "val"), yaw_deg, out / "choice" / f"eval_{m or 'base'}")
        for part, splits in (("all", ("train", "val")), ("train", ("train",)), ("val", ("val",))):
            choice[part][label] = pooled([parts[k] for k in splits])
    best = min(METHODS, key=lambda m: choice["all"][_label(m)]["median (m)"])
    doc["choice"] = {
        "scores": choice,
        "adaptations": records,
        "best": best,
        "rule": "the lower median error (known start) at the POSI points of every training trial",
    }
    doc["fix_label_bias"] = fix_label_bias(model, data_dir, ("train", "val"))
    doc["seconds"]["choice"] = round(time.perf_counter() - t0, 1)

    # the table: adapt on every training trial, score at the held-out trials
    t0 = time.perf_counter()
    pdr_cfg = TrainConfig(
        model="pdr",
        data=str(data_dir),
        devices=("phone",),
        frame_align="none",
        truth_max_gap=TRUTH_MAX_GAP_S,
        yaw_deg=yaw_deg,
    )
    pdr = prepare_run(pdr_cfg, out / "runs" / "pdr")
    fit(pdr_cfg, pdr, progress=False)
    folders = {UNADAPTED: model}
    adaptations = {}
    for m in METHODS:
        run = out / "runs" / m
        adaptations[m] = _adapted(model, data_dir, ("train", "val"), run, dataclasses.replace(cfg, method=m))
        folders[_label(m)] = run
    folders[PDR] = pdr
    doc["adaptations"] = adaptations
    doc["seconds"]["adapt"] = {m: adaptations[m]["wall_s"] for m in METHODS}
    known, users = {}, {}
    for label, run in folders.items():
        known[label] = pooled(
            list(
                scored(run, data_dir, ("test",), yaw_deg, out / "eval" / re.sub(r"[^A-Za-z0-9]+", "_", label)).values()
            )
        )
        users[label] = user(run, data_dir, "test")
    fx = fix_errors(data_dir, "test")
    raw = (
        {
            "walks": fx["sequences"],
            **_stats(np.asarray(fx["point_errors"])),
            "length ratio": median_ratio(raw_fix_length_ratio(data_dir, "test")),
        }
        if fx
        else None
    )
    doc.update(known_start=known, user=users, raw_gnss=raw)
    doc["seconds"]["table"] = round(time.perf_counter() - t0, 1)
    doc["seconds"]["total"] = round(time.perf_counter() - t_start, 1)
    out.mkdir(parents=True, exist_ok=True)
    runs.write_json(out / "results.json", doc)
    write_page(doc, out / "results.md")
    return doc


def _table(rows: dict[str, dict], raw: dict | None, first: str = "method") -> str:
    df = pd.DataFrame([{first: k, **v} for k, v in rows.items()] + ([{first: RAW, **raw}] if raw else []))
    return df.to_markdown(index=False, floatfmt=".2f")


def write_page(doc: dict, path: Path) -> Path:
    """results.md for :func:`adapt_table`'s ``doc``."""
    import torch

    p = provenance()
    info, s = doc["split"], doc["seconds"]
    test = sorted(g for g, c in info["groups"].items() if "test" in c)
    user_rows = {
        f"{label} · {'smoother' if a == 'smooth' else 'rigid fit'}": r[a]
        for label, r in doc["user"].items()
        for a in ANCHORS
    }
    ad = doc["adaptations"]
    lines = [
        "# Adaptation from the user's own fixes: IPIN 2023",
        "",
        f"Generated by `wearnav bench adapt` ({p['created']}, wearnav {p['wearnav']} {p['commit']}) on "
        f"{platform.machine()}, {os.cpu_count()} CPUs, torch {torch.__version__}, CPU only, one thread, shared "
        f"with other work; {s['total'] / 60:.1f} min in all. Base model `{shown_path(doc['model'])}` (never "
        f"trained on IPIN), adapted by `wearnav adapt` on the GNSS fixes of IPIN's training trials "
        f"({ad[METHODS[0]]['recordings']} walks, {ad[METHODS[0]]['fixes_used']} fixes used; no POSI point read), "
        f"scored at the POSI points of the held-out trials {', '.join(test)}. Seed 0.",
        "",
        "## Known start + site yaw (m)",
        "",
        "Each walk starts at its true first point, its input turned by the site yaw "
        f"({doc['site_yaw']['yaw_deg']:+.1f}°, PDR on the training trials), as `bench real-odometry` scores; "
        "errors at every later POSI point; *length ratio*: median over walks of the path's length through "
        "its positions at the POSI times over the truth's (1 is right).",
        "",
        _table(doc["known_start"], doc["raw_gnss"]),
        "",
        "## User protocol: no truth (m)",
        "",
        "Each path integrated from (0, 0) in the phone's own frame and placed on the walk's own fixes by the "
        "smoother (`track`'s default) or one rigid fit (`wearnav.bench.user_protocol`).",
        "",
        _table(user_rows, doc["raw_gnss"], "path"),
        "",
        "## What the adaptations did",
        "",
        _adaptation_table(ad),
        "",
        "*held-out*: the walks `wearnav adapt` held out of the training trials' fixes; *length ratio* "
        "(odometry over fixes, per 10-s segment) and *segment error* (after each walk's yaw fit) against "
        "the fixes, before → after.",
        "",
        "## The default method, chosen on the training trials only",
        "",
        f"Each method adapted on the fixes of the training trials' train split and scored (known start) at "
        f"the POSI points of the training trials (*train*: the walks it adapted on, as a user tracks their "
        f"own walks; *val*: training-trial walks it did not see); rule: {doc['choice']['rule']}. Chosen: "
        f"**{doc['choice']['best']}**.",
        "",
        _table(
            {f"{k} · {part}": v for part in ("all", "train", "val") for k, v in doc["choice"]["scores"][part].items()},
            None,
        ),
        "",
        _bias_line(doc["fix_label_bias"]),
        "",
    ]
    return write_text_atomic("\n".join(lines), path)


def _bias_line(b: dict) -> str:
    if not b.get("segments"):
        return ""
    return (
        f"The labels themselves (a diagnostic, not used to adapt): over the {b['segments']} segments `wearnav "
        f"adapt` takes from the training trials, the fixes' displacement is {b['median']:.2f} of the truth's in "
        f"length (median; IQR {b['iqr'][0]:.2f}–{b['iqr'][1]:.2f}; truth: the POSI points joined by straight "
        "lines), so a model calibrated to them is calibrated to that."
    )


def _adaptation_table(ad: dict) -> str:
    rows = []
    for m, r in ad.items():
        b, a = r["held_out_before"], r["held_out_after"]
        best = next((h["best_epoch"] for h in r.get("finetune", []) if "best_epoch" in h), None)
        rows.append(
            {
                "method": m,
                "velocity scale": r["velocity_scale"],
                "best epoch": best if best is not None else "—",
                "segments train / held-out": f"{r['segments']['train']} / {r['segments']['held_out']}",
                "held-out length ratio": f"{b['length_ratio_median']} → {a['length_ratio_median']}",
                "held-out segment error (m)": f"{b['segment_error_median_m']} → {a['segment_error_median_m']}",
                "seconds": r["wall_s"],
            }
        )
    return pd.DataFrame(rows).to_markdown(index=False)


__all__ = ["adapt_table", "fix_label_bias", "pooled", "scored", "user", "write_page"]
