"""Figures and the datasets page. PNGs are read back and checked for size and content."""

from __future__ import annotations

import os
import re
import stat

import matplotlib.colors as mcolors
import matplotlib.image as mpimg
import numpy as np
import pytest
from matplotlib import colormaps

from synthetic import synthetic_recording
from wearnav.dataset import Dataset, write_dataset
from wearnav.errors import ValidationError, WearnavError
from wearnav.importers.sensorlogger_export import write_export
from wearnav.recording import DeviceStream, Fixes, Recording, Trajectory
from wearnav.report import (
    ACC_COLOR,
    FIX_COLOR,
    GYRO_COLOR,
    dataset_stats,
    decimate_minmax,
    plot_recording,
    plot_trajectories,
    stats_markdown,
    write_datasets_report,
)


def _png(path):
    assert path.exists() and path.stat().st_size > 10_000
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[2] in (3, 4)
    return img[..., :3]


def _pixels(img, color, min_alpha=0.5) -> int:
    """How many pixels show ``color`` drawn over white with opacity >= min_alpha.

    Antialiased lines are mostly blends p = a*c + (1-a)*white: estimate a from the channel that
    tells the colour from white best, and count pixels that this blend reproduces."""
    c = np.array(mcolors.to_rgb(color))
    k = int(np.argmax(1 - c))
    a = (1 - img[..., k]) / (1 - c[k])
    blend = a[..., None] * c + (1 - a[..., None])
    return int(np.sum((np.abs(img - blend).max(axis=-1) < 0.04) & (a >= min_alpha)))


@pytest.fixture(scope="module")
def full() -> Recording:
    return synthetic_recording(duration=40.0, seed=1)


def _bare(full: Recording) -> Recording:
    s = full.devices["phone"]
    return Recording("bare", {"phone": DeviceStream(s.t, s.acc)})


def test_plot_recording_with_everything(full, tmp_path):
    out = plot_recording(full, tmp_path / "fig" / "full.png")
    img = _png(out)
    h, w, _ = img.shape
    assert w == 1760 and 900 < h < 1300  # 16 in at 110 dpi; three devices and label lanes
    assert _pixels(img, ACC_COLOR) > 10_000  # three |acc| lines
    assert _pixels(img, GYRO_COLOR) > 10_000  # three |gyro| lines
    assert _pixels(img, FIX_COLOR) > 100  # fixes and their accuracy circles
    assert _pixels(img, "tab:green") > 30  # start marker
    # label lanes: one colour per value (4 values in 2 kinds), none of them a signal colour
    dark2 = colormaps["Dark2"].colors
    assert all(_pixels(img, c) > 500 for c in dark2[:4])
    assert not any(p.name.startswith(".") for p in out.parent.iterdir())  # no temporary left
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~umask  # not mkstemp's 0600


def test_plot_recording_without_truth_fixes_labels_gyro(full, tmp_path):
    big = _png(plot_recording(full, tmp_path / "full.png"))
    img = _png(plot_recording(_bare(full), tmp_path / "bare.png"))
    assert img.shape[1] == 1760 and img.shape[0] < 0.6 * big.shape[0]
    assert _pixels(img, ACC_COLOR) > 10_000
    assert _pixels(img, FIX_COLOR) == 0
    # no gyro line, only the "no gyroscope" note in that colour
    assert 0 < _pixels(img, GYRO_COLOR) < 0.1 * _pixels(big, GYRO_COLOR)


def test_not_worn_spans_are_shaded(full, tmp_path):
    e = full.devices["earbuds"]
    assert not e.worn.all()
    always_worn = Recording("w", {**full.devices, "earbuds": DeviceStream(e.t, e.acc, e.gyro, e.quat)})
    counts = []
    for rec in (Recording("nw", dict(full.devices)), always_worn):
        img = _png(plot_recording(rec, tmp_path / f"{rec.name}.png"))
        grey = (np.ptp(img, axis=-1) < 0.02) & (img.mean(-1) > 0.75) & (img.mean(-1) < 0.9)
        counts.append(int(grey.sum()))
    assert counts[0] > 1.4 * counts[1]


# The truth is drawn in black like the text; tests recolour it to see it alone.
TRUTH_SEEN = "#ff00ff"


