"""Labelling recordings with a trained classifier (``wearnav classify``, the live page's activity,
``track``'s trajectory.html): each recording aligned and cut as in training, every window's class
decided over the model's context (:func:`wearnav.train.classify.context_probs`), windows the model
is unsure of labelled :data:`UNKNOWN` (issue 35 §3), consecutive windows merged into intervals, and
the reasons not to trust the labels (:mod:`wearnav.trust`). Training and evaluating the classifier
itself is :mod:`wearnav.train.classify`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from wearnav import runs, trust
from wearnav.core.fileio import write_text_atomic
from wearnav.core.textio import read_json
from wearnav.errors import ValidationError, WearnavWarning
from wearnav.export.header import is_exported, read_header
from wearnav.preprocess import Aligned, align
from wearnav.preprocess.windows import WindowConfig, WindowDataset
from wearnav.train.classify import (
    TRAINING,
    ClassifyConfig,
    context_mean,
    context_probs,
    decide,
    gyro_rad_s,
    load_model,
    window_probs,
)

UNKNOWN = "unknown"  # the label of a window the model is unsure of (issue 35 §3)
UNKNOWN_INDEX = -1  # its class index in window_classes' output


def class_name(classes, i: int) -> str:
    """The name of class index ``i`` (:data:`UNKNOWN_INDEX`: :data:`UNKNOWN`)."""
    return UNKNOWN if int(i) == UNKNOWN_INDEX else classes[int(i)]


def held_unlike_training(model, seq: Aligned, t: np.ndarray) -> np.ndarray:
    """Which windows are labelled :data:`UNKNOWN` because of how the device is held: for a model
    that takes the device's own frame (not turned to gravity, ``gravity_align``), the window's
    gravity direction lies further than :data:`wearnav.trust.GRAVITY_MATCH_DEG` from every
    training window's (the trust check of :func:`trust.gravity_outside`, per window). A model
    without that record, or turned to gravity: none. Windows the model is unsure of are
    :func:`wearnav.train.classify.decide`'s."""
    out = np.zeros(len(t), bool)
    dirs = getattr(model, "training_gravity", None)
    if dirs and not getattr(model, "gravity_align", False):
        d = int(np.argmax(seq.mask.any(axis=1)))
        i0 = np.clip(np.searchsorted(seq.t, t[:, 0]), 0, len(seq.t) - 1)
        i1 = np.clip(np.searchsorted(seq.t, t[:, 1]), 1, len(seq.t))
        g = np.stack([seq.imu[d, a:b, :3].mean(axis=0) for a, b in zip(i0, np.maximum(i1, i0 + 1))])
        g /= np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-9)
        out |= trust.angles_deg(g, np.asarray(dirs, float)).min(axis=1) > trust.GRAVITY_MATCH_DEG
    return out


def unknown_note(model, k: int, n: int) -> str:
    """The sentence saying that ``k`` of ``n`` windows are :data:`UNKNOWN`, and why."""
    thr = getattr(model, "unknown_threshold", None)
    why = [f"the model's top probability is under {thr:.2f}"] if thr is not None else []
    if (still := getattr(model, "still_rule", None)) is not None:
        why.append(f"standing and sitting together are under {still.threshold:.2f}")
    if getattr(model, "training_gravity", None) and not getattr(model, "gravity_align", False):
        why.append("the device is held unlike any training window")
    return (
        f"{k} of {n} windows ({100 * k / n:.0f} %) labelled {UNKNOWN}: {' or '.join(why)}; "
        "the model is not sure what the wearer did there"
    )


def intervals(t0: np.ndarray, t1: np.ndarray, cls: np.ndarray, conf: np.ndarray, classes) -> list[dict]:
    """Consecutive windows of one class merged into intervals. Windows overlap, so a boundary is
    put midway between the last window of one class and the first of the next."""
    out: list[dict] = []
    mid = (t0 + t1) / 2
    for i in range(len(cls)):
        if out and out[-1]["label"] == class_name(classes, cls[i]):
            r = out[-1]
            r["end_s"], r["windows"], r["_c"] = float(t1[i]), r["windows"] + 1, r["_c"] + float(conf[i])
            continue
        start = float(t0[i]) if not out else float((mid[i - 1] + mid[i]) / 2)
        if out:
            out[-1]["end_s"] = start
        out.append(
            {
                "start_s": start,
                "end_s": float(t1[i]),
                "label": class_name(classes, cls[i]),
                "windows": 1,
                "_c": float(conf[i]),
            }
        )
    for r in out:
        r["mean_confidence"] = round(r.pop("_c") / r["windows"], 4)
    return out


CLASSIFY_JSON = "classify.json"  # the marker of a `wearnav classify` output folder (wearnav.outputs)


