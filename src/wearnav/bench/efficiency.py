"""Model efficiency (paper 000, Table VI analogue) for any registered odometry model.

For one model: trainable parameters; FLOPs of one forward pass on one window
(:class:`torch.utils.flop_counter.FlopCounterMode`, which counts a multiply-add as 2 FLOPs and
counts only matrix products and convolutions); inference windows/s on this CPU at batch 1 and
256 (eval mode, ``torch.inference_mode``, warm-up, median of repeats); and, in the same run, the
CPU's dense fp32 rate (a large square matmul), so that

    fraction of the FLOP-bound limit = FLOPs/window × windows/s ÷ dense FLOP/s.

A fraction near 1 means the model runs as fast as its arithmetic allows; small temporal
convolutions are usually memory-bound and sit far below. On a shared machine every timing is
noisy: each figure is the median of ``repeats`` timed calls, and the dense rate is measured
between the model timings (median as well) so both see the same load. ``clock="cpu"`` times with
the process's CPU time instead of the wall clock: with one thread it leaves out the time other
programs hold the core, which makes the fraction reproducible on a busy machine (memory and
cache contention remain).
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from pathlib import Path

import torch
from torch.utils.flop_counter import FlopCounterMode

from wearnav.models.registry import build, get, n_parameters

DEVICES = 3
WINDOW = 100
IMU_CHANNELS = 6


CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def _median_seconds(fn: Callable[[], object], repeats: int, warmup: int = 2,
                    min_time: float = 0.0, clock: str = "wall") -> float:
    """Median time of ``fn``; a call shorter than ``min_time`` is repeated inside one sample."""
    now = CLOCKS[clock]
    for _ in range(warmup):
        fn()
    inner = 1
    if min_time > 0:
        t0 = now()
        fn()
        inner = max(1, int(min_time / max(now() - t0, 1e-6)))
    samples = []
    for _ in range(repeats):
        t0 = now()
        for _ in range(inner):
            fn()
        samples.append((now() - t0) / inner)
    return max(statistics.median(samples), 1e-9)


@contextmanager
def _threads(n: int | None):
    old = torch.get_num_threads()
    torch.set_num_threads(n or old)
    try:
        yield
    finally:
        torch.set_num_threads(old)


def dense_gflops(n: int = 2048, repeats: int = 5, clock: str = "wall") -> float:
    """Measured dense fp32 matmul rate of this CPU in GFLOP/s (2·n³ FLOPs per n×n product)."""
    a, b = torch.randn(n, n), torch.randn(n, n)
    with torch.inference_mode():
        dt = _median_seconds(lambda: a @ b, repeats, warmup=1, clock=clock)
    return 2 * n**3 / dt / 1e9


def window_batch(batch: int, n_devices: int = DEVICES, window: int = WINDOW,
                 seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """Random world-frame windows with every device present (the shapes, not the values, matter)."""
    g = torch.Generator().manual_seed(seed)
    return torch.randn(batch, n_devices, window, IMU_CHANNELS, generator=g), torch.ones(batch, n_devices)


def flops_per_window(model: torch.nn.Module, n_devices: int = DEVICES, window: int = WINDOW) -> int:
    """FLOPs of one forward pass at batch 1 (eval mode), as FlopCounterMode counts them."""
    x, mask = window_batch(1, n_devices, window)
    model.eval()
    with torch.inference_mode(), FlopCounterMode(display=False) as counter:
        model(x, mask)
    return int(counter.get_total_flops())


def windows_per_second(model: torch.nn.Module, batch: int, repeats: int = 7,
                       n_devices: int = DEVICES, window: int = WINDOW, clock: str = "wall") -> float:
    """Inference throughput at a batch size: eval mode, inference_mode, median of repeats."""
    x, mask = window_batch(batch, n_devices, window)
    model.eval()
    with torch.inference_mode():
        dt = _median_seconds(lambda: model(x, mask), repeats, warmup=3, min_time=0.02, clock=clock)
    return batch / dt


def train_step_seconds(model: torch.nn.Module, batch: int = 128, repeats: int = 5,
                       n_devices: int = DEVICES, window: int = WINDOW, clock: str = "wall") -> float:
    """Seconds of one Adam step on ``model.loss`` (forward, backward, update) at a batch size:
    the model's share of a training epoch, without the data path. Works on a copy, so the
    model's weights and statistics are left as they were."""
    import copy

    model = copy.deepcopy(model).train()
    x, mask = window_batch(batch, n_devices, window)
    b = {"x": x, "mask": mask, "vel": torch.randn(batch, 2, generator=torch.Generator().manual_seed(1))}
    opt = torch.optim.Adam(model.parameters(), lr=1e-4)

    def step():
        opt.zero_grad(set_to_none=True)
        model.loss(b)[0].backward()
        opt.step()

    return _median_seconds(step, repeats, warmup=2, clock=clock)