@pytest.mark.parametrize("what", ["truth_only", "fixes_only", "sparse_waypoints"])
def test_plot_recording_partial(full, tmp_path, monkeypatch, what):
    monkeypatch.setattr("wearnav.report.plots.TRUTH_COLOR", TRUTH_SEEN)
    t = np.arange(0.0, 40.0, 10.0)
    rec = Recording(
        what,
        dict(full.devices),
        truth={
            "truth_only": full.truth,
            "fixes_only": None,
            "sparse_waypoints": Trajectory(t, np.stack([t, t**1.2], 1), floor=[0, 0, 1, 1]),
        }[what],
        fixes=full.fixes if what == "fixes_only" else None,
        meta={"subject": "u1"},
    )
    img = _png(plot_recording(rec, tmp_path / f"{what}.png"))
    assert (_pixels(img, FIX_COLOR) > 100) == (what == "fixes_only")
    assert (_pixels(img, TRUTH_SEEN) > 300) == (what != "fixes_only")  # dense line or waypoints


def test_decimation_keeps_extremes_and_breaks_gaps():
    t = np.arange(0, 1000, 0.01)
    t = t[(t < 400) | (t > 500)]
    y = np.sin(t)
    y[12345] = 50.0
    tt, yy = decimate_minmax(t, y, max_points=2000)
    assert len(tt) <= 2100
    assert np.nanmax(yy) == 50.0 and np.nanmin(yy) == pytest.approx(-1.0, abs=1e-3)
    # exactly one NaN break, inside the gap
    nan = np.flatnonzero(np.isnan(tt))
    assert len(nan) == 1 and tt[nan[0] - 1] < 400 and tt[nan[0] + 1] > 500
    short_t, short_y = decimate_minmax(t[:100], y[:100])
    np.testing.assert_array_equal(short_y, y[:100])


def test_plot_ecdf_draws_the_metrics_ecdf_as_steps_from_0_to_1():
    """plot_ecdf: one step line from (min, 0) to (max, 1), each step rising at a value by its
    share of the sample (a tie: twice); a long sample is thinned to about max_points steps but
    keeps its first and last."""
    from matplotlib.figure import Figure

    from wearnav.report.plots import plot_ecdf

    ax = Figure().add_subplot()
    plot_ecdf(ax, [3.0, 1.0, 2.0, 2.0], label="x")
    line = ax.get_lines()[0]
    assert line.get_drawstyle() == "steps-post" and line.get_label() == "x"
    np.testing.assert_allclose(line.get_xdata(), [1, 1, 2, 3])
    np.testing.assert_allclose(line.get_ydata(), [0, 0.25, 0.75, 1.0])
    plot_ecdf(ax, np.arange(10_000.0), max_points=100)
    x, y = ax.get_lines()[1].get_xdata(), ax.get_lines()[1].get_ydata()
    assert 90 <= x.size <= 110 and x[-1] == 9999 and y[-1] == 1.0 and y[0] == 0.0 and np.all(np.diff(y) >= 0)


def _dataset(tmp_path, n):
    recs = [
        (synthetic_recording(name=f"r{i}", seed=i, duration=20.0 + 5 * i, devices=("phone",)), "") for i in range(n)
    ]
    recs.append((Recording("no_truth", {"phone": recs[0][0].devices["phone"]}), ""))
    return write_dataset(tmp_path / "ds", recs)


def test_plot_trajectories_grid(tmp_path, monkeypatch):
    monkeypatch.setattr("wearnav.report.plots.TRUTH_COLOR", TRUTH_SEEN)
    ds = _dataset(tmp_path, 6)
    img = _png(plot_trajectories(ds, tmp_path / "grid.png"))  # 7 maps: 4 x 2
    few = _png(plot_trajectories(ds, tmp_path / "few.png", max_recordings=3))  # 3 x 1
    assert img.shape[1] > few.shape[1] and img.shape[0] > 1.7 * few.shape[0]
    assert _pixels(img, "tab:green") > 6 * _pixels(few, "tab:green") / 3 * 0.8
    assert _pixels(img, TRUTH_SEEN) > 6 * 300 and _pixels(few, TRUTH_SEEN) > 3 * 300  # 6 / 3 truths
    empty = write_dataset(tmp_path / "empty", [])
    with pytest.raises(ValidationError, match="empty"):
        plot_trajectories(empty, tmp_path / "none.png")


# ---- dataset statistics ---------------------------------------------------------------------


def _stream(t, quat=False, gyro=True):
    n = len(t)
    return DeviceStream(
        t=t,
        acc=np.tile([0.0, 0.0, 9.81], (n, 1)),
        gyro=np.zeros((n, 3)) if gyro else None,
        quat=np.tile([1.0, 0, 0, 0], (n, 1)) if quat else None,
    )


