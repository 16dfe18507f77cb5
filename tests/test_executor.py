"""The one runner of every suite (wearnav.bench.executor): skip complete run folders, run the rest
here, in local processes or on a Ray instance, longest first; the run folders are the same."""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import pytest

from wearnav import runs
from wearnav.bench.executor import Execution, Job, run_jobs
from wearnav.errors import ConfigError


def write_run(config: dict, folder: Path) -> Path:
    """A trivial pure job: its metrics are its config (plus who ran it, for the test)."""
    import torch

    if config.get("fail"):
        raise ConfigError("this job fails", folder)
    time.sleep(config.get("sleep_s", 0.0))
    folder.mkdir(parents=True, exist_ok=True)
    if config.get("log"):
        with open(config["log"], "a") as f:
            f.write(folder.name + "\n")
    runs.write_metrics(folder, {"x": config["x"], "pid": os.getpid(), "threads": torch.get_num_threads()})
    return folder


def _small(tiny_dataset, dest: Path) -> Path:
    """One training, one validation and one test recording of the tiny dataset (seed 0) at ``dest``:
    what a suite job (PDR, evaluated on the test split) reads, at a sixth of the evaluation."""
    from wearnav.dataset import Dataset, write_dataset

    ds = Dataset.open(tiny_dataset(0))
    split = ds.manifest.set_index("name")["split"]
    pick = [next(n for n in ds.names if split[n] == s) for s in ("train", "val", "test")]
    return write_dataset(dest, [(ds.load(n), split[n]) for n in pick]).root


def _jobs(root: Path, n: int = 3, **kw) -> list[Job]:
    return [Job(write_run, {"x": i, **kw}, root / f"run{i}", cost=i) for i in range(n)]


def test_serial_runs_every_job_in_this_process_and_resume_skips_them(tmp_path):
    lines = []
    jobs = _jobs(tmp_path)
    assert run_jobs(jobs, Execution(), echo=lines.append) == [j.folder for j in jobs]
    for i, j in enumerate(jobs):
        m = runs.read_metrics(j.folder)
        assert m["x"] == i and m["pid"] == os.getpid()
    assert len(lines) == 3 and all(": done in " in s for s in lines)
    # resume: complete folders are not run again (a job that would fail proves it)
    lines.clear()
    again = [Job(write_run, {"fail": True}, j.folder) for j in jobs]
    run_jobs(again, Execution(), echo=lines.append)
    assert lines == [f"run{i}: complete, skipped" for i in range(3)]


def test_an_interrupted_suite_runs_only_what_is_missing(tmp_path):
    jobs = _jobs(tmp_path)
    write_run({"x": 1}, jobs[1].folder)
    log = tmp_path / "ran.txt"
    jobs = _jobs(tmp_path, log=str(log))
    run_jobs(jobs, Execution(), echo=lambda s: None)
    assert sorted(log.read_text().split()) == ["run0", "run2"]
    assert all(runs.is_complete(j.folder) for j in jobs)


def test_longest_first_and_marks(tmp_path):
    log = tmp_path / "ran.txt"
    jobs = _jobs(tmp_path, n=4, log=str(log))
    run_jobs(jobs, Execution(), echo=lambda s: None)
    assert log.read_text().split() == ["run3", "run2", "run1", "run0"]
    # a job marked done by other folders is complete only when all of them are
    marks = (tmp_path / "eval_a", tmp_path / "eval_b")
    job = Job(write_run, {"x": 9}, tmp_path / "run9", marks=marks)
    runs.write_metrics(marks[0].mkdir() or marks[0], {})
    assert not job.complete()
    runs.write_metrics(marks[1].mkdir() or marks[1], {})
    assert job.complete()


def test_local_processes_one_thread_each_same_folders(tmp_path):
    import torch

    jobs = _jobs(tmp_path, n=4, sleep_s=0.3)
    lines = []
    old = torch.get_num_threads()
    torch.set_num_threads(2)  # forked workers inherit this: one thread each must be the executor's doing
    try:
        run_jobs(jobs, Execution(jobs=2), echo=lines.append)
    finally:
        torch.set_num_threads(old)
    ms = [runs.read_metrics(j.folder) for j in jobs]
    assert [m["x"] for m in ms] == [0, 1, 2, 3]
    assert {m["threads"] for m in ms} == {1}
    pids = {m["pid"] for m in ms}
    assert os.getpid() not in pids and len(pids) == 2
    assert sorted(int(s.split("(")[1].split("/")[0]) for s in lines) == [1, 2, 3, 4]


