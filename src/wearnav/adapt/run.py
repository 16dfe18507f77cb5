"""`wearnav adapt`: a trained odometry run adapted to a user's own walks, from the phone's own
location fixes only (issue 18 §3), written as a new run folder that `wearnav track` takes.

Methods (:data:`METHODS`):

``scale``     one factor on the model's speed: the median over the training segments of the
              speed factor of :func:`wearnav.adapt.segments.compare` (the length of the fixes'
              displacement over the odometry's; a median, so fix jumps do not move it), stored
              as ``velocity_scale`` in the run's ``adaptation.json``, which
              :func:`wearnav.train.odometry.load_model` applies (:class:`wearnav.models.base.ScaledVelocity`);
              refused where the fixes cannot support it (:func:`check_scale`: a factor outside
              :data:`SCALE_RANGE`, or one whose standard error is wider than
              :data:`SCALE_MAX_RELATIVE_SE`; ``scale_fit`` in adaptation.json says both).
``finetune``  a few epochs on the segments (:mod:`wearnav.adapt.finetune`), new weights; where
              no epoch beats the starting weights on the held-out segments, those are kept and
              the command says "nothing changed" (``changed`` false in adaptation.json).

Each method needs a least number of good segments (:data:`MIN_SEGMENTS`; ``--segment-s`` sets
their length, so a short walk cut shorter gives more).

A share of the user's segments is held out (:func:`split_walks`): whole recordings where there
are several, else the last part of the one walk. ``adaptation.json`` says what was done, on how
many recordings, fixes and segments, and how the held-out segments agree with the model before
and after (:func:`wearnav.adapt.segments.summary`: length ratio, speed factor, segment error).

The new run folder holds the base run's config.yaml (with ``adapted_from``), training.json
(what it was trained on, for `track`'s warnings) and smoother calibration where it has one, the
weights in checkpoints/best.ckpt, and adaptation.json.

Decision: docs/decisions/0017-adaptation-from-fixes.md.
"""

from __future__ import annotations

import dataclasses
import hashlib
import shutil
import time
import warnings
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from wearnav import fuse, runs
from wearnav.adapt.finetune import FinetuneConfig, finetune
from wearnav.adapt.segments import SegmentConfig, WalkSegments, compare, odometry_displacements, summary, walk_segments
from wearnav.dataset import MANIFEST, Dataset
from wearnav.errors import ConfigError, FormatError, ValidationError, WearnavWarning
from wearnav.models.base import ScaledVelocity
from wearnav.outputs import staged_output
from wearnav.recording import Recording
from wearnav.train.common import BEST, CHECKPOINTS
from wearnav.train.odometry import ADAPTATION, TRAINING, load_model

