"""A newcomer's first hour (issue 22 §3–§4): the commands run as a user runs them, in a subprocess,
checked by exit code and by the words they print."""

from __future__ import annotations

import functools
import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import typer

from wearnav.cli import app

REPO = Path(__file__).resolve().parents[1]


def _env(**extra) -> dict:
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"), OMP_NUM_THREADS="1", **extra)
    env.pop("WEARNAV_DEBUG", None)
    return env


def wearnav(*args, cwd: Path, timeout: float = 120, **env) -> subprocess.CompletedProcess:
    """``wearnav ARGS`` in ``cwd`` with stdout and stderr pipes (not a terminal)."""
    return subprocess.run(
        [sys.executable, "-m", "wearnav", *map(str, args)],
        cwd=cwd,
        env=_env(**env),
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    """`wearnav simulate`'s --help example (``simulate --preset tiny --out data/sim``, the first of the
    cheap examples) run in a work folder, with progress lines every 0.05 s: (work folder, process).
    One simulation shared by the tests below (each costs ~10 s)."""
    work = tmp_path_factory.mktemp("newcomer") / "work"
    work.mkdir()
    res = wearnav(*_example(("simulate",)), cwd=work, WEARNAV_PROGRESS_INTERVAL_S="0.05")
    assert res.returncode == 0, res.stderr
    return work, res


@pytest.fixture(scope="module")
def sim(simulated) -> Path:
    """A tiny simulated dataset written by the command itself (``data/sim`` of a work folder)."""
    args = _example(("simulate",))
    return simulated[0] / args[args.index("--out") + 1]


def write_demo_data(sim: Path, dest: Path, train: int = 1) -> Path:
    """The first recording of each split of ``sim`` (the data the demo simulates first: the tiny
    preset, seed 0; ``train`` of the training split) as the demo folder's ``data`` at ``dest``: the
    demo reuses it, and so loads, trains on and plots a few recordings instead of 32 (the demo's
    words do not depend on how many)."""
    from wearnav.dataset import Dataset, DatasetWriter

    ds = Dataset.open(sim)
    with DatasetWriter(dest, {k: ds.provenance[k] for k in ("generator", "preset", "seed")}) as w:
        for split, names in ds.manifest.groupby("split", sort=False)["name"]:
            for name in list(names)[: train if split == "train" else 1]:
                w.add(ds.load(name), split=split)
    return dest


# ---- §3 nothing of the user's lost ------------------------------------------------------------


def test_simulate_refuses_an_existing_dataset_without_overwrite(sim):
    before = sorted(p.name for p in sim.iterdir())
    res = wearnav("simulate", "--preset", "tiny", "--out", sim, "--seed", "1", cwd=sim.parent)
    assert res.returncode == 2
    assert res.stderr.strip() == (
        f"error: {sim}: already holds a wearnav dataset (32 recordings); add --overwrite "
        "to replace it, or choose another --out for `wearnav simulate`"
    )
    assert sorted(p.name for p in sim.iterdir()) == before


@pytest.fixture(scope="module")
def export(sim, tmp_path_factory) -> Path:
    """A Sensor Logger export (no dense truth) of the first simulated walk."""
    from wearnav.dataset import Dataset
    from wearnav.importers.sensorlogger_export import write_export

    ds = Dataset.open(sim)
    return write_export(ds.load(ds.names[0]), tmp_path_factory.mktemp("export") / "walk", platform="android")


@pytest.fixture(scope="module")
def imported(export, tmp_path_factory) -> Path:
    """``export`` imported by `wearnav import sensorlogger` (the same recording again, should a test
    replace it with --overwrite)."""
    out = tmp_path_factory.mktemp("imported") / "ds"
    res = wearnav("import", "sensorlogger", export, "--out", out, cwd=out.parent)
    assert res.returncode == 0, res.stderr
    return out


def test_import_refuses_an_existing_dataset_and_overwrite_replaces_it(tmp_path, export, imported):
    out = imported  # imported there by the command (exit 0)
    stamp = (out / "dataset.yaml").read_text()
    res = wearnav("import", "sensorlogger", export, "--out", out, cwd=tmp_path)
    assert res.returncode == 2 and "already holds a wearnav dataset (1 recordings); add --overwrite" in res.stderr
    assert (out / "dataset.yaml").read_text() == stamp  # untouched
    res = wearnav("import", "sensorlogger", export, "--out", out, "--overwrite", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert (out / "dataset.yaml").read_text() != stamp


def _start_demo(work: Path, out: str) -> subprocess.Popen:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "wearnav",
            "demo",
            "--out",
            out,
            "--preset",
            "tiny",
            "--models",
            "ronin",
            "--minutes",
            "1",
        ],
        cwd=work,
        env=_env(WEARNAV_PROGRESS_INTERVAL_S="0.2"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _wait_for_training(proc: subprocess.Popen, epochs: float = 0.0, timeout_s: float = 120) -> list[str]:
    """stderr lines up to the first training progress line past ``epochs``."""
    lines, t0 = [], time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        line = proc.stderr.readline()
        if not line:
            break
        lines.append(line)
        m = re.match(r"train ronin-\w+: ([\d.]+)/", line)
        if m and float(m.group(1)) > epochs:
            return lines
    proc.kill()
    raise AssertionError(f"no training progress line: {lines}")


def _stopped_saying_what_was_kept(proc: subprocess.Popen, code: int, word: str) -> None:
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert err.strip().splitlines()[-1] == (
        f"error: {word}; finished runs are kept in demo; run the same command again to resume"
    )


@pytest.mark.slow
def test_demo_interrupted_says_what_was_kept_and_resumes(tmp_path, sim):
    """Ctrl-C during the demo's training exits 130 saying what was kept; the same command again
    resumes and says so; SIGTERM during its training exits 143 with the same words."""
    # data of the kind the demo would simulate first, there already: the signals come during training
    # (3 training recordings: two batches per epoch, ~1 s)
    write_demo_data(sim, tmp_path / "demo" / "data", train=3)
    proc = _start_demo(tmp_path, "demo")
    _wait_for_training(proc, epochs=1.1)  # a checkpoint to resume from
    deadline = time.monotonic() + 60  # on a busy machine the progress line can come before the checkpoint
    while not list(tmp_path.glob("demo/runs/ronin-*/checkpoints/last.ckpt")):
        assert time.monotonic() < deadline and proc.poll() is None, "no checkpoint to resume from"
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    _stopped_saying_what_was_kept(proc, 130, "interrupted")
    # the same command again resumes, and says so; SIGTERM comes during its training
    proc = _start_demo(tmp_path, "demo")
    lines = _wait_for_training(proc)
    proc.send_signal(signal.SIGTERM)
    _stopped_saying_what_was_kept(proc, 143, "terminated (SIGTERM)")
    assert any(re.match(r"ronin-\w+: resuming from \S+last\.ckpt \(\d+ epoch\(s\) done\)", l) for l in lines), lines


# ---- §3 no silence ------------------------------------------------------------------------------


def test_progress_without_a_terminal_is_log_lines_with_an_estimate(simulated):
    res = simulated[1]  # `wearnav simulate --preset tiny`, stderr a pipe, progress every 0.05 s
    lines = [l for l in res.stderr.splitlines() if l.startswith("simulate tiny: ")]
    assert lines, res.stderr
    assert all(re.fullmatch(r"simulate tiny: \d+/32 rec, \d+ s elapsed, about \d+ s left", l) for l in lines), lines
    assert "\r" not in res.stderr  # no bar fragments in a pipe


def test_progress_helper_interval(monkeypatch, caplog):
    import logging

    from wearnav.core.progress import Progress

    monkeypatch.setattr("wearnav.core.progress.on_terminal", lambda: False)
    caplog.set_level(logging.INFO, logger="wearnav.core.progress")
    list(Progress(range(5), desc="x", unit="rec", interval=0.0))
    assert [r.getMessage().split(",")[0] for r in caplog.records] == [f"x: {i}/5 rec" for i in range(1, 6)]
    caplog.clear()
    list(Progress(range(5), desc="x", interval=3600.0))
    assert not caplog.records  # nothing before the interval is up
    caplog.clear()
    list(Progress(range(5), desc="x", interval=0.0, enabled=False))
    assert not caplog.records


# ---- §4 words a newcomer reads ------------------------------------------------------------------


def _commands(group, prefix=()) -> list[tuple]:
    found = []
    for name, cmd in group.commands.items():
        if hasattr(cmd, "commands"):  # a group (typer's own click classes)
            found += _commands(cmd, prefix + (name,))
        else:
            found.append((prefix + (name,), cmd))
    return found


@functools.cache
def _help(path: tuple[str, ...]) -> str:
    """``wearnav PATH --help`` as printed (in this process: one subprocess per command is slow)."""
    from typer.testing import CliRunner

    res = CliRunner().invoke(app, [*path, "--help"], terminal_width=200)
    assert res.exit_code == 0, res.output
    return res.output


def _example(path: tuple[str, ...]) -> list[str]:
    text = _help(path)
    m = re.search(r"^\s*Example:\n\s*(wearnav .+)$", text, flags=re.M)
    assert m, f"`wearnav {' '.join(path)} --help` has no Example:\n{text}"
    args = shlex.split(m.group(1))[1:]
    assert args[: len(path)] == list(path)
    return args


ROOT = typer.main.get_command(app)
COMMANDS = _commands(ROOT)
# Examples cheap enough to run here, in this order (each may use what the one before wrote); the
# others need trained models or hours of data: their arguments are parsed by the command itself
# (every option exists, every value is of its type and choice), and must name no path that a
# run example would not also leave (the paths are the README's).
RUN = [("simulate",), ("info",), ("plot",), ("models",), ("label-from-fixes",), ("import",)]


def test_every_command_has_an_example_that_parses():
    assert len(COMMANDS) >= 18
    for path, cmd in COMMANDS:
        args = _example(path)
        cmd.make_context(" ".join(("wearnav",) + path), args[len(path) :])  # raises on a bad option or value


@pytest.mark.slow
def test_the_cheap_examples_run(simulated, shared_data):
    from wearnav.dataset import Dataset

    work, res = simulated  # the first example, `wearnav simulate`, ran there (exit 0) in the fixture
    assert RUN[0] == ("simulate",) and res.args[3:] == _example(RUN[0])
    (work.parent / "shared").mkdir()
    (work.parent / "shared" / "data").symlink_to(shared_data)  # the README's ../shared/data
    for path in RUN[1:]:
        args = _example(path)
        res = wearnav(*args, cwd=work, timeout=300)
        assert res.returncode == 0, f"wearnav {' '.join(args)}: {res.stderr}"
    assert (work / "sim.png").is_file() and (work / "labels" / "label_noise_cdf.png").is_file()
    assert len(Dataset.open(work / "data" / "ilc2").names) == 2


def test_flags_read_as_flags_and_seed_is_documented():
    for path, _ in COMMANDS:
        text = _help(path)
        assert "<bool>" not in text, path
        for line in text.splitlines():
            if re.match(r"\s+--seed\b", line):
                assert len(line.split(None, 2)) == 3 and "seed" in line.split(None, 2)[2].lower(), (path, line)


def test_models_tables_have_column_headers():
    """`wearnav models`: each table's first line names its columns, aligned with the rows."""
    from typer.testing import CliRunner

    res = CliRunner().invoke(app, ["models"], terminal_width=200)
    assert res.exit_code == 0, res.output
    registered, shipped = res.output.split("\nshipped", 1)
    header, first = registered.splitlines()[:2]
    assert header.split()[:5] == ["model", "task", "layout", "parameters", "description"]
    assert header.index("description") == first.index(first.split("  ")[-1].strip())  # same column
    task_at = header.index("task")  # every row's task in the header's column, the longest name's too
    assert all(row[task_at:].split()[0] in ("odometry", "classify") for row in registered.splitlines()[1:])
    header = shipped.splitlines()[1]
    assert header.split()[:3] == ["name", "task", "devices"], shipped


def test_plot_and_info_list_the_recordings(sim):
    res = wearnav("plot", sim, "--name", "nope", "--out", sim.parent / "x.png", cwd=sim.parent)
    assert res.returncode == 2
    assert re.fullmatch(
        rf"error: {sim}: no recording named 'nope'; it holds u1_\w+, .*, \.\.\. \(32 recordings\)\n", res.stderr
    )
    res = wearnav("info", sim / "nope.h5", cwd=sim.parent)
    assert res.returncode == 2 and "no such recording" in res.stderr and "(32 recordings)" in res.stderr
    info = json.loads(wearnav("info", sim, cwd=sim.parent).stdout)
    assert info["names"].startswith("u1_") and info["names"].endswith("(32 recordings)")


def test_label_from_fixes_without_truth_says_why_there_is_no_figure(tmp_path, imported):
    res = wearnav("label-from-fixes", imported, "--out", tmp_path / "labels", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert "None cm" not in res.stdout
    assert res.stdout.splitlines()[-1].endswith(
        "label noise not measured: the recordings have no dense truth to "
        "compare the labels with (so no label_noise_cdf.png)"
    )
    assert not (tmp_path / "labels" / "label_noise_cdf.png").exists()


def test_data_folder_is_ignored_by_git():
    res = subprocess.run(["git", "check-ignore", "-q", "data/ilc2/manifest.csv"], cwd=REPO)
    assert res.returncode == 0


@pytest.mark.slow
def test_demo_report_has_its_own_title_and_explains_its_numbers(tmp_path, sim):
    write_demo_data(sim, tmp_path / "d" / "data")  # reused: the page's words are the same for any data
    res = wearnav("demo", "--out", "d", "--preset", "tiny", "--models", "pdr", cwd=tmp_path, timeout=300)
    assert res.returncode == 0, res.stderr
    page = (tmp_path / "d" / "results.md").read_text()
    assert page.startswith("# wearnav demo: odometry on simulated walking\n")
    assert "Generated by `wearnav demo --out d`" in page and "bench odometry` from" not in page
    assert "**ATE** (absolute trajectory error, metres)" in page and "**RTE**" in page and "**pdr**" in page


def test_a_suite_folder_holding_the_users_results_md_is_refused(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "results.md").write_text("my notes\n")
    res = wearnav("demo", "--out", "mine", "--preset", "tiny", "--models", "pdr", cwd=tmp_path)
    assert res.returncode == 2
    assert res.stderr == "error: mine: holds results.md, which `wearnav demo` did not write; choose another --out\n"
    assert (tmp_path / "mine" / "results.md").read_text() == "my notes\n"
    assert sorted(p.name for p in (tmp_path / "mine").iterdir()) == ["results.md"]
