"""The registry of experiments (issue 58 §4): every suite the results page answers with is a named
configuration whose command the command line accepts, and `wearnav bench experiment` runs it."""

from __future__ import annotations

from pathlib import Path

import pytest
import typer

from conftest import run_cli
from wearnav.bench import experiments
from wearnav.bench.experiments import DATA, EXPERIMENTS, HISTORY, PYTHON, STATUSES, data_read, fill
from wearnav.bench.questions import QUESTIONS
from wearnav.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
VALUES = {"out": "/tmp/o", "data": "/tmp/d", "shared": "/tmp/s", "jobs": "2", "path": "/tmp/p"}


def _commands() -> list[tuple[str, tuple[str, ...]]]:
    return [(e.name, e.command) for e in EXPERIMENTS] + [(d.name, d.command) for d in DATA if d.command]


def test_every_suite_of_a_question_is_a_named_experiment_answering_it():
    ids = {q.id for q in QUESTIONS}
    for q in QUESTIONS:
        for suite in q.suites:
            assert q.id in experiments.get(suite).answers, (q.id, suite)
    for e in EXPERIMENTS:  # and no entry claims a question whose page would refuse its suite
        if e.answers != (HISTORY,):
            assert set(e.answers) <= ids, e.name
            assert all(e.name in q.suites for q in QUESTIONS if q.id in e.answers), e.name


def test_names_are_unique_and_each_entry_says_its_status_and_decision():
    assert len({e.name for e in EXPERIMENTS}) == len(EXPERIMENTS)
    assert len({d.name for d in DATA}) == len(DATA)
    for e in EXPERIMENTS:
        assert e.status in STATUSES and e.purpose, e.name
        if e.decision:
            assert len(list((ROOT / "docs" / "decisions").glob(f"{e.decision}-*.md"))) == 1, e.name


def test_every_command_parses_with_the_command_line_it_names():
    """Each wearnav command line parses against its command's own parameters (types, choices,
    required options: click's parser, nothing run); each script is in scripts/."""
    from wearnav.cli import app

    root = typer.main.get_command(app)
    for name, command in _commands():
        argv = fill(command, **VALUES)
        if argv[0] == PYTHON:
            assert (ROOT / argv[1]).is_file(), name
            continue
        cmd, rest = root, argv
        while hasattr(cmd, "commands"):  # a group (typer carries its own click): down to the command
            cmd, rest = cmd.commands[rest[0]], rest[1:]
        assert not hasattr(cmd, "commands") and cmd.name == argv[len(argv) - len(rest) - 1], name
        cmd.make_context(f"wearnav {name}", list(rest))  # raises on an unknown option or a bad value


def test_a_command_line_that_does_not_parse_is_refused_by_that_check():
    from wearnav.cli import app

    cmd = typer.main.get_command(app).commands["bench"].commands["real-odometry"]
    with pytest.raises(typer.BadParameter):
        cmd.make_context("x", ["--data", "d", "--vel-loss", "huber"])
    with pytest.raises(Exception, match="No such option"):
        cmd.make_context("x", ["--data", "d", "--speed-wrap", "0.8"])


def test_the_data_each_command_reads_is_registered_with_what_makes_it():
    names = {d.name for d in DATA}
    for e in EXPERIMENTS:
        assert set(data_read(e.command)) == set(e.data) <= names, e.name
    for d in DATA:
        assert set(data_read(d.command)) == set(d.needs) <= names, d.name
        assert bool(d.command) != bool(d.made_by), d.name


def test_list_prints_every_experiment_and_variant(monkeypatch, capsys):
    code, out, _ = run_cli(monkeypatch, capsys, "bench", "experiment", "--list")
    assert code == 0
    lines = out.splitlines()
    for e in EXPERIMENTS:
        row = next(line for line in lines if line.startswith(e.name + " "))
        assert e.status in row and ", ".join(e.answers) in row
    assert all(any(line.split()[:1] == [d.name] for line in lines) for d in DATA)


def test_dry_run_prints_the_missing_data_then_the_command(monkeypatch, capsys, tmp_path):
    data = tmp_path / "data"
    (data / "ipin").mkdir(parents=True)
    (data / "ipin" / "manifest.csv").write_text("name,file,duration,devices\n")  # made already: not again
    args = ("bench", "experiment", "seeds-lobo-ipin-polar-heading", "--dry-run", "--data", data, "--jobs", "2")
    code, out, _ = run_cli(monkeypatch, capsys, *args)
    assert code == 0
    lines = out.splitlines()
    assert [line.split()[:2] for line in lines] == [
        ["wearnav", "import"],  # ilc2
        ["wearnav", "simulate"],  # sim
        ["python", "scripts/mix_dataset.py"],  # mix-noipin from both
        ["wearnav", "bench"],
    ]
    assert f"{data}/ilc2" in lines[0] and f"ilc2={data}/ilc2" in lines[2]
    assert "--out runs/seeds-lobo-ipin-polar-heading --jobs 2" in lines[3] and "--augment ''" in lines[3]
    assert not (tmp_path / "runs").exists() and sorted(p.name for p in data.iterdir()) == ["ipin"]


def test_an_unknown_name_or_unmade_data_is_one_line(monkeypatch, capsys, tmp_path):
    code, _, err = run_cli(monkeypatch, capsys, "bench", "experiment", "sim-hd3")
    assert code == 2 and "no experiment 'sim-hd3'" in err and len(err.strip().splitlines()) == 1
    code, _, err = run_cli(monkeypatch, capsys, "bench", "experiment", "sim-hd2", "--data", tmp_path, "--dry-run")
    assert code == 2 and "sim-hd2: made by hand" in err
    with pytest.raises(ConfigError, match="no value for"):
        fill(("--out", "{nowhere}"), out="o")


def test_a_registered_command_runs_the_existing_command(monkeypatch, capsys, tmp_path):
    """`bench experiment` hands the filled arguments to the command itself: its own checks answer."""
    (tmp_path / "small").mkdir()
    (tmp_path / "small" / "manifest.csv").write_text("name,file,duration,devices\n")
    out = tmp_path / "suite"
    out.mkdir()
    (out / "results.md").write_text("the user's own page\n")  # bench fusion refuses a folder it did not write
    code, _, err = run_cli(monkeypatch, capsys, "bench", "experiment", "fusion-phone", "--data", tmp_path, "--out", out)
    assert code == 2 and "results.md" in err