def label_recordings(recordings, run: str | Path, out: str | Path, classifier=None) -> dict:
    """Classify every window of each recording with the run's model; write ``<name>_intervals.csv``
    (start_s, end_s, label, windows, mean_confidence) and ``<name>_timeline.png`` (|acc| of the
    first present device with the labels as coloured bands) into ``out``, and ``classify.json``
    (the run, the model's label set ``classes``, the recordings, the files and ``warnings``: one
    line per reason not to trust the labels, :func:`trust_warnings`, also raised as
    :class:`WearnavWarning`). All or nothing: a recording that fails leaves ``out`` as it was
    (:func:`wearnav.outputs.staged_output`). ``classifier``: the run's (model, config, classes) when
    already loaded (:func:`wearnav.train.resolve.resolve_model`). Returns ``files`` (paths), ``classes``,
    ``warnings``."""
    import json
    import warnings

    from wearnav.outputs import check_out_folder, staged_output

    check_out_folder(out, (), CLASSIFY_JSON, "classify")
    model, cfg, classes = classifier or load_model(run)
    found: list[str] = []
    with staged_output(out, CLASSIFY_JSON, "classify", replace=False) as stage:
        names = _label_into(recordings, model, cfg, classes, stage, found, Path(run))
        files = [f for n in names for f in (f"{n}_intervals.csv", f"{n}_timeline.png")] + [CLASSIFY_JSON]
        write_text_atomic(
            json.dumps(
                {
                    "run": str(run),
                    "model": cfg.model,
                    "classes": classes,
                    "recordings": names,
                    "files": files,
                    "warnings": found,
                },
                indent=2,
            ),
            stage / CLASSIFY_JSON,
        )
    for w in found:
        warnings.warn(WearnavWarning(w), stacklevel=2)
    return {"files": [Path(out) / f for f in files[:-1]], "classes": classes, "warnings": found}


def gravity_aligned(cfg: ClassifyConfig) -> bool:
    """Whether the model turns every window to gravity (``har-gravity``, :mod:`wearnav.models.har`):
    then the device's gravity direction, the trust check of how it is held, says nothing about it."""
    return cfg.model == "har-gravity" or bool(cfg.model_args.get("gravity_align"))


def trust_warnings(run: Path, cfg: ClassifyConfig, rec) -> list[str]:
    """Reasons not to trust a recording's labels (:mod:`wearnav.trust`), each with what to do:
    devices it lacks, a placement, rate or gravity direction unlike the training data's, a model
    that did not beat always answering the majority class. ``run``: the run folder, or the model file
    of ``wearnav export`` whose header holds the run's records."""
    out = []
    if (m := trust.missing_devices(cfg.devices, rec.devices)) is not None:
        out.append(f"{m}: {trust.CLASSIFY_DOMAIN_ADVICE}")
    if is_exported(run):  # a `wearnav export` file carries both records in its header
        header = read_header(run)
        record, metrics = header.get("training") or {}, header.get("metrics") or {}
    else:
        record = read_json(run / TRAINING) if (run / TRAINING).is_file() else {}
        metrics = runs.read_metrics(run) if runs.is_complete(run) else {}
    facts = trust.recording_facts(rec, cfg.devices, cfg.window / cfg.rate)
    training = record.get("training_data")
    if training and gravity_aligned(cfg):  # how the device is held is not this model's input
        devices = {d: {**v, "gravity_directions": []} for d, v in (training.get("devices") or {}).items()}
        training = {**training, "devices": devices}
    out += [f"{f}: {trust.CLASSIFY_DOMAIN_ADVICE}" for f in trust.domain_findings(facts, training, cfg.rate)]
    if (m := trust.did_not_learn(metrics)) is not None:
        out.append(f"{m}: {trust.CLASSIFY_LEARN_ADVICE}")
    return [f"{rec.name}: {w}" for w in out]


@dataclasses.dataclass
class Windows:
    """A recording's windows as :func:`window_classes` cuts them, before the model: the aligned input
    ``seq``, the windows ``wds``, the ``index`` of those the model is to see (``x``, ``mask``), and
    how many of them, the last, are labelled (``keep``)."""

    seq: Aligned
    wds: WindowDataset
    index: np.ndarray
    keep: int

    def inputs(self) -> dict:
        return self.wds[self.index.tolist()]

    def probs(self, model) -> np.ndarray:
        """The classifier's softmax probabilities of the windows at ``index`` (this recording alone;
        :func:`wearnav.live.models.classify_windows` runs many recordings' windows in one pass)."""
        if len(self.index) == 0:
            return np.empty((0, 0), np.float32)
        b = self.inputs()
        return window_probs(model, b["x"], b["mask"])


