"""The demo: the main job on built-in data (``wearnav demo`` / ``make demo``).

Simulate a preset, train and compare odometry models on it (Suite-IN++, RoNIN, PDR by default)
through the odometry suite, and write its page with trajectory plots. Runs resume: a second call
reuses the simulated data and the finished runs.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pandas as pd

from wearnav.bench.odometry import METRICS_EXPLAINED, comparison_table, run_suite, suite_configs, write_suite_report
from wearnav.dataset import Dataset
from wearnav.report.plots import plot_trajectories
from wearnav.simulate import simulate_dataset

SPLITS = ("test", "cross_subject")
TITLE = "wearnav demo: odometry on simulated walking"
# The console's columns of each split's comparison table (metres, epochs, seconds).
CONSOLE_COLUMNS = ("model", "ATE", "RTE", "STW ATE", "DRW ATE", "epochs", "train s/epoch", "beats standing still")


def run_demo(
    out: Path,
    models: tuple[str, ...],
    epochs: int,
    seed: int = 0,
    minutes: float | None = None,
    preset: str = "small",
    progress: bool = True,
    echo: Callable[[str], None] = print,
) -> tuple[Path, dict[str, pd.DataFrame]]:
    """Simulate ``preset`` into ``out/data`` (or reuse it), train and evaluate ``models`` (at most
    ``epochs`` each; ``minutes``: an optional time cap) into ``out/runs`` and write ``out/results.md``. Returns the page and, per split, the comparison
    table's console columns."""
    data_dir = out / "data"
    if (data_dir / "manifest.csv").exists():
        ds = Dataset.open(data_dir)
        echo(f"using existing simulated dataset {data_dir}")
    else:
        ds = simulate_dataset(preset, data_dir, seed=seed, progress=progress)
    s = ds.summary()
    echo(f"simulated {s['recordings']} recordings, {s['total_duration_h']:.2f} h; splits {s['splits']}")
    plot_trajectories(ds, out / "truth_trajectories.png")
    # The default "fast" recipe (lr 1e-3, warm-up, cosine decay over the second half), not the
    # papers' 1e-4: a few minutes of training instead of ~100 epochs (wearnav.train.odometry.RECIPES).
    configs = suite_configs(data_dir, models, epochs=epochs, max_minutes=minutes, seed=seed, patience=5)
    folders = run_suite(configs, out / "runs", splits=SPLITS, progress=progress, echo=echo)
    budget = f"{epochs} epochs" + (f" or {minutes:g} min, whichever ends first," if minutes else "")
    note = (
        f"Built-in data: simulator preset `{preset}` (seed {seed}). Demo budget: at most {budget} of "
        "training per learned model (early stopping after 5 epochs without improvement) with the `fast` recipe "
        "(Adam lr 1e-3, one epoch of warm-up, cosine decay over the second half; the papers train ~100 epochs "
        "at 1e-4), far below the papers' training. Test walks are scored in the honest frame: one constant "
        "yaw from the first 10 s of truth, the heading drift after that left in; see `wearnav bench odometry` for "
        "the full comparison. The budget is counted in epochs, not minutes, so the same seed gives the same "
        "figures on a fast or a busy machine (up to floating-point differences between CPUs).\n\n" + METRICS_EXPLAINED
    )
    page = write_suite_report(folders, out, TITLE, splits=SPLITS, note=note, command=f"wearnav demo --out {out}")
    tables = {}
    for split in SPLITS:
        table = comparison_table(folders, split)
        tables[split] = table[[c for c in CONSOLE_COLUMNS if c in table]]
    return page, tables
