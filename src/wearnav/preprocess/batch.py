""":func:`wearnav.preprocess.align` for many recordings at once: :func:`align_many` (issue 61 §2).

The live tracker aligns a few seconds of every due session at each tick (:mod:`wearnav.live.crowd`).
Per session, most of that cost was not arithmetic but the calls around it: a scipy ``Rotation``
made and applied three times, the low-pass's initial state solved again (``sosfilt_zi``) and two
filter passes, each over a few hundred samples. Here every session's streams are rotated by one
``Rotation`` over all their samples, and the zero-phase low-pass runs as two ``sosfilt`` calls
over all streams of one rate stacked (:func:`lowpass_many`, ragged lengths kept exact: each
stream's forward pass starts at its own first sample, its backward pass at its own last), the
rest (interpolation onto each clock, the common frame, the headings) per recording as
:func:`~wearnav.preprocess.align` does it, except where one device is present: its common frame is
its own, not estimated (:func:`_one_device_frame`). Every output equals ``align``'s to round-off
(tests/test_live_batched.py).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy import signal

from wearnav.core.rotations import from_wxyz
from wearnav.core.timeseries import interp_onto, periods
from wearnav.preprocess import (
    HEADING_AXIS,
    MIN_HEADING_NORM,
    STREAM_MAX_GAP_PERIODS,
    Aligned,
    PreprocessConfig,
    _butter,
    _carrier_heading,
    align,
    nominal_rate,
)
from wearnav.preprocess.frames import frame_yaws, reference_index, rotate_stacked, turn_devices
from wearnav.recording import Recording


@functools.lru_cache(maxsize=64)
def _zi(cutoff: float, fs: float) -> np.ndarray:
    """``sosfilt_zi`` of :func:`wearnav.preprocess._butter`'s sections, solved once per design."""
    return signal.sosfilt_zi(_butter(cutoff, fs))


def lowpass_many(xs: list[np.ndarray], fs: float, target_rate: float) -> list[np.ndarray]:
    """:func:`wearnav.preprocess._lowpass` of each of ``xs`` ((n_i, C) float64, one rate ``fs``):
    scipy's ``sosfiltfilt`` (odd extension, its default pad length) over all of them in two
    ``sosfilt`` calls. The rows are left-aligned in one array, zero-padded on the right, which a
    causal filter never reads back; the backward pass runs on each row reversed within its own
    length."""
    cutoff = 0.4 * target_rate
    if fs < 2.5 * cutoff:
        return list(xs)
    out: list[np.ndarray | None] = [x if len(x) < 30 else None for x in xs]
    todo = [i for i, x in enumerate(xs) if len(x) >= 30]
    if not todo:
        return list(xs)
    sos = _butter(cutoff, fs)
    ntaps = 2 * len(sos) + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    pad = 3 * ntaps
    if min(len(xs[i]) for i in todo) <= pad:  # scipy's own error for a short input: leave it to scipy
        return [signal.sosfiltfilt(sos, x, axis=0) if len(x) >= 30 else x for x in xs]
    n = np.array([len(xs[i]) + 2 * pad for i in todo])
    C = xs[todo[0]].shape[1]
    ext = np.zeros((len(todo), int(n.max()), C))
    for r, i in enumerate(todo):  # scipy's odd_ext
        x = xs[i]
        ext[r, : n[r]] = np.concatenate([2 * x[0] - x[pad:0:-1], x, 2 * x[-1] - x[-2 : -pad - 2 : -1]])
    zi = _zi(cutoff, fs)[:, None, :, None]  # (sections, rows, 2, channels)
    y, _ = signal.sosfilt(sos, ext, axis=1, zi=zi * ext[None, :, 0:1, :])
    k = np.arange(ext.shape[1])
    back = np.clip(n[:, None] - 1 - k[None, :], 0, None)  # each row reversed within its length
    rev = np.take_along_axis(y, back[:, :, None], axis=1)
    rev[k[None, :] >= n[:, None]] = 0.0
    z, _ = signal.sosfilt(sos, rev, axis=1, zi=zi * rev[None, :, 0:1, :])
    for r, i in enumerate(todo):
        out[i] = z[r, : n[r]][::-1][pad:-pad]
    return out  # type: ignore[return-value]