def class_windows(model, cfg: ClassifyConfig, rec, last: int | None = None) -> Windows:
    """The first half of :func:`window_classes` (the model's input); a caller may run the model
    on many recordings' windows at once (the live receiver, one batch per tick)."""
    from wearnav.preprocess.augment import moving_average

    seq = align(rec, cfg.preprocess_config())
    if cfg.denoise > 1:
        seq = dataclasses.replace(seq, imu=moving_average(seq.imu, cfg.denoise, axis=1).astype(seq.imu.dtype))
    wds = WindowDataset([seq], WindowConfig(window=cfg.window, stride=max(1, cfg.window // 2), target=None))
    k = getattr(model, "context_windows", 1)
    index = np.arange(0 if last is None else max(0, len(wds) - last - k // 2), len(wds))
    return Windows(seq, wds, index, len(index) if last is None else min(last, len(wds)))


def decide_classes(model, w: Windows, prob: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The second half of :func:`window_classes`: from the softmax probabilities ``prob`` of
    ``w``'s windows, each labelled window's times, class and confidence."""
    if w.keep == 0:
        return np.empty((0, 2)), np.empty(0, np.int64), np.empty(0)
    k = getattr(model, "context_windows", 1)
    prob = context_probs(prob, k)[-w.keep :]
    still = getattr(model, "still_rule", None)
    gyro = None
    if still is not None and still.gyro_rad_s is not None:  # how much the phone turns, for the posture
        x = w.inputs()["x"].numpy()  # (N, D, L, 6): the first present device's windows
        gyro = context_mean(gyro_rad_s(x[:, int(np.argmax(w.seq.mask.any(axis=1)))]), k)[-w.keep :]
    cls, conf = decide(prob, getattr(model, "unknown_threshold", None), still, gyro)
    t = w.wds[w.index[-w.keep :].tolist()]["t"].numpy()
    cls = np.where(held_unlike_training(model, w.seq, t), UNKNOWN_INDEX, cls)
    return t, cls, conf


def window_classes(
    model, cfg: ClassifyConfig, rec, last: int | None = None
) -> tuple[Aligned, np.ndarray, np.ndarray, np.ndarray]:
    """How ``classify`` labels a recording (and the live receiver its latest seconds, and
    ``track``'s trajectory.html its path): ``rec`` aligned by the run's preprocessing (with eq. 13's
    moving average when ``cfg.denoise``), cut into windows of the run's length at half-window
    strides; returns the aligned input, each window's start and end time (N, 2) s, its class index
    (:data:`UNKNOWN_INDEX` where :func:`wearnav.train.classify.decide` or :func:`held_unlike_training`
    says so) and confidence (N,) (N = 0 when
    shorter than one window), both decided over the model's ``context_windows`` (training.json;
    :func:`context_probs`; 1 where it has none). ``last``: only the last ``last`` windows, each decided
    as the whole would decide it; the model sees only the windows their contexts hold (the live
    page labels its latest window every second). :func:`class_windows`, the model, then
    :func:`decide_classes`."""
    w = class_windows(model, cfg, rec, last)
    prob = w.probs(model) if w.keep else np.empty((0, 0))
    return (w.seq, *decide_classes(model, w, prob))


def _label_into(recordings, model, cfg, classes: list[str], out: Path, found: list[str], run: Path) -> list[str]:
    """Write each recording's intervals CSV and timeline PNG into ``out``; returns the names and
    adds each recording's :func:`trust_warnings` to ``found``."""
    import pandas as pd
    from matplotlib.figure import Figure

    from wearnav.report.plots import save

    written = []
    colours = {c: f"C{i % 10}" for i, c in enumerate(classes)} | {UNKNOWN: "0.6"}
    for rec in recordings:
        found += trust_warnings(run, cfg, rec)
        seq, t, cls, conf = window_classes(model, cfg, rec)
        if len(cls) == 0:
            raise ValidationError(f"shorter than one window ({cfg.window / cfg.rate:g} s)", rec.name)
        if (k := int(np.sum(cls == UNKNOWN_INDEX))) > 0:
            found.append(f"{rec.name}: {unknown_note(model, k, len(cls))}")
        rows = intervals(t[:, 0], t[:, 1], cls, conf, classes)
        df = pd.DataFrame(rows, columns=["start_s", "end_s", "label", "windows", "mean_confidence"])
        if rec.name in written:
            raise ValidationError("two recordings of this name; their files would collide", rec.name)
        written.append(rec.name)
        write_text_atomic(df.to_csv(index=False, float_format="%.3f"), out / f"{rec.name}_intervals.csv")
        d = int(np.argmax(seq.mask.any(axis=1)))
        fig = Figure(figsize=(10, 3))
        ax = fig.add_subplot()
        for r in rows:
            ax.axvspan(r["start_s"] - seq.t[0], r["end_s"] - seq.t[0], color=colours[r["label"]], alpha=0.3, lw=0)
        ax.plot(seq.t - seq.t[0], np.linalg.norm(seq.imu[d, :, :3], axis=1), color="k", lw=0.5)
        from matplotlib.patches import Patch

        ax.legend(
            handles=[Patch(color=colours[c], alpha=0.3, label=c) for c in [*classes, UNKNOWN] if c in set(df["label"])],
            fontsize=7,
            loc="upper right",
            ncol=3,
        )
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"|acc| {seq.devices[d]} (m/s²)")
        ax.set_title(f"{rec.name}: {cfg.label_kind} by {cfg.model}", fontsize=9)
        fig.tight_layout()
        save(fig, out / f"{rec.name}_timeline.png")
    if not written:
        raise ValidationError("no recording to classify")
    return written