def test_a_failing_job_is_raised_as_itself(tmp_path):
    jobs = [Job(write_run, {"x": 0, "fail": True}, tmp_path / "bad")]
    for ex in (Execution(), Execution(jobs=2)):
        with pytest.raises(ConfigError, match="this job fails"):
            run_jobs(jobs, ex, echo=lambda s: None)


def test_ray_missing_is_one_line_naming_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray → ImportError
    with pytest.raises(ConfigError, match=r"install wearnav\[cluster\]"):
        run_jobs(_jobs(tmp_path), Execution(backend="ray"), echo=lambda s: None)
    assert not any(runs.is_complete(j.folder) for j in _jobs(tmp_path))


def test_execution_is_checked():
    with pytest.raises(ConfigError):
        Execution(jobs=0)
    with pytest.raises(ConfigError, match="--address"):
        Execution(address="auto")
    assert Execution().in_process and not Execution(jobs=2).in_process
    assert not Execution(backend="ray").in_process


@pytest.mark.slow
def test_cli_executor_options_one_line_errors(tmp_path, monkeypatch, capsys, tiny_dataset):
    from conftest import run_cli

    code, _, err = run_cli(monkeypatch, capsys, "bench", "odometry", "--data", tmp_path, "--address", "auto")
    assert code == 2 and "--address is for --executor ray" in err and err.count("\n") == 1
    code, _, err = run_cli(monkeypatch, capsys, "bench", "har", "--executor", "slurm")
    assert code == 2 and "local" in err and "ray" in err
    # without Ray installed, --executor ray is one line naming the extra, exit 2, nothing run
    data = _small(tiny_dataset, tmp_path / "small")
    capsys.readouterr()
    monkeypatch.setitem(sys.modules, "ray", None)
    code, _, err = run_cli(
        monkeypatch,
        capsys,
        "bench",
        "odometry",
        "--data",
        data,
        "--out",
        tmp_path / "suite",
        "--models",
        "pdr",
        "--executor",
        "ray",
    )
    assert code == 2 and "install wearnav[cluster]" in err and err.count("\n") == 1
    assert not list((tmp_path / "suite").glob("*/metrics.json"))
    # the same suite locally in two processes: the folder Ray would have written
    code, out, err = run_cli(
        monkeypatch,
        capsys,
        "bench",
        "odometry",
        "--data",
        data,
        "--out",
        tmp_path / "suite",
        "--models",
        "pdr",
        "--jobs",
        "2",
    )
    assert code == 0, err
    cfg = odometry_config(data)
    assert runs.is_complete(runs.run_dir(tmp_path / "suite", "pdr", cfg)) and ": done in " in out


def odometry_config(data: Path) -> dict:
    from wearnav.bench import odometry

    return odometry.run_key(odometry.suite_configs(data, ("pdr",), epochs=100, max_minutes=None, seed=0, lr=None)[0])


@pytest.fixture(scope="module")
def local_ray():
    """A Ray instance on this machine with 2 CPUs (as a CI runner has)."""
    ray = pytest.importorskip("ray")
    src = str(Path(__file__).resolve().parents[1] / "src")
    tests = str(Path(__file__).resolve().parent)
    # workers import wearnav and this file's job function by module name
    ray.init(
        num_cpus=2,
        include_dashboard=False,
        logging_level="WARNING",
        runtime_env={
            "env_vars": {
                "PYTHONPATH": os.pathsep.join([src, tests, os.environ.get("PYTHONPATH", "")]),
                "OMP_NUM_THREADS": "1",
            }
        },
    )
    yield ray
    ray.shutdown()