def align_many(items: list[tuple[Recording, PreprocessConfig, np.ndarray]]) -> list[Aligned]:
    """``[align(rec, cfg, t) for rec, cfg, t in items]`` (module docstring), each clock ``t`` given.
    Recordings with truth, and configurations that remove gravity, go to ``align`` one by one
    (the live tracker has neither)."""
    out: list[Aligned | None] = [None] * len(items)
    fast = []
    for i, (rec, cfg, t) in enumerate(items):
        if (
            rec.truth is not None
            or cfg.remove_gravity
            or (cfg.frame == "world" and any(rec.devices[d].quat is None for d in cfg.devices if d in rec.devices))
        ):
            out[i] = align(rec, cfg, t)
        else:
            if t.size < 2:
                align(rec, cfg, t)  # its error
            fast.append(i)
    if not fast:
        return out  # type: ignore[return-value]
    # every present stream of every fast item; the world-frame ones rotated by one Rotation
    streams = [
        (i, d, items[i][0].devices[dev])
        for i in fast
        for d, dev in enumerate(items[i][1].devices)
        if dev in items[i][0].devices
    ]
    xs = [
        np.concatenate(
            [s.acc.astype(np.float64), s.gyro.astype(np.float64) if s.gyro is not None else np.zeros((len(s.t), 3))],
            axis=1,
        )
        for _, _, s in streams
    ]
    heads: list[np.ndarray | None] = [None] * len(streams)
    world = [k for k, (i, _d, _s) in enumerate(streams) if items[i][1].frame == "world"]
    if world:
        rot = from_wxyz(np.concatenate([streams[k][2].quat for k in world]))
        x = np.concatenate([xs[k] for k in world])
        x = np.concatenate([rot.apply(x[:, :3]), rot.apply(x[:, 3:])], axis=1)
        cuts = np.cumsum([len(xs[k]) for k in world])[:-1]
        for k, part in zip(world, np.split(x, cuts)):
            xs[k] = part
        if any(items[streams[k][0]][1].heading_frame for k in world):
            for k, part in zip(world, np.split(rot.apply(HEADING_AXIS), cuts)):
                heads[k] = part
    rates = [s.rate for _, _, s in streams]  # a median of the stream's intervals: once each
    # the low-pass: one stacked pass per (stream rate, clock rate)
    groups: dict[tuple[float, float], list[int]] = {}
    for k, (i, _d, _s) in enumerate(streams):
        cfg = items[i][1]
        if cfg.lowpass:
            groups.setdefault((nominal_rate(rates[k]), cfg.rate), []).append(k)
    for (fs, rate), ks in groups.items():
        for k, y in zip(ks, lowpass_many([xs[k] for k in ks], fs, rate)):
            xs[k] = y
    per_item: dict[int, list[int]] = {}
    for k, (i, _d, _s) in enumerate(streams):
        per_item.setdefault(i, []).append(k)
    for i in fast:
        rec, cfg, t = items[i]
        imu = np.zeros((len(cfg.devices), t.size, 6), np.float32)
        mask = np.zeros((len(cfg.devices), t.size), bool)
        hs: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for k in per_item.get(i, []):
            _, d, s = streams[k]
            imu[d], mask[d], h = _to_clock(s, xs[k], t, rates[k], heads[k])
            if h is not None:
                hs[d] = h
        meta = dict(rec.meta)
        turned = None
        if cfg.frame == "world" and cfg.frame_align != "none":
            one = _one_device_frame(mask, tuple(cfg.devices))
            if one is not None:  # nothing to turn: the one device is its own frame
                turned, meta["frame"] = one
            else:
                turned, meta["frame"] = frame_yaws(imu, mask, tuple(cfg.devices), cfg.rate, None, cfg.frame_align)
                if turned is not None:
                    imu = turn_devices(imu, mask, turned)
        if cfg.yaw_deg:
            imu = np.stack([rotate_stacked(x, -np.deg2rad(cfg.yaw_deg)) for x in imu]).astype(np.float32)
        yaws = _headings(rec, cfg, t, mask, turned, hs) if cfg.heading_frame else None
        yaw = _carrier_heading(yaws) if yaws is not None else None
        out[i] = Aligned(rec.name, t, tuple(cfg.devices), imu, mask, None, meta, rec, yaw, yaws)
    return out  # type: ignore[return-value]


def _one_device_frame(mask: np.ndarray, devices: tuple[str, ...]) -> tuple[np.ndarray, dict] | None:
    """:func:`~wearnav.preprocess.frames.frame_yaws` without truth where exactly one device is present
    (a phone-only session): that device is the reference, every yaw 0 and turning by it changes
    nothing, so it is not done (the frame's estimate, per time step, was a tenth of a phone-only
    session's alignment); None where more or none are present (``frame_yaws`` decides)."""
    present = mask.any(axis=1)
    if int(present.sum()) != 1:
        return None
    ref = reference_index(devices, mask)
    return np.zeros(mask.shape), {"frame": "common", "reference": devices[ref], "devices": {}, "truth": None}


def _to_clock(
    s, x: np.ndarray, t: np.ndarray, rate: float, head: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
    """:func:`wearnav.preprocess.stream_to_clock` after its rotation and low-pass (``x``; the
    stream's ``rate``), and where ``head`` (the rotated heading axis, (n, 3)) is given, the
    heading interpolated onto ``t`` with its mask (:func:`_headings`): in the same call, each
    column interpolated alone as before."""
    if head is not None:  # (as _device_headings: a heading too short to tell is NaN)
        h = head[:, 0] + 1j * head[:, 1]
        h = np.where(np.abs(h) >= MIN_HEADING_NORM, h, np.nan)
        x = np.concatenate([x, h.real[:, None], h.imag[:, None]], axis=1)
    both, mask = interp_onto(t, s.t, x, max_gap=periods(STREAM_MAX_GAP_PERIODS, rate))
    both = np.asarray(both, dtype=np.float64)
    heading = None if head is None else (both[:, 6] + 1j * both[:, 7], mask.copy())
    out = np.array(both[:, :6], dtype=np.float64)
    if s.worn is not None:
        nearest = np.clip(np.searchsorted(s.t, t), 0, len(s.t) - 1)
        mask &= s.worn[nearest]
    if s.gyro is None:
        out[:, 3:] = 0.0
    out[~mask] = 0.0
    return out.astype(np.float32), mask, heading


def _headings(rec, cfg, t, mask, turned, hs: dict[int, tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """:func:`wearnav.preprocess._device_headings` from each device's heading on the clock and its
    mask, ``hs`` (:func:`_to_clock`)."""
    yaws = np.full((len(cfg.devices), t.size), np.nan)
    for d, dev in enumerate(cfg.devices):
        if dev not in rec.devices or not mask[d].any():
            continue
        v, ok = hs[d]
        v = np.where(ok & (np.abs(v) > 0), v, np.nan)
        with np.errstate(invalid="ignore"):
            psi = np.angle(v / np.abs(v))
        if turned is not None:
            psi = psi - turned[d]
        psi = psi - np.deg2rad(cfg.yaw_deg)
        here = mask[d] & np.isfinite(psi)
        yaws[d, here] = np.angle(np.exp(1j * psi[here]))
    return yaws


__all__ = ["align_many", "lowpass_many"]