METHODS = ("scale", "finetune")
# Chosen by `wearnav bench adapt` on IPIN 2023's training trials only
# (docs/decisions/0017-adaptation-from-fixes.md) for the base users adapt: the shipped recipe trained without IPIN,
# median at their POSI points un-adapted 7.81 m, scale 6.90, finetune 4.75. (A base trained on the
# simulator alone, already right in length, read scale 4.23, finetune 4.93, un-adapted 4.06.)
DEFAULT_METHOD = "finetune"
# The fewest good segments each method accepts. finetune: 20, a fifth of them held out (at least
# 4) to stop on, the rest a few batches of training. scale: 5, one number from a median; one
# walk's held-out fifth (at least 1) leaves 4 training segments, whose median still stands when
# one of them is a fix jump; whether they agree well enough is checked on the fit itself
# (SCALE_MAX_RELATIVE_SE).
MIN_SEGMENTS = {"scale": 5, "finetune": 20}
# The speed factors a scale adaptation may set: walking speeds of one person vary by about a
# factor 2 either way (0.7–1.6 m/s for slow to brisk walking), and a model trained on walking
# is right to well within it (the shipped recipe's length ratio on IPIN's held-out routes:
# 0.8–1.2); a factor outside says the fixes, not the model, are off (e.g. 11.4 from 4-s
# segments of a phone's fixes on a 158-s walk).
SCALE_RANGE = (0.5, 2.0)
# The largest relative standard error of the fitted factor (a median: 1.2533 · 1.4826 · MAD / √n,
# over the factor) accepted: a factor known to ±20 % (1 σ) moves a 100-m walk's length by less
# than 20 m, about what the fixes' own noise spans over it; wider, and the fit is noise.
SCALE_MAX_RELATIVE_SE = 0.2
# The standard error of a median of n normal values over the σ/√n of their mean: √(π/2).
MEDIAN_SE_FACTOR = 1.2533
# MAD → σ of a normal distribution.
MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True)
class AdaptConfig:
    """Everything that decides an adaptation (saved in ``adaptation.json``)."""

    method: str = DEFAULT_METHOD
    segments: SegmentConfig = field(default_factory=SegmentConfig)
    finetune: FinetuneConfig = field(default_factory=FinetuneConfig)
    holdout: float = 0.2  # share of the user's recordings (or of one walk's segments) held out
    # fewer good segments than this: refused (None: the method's MIN_SEGMENTS)
    min_segments: int | None = None
    # the speed factors a scale adaptation may set, and the widest relative standard error it may
    # have (SCALE_RANGE, SCALE_MAX_RELATIVE_SE); outside them it is refused
    scale_range: tuple[float, float] = SCALE_RANGE
    max_relative_se: float = SCALE_MAX_RELATIVE_SE

    @property
    def least_segments(self) -> int:
        """The segments this method needs: ``min_segments``, or the method's :data:`MIN_SEGMENTS`."""
        return self.min_segments if self.min_segments is not None else MIN_SEGMENTS[self.method]

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ConfigError(f"unknown adaptation method {self.method!r}; one of {', '.join(METHODS)}")
        if self.min_segments is None:
            object.__setattr__(self, "min_segments", MIN_SEGMENTS[self.method])
        if not 0 < self.holdout < 1 or self.least_segments < 2:
            raise ConfigError(
                f"holdout must be in (0, 1) and min_segments ≥ 2, got {self.holdout}, {self.min_segments}"
            )


def read_recordings(sources: Iterable[str | Path], split: str | None = None) -> Iterator[Recording]:
    """Every recording of ``sources``: ``.h5`` recordings, dataset folders (``split``: only that
    split's recordings) and Sensor Logger exports (a folder, zip, or folder of several)."""
    from wearnav.importers import sensorlogger

    for src in map(Path, sources):
        if not src.exists():
            raise FormatError("no such file or folder", src)
        if src.is_file() and src.suffix.lower() == ".h5":
            yield Recording.load(src)
        elif src.is_dir() and (src / MANIFEST).is_file():
            ds = Dataset.open(src)
            view = ds.split(split) if split else ds
            for name in view.names:
                yield view.load(name)
        else:
            yield from sensorlogger.read(src)


def _order(name: str) -> str:
    return hashlib.sha1(name.encode()).hexdigest()


def split_walks(walks: list[WalkSegments], holdout: float) -> tuple[list[WalkSegments], list[WalkSegments], str]:
    """(training walks, held-out walks, how): with several walks, round(``holdout`` · n) of them
    (at least one) held out, chosen by a hash of their names; with one walk, its last ``holdout``
    share of segments in time."""
    if len(walks) >= 2:
        ranked = sorted(walks, key=lambda w: _order(w.name))
        k = max(1, int(round(holdout * len(walks))))
        return ranked[k:], ranked[:k], "recording"
    w = walks[0]
    order = np.argsort(w.t0)
    k = max(1, int(np.ceil(holdout * len(w))))
    return [w.subset(order[:-k])], [w.subset(order[-k:])], "time"


def agreement(model, walks: list[WalkSegments], window: int, stride: int) -> tuple[dict, list[dict]]:
    """:func:`wearnav.adapt.segments.summary` of ``model`` on ``walks`` and the per-walk parts."""
    parts = [compare(odometry_displacements(model, w, window, stride), w.d_fix, 0.5 * (w.t0 + w.t1)) for w in walks]
    return summary(parts), parts


