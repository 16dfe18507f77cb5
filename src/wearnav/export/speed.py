"""CPU inference speed of one odometry model in PyTorch, ONNX Runtime and TorchScript (issue 18 §4).

The model is built with random weights (speed does not depend on them) at the efficiency
benchmark's shapes (:mod:`wearnav.bench.efficiency`: 3 devices × 100 samples × 6 channels, every
device present), exported to both formats in a temporary folder (:func:`wearnav.export.write.
export_model`, parity-checked), and each runtime is timed by the benchmark's
:func:`~wearnav.bench.efficiency.time_call` at each batch size with ``threads`` threads (torch's
intra-op threads; ONNX Runtime's intra-op threads, one inter-op). PyTorch runs the model as
``wearnav track`` does (eval mode, ``torch.inference_mode``; Suite-IN++ with its fused oneDNN
kernels); the exported files run the traced graph, which ``pytorch-traced-graph`` also times in
eager PyTorch (for Suite-IN++: no fused kernel, no chunking of the batch).

    PYTHONPATH=src python -m wearnav.export.speed [--model suitein++] [--clock cpu]
"""

from __future__ import annotations

import argparse
import tempfile
from collections.abc import Sequence
from functools import partial
from pathlib import Path

import pandas as pd
import torch

from wearnav.bench.efficiency import CLOCKS, DEVICES, MIN_RUN_TIME_S, WINDOW, time_call, torch_threads, window_batch
from wearnav.export.header import FORMATS
from wearnav.export.runtime import load_file
from wearnav.export.write import export_model, make_header
from wearnav.models.registry import build, n_parameters
from wearnav.train.odometry import TrainConfig

RUNTIMES = {"onnx": "onnxruntime", "torchscript": "torchscript"}  # format → the runtime that runs it


def export_speed(
    model: str = "suitein++",
    batches: Sequence[int] = (1, 256),
    threads: int = 1,
    min_run_time_s: float = MIN_RUN_TIME_S,
    clock: str = "wall",
    **model_args,
) -> list[dict]:
    """One row per (runtime, batch): ``runtime`` (pytorch; pytorch-traced-graph, eager PyTorch on
    the module the exporters trace, :meth:`~wearnav.models.base.OdometryModel.for_export`;
    onnxruntime; torchscript), ``batch``,
    ``win_per_s`` (median) and ``win_per_s_iqr`` (windows/s), ``params``, ``threads``, ``clock``;
    plus ``max_abs_diff`` (m/s) of the export's parity check."""
    if clock not in CLOCKS:
        raise ValueError(f"clock must be one of {sorted(CLOCKS)}, got {clock!r}")
    with torch_threads(threads):
        torch.manual_seed(0)
        net = build(model, n_devices=DEVICES, window=WINDOW, **model_args).eval()
        header = make_header("odometry", TrainConfig(model=model, data="", window=WINDOW, model_args=model_args))
        with tempfile.TemporaryDirectory() as tmp:
            runners = {"pytorch": net, "pytorch-traced-graph": net.for_export()}  # type: ignore[operator]  # an OdometryModel's
            diffs = {"pytorch": 0.0, "pytorch-traced-graph": 0.0}
            for fmt, suffix in FORMATS.items():
                written = export_model(net, header, fmt, Path(tmp) / f"model{suffix}")
                runners[RUNTIMES[fmt]] = load_file(written["path"], threads=threads)
                diffs[RUNTIMES[fmt]] = written["max_abs_diff"]
            rows = []
            for b in batches:
                x, mask = window_batch(b)
                for name, run in runners.items():
                    with torch.inference_mode():
                        rate, iqr = time_call(partial(run, x, mask), min_run_time_s, clock).rate(b)
                    rows.append(
                        {
                            "runtime": name,
                            "batch": b,
                            "win_per_s": rate,
                            "win_per_s_iqr": iqr,
                            "max_abs_diff": diffs[name],
                            "params": n_parameters(net),
                            "threads": threads,
                            "clock": clock,
                        }
                    )
    return rows


def speed_table(rows: list[dict]) -> str:
    """Markdown: one row per runtime, windows/s (median ± IQR) per batch size."""
    df = pd.DataFrame(rows)
    cells = df.assign(cell=[f"{r:,.0f} ± {q:,.0f}" for r, q in zip(df["win_per_s"], df["win_per_s_iqr"])])
    table = cells.pivot(index="runtime", columns="batch", values="cell").reindex(list(dict.fromkeys(df["runtime"])))
    table.columns = [f"batch {b} (windows/s)" for b in table.columns]
    return table.to_markdown()


def main(argv: Sequence[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="suitein++")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--clock", choices=sorted(CLOCKS), default="wall")
    p.add_argument("--min-run-time", type=float, default=1.0, help="seconds per timing")
    a = p.parse_args(argv)
    rows = export_speed(a.model, threads=a.threads, clock=a.clock, min_run_time_s=a.min_run_time)
    print(
        f"{a.model}: {rows[0]['params'] / 1e3:.1f} K parameters, {a.threads} thread(s), {a.clock} clock, "
        f"torch {torch.__version__}"
    )
    print(speed_table(rows))


if __name__ == "__main__":
    main()
