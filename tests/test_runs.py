"""runs: one process per run folder (the lock), and the lock never looks like a result."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import error_line
from wearnav import runs
from wearnav.errors import BusyError

SRC = Path(__file__).resolve().parents[1] / "src"
# Who holds a lock is read from Linux's /proc/locks; elsewhere the error line names no pid.
LINUX = Path("/proc/locks").is_file()
linux_only = pytest.mark.skipif(not LINUX, reason="lock holders are read from /proc/locks")

HOLDER = """
import sys, time
sys.path.insert(0, {src!r})
from wearnav.runs import locked
with locked(sys.argv[1]):
    print("held", flush=True)
    time.sleep(60)
"""


def hold(run: Path) -> subprocess.Popen:
    """Another process holding ``run``'s lock (until killed)."""
    p = subprocess.Popen(
        [sys.executable, "-c", HOLDER.format(src=str(SRC)), str(run)], stdout=subprocess.PIPE, text=True
    )
    assert p.stdout.readline().strip() == "held"
    return p


@linux_only
def test_a_second_process_is_refused_until_the_holder_dies(tmp_path):
    run = tmp_path / "R"
    p = hold(run)
    try:
        assert runs.lock_holder(run) == p.pid
        with pytest.raises(BusyError) as err, runs.locked(run):
            pytest.fail("entered a run folder another process holds")
        assert error_line(err.value) == f"{run}: another wearnav process is using this run folder (pid {p.pid})"
    finally:
        p.send_signal(signal.SIGKILL)  # the OS releases the lock of a killed process
        p.wait()
        p.stdout.close()
    assert runs.lock_holder(run) is None
    with runs.locked(run):
        assert runs.lock_holder(run) == os.getpid()


@linux_only
def test_the_lock_is_reentrant_within_a_process_and_released_after(tmp_path):
    run = tmp_path / "R"
    with runs.locked(run):
        with runs.locked(run):  # the CLI holds the folder, fit takes it again inside
            assert runs.lock_holder(run) == os.getpid()
        assert runs.lock_holder(run) == os.getpid()  # the outer hold stays
    assert runs.lock_holder(run) is None
    assert runs._held == {}


def test_the_lock_file_is_not_a_result(tmp_path):
    run = tmp_path / "R"
    with runs.locked(run):
        pass
    assert [p.name for p in run.iterdir()] == [runs.LOCK]
    assert not runs.is_complete(run)
    assert runs.is_blank(run)  # may still become a new run (prepare_run accepts it)
    (run / "notes.txt").write_text("mine")
    assert not runs.is_blank(run)


def test_fit_takes_the_lock(tmp_path, monkeypatch):
    """Every trainer goes through runs.locked: a held folder is refused before any work."""
    from wearnav.train import classify, noisy, odometry

    run = tmp_path / "R"
    p = hold(run)
    try:
        for fit, args in (
            (odometry.fit, (None, run)),
            (classify.fit, (None, run)),
            (noisy.fit_noisy, (None, None, run)),
        ):
            with pytest.raises(BusyError, match="another wearnav process"):
                fit(*args)
    finally:
        p.kill()
        p.wait()
        p.stdout.close()


@pytest.mark.slow
@linux_only
def test_two_train_commands_on_one_folder(tmp_path):
    """Two real `wearnav train` processes on one --out: the second exits 2 with one line."""
    from wearnav.dataset import DatasetWriter
    from wearnav.simulate import WalkConfig, simulate_recording

    data = tmp_path / "walks"  # three short walks: enough to train on (the first trains until stopped)
    with DatasetWriter(data, {"made_by": "test_runs"}) as w:
        for i, split in enumerate(("train", "train", "val")):
            w.add(simulate_recording(WalkConfig(name=f"walk{i}", duration_s=20), seed=i), split=split)
    run = tmp_path / "R"
    cmd = [
        sys.executable,
        "-m",
        "wearnav",
        "train",
        "ionet",
        "--data",
        str(data),
        "--out",
        str(run),
        "--epochs",
        "1000",
        "--patience",
        "1000",
        "--max-time",
        "2",
        "--no-evaluate",
    ]
    env = {**os.environ, "PYTHONPATH": str(SRC), "OMP_NUM_THREADS": "1"}
    first = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while runs.lock_holder(run) != first.pid:
            assert first.poll() is None, first.stderr.read()
            assert time.monotonic() < deadline, "the first process never took the lock"
            time.sleep(0.2)
        # paused while the second runs (it holds the lock all the same): its training would only
        # take the second's CPU (a ~10 s start, twice that beside a training process)
        first.send_signal(signal.SIGSTOP)
        second = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
        assert second.returncode == 2
        assert second.stderr == f"error: {run}: another wearnav process is using this run folder (pid {first.pid})\n"
        first.send_signal(signal.SIGCONT)
        assert first.poll() is None and runs.lock_holder(run) == first.pid  # the first trains on, undisturbed
    finally:
        first.send_signal(signal.SIGCONT)  # (a stopped process acts on SIGTERM only once continued)
        first.send_signal(signal.SIGTERM)
        first.wait(timeout=60)
        first.stderr.close()