@pytest.fixture
def stats_ds(tmp_path):
    """Hand-made: phone exactly 100 Hz; watch intervals alternating 19 / 21 ms (IQR 2 ms);
    fixes = truth + (3, 4) m (error 5 m) except at one truth time with no fix within 2 s."""
    recs = []
    for i in range(2):
        t_phone = np.arange(1000) * 0.01
        t_watch = np.cumsum(np.tile([0.019, 0.021], 250))
        t_truth = np.array([1.0, 2.0, 3.0, 9.0])
        p_truth = np.stack([t_truth, 2 * t_truth], 1)
        t_fix = np.arange(0.0, 5.0, 0.5)
        fixes = Fixes(t_fix, np.stack([t_fix, 2 * t_fix], 1) + [3.0, 4.0], np.full(len(t_fix), 5.0))
        recs.append(
            (
                Recording(
                    f"rec{i}",
                    {"phone": _stream(t_phone, quat=(i == 0)), "watch": _stream(t_watch, gyro=False)},
                    truth=Trajectory(t_truth, p_truth),
                    fixes=fixes,
                    labels=[(0, 4, "activity", "walk"), (4, 9, "activity", "sit"), (2, 2, "step", "step")],
                    meta={"subject": "u7"},
                ),
                "",
            )
        )
    return write_dataset(tmp_path / "stats", recs)


def test_dataset_stats(stats_ds):
    s = dataset_stats(stats_ds)
    assert s["recordings"] == 2 and s["subjects"] == 1
    assert s["duration_s"] == pytest.approx(2 * 10.0)  # phone from 0 s, watch to 10 s
    ph, wa = s["devices"]["phone"], s["devices"]["watch"]
    assert ph["samples"] == 2000 and ph["rate_hz"] == pytest.approx(100.0, rel=1e-4)
    assert ph["jitter_iqr_ms"] == pytest.approx(0.0, abs=1e-3)
    assert ph["orientation_share"] == pytest.approx(0.5) and ph["gyro_share"] == 1.0
    assert wa["rate_hz"] == pytest.approx(50.0, rel=0.06)
    assert wa["jitter_iqr_ms"] == pytest.approx(2.0, abs=0.01)
    assert wa["gyro_share"] == 0.0 and wa["orientation_share"] == 0.0
    assert s["labels"][("activity", "walk")] == {"intervals": 2, "duration_s": 8.0}
    assert s["labels"][("step", "step")]["intervals"] == 2
    assert s["truth_points"] == 8 and s["fixes"] == 20
    fe = s["fix_error_m"]
    assert fe["points"] == 6 and fe["recordings"] == 2  # t=9 has no fix within 2 s
    assert fe["median"] == pytest.approx(5.0) and fe["p75"] == pytest.approx(5.0)
    md = stats_markdown(s)
    cells = re.sub(r" *\| *", "|", md)  # the tables' cells, whatever their padding
    assert "|2|1|20.0 s|8 in 2 recordings|20|" in cells
    assert "|phone|2|2,000|100.00 Hz|" in cells
    assert "|activity|walk|2|8.0 s|" in cells
    assert "median **5.00 m**, 75th percentile **5.00 m** over 6 points in 2 recordings" in md


def test_write_datasets_report(tmp_path, monkeypatch):
    data = tmp_path / "data"
    write_export(synthetic_recording(duration=30.0, seed=2), data / "sl_exports" / "2023-11-14_22-13-20")
    out, work = tmp_path / "docs" / "datasets.md", tmp_path / "work"
    datasets = {"sl_exports": "sensorlogger", "not_here": "ilc2"}
    with pytest.raises(WearnavError, match="1 dataset.*not_here: not found"):
        write_datasets_report(data, out, work, progress=False, datasets=datasets)
    text = out.read_text()
    assert text.startswith("_Generated by `wearnav datasets-report --data ")
    assert "## sl_exports (`sensorlogger`)" in text and "|earbuds|1|750|25.00 Hz|" in re.sub(r" *\| *", "|", text)
    assert "Not found" in text and "jitter = interquartile range" in text
    assert "![sensorlogger: recording 2023-11-14_22-13-20](img/sensorlogger.png)" in text
    _png(tmp_path / "docs" / "img" / "sensorlogger.png")
    assert Dataset.open(work / "sensorlogger").names == ["2023-11-14_22-13-20"]

    # a second run reuses the imported dataset instead of importing again
    def no_import(*a, **k):
        raise AssertionError("imported again")

    monkeypatch.setattr("wearnav.importers.import_dataset", no_import)
    write_datasets_report(data, out, work, progress=False, datasets={"sl_exports": "sensorlogger"})
    assert "## sl_exports" in out.read_text() and "not_here" not in out.read_text()