def adapt(
    recordings: Iterable[Recording], model_run: str | Path, out: str | Path, cfg: AdaptConfig = AdaptConfig()
) -> dict:
    """Adapt the model of run folder ``model_run`` to ``recordings`` (module docstring) into the new
    run folder ``out``; returns what ``adaptation.json`` holds."""
    t_start = time.perf_counter()
    model_run, out = Path(model_run), Path(out)
    if out.exists() and not runs.is_blank(out):
        raise ConfigError("exists and is not an empty folder; choose another --out for the adapted run", out)
    model, tcfg = load_model(model_run)
    base_scale = float(model.scale) if isinstance(model, ScaledVelocity) else 1.0
    if cfg.method == "finetune" and not getattr(model, "learned", True):
        raise ConfigError(f"{tcfg.model} has no weights to fine-tune; use --method scale", model_run)
    n_rec, n_fix_rec, walks = 0, 0, []
    for rec in recordings:
        n_rec += 1
        n_fix_rec += rec.fixes is not None and len(rec.fixes) > 0
        w = walk_segments(rec, tcfg, cfg.segments)
        if w is not None:
            walks.append(w)
    if n_fix_rec == 0:
        raise ValidationError(
            f"none of the {n_rec} recording(s) has location fixes: adaptation labels the IMU "
            "with the phone's own fixes (record with location on)"
        )
    n_seg = sum(len(w) for w in walks)
    s = cfg.segments
    if n_seg < cfg.least_segments:
        raise ValidationError(
            f"only {n_seg} segment(s) between good fixes ({s.segment_s:g} s apart, accuracy ≤ "
            f"{s.max_accuracy_m:g} m, moved ≥ {s.min_length_m:g} m) in {n_rec} recording(s); "
            f"--method {cfg.method} needs at least {cfg.least_segments}: walk longer with location on, "
            f"or cut shorter segments with --segment-s (each must still span ≥ {s.min_length_m:g} m)"
        )
    train, held, held_by = split_walks(walks, cfg.holdout)
    window, stride = tcfg.window, tcfg.stride
    before, _ = agreement(model, held, window, stride)
    train_before, train_parts = agreement(model, train, window, stride)
    record: dict = {"method": cfg.method}
    if cfg.method == "scale":
        factor = np.concatenate([p["factor"] for p in train_parts])
        factor = factor[np.isfinite(factor)]
        scale = float(np.median(factor)) if factor.size else float("nan")
        if not (np.isfinite(scale) and scale > 0):
            raise ValidationError(
                f"the fixes give no usable speed factor (median {scale:.3g}): does the model move at all?"
            )
        fit = scale_fit(factor, cfg.scale_range, cfg.max_relative_se)
        check_scale(fit, s.segment_s)
        adapted: torch.nn.Module = ScaledVelocity(
            model.inner if isinstance(model, ScaledVelocity) else model, base_scale * scale
        )
        record["scale_fit"] = fit
        velocity_scale, state = base_scale * scale, None
    else:
        adapted, history = finetune(model, train, held, window, tcfg.rate, cfg.finetune)
        record["finetune"] = history
        inner = adapted.inner if isinstance(adapted, ScaledVelocity) else adapted
        velocity_scale, state = base_scale, inner.state_dict()
    after, _ = agreement(adapted, held, window, stride)
    improved = after["segment_error_median_m"] < before["segment_error_median_m"]
    kept = cfg.method == "finetune" and record["finetune"][-1].get("best_epoch") == 0
    record["changed"] = not kept
    if kept:  # no epoch beat the starting weights on the held-out segments
        warnings.warn(
            WearnavWarning(
                f"nothing changed: the starting model was kept (no fine-tuning epoch agreed better with the "
                f"held-out fixes: median segment error {before['segment_error_median_m']:.2f} m); "
                f"{out} holds the same model"
            ),
            stacklevel=2,
        )
    elif not improved:
        warnings.warn(
            WearnavWarning(
                f"the held-out walks agree less with their own fixes after adapting ({cfg.method}: median segment error "
                f"{before['segment_error_median_m']:.2f} → {after['segment_error_median_m']:.2f} m, length ratio "
                f"{before['length_ratio_median']:.2f} → {after['length_ratio_median']:.2f}): the adaptation may not help; "
                f"compare both runs with `wearnav track`"
            ),
            stacklevel=2,
        )
    record.update(
        {
            "held_out_improved": bool(improved),
            "velocity_scale": round(velocity_scale, 6),
            "base_run": str(model_run.resolve()),
            "base_velocity_scale": base_scale,
            "recordings": n_rec,
            "recordings_with_fixes": n_fix_rec,
            "recordings_with_segments": len(walks),
            "fixes_used": int(sum(w.fixes for w in walks)),
            "segments": {"train": int(sum(len(w) for w in train)), "held_out": int(sum(len(w) for w in held))},
            "held_out_by": held_by,
            "held_out_recordings": [w.name for w in held],
            "held_out_before": before,
            "held_out_after": after,
            "train_before": train_before,
            "config": dataclasses.asdict(cfg),
            "wall_s": round(time.perf_counter() - t_start, 2),
        }
    )
    _write_run(model_run, out, record, state)
    return record


