"""Phone labels: IMU segments labelled by the phone's own location fixes (EasyTrack, paper 004,
§III-A, eq. 4).

A phone logs IMU and location fixes P̃_0, P̃_1, … on one clock. The IMU is cut into segments whose
ends are fix times, and each segment s_i is labelled with the displacement between the fixes at
its ends, d̃_i = P̃_{i+1} − P̃_i (eq. 4). The fixes a trajectory's segments start and end on are its
*nodes*; segments keep the (global) indices of their two nodes, so CNAL (eq. 12) can learn one
correction vector per node and a correction telescopes along a trajectory.

Input. The phone's IMU is rotated into the world frame with its own orientation and resampled
(:mod:`wearnav.preprocess`, phone only). A phone's orientation is a game rotation vector with an
arbitrary yaw, while the fixes are east/north, so the IMU frame is then turned onto the *fixes'*
frame by the same estimator that turns it onto the truth elsewhere (:func:`wearnav.preprocess.frames.
align_frames`), fed the fixes instead of the truth: only what the phone itself logged is used,
as the user of this setting has no truth. Where a recording has dense truth, each segment also
carries its true displacement between the same two times (for label-noise statistics, eqs. 5–7,
BaseModel-GT and ADE); the model input never depends on the truth.

Segmentation. Fix spacing need not equal the segment length: from a node at time t_i the next
node is the fix nearest t_i + ``segment_s``; the pair is a segment only when its spacing is within
± ``tolerance`` · ``segment_s`` of it (an outage breaks the chain, a new chain starts after it).
The model input is the ``round(segment_s · rate)`` IMU samples from t_i on (a fixed length, as
the paper's segments of size N). Overlapping segments (``stride_s``, e.g. 0.2 s): a segment also
starts every ``stride_s`` between two fixes, its ends' positions linearly interpolated between the
fixes around them (the interpolated points are nodes too, so CNAL corrects them). The paper's
Table I implies this: 41 K segments over 8.3 km is one segment per ~0.2 m of path, while a 1-s
segment of walking covers ~1 m (its phone labels average ~100 cm, §III-B), i.e. ~5 starts per
segment length. A label faster than ``max_speed`` is a gross fix jump, not a
displacement, and is dropped: a plausibility check the phone can make on its own (indoors, GNSS
fixes jump by tens of metres; a single such label dominates an MSE). The threshold, 5 m/s, is a
brisk walker (≤ 2.5 m/s) plus 2.5 m of label noise: the 1–3 m errors of a multipath episode the
receiver ramps in are what CNAL / CoAdapt exist to handle, so they stay (with the simulator's
noise, 5 m/s drops 0.3 % of labels and keeps 85 % of those with over 1 m of noise; 3 m/s dropped
0.8 % and kept 60 %). What it drops is counted per recording (``Segments.dropped``), reported by
:func:`noise_summary` and warned about.

Test segments of held-out trajectories (:func:`segments_from_truth`) are cut from dense truth
instead: contiguous, N samples each, labelled by the true displacement from each segment's first
sample to the next segment's first sample, so summing them integrates a trajectory.

Decision: docs/decisions/0007-easytrack-phone-labels-and-frame.md.
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from wearnav.core.fileio import savez_atomic
from wearnav.core.progress import progress as report_progress
from wearnav.core.timeseries import interp_onto
from wearnav.errors import ConfigError, ValidationError, WearnavWarning
from wearnav.metrics import FIX_MAX_GAP_S
from wearnav.preprocess import PreprocessConfig, align, interpolate_position
from wearnav.recording import Recording

# Fixes of one recording that all lie within this distance (m) of each other never moved: a stuck
# receiver, a placeholder position or a copy of one fix. Their labels would all be 0 m, so the
# recording is left out with a warning (a standing walker's real GNSS still scatters by metres).
FIX_SPREAD_MIN_M = 0.01


@dataclass(frozen=True)
class LabelConfig:
    """How fixes and IMU become labelled segments (defaults: the paper's 1-s segments)."""

    segment_s: float = 1.0
    rate: float = 25.0
    tolerance: float = 0.25  # allowed relative deviation of a fix pair's spacing from segment_s
    align_to_fixes: bool = True  # turn the IMU frame onto the fixes' east/north frame
    max_speed: float | None = 5.0  # m/s: drop gross fix jumps (module docstring); None keeps all
    stride_s: float | None = None  # start a segment every stride_s (overlapping; module docstring); None: segment_s

    def __post_init__(self):
        if not self.segment_s > 0 or not self.rate > 0 or not 0 <= self.tolerance < 1:
            raise ConfigError(
                f"segment_s and rate must be positive and tolerance in [0, 1), got "
                f"{self.segment_s}, {self.rate}, {self.tolerance}"
            )
        if self.stride_s is not None and not (
            self.stride_s > 0 and abs(self.segment_s / self.stride_s - self.steps) < 1e-6
        ):
            raise ConfigError(
                f"stride_s must divide segment_s ({self.segment_s} s) into whole steps, got {self.stride_s}"
            )

    @property
    def steps(self) -> int:
        """Segment starts per fix spacing (1: back-to-back segments between fixes)."""
        return max(1, int(round(self.segment_s / (self.stride_s or self.segment_s))))

    @property
    def samples(self) -> int:
        return max(2, int(round(self.segment_s * self.rate)))

    def preprocess(self) -> PreprocessConfig:
        return PreprocessConfig(rate=self.rate, devices=("phone",), frame="world", frame_align="none")


@dataclass
class Segments:
    """Labelled IMU segments of one or more trajectories.

    ``x`` (n, N, 6) world-frame acc (with gravity) + gyro; ``label`` (n, 2) the phone label d̃
    (eq. 4; for :func:`segments_from_truth` the truth); ``truth`` (n, 2) the true displacement
    (NaN without dense truth); ``traj`` (n,) trajectory index into ``names``; ``node0``/``node1``
    (n,) global node indices of the segment's ends; ``t0``/``t1`` (n,) their times. Nodes:
    ``node_pos`` (m, 2) the fix positions P̃, ``node_traj`` (m,), ``node_t`` (m,). ``dropped``
    (n_traj,) how many labels of each trajectory the jump filter (``LabelConfig.max_speed``) dropped."""

    x: np.ndarray
    label: np.ndarray
    truth: np.ndarray
    traj: np.ndarray
    node0: np.ndarray
    node1: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    node_pos: np.ndarray
    node_traj: np.ndarray
    node_t: np.ndarray
    names: list[str] = field(default_factory=list)
    start_pos: np.ndarray | None = None  # (n_traj, 2) true position at each trajectory's first node
    dropped: np.ndarray | None = None  # (n_traj,) labels the jump filter dropped per trajectory

    def __len__(self) -> int:
        return int(self.label.shape[0])

    @property
    def n_nodes(self) -> int:
        return int(self.node_pos.shape[0])

    def subset(self, idx) -> Segments:
        """Segments ``idx`` (nodes and names kept, so node indices stay valid)."""
        idx = np.asarray(idx)
        return Segments(
            self.x[idx],
            self.label[idx],
            self.truth[idx],
            self.traj[idx],
            self.node0[idx],
            self.node1[idx],
            self.t0[idx],
            self.t1[idx],
            self.node_pos,
            self.node_traj,
            self.node_t,
            list(self.names),
            self.start_pos,
            self.dropped,
        )

    def noise(self) -> np.ndarray:
        """Label noise vectors d_e = d − d̃ (eq. 5), NaN where the truth is unknown."""
        return self.truth - self.label

    @staticmethod
    def concat(parts: list[Segments]) -> Segments:
        parts = [p for p in parts if p is not None]
        if not parts:
            raise ValidationError("no segments to concatenate")
        n_off, t_off = 0, 0
        cols: dict[str, list[np.ndarray]] = {
            k: []
            for k in (
                "x",
                "label",
                "truth",
                "traj",
                "node0",
                "node1",
                "t0",
                "t1",
                "node_pos",
                "node_traj",
                "node_t",
                "start_pos",
                "dropped",
            )
        }
        names: list[str] = []
        for p in parts:
            for k in ("x", "label", "truth", "t0", "t1", "node_pos", "node_t"):
                cols[k].append(getattr(p, k))
            cols["traj"].append(p.traj + t_off)
            cols["node_traj"].append(p.node_traj + t_off)
            cols["node0"].append(p.node0 + n_off)
            cols["node1"].append(p.node1 + n_off)
            sp = p.start_pos if p.start_pos is not None else np.full((len(p.names), 2), np.nan)
            cols["start_pos"].append(sp)
            cols["dropped"].append(p.dropped if p.dropped is not None else np.zeros(len(p.names), np.int64))
            names += p.names
            n_off += p.n_nodes
            t_off += len(p.names)
        return Segments(**{k: np.concatenate(v) for k, v in cols.items()}, names=names)

    def save(self, path: str | Path) -> Path:
        """Write the segments as ``.npz`` at ``path``, atomically and durably."""
        d = {k: v for k, v in asdict(self).items() if k not in ("names", "start_pos", "dropped")}
        dropped = self.dropped if self.dropped is not None else np.zeros(len(self.names), np.int64)
        return savez_atomic(
            path,
            durable=True,
            names=np.asarray(self.names, dtype=str),
            dropped=dropped,
            start_pos=self.start_pos if self.start_pos is not None else np.full((len(self.names), 2), np.nan),
            **d,
        )

    @classmethod
    def load(cls, path: str | Path) -> Segments:
        with np.load(path) as z:
            d = {k: z[k] for k in z.files}
        names = [str(s) for s in d.pop("names")]
        return cls(**d, names=names)


def plausible_labels(label: np.ndarray, dt: np.ndarray, max_speed: float | None) -> np.ndarray:
    """Mask of labels (n, 2) over spacings dt (n,) no faster than ``max_speed`` (None: all)."""
    label = np.asarray(label, dtype=np.float64)
    if max_speed is None:
        return np.ones(label.shape[0], bool)
    return np.linalg.norm(label[:, :2], axis=1) <= max_speed * np.asarray(dt, dtype=np.float64)


def _fix_chain(t_fix: np.ndarray, cfg: LabelConfig, t_lo: float, t_hi: float) -> list[tuple[int, int]]:
    """Pairs (i, j) of fix indices forming consecutive segments (module docstring)."""
    pairs = []
    i = int(np.searchsorted(t_fix, t_lo))
    tol = cfg.tolerance * cfg.segment_s
    while i < t_fix.size - 1:
        target = t_fix[i] + cfg.segment_s
        j = int(np.searchsorted(t_fix, target))
        cand = [k for k in (j - 1, j) if i < k < t_fix.size]
        if not cand:
            break
        j = min(cand, key=lambda k: abs(t_fix[k] - target))
        if abs(t_fix[j] - target) <= tol and t_fix[j] <= t_hi:
            pairs.append((i, j))
            i = j
        else:
            i += 1
    return pairs


def fix_frame_yaw(
    imu: np.ndarray,
    t: np.ndarray,
    rate: float,
    t_fix: np.ndarray,
    p_fix: np.ndarray,
    window_s: float = 4.0,
    kernel_s: float = 60.0,
) -> tuple[np.ndarray, dict]:
    """Yaw δ(t) (rad, per clock sample) that turns a phone's world-frame IMU (T, 6) onto the fixes'
    east/north frame: rotate with ``rotate_stacked(imu, δ)``.

    Why not the truth-frame estimator of :mod:`wearnav.preprocess.frames` fed the fixes: it compares
    accelerations, and the second difference of 1-Hz fixes is dominated by their noise (measured on a
    simulated L2 walk: coherence 0.12, yaw spread 300°). Instead, per ``window_s`` window (stride 1 s)
    the walking direction in the IMU frame comes from the step-frequency acceleration (PDR's
    :meth:`~wearnav.models.pdr.PDR.heading`, principal axis + fore-aft/vertical phase for the sign)
    and in the fix frame from the fixes' displacement over the same window, kept while it looks
    like walking (0.4–2.5 m/s); δ is their difference, averaged on the circle with a Gaussian
    kernel in time (σ = ``kernel_s``, following the orientation's slow yaw walk), after dropping
    windows more than 60° off the recording's overall mean (PDR's sign flips)."""
    from wearnav.models.pdr import PDR

    W = int(round(window_s * rate))
    info: dict[str, Any] = {"windows": 0, "yaw_deg": None}
    if t.size < W + 2 or t_fix.size < 3:
        return np.zeros(t.size), info
    starts = np.arange(0, t.size - W, int(round(rate)))
    pdr = PDR(n_devices=1, window=W, rate=rate)
    acc = np.stack([imu[s : s + W, :3] for s in starts]).astype(np.float64)
    h = pdr.heading(pdr.bandpass(acc))
    p0, ok0 = interp_onto(t[starts], t_fix, p_fix, max_gap=FIX_MAX_GAP_S)
    p1, ok1 = interp_onto(t[starts + W - 1], t_fix, p_fix, max_gap=FIX_MAX_GAP_S)
    d = np.asarray(p1) - np.asarray(p0)
    speed = np.linalg.norm(d, axis=1) / ((W - 1) / rate)
    use = ok0 & ok1 & (speed > 0.4) & (speed < 2.5)
    if use.sum() < 3:
        return np.zeros(t.size), info
    delta = np.arctan2(d[:, 1], d[:, 0]) - np.arctan2(h[:, 1], h[:, 0])
    z = np.exp(1j * delta)
    w = use.astype(np.float64)
    mean = np.angle(np.sum(w * z))
    w = w * (np.abs(np.angle(z * np.exp(-1j * mean))) < np.deg2rad(60.0))
    tc = t[starts] + 0.5 * window_s
    kern = np.exp(-0.5 * ((t[:, None] - tc[None, :]) / kernel_s) ** 2) * w[None, :] if t.size * tc.size < 5e7 else None
    overall = np.sum(w * z)
    if kern is None:
        yaw = np.full(t.size, np.angle(overall))
    else:
        acc_z = kern @ z + 1e-6 * overall  # where no window is near, hold the overall mean
        yaw = np.angle(acc_z)
    info = {
        "windows": int(w.sum()),
        "yaw_deg": round(float(np.rad2deg(np.angle(overall))), 2),
        "span_deg": round(float(np.rad2deg(np.ptp(np.unwrap(yaw)))), 2),
    }
    return yaw, info


def aligned_phone(rec: Recording, cfg: LabelConfig):
    """The recording's phone IMU as the labeller sees it: world frame, resampled, turned onto its
    own fixes' east/north frame (:func:`fix_frame_yaw`; module docstring, "Input")."""
    seq = align(rec, cfg.preprocess())
    if cfg.align_to_fixes and rec.fixes is not None and len(rec.fixes) >= 3:
        from wearnav.preprocess.frames import rotate_stacked

        yaw, info = fix_frame_yaw(seq.imu[0], seq.t, seq.rate, rec.fixes.t, rec.fixes.pos[:, :2])
        if info["windows"]:
            seq.imu = seq.imu.copy()
            seq.imu[0] = rotate_stacked(seq.imu[0], yaw)
            seq.imu[0][~seq.mask[0]] = 0.0
        seq.meta["frame"] = {"frame": "fixes" if info["windows"] else "none", **info}
    return seq


def _dense_truth(rec: Recording) -> bool:
    return rec.truth is not None and len(rec.truth) > 1 and float(np.median(np.diff(rec.truth.t))) <= 0.2


def label_recording(rec: Recording, cfg: LabelConfig = LabelConfig(), warn_drops: bool = True) -> Segments | None:
    """Phone-labelled segments of one recording (None if it has no usable fix pair). ``warn_drops``:
    warn when the jump filter drops labels (:func:`label_dataset` warns once for all recordings)."""
    if rec.fixes is None or len(rec.fixes) < 2 or "phone" not in rec.devices:
        return None
    spread = float(np.max(np.ptp(rec.fixes.pos[:, :2], axis=0)))
    if spread < FIX_SPREAD_MIN_M:
        warnings.warn(
            f"{rec.name}: all {len(rec.fixes)} location fixes lie at one point (spread "
            f"{spread:.3g} m): its labels would all be 0 m, so it is left out",
            WearnavWarning,
            stacklevel=2,
        )
        return None
    seq = aligned_phone(rec, cfg)
    N = cfg.samples
    t_fix, p_fix = rec.fixes.t, rec.fixes.pos[:, :2]
    t_pt, p_pt, span = _chain_points(_fix_chain(t_fix, cfg, seq.t[0], seq.t[-1]), t_fix, p_fix, cfg.steps)
    keep = []  # (start point, end point, first IMU sample)
    for a, b in span:
        for k in range(a, b - cfg.steps + 1):
            s = int(np.searchsorted(seq.t, t_pt[k] - 0.5 / cfg.rate))
            if s + N <= seq.t.size and seq.mask[0, s : s + N].all():
                keep.append((k, k + cfg.steps, s))
    n_drop = 0
    if keep:
        ij = np.array([(i, j) for i, j, _ in keep])
        ok = plausible_labels(p_pt[ij[:, 1]] - p_pt[ij[:, 0]], t_pt[ij[:, 1]] - t_pt[ij[:, 0]], cfg.max_speed)
        n_drop = int((~ok).sum())
        if n_drop and warn_drops:
            warnings.warn(
                f"{rec.name}: the jump filter (max_speed {cfg.max_speed} m/s) dropped {n_drop} of {len(keep)} labels",
                WearnavWarning,
                stacklevel=2,
            )
        keep = [k for k, good in zip(keep, ok) if good]
    if not keep:
        return None
    nodes = np.array(sorted({k for i, j, _ in keep for k in (i, j)}))
    node_of = {k: n for n, k in enumerate(nodes)}
    x = np.stack([seq.imu[0, s : s + N] for _, _, s in keep]).astype(np.float32)
    i_idx = np.array([i for i, _, _ in keep])
    j_idx = np.array([j for _, j, _ in keep])
    label = p_pt[j_idx] - p_pt[i_idx]
    truth = np.full_like(label, np.nan)
    start = np.full((1, 2), np.nan)
    if _dense_truth(rec):
        assert rec.truth is not None  # _dense_truth checked it
        tt = interpolate_position(rec.truth.t, rec.truth.pos, t_pt[nodes])
        truth = tt[[node_of[j] for j in j_idx]] - tt[[node_of[i] for i in i_idx]]
        start = tt[:1]
    return Segments(
        x=x,
        label=label,
        truth=truth,
        traj=np.zeros(len(keep), np.int64),
        node0=np.array([node_of[i] for i in i_idx]),
        node1=np.array([node_of[j] for j in j_idx]),
        t0=t_pt[i_idx],
        t1=t_pt[j_idx],
        node_pos=p_pt[nodes],
        node_traj=np.zeros(len(nodes), np.int64),
        node_t=t_pt[nodes],
        names=[rec.name],
        start_pos=start,
        dropped=np.array([n_drop]),
    )


def _chain_points(
    pairs: list[tuple[int, int]], t_fix: np.ndarray, p_fix: np.ndarray, steps: int
) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """The points segments start and end on: every fix of the chain of ``pairs`` and, with
    ``steps`` > 1, ``steps`` − 1 points evenly between each pair, positions linearly interpolated
    between the two fixes. Returns times, positions and each unbroken chain's [first, last] point
    indices (a segment spans ``steps`` points: the fix spacing)."""
    t_pt: list[float] = []
    p_pt: list[np.ndarray] = []
    span = []
    k = 0
    while k < len(pairs):
        chain = [pairs[k][0]]
        while k < len(pairs) and pairs[k][0] == chain[-1]:
            chain.append(pairs[k][1])
            k += 1
        first = len(t_pt)
        for a, b in zip(chain[:-1], chain[1:]):
            for q in range(steps):
                w = q / steps
                t_pt.append((1 - w) * t_fix[a] + w * t_fix[b])
                p_pt.append((1 - w) * p_fix[a] + w * p_fix[b])
        t_pt.append(t_fix[chain[-1]])
        p_pt.append(p_fix[chain[-1]])
        span.append((first, len(t_pt) - 1))
    return np.asarray(t_pt, dtype=np.float64), np.asarray(p_pt, dtype=np.float64).reshape(-1, 2), span


def segments_from_truth(rec: Recording, cfg: LabelConfig = LabelConfig()) -> Segments | None:
    """Contiguous N-sample segments labelled with the true displacement (test trajectories; see
    module docstring). The IMU frame is still turned onto the fixes' frame, never the truth's."""
    if not _dense_truth(rec) or "phone" not in rec.devices:
        return None
    seq = aligned_phone(rec, cfg)
    assert rec.truth is not None  # _dense_truth checked it
    pos = interpolate_position(rec.truth.t, rec.truth.pos, seq.t)
    N = cfg.samples
    starts = np.arange(0, seq.t.size - N, N)
    ok = (
        np.array(
            [
                seq.mask[0, s : s + N].all() and np.isfinite(pos[s]).all() and np.isfinite(pos[s + N]).all()
                for s in starts
            ],
            bool,
        )
        if starts.size
        else np.zeros(0, bool)
    )
    # keep the longest contiguous stretch so the displacements integrate one trajectory
    if not ok.any():
        return None
    cur: list[int] = []
    best_run: list[int] = []
    for k, good in enumerate(ok):
        cur = cur + [k] if good else []
        if len(cur) > len(best_run):
            best_run = list(cur)
    best = starts[np.array(best_run)]
    node_idx = np.concatenate([best, [best[-1] + N]])
    label = pos[best + N] - pos[best]
    n = best.size
    return Segments(
        x=np.stack([seq.imu[0, s : s + N] for s in best]).astype(np.float32),
        label=label,
        truth=label.copy(),
        traj=np.zeros(n, np.int64),
        node0=np.arange(n),
        node1=np.arange(1, n + 1),
        t0=seq.t[best],
        t1=seq.t[best + N],
        node_pos=pos[node_idx],
        node_traj=np.zeros(n + 1, np.int64),
        node_t=seq.t[node_idx],
        names=[rec.name],
        start_pos=pos[best[:1]],
    )


def label_dataset(view, cfg: LabelConfig = LabelConfig(), from_truth: bool = False, progress: bool = False) -> Segments:
    """All recordings of a dataset view, phone-labelled (or truth-labelled with ``from_truth``)."""
    recs = report_progress(view, total=len(view), desc="label", unit="rec", enabled=progress)
    labelled = [
        segments_from_truth(rec, cfg) if from_truth else label_recording(rec, cfg, warn_drops=False) for rec in recs
    ]
    parts = [p for p in labelled if p is not None and len(p)]
    dropped = sum(int(p.dropped.sum()) for p in parts if p.dropped is not None)
    if dropped:
        hit = sum(int((p.dropped > 0).sum()) for p in parts if p.dropped is not None)
        warnings.warn(
            f"the jump filter (max_speed {cfg.max_speed} m/s) dropped {dropped} of "
            f"{dropped + sum(len(p) for p in parts)} labels in {hit} recording(s)",
            WearnavWarning,
            stacklevel=2,
        )
    if not parts:
        raise ValidationError(
            "no recording gave a labelled segment (need phone IMU and fixes that move"
            + (" and dense truth)" if from_truth else ")")
        )
    return Segments.concat(parts)


# ---- label-noise statistics (eqs. 5–7) -----------------------------------------------------------


def neighbour_correlation(seg: Segments) -> dict:
    """:func:`wearnav.metrics.label_noise_correlation` over pairs of consecutive segments
    (node1(i) == node0(i+1)) that both have truth."""
    from wearnav.metrics import label_noise_correlation

    e = seg.noise()
    nxt = np.flatnonzero(seg.node1[:-1] == seg.node0[1:]) if len(seg) > 1 else np.empty(0, int)
    ok = nxt[np.isfinite(e[nxt]).all(1) & np.isfinite(e[nxt + 1]).all(1)]
    if ok.size < 3:
        return {"pairs": int(ok.size), "x": None, "y": None}
    rx, ry = label_noise_correlation(e, ok)
    return {"pairs": int(ok.size), "x": rx, "y": ry}


def noise_summary(seg: Segments) -> dict:
    """Median / mean / p90 of |d_e| (cm), the shares over 1 m and 2 m, the segment count, the labels
    the jump filter dropped (count, share of all labels) and the neighbour correlation."""
    e = seg.noise()
    mag = np.linalg.norm(e[np.isfinite(e).all(1)], axis=1)
    dist = (
        float(np.nansum(np.linalg.norm(seg.truth, axis=1)))
        if np.isfinite(seg.truth).any()
        else float(np.sum(np.linalg.norm(seg.label, axis=1)))
    )
    out: dict[str, Any] = {
        "segments": len(seg),
        "trajectories": len(seg.names),
        "length_km": round(dist / 1000, 3),
        "label_noise_median_cm": None,
        "label_noise_mean_cm": None,
        "label_noise_p90_cm": None,
    }
    if mag.size:
        out.update(
            label_noise_median_cm=round(100 * float(np.median(mag)), 2),
            label_noise_mean_cm=round(100 * float(np.mean(mag)), 2),
            label_noise_p90_cm=round(100 * float(np.percentile(mag, 90)), 2),
            label_noise_over_1m=round(float(np.mean(mag > 1.0)), 5),
            label_noise_over_2m=round(float(np.mean(mag > 2.0)), 5),
        )
    dropped = int(seg.dropped.sum()) if seg.dropped is not None else 0
    out.update(dropped_labels=dropped, dropped_share=round(dropped / max(dropped + len(seg), 1), 5))
    out["neighbour_correlation"] = neighbour_correlation(seg)
    return out


def plot_noise_cdf(seg: Segments, out: str | Path):
    """CDF of |d_e| (cm) where the truth is known; None without truth."""
    e = np.linalg.norm(seg.noise(), axis=1)
    e = e[np.isfinite(e)] * 100
    if not e.size:
        return None
    from matplotlib.figure import Figure

    from wearnav.report.plots import plot_ecdf, save

    fig = Figure(figsize=(5, 3.4), layout="constrained")
    ax = fig.subplots()
    plot_ecdf(ax, e)
    ax.set(
        xlabel="phone-label noise |d_e| (cm)", ylabel="CDF", title=f"median {np.median(e):.1f} cm, {e.size} segments"
    )
    ax.grid(alpha=0.3)
    return save(fig, Path(out))