@pytest.mark.slow
@pytest.mark.cluster
def test_ray_runs_jobs_and_a_real_suite_then_resumes(local_ray, tmp_path, tiny_dataset):
    from wearnav.bench import odometry

    jobs = _jobs(tmp_path / "trivial", n=3)
    lines = []
    run_jobs(jobs, Execution(backend="ray"), echo=lines.append)
    ms = [runs.read_metrics(j.folder) for j in jobs]
    assert [m["x"] for m in ms] == [0, 1, 2] and os.getpid() not in {m["pid"] for m in ms}
    assert {m["threads"] for m in ms} == {1} and len(lines) == 3
    with pytest.raises(ConfigError) as err:  # a job's own error comes back as itself, one line
        run_jobs([Job(write_run, {"fail": True}, tmp_path / "bad")], Execution(backend="ray"), echo=lines.append)
    assert str(err.value) == f"{tmp_path / 'bad'}: this job fails"
    # a real suite job (PDR: evaluated, not trained) through Ray, then the same folder resumed locally
    data = _small(tiny_dataset, tmp_path / "small")
    cfgs = odometry.suite_configs(data, ("pdr",))
    folders = odometry.run_suite(
        cfgs,
        tmp_path / "suite",
        splits=("test",),
        progress=False,
        echo=lines.append,
        execution=Execution(backend="ray"),
    )
    assert runs.is_complete(folders[0]) and json.loads((folders[0] / "metrics.json").read_text())["model"] == "pdr"
    assert folders == [runs.run_dir(tmp_path / "suite", "pdr", odometry.run_key(cfgs[0]))]
    lines.clear()
    run_jobs(jobs, Execution(backend="ray"), echo=lines.append)
    odometry.run_suite(cfgs, tmp_path / "suite", splits=("test",), progress=False, echo=lines.append)
    assert len(lines) == 4 and all(s.endswith("complete, skipped") for s in lines)


def test_a_folder_another_process_is_training_is_skipped_with_a_line(tmp_path):
    """Two invocations of one suite never train into the same folder: the second skips a folder
    whose lock another process holds (and runs the rest)."""
    from test_runs import hold

    log = tmp_path / "ran.txt"
    jobs = _jobs(tmp_path, n=2, log=str(log))
    p = hold(jobs[1].folder)
    try:
        lines = []
        run_jobs(jobs, Execution(), echo=lines.append)
    finally:
        p.kill()
        p.wait()
    assert log.read_text().split() == ["run0"]
    assert not runs.is_complete(jobs[1].folder)
    assert any(s.startswith("run1: skipped, another wearnav process is using this run folder") for s in lines)
    # once the other process is gone, a rerun trains what it left
    run_jobs(jobs, Execution(), echo=lambda s: None)
    assert runs.is_complete(jobs[1].folder)


def test_the_lock_is_taken_by_rank_zero_only(tmp_path, monkeypatch):
    """A DDP worker re-runs the command with LOCAL_RANK set: it shares rank 0's folder instead of
    being refused by rank 0's lock."""
    from test_runs import hold

    run = tmp_path / "run"
    p = hold(run)
    try:
        monkeypatch.setenv("LOCAL_RANK", "1")
        with runs.locked(run):
            pass
        monkeypatch.setenv("LOCAL_RANK", "0")
        with pytest.raises(Exception, match="another wearnav process"), runs.locked(run):
            pass
    finally:
        p.kill()
        p.wait()


SIGTERM_SCRIPT = """
import os, signal, sys, time
from pathlib import Path
from wearnav.bench.executor import Execution, Job, run_jobs
from wearnav.errors import Terminated

def slow(config, folder):
    Path(config["mark"] + str(config["x"])).write_text(str(os.getpid()))
    time.sleep(120)

def on_term(signum, frame):
    raise Terminated("terminated (SIGTERM)")

signal.signal(signal.SIGTERM, on_term)  # as wearnav.cli.main does
root = Path(sys.argv[1])
try:
    run_jobs([Job(slow, {"x": i, "mark": str(root / "started")}, root / f"run{i}") for i in range(2)],
             Execution(jobs=2), echo=lambda s: None)
except Terminated:
    sys.exit(143)
"""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_sigterm_stops_a_multi_process_suite_at_once(tmp_path):
    """SIGTERM (or Ctrl-C) to a suite running jobs in worker processes ends it within seconds,
    workers included, instead of waiting for the runs still training (they resume later)."""
    import signal
    import subprocess

    script = tmp_path / "suite.py"
    script.write_text(SIGTERM_SCRIPT)
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path)])
    marks = [tmp_path / f"started{i}" for i in range(2)]
    deadline = time.monotonic() + 60
    while not all(m.exists() and m.read_text() for m in marks):
        assert time.monotonic() < deadline and proc.poll() is None, "the workers did not start"
        time.sleep(0.1)
    t0 = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 143
    assert time.monotonic() - t0 < 30  # not the jobs' 120 s
    for m in marks:  # no worker left running (given a few seconds to exit on a loaded machine)
        deadline = time.monotonic() + 10
        while _alive(int(m.read_text())):
            assert time.monotonic() < deadline, f"worker {m.read_text()} still runs"
            time.sleep(0.1)