def measure(model: torch.nn.Module | str, name: str | None = None, batches: Sequence[int] = (1, 256),
            repeats: int = 7, n_devices: int = DEVICES, window: int = WINDOW, threads: int | None = None,
            clock: str = "wall", train_batch: int | None = 128, **build_kw) -> dict:
    """One row of the efficiency table for a model (an instance or a registered name), with
    ``threads`` intra-op threads (default: torch's current setting); ``train_batch`` None skips
    the training-step timing."""
    if clock not in CLOCKS:
        raise ValueError(f"clock must be one of {sorted(CLOCKS)}, got {clock!r}")
    with _threads(threads):
        return _measure(model, name, batches, repeats, n_devices, window, clock, train_batch, build_kw)


def _measure(model, name, batches, repeats, n_devices, window, clock, train_batch, build_kw) -> dict:
    if isinstance(model, str):
        name = name or model
        if get(model).task != "odometry":
            raise ValueError(f"{model!r} is not an odometry model")
        model = build(model, n_devices=n_devices, window=window, **build_kw)
    name = name or type(model).__name__
    flops = flops_per_window(model, n_devices, window)
    row: dict = {"model": name, "params": n_parameters(model), "mflops_per_window": flops / 1e6}
    dense = []
    for b in batches:
        dense.append(dense_gflops(clock=clock))
        row[f"win_per_s_b{b}"] = windows_per_second(model, b, repeats, n_devices, window, clock)
    dense.append(dense_gflops(clock=clock))
    row["dense_gflops"] = statistics.median(dense)
    for b in batches:
        row[f"fraction_b{b}"] = flops * row[f"win_per_s_b{b}"] / (row["dense_gflops"] * 1e9)
    if train_batch and getattr(model, "learned", True) and any(p.requires_grad for p in model.parameters()):
        row[f"train_step_s_b{train_batch}"] = train_step_seconds(model, train_batch, max(3, repeats // 2),
                                                               n_devices, window, clock)
    row["threads"] = torch.get_num_threads()
    row["clock"] = clock
    return row


def table(models: Sequence[str], **kw):
    """Rows for several registered models as a pandas DataFrame."""
    import pandas as pd

    return pd.DataFrame([measure(m, **kw) for m in models])


def write_report(rows, out, odometry_suite=None) -> "Path":
    """results.md + results.json in ``out``: the efficiency table (Table VI analogue), with training
    seconds per epoch taken from the run folders of an odometry suite where given."""
    import platform

    import pandas as pd

    from wearnav import runs
    from wearnav.fileio import write_text_atomic
    from wearnav.provenance import provenance
    from wearnav.textio import read_json

    out = Path(out)
    df = pd.DataFrame(rows)
    if odometry_suite is not None:
        per_epoch = {}
        for tj in Path(odometry_suite).glob("*/training.json"):
            rec = read_json(tj)
            if rec.get("learned"):
                per_epoch[runs.read_config(tj.parent)["config"]["train"]["model"]] = rec.get("s_per_epoch")
        df["train_s_per_epoch"] = df["model"].map(per_epoch)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(df.to_json(orient="records", indent=1), out / "results.json")
    p = provenance()
    cpu = platform.processor() or platform.machine()
    lines = ["# Efficiency (Table VI analogue)", "",
             f"Generated by `wearnav bench efficiency` ({p['created']}, wearnav {p['wearnav']} {p['commit']}) on "
             f"this machine: {cpu}, {os.cpu_count()} CPUs, torch {torch.__version__}, "
             f"{int(df['threads'].iloc[0])} thread(s), {df['clock'].iloc[0]} clock.", "",
             "FLOPs per window: one forward pass on one window (3 devices × 100 samples × 6 channels), "
             "`torch.utils.flop_counter` (a multiply-add = 2 FLOPs). Windows/s: inference, median of repeats. "
             "Fraction = FLOPs/window × windows/s ÷ the dense fp32 matmul rate measured in the same run "
             "(the FLOP-bound limit). Train step: one Adam step at batch 128. "
             + ("Train s/epoch: measured by the odometry suite's runs. " if odometry_suite else "")
             + "The machine is shared: timings are medians and vary with load.", "",
             df.drop(columns=["threads", "clock"]).to_markdown(index=False, floatfmt=".3g"), ""]
    return write_text_atomic("\n".join(lines), out / "results.md")