def scale_fit(
    factor: np.ndarray, scale_range: tuple[float, float] = SCALE_RANGE, max_relative_se: float = SCALE_MAX_RELATIVE_SE
) -> dict:
    """What a scale adaptation's fit says (``adaptation.json`` ``scale_fit``): the ``factor`` (the
    median of the segments' speed factors), ``segments``, ``iqr``, ``relative_se`` (the median's
    standard error over it, :data:`MEDIAN_SE_FACTOR` · :data:`MAD_TO_SIGMA` · MAD / √n / factor),
    and the bounds it must meet: ``range`` (:data:`SCALE_RANGE`) and ``max_relative_se``
    (:data:`SCALE_MAX_RELATIVE_SE`)."""
    factor = np.asarray(factor, np.float64)
    med = float(np.median(factor))
    mad = float(np.median(np.abs(factor - med)))
    rel_se = MEDIAN_SE_FACTOR * MAD_TO_SIGMA * mad / np.sqrt(factor.size) / med
    return {
        "factor": round(med, 4),
        "segments": int(factor.size),
        "iqr": [round(float(q), 4) for q in np.percentile(factor, [25, 75])],
        "relative_se": round(float(rel_se), 4),
        "range": list(scale_range),
        "max_relative_se": max_relative_se,
    }


def check_scale(fit: dict, segment_s: float) -> None:
    """Refuse a scale the fixes cannot support (:func:`scale_fit`): outside ``range``, or with a
    relative standard error above ``max_relative_se``; the message names what to change."""
    lo, hi = fit["range"]
    advice = (
        f"the fixes over {segment_s:g}-s segments are too noisy to scale the model: record longer walks "
        f"with location on, or use longer segments (--segment-s)"
    )
    if not lo <= fit["factor"] <= hi:
        raise ValidationError(
            f"the fixes ask for a speed factor of {fit['factor']:.3g} over {fit['segments']} segment(s), "
            f"outside the {lo:g}–{hi:g} a walking model can be off by; {advice}"
        )
    if fit["relative_se"] > fit["max_relative_se"]:
        raise ValidationError(
            f"the fitted speed factor {fit['factor']:.3g} is uncertain by ±{fit['relative_se']:.0%} (1 σ, "
            f"{fit['segments']} segment(s), more than ±{fit['max_relative_se']:.0%} accepted); {advice}"
        )


def _write_run(base: Path, out: Path, record: dict, state: dict | None) -> None:
    """The adapted run folder (module docstring), written whole or not at all."""
    doc = runs.read_config(base)
    with staged_output(out, ADAPTATION, "adapt") as stage:
        extra = {k: v for k, v in doc.items() if k not in ("config", "provenance")}
        runs.write_config(
            stage, doc["config"], {**extra, "adapted_from": {"run": str(base.resolve()), "method": record["method"]}}
        )
        ckpt = base / CHECKPOINTS / BEST
        (stage / CHECKPOINTS).mkdir()
        if state is not None:
            torch.save(
                {"state_dict": {f"model.{k}": v for k, v in state.items()}, "adapted": record["method"]},
                stage / CHECKPOINTS / BEST,
            )
        elif ckpt.is_file():
            shutil.copyfile(ckpt, stage / CHECKPOINTS / BEST)
        for name in (TRAINING, fuse.CALIBRATION_JSON):
            if (base / name).is_file():
                shutil.copyfile(base / name, stage / name)
        runs.write_json(stage / ADAPTATION, record)


__all__ = [
    "AdaptConfig",
    "METHODS",
    "DEFAULT_METHOD",
    "MIN_SEGMENTS",
    "SCALE_RANGE",
    "SCALE_MAX_RELATIVE_SE",
    "scale_fit",
    "check_scale",
    "adapt",
    "agreement",
    "read_recordings",
    "split_walks",
]
