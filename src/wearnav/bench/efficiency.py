"""Model efficiency (paper 000, Table VI analogue) for any registered odometry model.

For one model: trainable parameters; FLOPs of one forward pass on one window
(:class:`torch.utils.flop_counter.FlopCounterMode`, which counts a multiply-add as 2 FLOPs and
counts only matrix products and convolutions); inference windows/s on this CPU at batch 1 and
256 (eval mode, ``torch.inference_mode``); and, in the same run, the CPU's dense fp32 rate (a
large square matmul), so that

    fraction of the FLOP-bound limit = FLOPs/window × windows/s ÷ dense FLOP/s.

A fraction near 1 means the model runs as fast as its arithmetic allows; small temporal
convolutions are usually memory-bound and sit far below. On a shared machine every timing is
noisy. Every timing is :func:`time_call`: ``torch.utils.benchmark.Timer.blocked_autorange``
(a warm-up that also picks the block size, calls per timed block, so the clock's own overhead is
negligible; then blocks for at least ``min_run_time_s``), reported as the median and the
interquartile range over blocks. The dense rate is measured between the model timings (their
median) so both see the same load. ``clock="cpu"`` times with
the process's CPU time instead of the wall clock: with one thread it leaves out the time other
programs hold the core, which makes the fraction reproducible on a busy machine (memory and
cache contention remain).

Decision: docs/decisions/0012-table-iii-models-at-table-vi-size.md.
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np
import torch
from torch.utils import benchmark
from torch.utils.flop_counter import FlopCounterMode

from wearnav.core.fileio import write_text_atomic
from wearnav.core.textio import read_json
from wearnav.models.base import OdometryModel
from wearnav.models.registry import build, get, n_parameters

DEVICES = 3
WINDOW = 100
IMU_CHANNELS = 6


CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}  # what a timing counts (module doc)
MIN_RUN_TIME_S = 0.2  # blocked_autorange's default: timed blocks per measurement, in seconds


@dataclass(frozen=True)
class Timing:
    """Seconds per call of one timed function: median and quartiles over timed blocks."""

    median_s: float
    q25_s: float
    q75_s: float
    blocks: int  # timed blocks (replicates)
    calls_per_block: int

    @property
    def iqr_s(self) -> float:
        return self.q75_s - self.q25_s

    def rate(self, per_call: float = 1.0) -> tuple[float, float]:
        """(median, IQR) of ``per_call`` ÷ seconds per call, e.g. windows/s with ``per_call`` =
        the batch size; the IQR from the quartiles of the time (a rate's quartiles are the
        time's, reciprocated)."""
        return per_call / self.median_s, per_call / self.q25_s - per_call / self.q75_s


def time_call(
    fn: Callable[[], object], min_run_time_s: float = MIN_RUN_TIME_S, clock: str = "wall", device: str = "cpu"
) -> Timing:
    """Time ``fn`` with ``torch.utils.benchmark.Timer.blocked_autorange`` on the current number of
    torch threads (Timer's default would be one), counting ``clock`` (:data:`CLOCKS`). On a CUDA
    ``device`` each clock reading waits for the GPU's queued work first (the wall clock only: the
    process's CPU time says nothing of a GPU's)."""
    read = CLOCKS[clock]
    if torch.device(device).type == "cuda":
        if clock != "wall":
            raise ValueError("a GPU is timed with the wall clock")

        def read() -> float:
            torch.cuda.synchronize(device)
            return time.perf_counter()

    timer = benchmark.Timer(stmt="fn()", globals={"fn": fn}, num_threads=torch.get_num_threads(), timer=read)
    m = timer.blocked_autorange(min_run_time=min_run_time_s)
    q25, q50, q75 = (max(float(v), 1e-12) for v in np.percentile(m.times, [25, 50, 75]))
    return Timing(q50, q25, q75, len(m.times), int(m.number_per_run))


@contextmanager
def torch_threads(n: int | None):
    """Run the block with ``n`` torch intra-op threads (None: the current setting), then restore."""
    old = torch.get_num_threads()
    torch.set_num_threads(n or old)
    try:
        yield
    finally:
        torch.set_num_threads(old)


def dense_gflops(
    n: int = 2048, min_run_time_s: float = MIN_RUN_TIME_S, clock: str = "wall", device: str = "cpu"
) -> float:
    """Measured dense fp32 matmul rate of this CPU (or ``device``) in GFLOP/s (2·n³ FLOPs per n×n
    product; the median time; on a GPU with torch's default of no TF32, so true fp32 as the models
    run)."""
    a, b = torch.randn(n, n, device=device), torch.randn(n, n, device=device)
    with torch.inference_mode():
        t = time_call(lambda: a @ b, min_run_time_s, clock, device)
    return 2 * n**3 / t.median_s / 1e9


def window_batch(
    batch: int, n_devices: int = DEVICES, window: int = WINDOW, seed: int = 0
) -> tuple[torch.Tensor, torch.Tensor]:
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


def recurrent_macs(module: torch.nn.Module, steps: int, batch: int = 1) -> int:
    """Multiply-accumulates of an ``nn.LSTM`` / ``nn.GRU`` over ``steps`` time steps, counted
    analytically as the paper's counter does: per step, direction and layer 4·(in·h + h·h) for
    an LSTM (four gates), 3·(in·h + h·h) for a GRU; biases and the element-wise gate products
    are left out. A layer above the first reads h·directions inputs; a projection (LSTM
    ``proj_size``) is not supported."""
    if isinstance(module, torch.nn.LSTM):
        gates = 4
        if module.proj_size:
            raise ValueError("recurrent_macs: LSTM proj_size is not supported")
    elif isinstance(module, torch.nn.GRU):
        gates = 3
    else:
        raise TypeError(f"recurrent_macs: not an LSTM or GRU: {type(module).__name__}")
    h, dirs = module.hidden_size, 2 if module.bidirectional else 1
    total, n_in = 0, module.input_size
    for _ in range(module.num_layers):
        total += gates * (n_in * h + h * h) * dirs
        n_in = h * dirs
    return total * steps * batch


def macs_per_window(model: torch.nn.Module, n_devices: int = DEVICES, window: int = WINDOW) -> int:
    """Multiply-accumulates of one forward pass on one window (batch 1, eval mode): the paper's
    "FLOPs" (Table VI counts a multiply-add once). Matrix products and convolutions as
    FlopCounterMode counts them, halved; every ``nn.LSTM`` / ``nn.GRU`` by :func:`recurrent_macs`
    instead (FlopCounterMode counts no LSTM on a CPU, and a GRU only where it is decomposed into
    matrix products), so what the counter saw inside a recurrent layer is taken out."""
    x, mask = window_batch(1, n_devices, window)
    model.eval()
    seen_inside, analytic, start = [0], [0], {}
    with torch.inference_mode(), FlopCounterMode(display=False) as counter:

        def pre(mod, args):
            start[id(mod)] = counter.get_total_flops()

        def post(mod, args, out):
            seen_inside[0] += counter.get_total_flops() - start.pop(id(mod))
            inp = args[0]
            if isinstance(inp, torch.nn.utils.rnn.PackedSequence):
                raise ValueError("macs_per_window: packed sequences are not supported")
            if inp.ndim == 2:  # unbatched (L, in)
                steps, batch = inp.shape[0], 1
            elif mod.batch_first:
                batch, steps = inp.shape[:2]
            else:
                steps, batch = inp.shape[:2]
            analytic[0] += recurrent_macs(mod, steps, batch)

        hooks = []
        for m in model.modules():
            if isinstance(m, (torch.nn.LSTM, torch.nn.GRU)):
                hooks += [m.register_forward_pre_hook(pre), m.register_forward_hook(post)]
        try:
            model(x, mask)
        finally:
            for hk in hooks:
                hk.remove()
    flops = counter.get_total_flops() - seen_inside[0]
    return int(flops // 2 + analytic[0])


def windows_per_second(
    model: torch.nn.Module,
    batch: int,
    min_run_time_s: float = MIN_RUN_TIME_S,
    n_devices: int = DEVICES,
    window: int = WINDOW,
    clock: str = "wall",
    device: str = "cpu",
    graph: bool = False,
) -> tuple[float, float]:
    """Inference throughput at a batch size (eval mode, inference_mode): (median, IQR) windows/s.
    The model must be on ``device``. ``graph``: on a GPU, the forward pass captured once as a CUDA
    graph and replayed (:class:`torch.cuda.CUDAGraph`: one launch instead of one per kernel, what
    batch 1 is bound by), on inputs of a fixed shape, as a live tracker's would be."""
    x, mask = (v.to(device) for v in window_batch(batch, n_devices, window))
    model.eval()
    with torch.inference_mode():
        if not graph:
            t = time_call(lambda: model(x, mask), min_run_time_s, clock, device)
            return t.rate(batch)
        side = torch.cuda.Stream(device)
        side.wait_stream(torch.cuda.current_stream(device))
        with torch.cuda.stream(side):  # warm-up on a side stream, as capture requires
            for _ in range(3):
                model(x, mask)
        torch.cuda.current_stream(device).wait_stream(side)
        g = torch.cuda.CUDAGraph()
        with torch.cuda.graph(g):
            model(x, mask)
        t = time_call(g.replay, min_run_time_s, clock, device)
    return t.rate(batch)


def compiled_windows_per_second(
    model: torch.nn.Module, batch: int, min_run_time_s: float = MIN_RUN_TIME_S, device: str = "cpu"
) -> tuple[float, float]:
    """Windows/s of ``torch.compile(model, mode="reduce-overhead")`` (kernels fused by Inductor and,
    on a GPU, replayed as CUDA graphs) at one batch size, after its compilation (not timed)."""
    x, mask = (v.to(device) for v in window_batch(batch))
    model.eval()
    fast = torch.compile(model, mode="reduce-overhead", dynamic=False)
    with torch.inference_mode():
        for _ in range(3):  # compiles, then records its graphs
            fast(x, mask)
        t = time_call(lambda: fast(x, mask), min_run_time_s, "wall", device)
    return t.rate(batch)


def train_step_seconds(
    model: torch.nn.Module,
    batch: int = 128,
    min_run_time_s: float = MIN_RUN_TIME_S,
    n_devices: int = DEVICES,
    window: int = WINDOW,
    clock: str = "wall",
    device: str = "cpu",
) -> Timing:
    """Seconds of one Adam step on ``model.loss`` (forward, backward, update) at a batch size:
    the model's share of a training epoch, without the data path. Works on a copy, so the
    model's weights and statistics are left as they were."""
    import copy

    model = cast(OdometryModel, copy.deepcopy(model).train())  # an odometry model: loss(batch)
    x, mask = window_batch(batch, n_devices, window)
    vel = torch.randn(batch, 2, generator=torch.Generator().manual_seed(1))
    b = {"x": x.to(device), "mask": mask.to(device), "vel": vel.to(device)}
    opt = torch.optim.Adam(model.parameters(), lr=1e-4)

    def step():
        opt.zero_grad(set_to_none=True)
        model.loss(b)[0].backward()
        opt.step()

    return time_call(step, min_run_time_s, clock, device)


def measure(
    model: torch.nn.Module | str,
    name: str | None = None,
    batches: Sequence[int] = (1, 256),
    min_run_time_s: float = MIN_RUN_TIME_S,
    n_devices: int = DEVICES,
    window: int = WINDOW,
    threads: int | None = None,
    clock: str = "wall",
    train_batch: int | None = 128,
    device: str = "cpu",
    faster_b1: bool = False,
    **build_kw,
) -> dict:
    """One row of the efficiency table for a model (an instance or a registered name), with
    ``threads`` intra-op threads (default: torch's current setting); ``train_batch`` None skips
    the training-step timing. Each timing runs for at least ``min_run_time_s``. ``device``: where
    the model runs (a GPU: ``cuda``); ``faster_b1``: also batch 1 as a CUDA graph (on a GPU) and
    through ``torch.compile`` (each a column, or the first line of its error where it fails)."""
    if clock not in CLOCKS:
        raise ValueError(f"clock must be one of {sorted(CLOCKS)}, got {clock!r}")
    with torch_threads(threads):
        return _measure(
            model, name, batches, min_run_time_s, n_devices, window, clock, train_batch, device, faster_b1, build_kw
        )


def _measure(
    model, name, batches, min_run_time_s, n_devices, window, clock, train_batch, device, faster_b1, build_kw
) -> dict:
    if isinstance(model, str):
        name = name or model
        if get(model).task != "odometry":
            raise ValueError(f"{model!r} is not an odometry model")
        model = build(model, n_devices=n_devices, window=window, **build_kw)
    name = name or type(model).__name__
    flops = flops_per_window(model, n_devices, window)
    row: dict = {
        "model": name,
        "params": n_parameters(model),
        "mflops_per_window": flops / 1e6,
        "mmacs_per_window": macs_per_window(model, n_devices, window) / 1e6,
    }
    model = model.to(device)
    gpu = torch.device(device).type == "cuda"
    dense = []
    for b in batches:
        dense.append(dense_gflops(min_run_time_s=min_run_time_s, clock=clock, device=device))
        row[f"win_per_s_b{b}"], row[f"win_per_s_b{b}_iqr"] = windows_per_second(
            model, b, min_run_time_s, n_devices, window, clock, device
        )
    dense.append(dense_gflops(min_run_time_s=min_run_time_s, clock=clock, device=device))
    row["dense_gflops"] = statistics.median(dense)
    for b in batches:
        row[f"fraction_b{b}"] = flops * row[f"win_per_s_b{b}"] / (row["dense_gflops"] * 1e9)
    if faster_b1:  # the launch-bound batch 1 (a live tracker's one walker), two ways round it
        tries: dict[str, Callable[[], tuple[float, float]]] = {
            "compiled": lambda: compiled_windows_per_second(model, 1, min_run_time_s, device)
        }
        if gpu:
            tries["graph"] = lambda: windows_per_second(
                model, 1, min_run_time_s, n_devices, window, clock, device, True
            )
        for how, run in tries.items():
            try:
                row[f"win_per_s_b1_{how}"], row[f"win_per_s_b1_{how}_iqr"] = run()
            except Exception as exc:  # a model that cannot be captured or compiled: say why, go on
                row[f"win_per_s_b1_{how}"] = f"failed: {(str(exc).splitlines() or [type(exc).__name__])[0][:120]}"
    if train_batch and getattr(model, "learned", True) and any(p.requires_grad for p in model.parameters()):
        t = train_step_seconds(model, train_batch, min_run_time_s, n_devices, window, clock, device)
        row[f"train_step_s_b{train_batch}"], row[f"train_step_s_b{train_batch}_iqr"] = t.median_s, t.iqr_s
    row["device"] = torch.cuda.get_device_name(device) if gpu else "cpu"
    row["threads"] = torch.get_num_threads()
    row["clock"] = clock
    row["min_run_time_s"] = min_run_time_s
    return row


def table(models: Sequence[str], **kw):
    """Rows for several registered models as a pandas DataFrame."""
    import pandas as pd

    return pd.DataFrame([measure(m, **kw) for m in models])


def write_report(rows, out, odometry_suite=None) -> Path:
    """results.md + results.json in ``out``: the efficiency table (Table VI analogue), with training
    seconds per epoch taken from the run folders of an odometry suite where given."""
    import platform

    import pandas as pd

    from wearnav import runs
    from wearnav.core.provenance import provenance

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
    lines = [
        "# Efficiency (Table VI analogue)",
        "",
        f"Generated by `wearnav bench efficiency` ({p['created']}, wearnav {p['wearnav']} {p['commit']}) on "
        f"this machine: {cpu}, {os.cpu_count()} CPUs, torch {torch.__version__}, "
        f"{int(df['threads'].iloc[0])} thread(s), {df['clock'].iloc[0]} clock.",
        "",
        "FLOPs per window: one forward pass on one window (3 devices × 100 samples × 6 channels), "
        "`torch.utils.flop_counter` (a multiply-add = 2 FLOPs; it misses LSTMs). MMACs per window: "
        'multiply-accumulates, the paper\'s "FLOPs (G)" of Table VI, with every LSTM/GRU counted '
        "analytically (4 resp. 3 gates × (in·h + h·h) per step, direction and layer). Timings: "
        "`torch.utils.benchmark.Timer.blocked_autorange` (warm-up, then blocks of calls for at least "
        f"{df['min_run_time_s'].iloc[0]:g} s per timing); each column gives the median over blocks and, in its `_iqr` column, the "
        "interquartile range (75th − 25th percentile). Windows/s: inference, on the `device` column's "
        "processor (a GPU's timings wait for its queued work at every clock reading). "
        + (
            "`_graph`: batch 1 captured once as a CUDA graph and replayed; `_compiled`: batch 1 through "
            '`torch.compile(mode="reduce-overhead")`, compilation not timed. '
            if any(c.endswith(("_graph", "_compiled")) for c in df.columns)
            else ""
        )
        + "Fraction = FLOPs/window × median windows/s ÷ the dense fp32 matmul rate measured in the same run "
        "(the FLOP-bound limit). Train step: one Adam step at batch 128, seconds. "
        + ("Train s/epoch: measured by the odometry suite's runs. " if odometry_suite else "")
        + "The machine is shared: timings vary with load.",
        "",
        df.drop(columns=["threads", "clock", "min_run_time_s"]).to_markdown(index=False, floatfmt=".3g"),
        "",
    ]
    return write_text_atomic("\n".join(lines), out / "results.md")