def test_walk_table_distance_and_label_noise(tmp_path):
    import numpy as np

    from wearnav.dataset import Dataset, DatasetWriter
    from wearnav.recording import DeviceStream, Fixes, Recording, Trajectory
    from wearnav.report import walk_tables

    t = np.arange(0, 10.001, 0.01)
    truth = Trajectory(t, np.stack([t, np.zeros_like(t)], 1))  # 10 m east at 1 m/s
    tf = np.arange(0, 11.0)
    err = np.stack([0.3 * (np.arange(11) % 2), np.zeros(11)], 1)  # every 1-s label off by 30 cm
    fixes = Fixes(tf, np.stack([tf, np.zeros(11)], 1) + err, np.full(11, 3.0))
    imu = DeviceStream(t=t, acc=np.tile([0, 0, 9.81], (t.size, 1)))
    with DatasetWriter(tmp_path / "d") as w:
        w.add(Recording("a", {"phone": imu}, truth, fixes, meta={"mode": "STW"}))
        w.add(Recording("b", {"phone": imu}, truth, meta={"mode": "DLW"}))
    table = walk_tables(Dataset.open(tmp_path / "d"), ("mode",))["mode"].set_index("mode")
    assert table.loc["STW", "distance_km"] == pytest.approx(0.01)
    assert table.loc["STW", "fix_label_noise_median_cm"] == pytest.approx(30.0)
    assert table.loc["DLW", "fix_label_noise_median_cm"] is None or np.isnan(
        table.loc["DLW", "fix_label_noise_median_cm"]
    )


def _questions(*tags):
    """A registry of one question per suite folder name, for the page's mechanics."""
    from wearnav.bench.questions import Question

    return tuple(Question(f"q-{t}", "Tests", f"Question {t.upper()}?", (t,)) for t in tags)


def _sources(text):
    """The page's sections as (suite, its page's title), in order."""
    return re.findall(r"^> Suite `([^`]+)` \(its page: \*(.*?)\*\)", text, flags=re.M)


def test_results_keep_updates_suite_by_suite(tmp_path):
    """`wearnav results --keep`: sections of suites not given now stay in place; a suite given
    again replaces its own section; a new suite is added in the registry's order."""
    from wearnav.bench.results import collect

    def suite(name, title, body):
        d = tmp_path / name
        d.mkdir(exist_ok=True)
        (d / "results.md").write_text(f"# {title}\n\n{body}\n\n## Detail\n\nx\n")
        return d

    qs = _questions("a", "b", "c", "d")
    out = tmp_path / "docs" / "results.md"
    # bodies no hex commit hash can contain (the page's header holds the current commit's)
    collect([suite("a", "Alpha", "body-a-one"), suite("b", "Beta", "body-b-one")], out, questions=qs)
    collect([suite("b", "Beta", "body-b-two"), suite("c", "Gamma", "body-c-one")], out, keep=True, questions=qs)
    text = out.read_text()
    assert [l for l in text.splitlines() if "<!-- suite:" in l] == [
        "## Question A? <!-- suite: a -->",
        "## Question B? <!-- suite: b -->",
        "## Question C? <!-- suite: c -->",
    ]
    assert _sources(text) == [("a", "Alpha"), ("b", "Beta"), ("c", "Gamma")]
    assert "body-a-one" in text and "body-b-two" in text and "body-b-one" not in text and "body-c-one" in text
    assert text.count("### Detail") == 3
    collect([suite("c", "Gamma", "body-c-two")], out, questions=qs)  # without keep the page holds only what is given
    assert _sources(out.read_text()) == [("c", "Gamma")]
    # two suites may share a title: their folders tell them apart
    collect([suite("d", "Gamma", "body-d-one")], out, keep=True, questions=qs)
    assert "body-c-two" in out.read_text() and "body-d-one" in out.read_text()
    # a suite retitled since replaces its own section in place (no stale copy under the old title)
    collect([suite("c", "Gamma, retitled", "body-c-three")], out, keep=True, questions=qs)
    text = out.read_text()
    assert _sources(text) == [("c", "Gamma, retitled"), ("d", "Gamma")]
    assert "body-c-two" not in text and "body-c-three" in text


