"""The labelled windows the multi-source activity model trains on and is scored on (issue 35):
every labelled source of ``../shared/data`` and the simulator (:data:`SOURCES`), each recording cut
into windows as ``classify`` cuts it, labelled in :mod:`wearnav.activity_labels`' one label set.

**Windows** (:func:`source_windows`): each source's recordings (imported datasets, one folder per
source, :data:`SOURCES`) go through the same preprocessing as inference (``classify`` and
``live``: :func:`wearnav.preprocess.align` with the run's :class:`ClassifyConfig`, i.e. resampled
to :data:`RATE_HZ` with the anti-alias low-pass, device frame), are cut into windows of
:data:`WINDOW` samples every :data:`STRIDE`, and each window takes the one label of
:mod:`wearnav.activity_labels` that at least :data:`LABEL_SHARE` of its samples carry (others are
unlabelled, −1); windows of the whole-walk sources are walking only where PDR's step detector
finds at least :data:`wearnav.trust.WALKING_STEP_RATE_HZ` steps per second (:func:`step_rate_hz`:
their walkers stop at surveyed points and exhibits). The model (``har-gravity``, :mod:`wearnav.models.har`) turns every window to gravity
and draws a random heading in training, so the input is placement- and orientation-agnostic.
Windows are cached per source (``<work>/windows/``).
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wearnav import activity_labels as al
from wearnav import trust
from wearnav.dataset import Dataset
from wearnav.models.pdr import PDR
from wearnav.preprocess import align
from wearnav.train.classify import TEST_SUBJECTS, ClassifyConfig, subject_number

MODEL = "har-gravity"
RATE_HZ = 50.0  # the benchmark's HAR rate (paper 002; MotionSense's and UCI HAPT's own)
WINDOW, STRIDE = 128, 64  # paper 002's windows: 2.56 s at 50 Hz, half overlapping
LABEL_SHARE = 0.8  # a window's label must cover this share of its samples (else: a boundary, left out)
CACHE_VERSION = 3  # of the cached windows: raise when what a source's windows are changes


@dataclass(frozen=True)
class Source:
    """A labelled source: ``fmt`` importer of the shared data folder ``src``, its recordings'
    ``device``; ``split``: how its in-dataset test recordings are chosen (a
    :data:`wearnav.train.classify.TEST_SUBJECTS` scheme, ``"manifest"``: its manifest's ``test``
    split, ``"every4"``: every fourth recording by name)."""

    name: str
    fmt: str
    src: str
    device: str
    split: str
    quick_limit: int | None = None


SOURCES: dict[str, Source] = {
    s.name: s
    for s in (
        Source("motionsense", "motionsense", "motionsense", "phone", "motionsense", 15),
        Source("uci-hapt", "uci-hapt", "uci_hapt", "phone", "uci-hapt", 6),
        Source("uji-phone", "uji-phone-watch", "uji_phone_watch_har", "phone", "uji", 20),
        Source("oxford", "oxford-steps", "oxford_step_counter", "phone", "oxford", 4),
        Source("ilc2", "ilc2", "ilc2_indoor_location", "phone", "every4", 4),
        Source("ipin", "ipin2023", "ipin2023_track3", "phone", "every4", 4),
        Source("sim", "simulate", "", "phone", "manifest"),
        Source("uji-watch", "uji-phone-watch", "uji_phone_watch_har", "watch", "uji", 20),
        Source("sim-watch", "simulate", "", "watch", "manifest"),
    )
}
PHONE_SOURCES = tuple(n for n, s in SOURCES.items() if s.device == "phone")
WATCH_SOURCES = tuple(n for n, s in SOURCES.items() if s.device == "watch")


def label_source(source: str) -> str:
    """The :mod:`wearnav.activity_labels` table of ``source`` (the watch's simulator track is the
    simulator's)."""
    return "sim" if source == "sim-watch" else source


@dataclass
class Windows:
    """Windows of one or more sources: ``x`` (N, L, 6) float32 device-frame acc (m/s²) + gyro
    (rad/s), ``y`` (N,) index into :data:`wearnav.activity_labels.LABELS` (−1: unlabelled),
    ``source`` (N,) str, ``test`` (N,) bool: on the source's in-dataset test side, ``rec`` (N,) the
    recording's number within its source; a recording's windows are consecutive, in time order."""

    x: np.ndarray
    y: np.ndarray
    source: np.ndarray
    test: np.ndarray
    rec: np.ndarray

    def __len__(self) -> int:
        return len(self.y)

    def take(self, keep) -> Windows:
        return Windows(self.x[keep], self.y[keep], self.source[keep], self.test[keep], self.rec[keep])

    @staticmethod
    def concat(parts: list[Windows]) -> Windows:
        if not parts:
            return Windows(
                np.empty((0, WINDOW, 6), np.float32),
                np.empty(0, np.int64),
                np.empty(0, str),
                np.empty(0, bool),
                np.empty(0, np.int64),
            )
        return Windows(*(np.concatenate([getattr(p, f) for p in parts]) for f in ("x", "y", "source", "test", "rec")))

    def runs(self) -> list[np.ndarray]:
        """The indices of each recording's windows (one source's recording after another)."""
        key = np.char.add(self.source.astype(str), np.char.mod("/%d", self.rec))
        change = np.flatnonzero(key[1:] != key[:-1]) + 1
        return np.split(np.arange(len(self.y)), change) if len(self.y) else []


def classify_config(
    device: str, data: str, classes=(), epochs: int = 1, seed: int = 0, members: int = 1
) -> ClassifyConfig:
    """The :class:`ClassifyConfig` ``classify`` reads back: the preprocessing inference repeats, and
    with ``members`` > 1 the ensemble it builds (:class:`wearnav.models.har.HAREnsemble`)."""
    return ClassifyConfig(
        model_args={"members": members} if members > 1 else {},
        model=MODEL,
        data=str(data),
        label_kind="activity",
        classes=tuple(classes),
        devices=(device,),
        frame="device",
        rate=RATE_HZ,
        window=WINDOW,
        stride=STRIDE,
        epochs=epochs,
        seed=seed,
    )


def _is_test(source: Source, rec_name: str, subject: str, split: str) -> bool:
    if source.split == "manifest":
        return split == "test"
    if source.split == "every4":
        return int(hashlib.sha1(rec_name.encode()).hexdigest(), 16) % 4 == 0
    return subject_number(subject) in TEST_SUBJECTS[source.split]


def _floor_change_spans(rec) -> list[tuple[float, float]]:
    """Spans between consecutive surveyed points on different floors (IPIN)."""
    tr = rec.truth
    if tr is None or tr.floor is None or len(tr.t) < 2:
        return []
    f = np.asarray(tr.floor)
    return [(float(tr.t[i]), float(tr.t[i + 1])) for i in range(len(f) - 1) if f[i] != f[i + 1]]


def sample_labels(source: str, rec, t: np.ndarray) -> np.ndarray:
    """Index into LABELS of every time of ``t`` (−1: unlabelled or left out)."""
    table = label_source(source)
    out = np.full(len(t), -1, np.int64)
    if table in al.WHOLE_RECORDING:
        keep = (t >= t[0] + al.EDGE_TRIM_S) & (t <= t[-1] - al.EDGE_TRIM_S)
        for a, b in _floor_change_spans(rec) if source == "ipin" else []:
            keep &= ~((t >= a) & (t <= b))
        out[keep] = al.LABELS.index(al.WHOLE_RECORDING[table])
        return out
    kind, mapping = al.MAPPINGS[table]
    names = rec.label_at(kind, t)
    for raw in set(names) - {""}:
        label = mapping[raw]
        if label is not None:
            out[names == raw] = al.LABELS.index(label)
    return out


def recording_windows(source: str, rec, cfg: ClassifyConfig) -> tuple[np.ndarray, np.ndarray]:
    """(x (N, L, 6), y (N,)) of one recording: aligned as inference aligns it, every window
    ``classify`` would cut (y −1 where unlabelled: a label boundary, or a stop in a whole-walk source)."""
    dev = cfg.devices[0]
    if dev not in rec.devices or len(rec.devices[dev]) < 2:
        return np.empty((0, cfg.window, 6), np.float32), np.empty(0, np.int64)
    seq = align(rec, cfg.preprocess_config())
    lab = sample_labels(source, rec, seq.t)
    xs, ys = [], []
    for s in range(0, len(seq.t) - cfg.window + 1, cfg.stride):
        w = lab[s : s + cfg.window]
        vals, counts = np.unique(w[w >= 0], return_counts=True)
        xs.append(seq.imu[0, s : s + cfg.window])
        ys.append(vals[np.argmax(counts)] if len(vals) and counts.max() >= LABEL_SHARE * cfg.window else -1)
    if not xs:
        return np.empty((0, cfg.window, 6), np.float32), np.empty(0, np.int64)
    x, y = np.stack(xs).astype(np.float32), np.asarray(ys, np.int64)
    if label_source(source) in al.WHOLE_RECORDING:  # the walker's stops are not walking
        y[step_rate_hz(x, cfg.rate) < trust.WALKING_STEP_RATE_HZ] = -1
    return x, y


def step_rate_hz(x: np.ndarray, rate: float) -> np.ndarray:
    """Steps per second in each window (N, L, 6) by PDR's step detector (:class:`wearnav.models.pdr.PDR`)
    on the acceleration along the window's mean (gravity) direction."""
    if len(x) == 0:
        return np.empty(0)
    acc = x[..., :3].astype(np.float64)
    g = acc.mean(axis=1, keepdims=True)
    vert = np.sum(acc * g / np.maximum(np.linalg.norm(g, axis=2, keepdims=True), 1e-9), axis=2)
    pdr = PDR(n_devices=1, window=x.shape[1], rate=rate)
    _, frac = pdr.steps(pdr.bandpass(vert[..., None])[..., 0])
    return frac / ((x.shape[1] - 1) / rate)


def source_windows(source: str, data: Path, cache: Path | None = None) -> tuple[Windows, dict]:
    """Every window of ``source`` imported at ``data`` (:func:`recording_windows`), and its training-data facts
    (:func:`wearnav.trust.recording_facts` per recording, merged). Cached in ``cache``."""
    spec = SOURCES[source]
    cfg = classify_config(spec.device, str(data))
    ds = Dataset.open(data)
    key = hashlib.sha1(
        json.dumps(
            [source, str(Path(data).resolve()), len(ds), WINDOW, STRIDE, RATE_HZ, LABEL_SHARE, CACHE_VERSION]
        ).encode()
    ).hexdigest()[:10]
    path = cache / f"{source}-{key}.npz" if cache else None
    if path is not None and path.is_file():
        z = np.load(path, allow_pickle=False)
        w = Windows(z["x"], z["y"], np.full(len(z["y"]), source), z["test"], z["rec"])
        return w, json.loads(str(z["facts"]))
    parts, rates, dirs, placements = [], [], [], set()
    m = ds.manifest.set_index("name")
    for number, rec in enumerate(ds):
        x, y = recording_windows(source, rec, cfg)
        row = m.loc[rec.name]
        test = _is_test(spec, rec.name, str(row.get("subject", "")), str(row.get("split", "")))
        parts.append(Windows(x, y, np.full(len(y), source), np.full(len(y), test), np.full(len(y), number)))
        f = trust.recording_facts(rec, (spec.device,), WINDOW / RATE_HZ)
        if f["placement"]:
            placements.add(f["placement"])
        if spec.device in f["devices"]:
            rates.append(f["devices"][spec.device]["rate_hz"])
            dirs.append(f["devices"][spec.device]["gravity_directions"])
    w = Windows.concat(parts)
    g = trust._spaced(np.concatenate(dirs), trust.MAX_DIRECTIONS) if dirs else np.empty((0, 3))
    facts = {"recordings": len(ds), "placements": sorted(placements), "rates": rates, "directions": g.tolist()}
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f"{path.stem}.{os.getpid()}.partial.npz")  # runs side by side may both write it
        np.savez(tmp, x=w.x, y=w.y, test=w.test, rec=w.rec, facts=json.dumps(facts))
        os.replace(tmp, path)
    return w, facts


def merge_facts(facts: list[dict], device: str) -> dict:
    """Per-source facts → :func:`wearnav.trust.data_facts`'s ``training_data`` record."""
    rates = np.asarray([r for f in facts for r in f["rates"]], float)
    dirs = [np.asarray(f["directions"]).reshape(-1, 3) for f in facts]
    g = trust._spaced(np.concatenate(dirs), trust.MAX_DIRECTIONS) if dirs else np.empty((0, 3))
    per = {}
    if rates.size:
        per[device] = {
            "recordings": int(rates.size),
            "rate_hz": [round(float(v), 2) for v in (rates.min(), np.median(rates), rates.max())],
            "gravity_directions": np.round(g, 3).tolist(),
        }
    return {
        "recordings": int(sum(f["recordings"] for f in facts)),
        "placements": sorted({p for f in facts for p in f["placements"]}),
        "devices": per,
        "window_s": WINDOW / RATE_HZ,
    }
