"""Sliding windows over aligned recordings as a torch Dataset (the only windowing routine).

As in RoNIN, sequences (:class:`wearnav.preprocess.Aligned`) know their data and the window
dataset only indexes (sequence, start) pairs. As in TLIO, the interface may speak seconds and
hertz (:meth:`WindowConfig.from_seconds`); they are converted to samples once, here.

Targets follow Suite-IN++ (paper 000, Sec. IV-A): for window n covering samples
[s, s+L−1], the displacement d = p(t_{s+L−1}) − p(t_s) of the horizontal truth, and the mean
horizontal world velocity v = d / (t_{s+L−1} − t_s).

Decisions: docs/decisions/0001-data-model-refinements.md,
docs/decisions/0003-exact-resume-and-batched-fetch.md, docs/decisions/0029-heading-frame.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch.utils.data import Dataset as TorchDataset

from wearnav.errors import ConfigError
from wearnav.preprocess import Aligned, PreprocessConfig, align


@dataclass(frozen=True)
class WindowConfig:
    """Window length and stride in samples of the aligned clock (Suite-IN++: L = 100 at 25 Hz)."""

    window: int = 100
    stride: int = 10
    # "velocity": keep windows whose ends have truth; "class": keep windows with a label of
    # ``label_kind``; None: keep every window (inference on recordings without truth).
    target: str | None = "velocity"
    label_kind: str | None = None
    # A device counts as present in a window when it is present in at least this share of it.
    min_present: float = 0.5

    def __post_init__(self) -> None:
        if self.window < 2 or self.stride < 1:
            raise ConfigError(f"window must be ≥ 2 and stride ≥ 1 samples, got {self.window}/{self.stride}")
        if self.target not in ("velocity", "class", None):
            raise ConfigError(f"target must be 'velocity', 'class' or None, got {self.target!r}")
        if self.target == "class" and not self.label_kind:
            raise ConfigError("target 'class' needs label_kind (e.g. 'activity')")

    @classmethod
    def from_seconds(cls, window_s: float, stride_s: float, rate: float, **kw) -> WindowConfig:
        return cls(window=int(round(window_s * rate)), stride=max(1, int(round(stride_s * rate))), **kw)


def _majority(idx: np.ndarray) -> int:
    """Most frequent non-negative class index, or −1 if the window has no label."""
    idx = idx[idx >= 0]
    return int(np.bincount(idx).argmax()) if idx.size else -1


class WindowDataset(TorchDataset):
    """Windows of aligned sequences. Each item is a dict of tensors:

    ``x`` (devices, L, 6), ``mask`` (devices,) 1.0 where the device is present, ``vel`` (2,)
    and ``disp`` (2,) (NaN without truth), ``label`` (−1 without label), ``seq`` (index of the
    sequence), ``t`` (window start and end times).
    """

    def __init__(
        self, sequences: Sequence[Aligned], cfg: WindowConfig = WindowConfig(), classes: Sequence[str] | None = None
    ):
        self.sequences = list(sequences)
        self.cfg = cfg
        self.classes = list(classes) if classes is not None else self._collect_classes()
        class_index = {c: i for i, c in enumerate(self.classes)}
        self._labels = []
        for seq in self.sequences:
            lab = np.full(len(seq), -1, np.int64)
            if cfg.label_kind and seq.recording is not None:
                names = seq.recording.label_at(cfg.label_kind, seq.t)
                lab = np.array([class_index.get(n, -1) for n in names], np.int64)
            self._labels.append(lab)
        self.index = self._build_index()
        self._resident: _Resident | None = None  # a copy on a device (:meth:`to`)
        # in the carrying device's heading frame (PreprocessConfig.heading_frame): each window and its
        # target turned by −ψ, ψ in the batch's ``yaw`` (every sequence the same way, or none)
        self.heading = any(seq.yaw is not None for seq in self.sequences)
        if self.heading and not all(seq.yaw is not None for seq in self.sequences):
            raise ConfigError("sequences with and without heading_frame cannot share a window dataset")

    def _collect_classes(self) -> list[str]:
        if not self.cfg.label_kind:
            return []
        values = set()
        for seq in self.sequences:
            if seq.recording is not None:
                lab = seq.recording.labels
                values |= set(lab.loc[lab["kind"] == self.cfg.label_kind, "value"])
        return sorted(values)

    def _build_index(self) -> np.ndarray:
        L, S = self.cfg.window, self.cfg.stride
        rows: list[tuple[int, int]] = []
        for i, seq in enumerate(self.sequences):
            starts = np.arange(0, len(seq) - L + 1, S)
            if self.cfg.target == "velocity":
                if seq.pos is None:
                    continue
                ok = np.isfinite(seq.pos[starts, 0]) & np.isfinite(seq.pos[starts + L - 1, 0])
                starts = starts[ok]
            elif self.cfg.target == "class":
                starts = np.array([s for s in starts if _majority(self._labels[i][s : s + L]) >= 0], np.int64)
            rows.extend((i, int(s)) for s in starts)
        return np.array(rows, np.int64).reshape(-1, 2)

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, k) -> dict[str, torch.Tensor]:
        """One window (``k`` an int) or a batch of windows (``k`` a sequence of ints; every tensor
        then gains a leading batch axis). Batched fetching is the training data path: one call per
        batch instead of one per window and a collate (see :class:`BatchSampler`). After
        :meth:`to` the batch is gathered from the copy on that device instead."""
        if np.ndim(k) == 0:
            b = self[[int(k)]]
            return {key: v[0] for key, v in b.items()}
        if self._resident is not None:
            return self._resident.fetch(k)
        return self._fetch(np.asarray(k, np.int64))

    def to(self, device: str | torch.device, chunk: int = 4096) -> WindowDataset:
        """Keep a copy of every window on ``device`` (a GPU's memory) and fetch batches there: one
        gather per batch, no per-window Python and no host-to-device copy per step, so that the GPU
        is not left waiting on the data path (issue 37). The batches are the ones :meth:`_fetch`
        makes, bit for bit: every field but ``x`` is made by it once, here; ``x`` is gathered from
        the sequences' samples, with an absent device's window zeroed as there. Returns self."""
        self._resident = None  # built from the host copy, not from an older device copy
        if self.heading:  # each window is turned by its own ψ on the host: kept there
            return self
        self._resident = _Resident(self, torch.device(device), chunk)
        return self

    def _fetch(self, k: np.ndarray) -> dict[str, torch.Tensor]:
        idx = self.index[k]
        L = self.cfg.window
        D = len(self.sequences[0].devices) if self.sequences else 0
        x = np.empty((len(idx), D, L, 6), np.float32)
        present = np.empty((len(idx), D), bool)
        disp = np.full((len(idx), 2), np.nan)
        dt = np.empty(len(idx))
        t = np.empty((len(idx), 2))
        label = np.empty(len(idx), np.int64)
        for j, (i, s) in enumerate(idx):
            seq, e = self.sequences[i], s + L - 1
            present[j] = seq.mask[:, s : s + L].mean(axis=1) >= self.cfg.min_present
            x[j] = seq.imu[:, s : s + L]
            x[j, ~present[j]] = 0.0
            if seq.pos is not None:
                disp[j] = seq.pos[e] - seq.pos[s]
            t[j] = seq.t[s], seq.t[e]
            dt[j] = seq.t[e] - seq.t[s]
            label[j] = _majority(self._labels[i][s : s + L])
        extra = {}
        if self.heading:
            psi = np.array([window_heading(self.sequences[i].yaw, s, L) for i, s in idx])
            turn = np.exp(-1j * psi)
            for c in (0, 3):  # acc and gyro: (x, y) turned by −ψ, z kept
                h = (x[..., c] + 1j * x[..., c + 1]) * turn[:, None, None]
                x[..., c], x[..., c + 1] = h.real, h.imag
            d = (disp[:, 0] + 1j * disp[:, 1]) * turn
            disp = np.stack([d.real, d.imag], 1)
            extra["yaw"] = torch.from_numpy(psi.astype(np.float32))
            if D > 1 and all(self.sequences[i].yaws is not None for i in set(idx[:, 0].tolist())):
                # every device's own ψ (NaN where it has none), for augment.drop_devices
                each = [device_headings(self.sequences[i].yaws, s, L) for i, s in idx]
                extra["yaws"] = torch.from_numpy(np.array(each, np.float32).reshape(len(idx), D))
        return {
            "x": torch.from_numpy(x),
            "mask": torch.from_numpy(present.astype(np.float32)),
            "vel": torch.from_numpy((disp / dt[:, None]).astype(np.float32)),
            "disp": torch.from_numpy(disp.astype(np.float32)),
            "label": torch.from_numpy(label),
            "seq": torch.from_numpy(idx[:, 0].copy()),
            "t": torch.from_numpy(t),
            **extra,
        }

    def loader(self, batch: int, shuffle_seed: int | None = None, shard: bool = False) -> torch.utils.data.DataLoader:
        """A DataLoader that fetches whole batches (shuffled per epoch from ``shuffle_seed``, or in
        order when None). ``shard``: under distributed training each process takes its share of
        every batch (:class:`BatchSampler`), so ``batch`` is the global batch."""
        from torch.utils.data import DataLoader

        # batch_size=None: each "index" the sampler yields is a list, fetched in one call. Its own
        # generator: creating an iterator otherwise draws from the global RNG, at moments Lightning
        # orders differently on a resumed epoch, which would shift dropout's draws.
        return DataLoader(
            self,
            batch_size=None,
            sampler=BatchSampler(len(self), batch, shuffle_seed, shard),
            num_workers=0,
            generator=torch.Generator(),
        )

    @classmethod
    def from_recordings(
        cls, recordings, pcfg: PreprocessConfig = PreprocessConfig(), wcfg: WindowConfig = WindowConfig(), classes=None
    ) -> WindowDataset:
        """Align each recording (a Dataset view or any iterable of Recordings) and window them."""
        return cls([align(r, pcfg) for r in recordings], wcfg, classes)


def turn(v: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Horizontal vectors ``v`` (N, 2) turned by ``psi`` (N,) rad, counter-clockwise: a heading-frame
    window's velocity back into the world frame."""
    z = (v[:, 0] + 1j * v[:, 1]) * np.exp(1j * np.asarray(psi, np.float64))
    return np.stack([z.real, z.imag], 1).astype(v.dtype)


def window_heading(yaw: np.ndarray | None, start: int, length: int) -> float:
    """ψ of one window: the circular mean of the carrying device's heading over its samples (0 where
    no sample has one: the window then stays in the world frame)."""
    if yaw is None:
        return 0.0
    v = np.exp(1j * yaw[start : start + length])
    v = v[np.isfinite(v)]
    return float(np.angle(v.mean())) if v.size and abs(v.mean()) > 0 else 0.0


def device_headings(yaws: np.ndarray, start: int, length: int) -> np.ndarray:
    """Each device's ψ over one window (devices,): the circular mean of its heading over the
    window's samples, NaN where it has none there."""
    v = np.exp(1j * yaws[:, start : start + length])
    ok = np.isfinite(v)
    m = np.where(ok, v, 0).sum(axis=1)
    return np.where(ok.any(axis=1) & (np.abs(m) > 0), np.angle(m), np.nan)


class _Resident:
    """A :class:`WindowDataset`'s windows on one device (:meth:`WindowDataset.to`): the samples of
    every sequence end to end (devices × samples × 6) and each window's other fields."""

    def __init__(self, ds: WindowDataset, device: torch.device, chunk: int):
        n = len(ds)
        parts = [ds._fetch(np.arange(i, min(i + chunk, n))) for i in range(0, n, chunk)]
        self.fields = {
            key: torch.cat([p[key] for p in parts]).to(device) if parts else torch.empty(0)
            for key in ("mask", "vel", "disp", "label", "seq", "t")
        }
        lengths = [len(s) for s in ds.sequences]
        offset = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        imu = np.concatenate([s.imu for s in ds.sequences], axis=1) if ds.sequences else np.zeros((0, 0, 6))
        self.imu = torch.from_numpy(np.ascontiguousarray(imu, np.float32)).to(device)
        self.start = torch.from_numpy(offset[ds.index[:, 0]] + ds.index[:, 1]).to(device)
        self.steps = torch.arange(ds.cfg.window, device=device)

    def fetch(self, k) -> dict[str, torch.Tensor]:
        k = torch.as_tensor(np.asarray(k, np.int64)).to(self.start.device)
        rows = self.start[k][:, None] + self.steps  # (batch, L) sample indices
        x = self.imu[:, rows].permute(1, 0, 2, 3)  # (batch, devices, L, 6)
        out = {key: v[k] for key, v in self.fields.items()}
        x = torch.where(out["mask"][:, :, None, None] > 0, x, torch.zeros((), dtype=x.dtype, device=x.device))
        return {"x": x, **out}


class BatchSampler(torch.utils.data.Sampler):
    """Yields lists of window indices, ``batch`` at a time. With a seed the order is a permutation
    that is a function of (seed, epoch) alone; Lightning calls :meth:`set_epoch` before every
    epoch, also on a resumed run, so a resumed epoch replays exactly.

    ``shard``: when torch.distributed runs W processes (Lightning's DDP), process r yields the
    r-th of W near-equal parts of every batch: with gradients averaged over processes, a step on
    W processes is the step one process takes on the whole batch (exactly, for equal parts and a
    model whose output for a window does not depend on the rest of its batch: no batch norm).
    A last batch smaller than W is dropped on every process."""

    def __init__(self, n: int, batch: int, seed: int | None = None, shard: bool = False):
        if batch < 1:
            raise ConfigError(f"batch must be ≥ 1, got {batch}")
        self.n, self.batch, self.seed, self.epoch, self.shard = n, batch, seed, 0, shard

    def set_epoch(self, epoch: int) -> None:
        self.epoch = epoch

    def _rank_world(self) -> tuple[int, int]:
        dist = torch.distributed
        if self.shard and dist.is_available() and dist.is_initialized():
            return dist.get_rank(), dist.get_world_size()
        return 0, 1

    def __len__(self) -> int:
        _, world = self._rank_world()
        full, rest = divmod(self.n, self.batch)
        return full + (1 if rest and rest >= world else 0)

    def __iter__(self):
        if self.seed is None:
            order = np.arange(self.n)
        else:
            g = torch.Generator().manual_seed(self.seed * 100_003 + self.epoch)
            order = torch.randperm(self.n, generator=g).numpy()
        rank, world = self._rank_world()
        for i in range(0, self.n, self.batch):
            idx = order[i : i + self.batch]
            if world > 1:
                if idx.size < world:
                    break
                idx = np.array_split(idx, world)[rank]
            yield idx.tolist()