def test_results_page_starts_with_a_headline_and_a_glossary_and_shows_no_absolute_path(tmp_path):
    """`wearnav results`: one screen per section (numbers, paper, seeds, command, commit, date,
    machine), the glossary of the metrics shown, the writer's absolute paths made relative; and
    `--keep` alone rebuilds the page from its own sections (no run folders needed)."""
    import subprocess
    import sys
    from pathlib import Path

    suite = tmp_path / "odometry"  # a suite folder the registry knows (docs/results.md's Tables III-VI)
    suite.mkdir()
    (suite / "results.md").write_text(
        "# Odometry comparison\n\nGenerated by `wearnav bench odometry` from 2 run folders "
        "(2026-11-25T10:00:00+00:00, wearnav 0.1.0 abc1234).\n\nData: `/work/main/runs/data/default` "
        "(seed 0). Machine: x86_64, 2 CPUs, torch 2.13.0+cpu.\n\n## Split `test`\n\n"
        "| model | ATE | RTE | sequences |\n|:--|--:|--:|--:|\n| suitein++ | 3.87 | 3.03 | 10 |\n"
        "| pdr | 5.82 | 5.85 | 10 |\n"
    )
    out = tmp_path / "docs" / "results.md"
    env = {"PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src"), "PATH": "/usr/bin:/bin"}
    res = subprocess.run(
        [sys.executable, "-m", "wearnav", "results", str(suite), "--out", str(out)],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    text = out.read_text()
    heads = [l for l in text.splitlines() if l.startswith("## ")]
    assert heads[:2] == ["## At a glance", "## Glossary"]
    assert (
        "| **The simulator (Suite-IN++ Tables III–VI)** | [On the simulator, how does Suite-IN++ compare with "
        "its baselines (Tables III–VI)?](#sim-tables) | suitein++ 3.87, pdr 5.82 (ATE) | not on its page | seed 0 | "
        "abc1234 | 2026-11-25 |"
    ) in text
    assert (
        "> Suite `odometry` (its page: *Odometry comparison*) · produced by `wearnav bench odometry` · "
        "commit abc1234 · 2026-11-25 · machine: x86_64, 2 CPUs, torch 2.13.0+cpu"
    ) in text
    assert "- **ATE** (m): absolute trajectory error" in text and "- **RTE** (m):" in text
    assert "macro-F1" not in text.split("## Glossary")[1].split("\n## ")[0]  # only the metrics the page shows
    assert "/work/" not in text and "`runs/data/default`" not in text and "`data/default`" in text
    res = subprocess.run(
        [sys.executable, "-m", "wearnav", "results", "--keep", "--out", str(out)],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    again = out.read_text()
    assert again.count("## At a glance") == 1 and again.count("## Glossary") == 1
    assert again.split("\n", 3)[3] == text.split("\n", 3)[3]  # the same page but for its date line


def test_results_drop_removes_a_superseded_suite_and_missing_figures_are_refused(tmp_path):
    from wearnav.bench.results import collect
    from wearnav.errors import MissingFileError

    def suite(name, body):
        d = tmp_path / name
        d.mkdir(exist_ok=True)
        (d / "results.md").write_text(f"# {name.upper()}\n\n{body}\n")
        return d

    qs = _questions("a", "b", "c", "d")
    out = tmp_path / "docs" / "results.md"
    collect([suite("a", "a1"), suite("b", "b1")], out, questions=qs)
    collect([suite("c", "c1")], out, keep=True, drop=("a=superseded by c",), questions=qs)
    assert _sources(out.read_text()) == [("b", "B"), ("c", "C")]
    history = (tmp_path / "docs" / "history.md").read_text()
    assert "| A | `a` |" in history and "superseded by c |" in history  # one line, why it left
    with pytest.raises(MissingFileError, match="summary.png"):
        collect([suite("d", "![summary](summary.png)")], out, keep=True, questions=qs)
    assert "suite: d" not in out.read_text()  # nothing written
    # a section from before sections were marked is dropped by its heading text
    out.write_text(out.read_text() + "\n## Old comparison\n\nold numbers\n")
    collect([], out, keep=True, drop=("Old comparison",), questions=qs)
    assert "old numbers" not in out.read_text() and ("c", "C") in _sources(out.read_text())
