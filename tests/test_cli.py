"""The `wearnav` command end to end on the tiny simulated preset."""

import json

import matplotlib.image as mpimg
import pytest

from conftest import run_cli

run = run_cli


def test_simulate_info_plot(tmp_path, monkeypatch, capsys):
    """`wearnav simulate` (its dataset records what made it), then `info` and `plot` on what it wrote."""
    from wearnav.dataset import Dataset

    code, out, _ = run(monkeypatch, capsys, "simulate", "--preset", "tiny", "--out", tmp_path / "sim", "--seed", "3")
    assert code == 0
    prov = Dataset.open(tmp_path / "sim").provenance  # one simulation (~10 s) serves both claims
    assert prov["generator"] == "wearnav.simulate" and prov["seed"] == 3 and prov["preset"]["name"] == "tiny"
    summary = json.loads(out)
    assert set(summary["modes"]) == {"STW", "PVW", "MVW", "DRW", "DLW"}
    assert set(summary["devices"]) == {"phone", "watch", "earbuds"}
    code, out, _ = run(monkeypatch, capsys, "info", tmp_path / "sim")
    info = json.loads(out)
    assert code == 0 and info["recordings"] == summary["recordings"]
    assert info["device_rates"]["phone"]["rate_hz"] == pytest.approx(100.0, abs=1.0)
    assert info["device_rates"]["earbuds"]["rate_hz"] == pytest.approx(25.0, abs=0.5)
    assert set(info["labels"]["mode"]) == {"STW", "PVW", "MVW", "DRW", "DLW"}
    assert 0.2 < info["fix_error_at_truth_m"]["median"] < 10.0
    first = sorted((tmp_path / "sim").glob("*.h5"))[0]
    code, out, _ = run(monkeypatch, capsys, "info", first)
    info = json.loads(out)
    assert code == 0 and info["devices"]["earbuds"]["rate_hz"] == pytest.approx(25.0, abs=0.5)
    code, _, _ = run(monkeypatch, capsys, "plot", tmp_path / "sim", "--out", tmp_path / "p.png")
    assert code == 0 and mpimg.imread(tmp_path / "p.png").shape[0] > 300


@pytest.mark.parametrize(
    "args, needle",
    [
        (["info", "missing.h5"], "missing.h5: no such file"),
        (["simulate", "--preset", "huge", "--out", "x"], "'huge' is not one of 'tiny', 'small', 'default'"),
        (["import", "nonsense", ".", "--out", "x"], "'nonsense' is not one of 'ilc2', 'ipin2023'"),
        (["bench", "real-odometry", "--data", ".", "--devices", "phone,watch"], "the real walks carry the phone alone"),
        (["bench", "real-odometry", "--data", ".", "--devices", "phone,ring"], "each of phone, watch, earbuds"),
        (["bench", "real-odometry", "--data", ".", "--augment", "spin"], "unknown augmentation 'spin'"),
    ],
)
def test_bad_input_is_one_line_exit_2(tmp_path, monkeypatch, capsys, args, needle):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(monkeypatch, capsys, *args)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0]


@pytest.mark.parametrize(
    "args, option, choices",
    [
        (["bench", "efficiency", "--clock", "sun"], "'--clock'", "'wall', 'cpu'"),
        (
            ["import", "sensorlogger", ".", "--out", "x", "--platform", "symbian"],
            "'--platform'",
            "'ios', 'watchos', 'android'",
        ),
        (
            ["track", "x.h5", "--model", "m", "--out", "o", "--platform", "symbian"],
            "'--platform'",
            "'ios', 'watchos', 'android'",
        ),
        (["bench", "real-odometry", "--data", ".", "--format", "gpx"], "'--format'", "'ilc2', 'ipin2023'"),
    ],
)
def test_fixed_choice_options_reject_other_values_before_running(tmp_path, monkeypatch, capsys, args, option, choices):
    """An option with a fixed set of values is a typer Enum: another value exits 2 with typer's
    one-line message naming the option and the choices, before the command runs."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run(monkeypatch, capsys, *args)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and f"Invalid value for {option}" in err and f"is not one of {choices}" in err


@pytest.mark.parametrize(
    "command, listed",
    [
        (["simulate"], "tiny|small|default"),
        (["import"], "ilc2|ipin2023|motionsense|uci-hapt|uji-phone-watch|oxford-steps|sensorlogger"),
        (["track"], "ios|watchos|android"),
        (["bench", "efficiency"], "wall|cpu"),
    ],
)
def test_help_lists_the_choices(monkeypatch, capsys, command, listed):
    monkeypatch.setenv("COLUMNS", "300")  # one line per option, so the choices are not wrapped
    code, out, _ = run(monkeypatch, capsys, *command, "--help")
    assert code == 0 and f"<{listed}>" in out


def test_cli_choices_are_the_librarys():
    """The CLI spells out some choice lists (so `--help` stays light); they must match the library's."""
    from wearnav import cli
    from wearnav.bench.efficiency import CLOCKS
    from wearnav.bench.odometry import GRIDS
    from wearnav.cli import bench as cli_bench
    from wearnav.cli import models as cli_models
    from wearnav.export.header import FORMATS as EXPORT_FORMATS
    from wearnav.importers import FORMATS
    from wearnav.importers.sensorlogger import PLATFORMS
    from wearnav.simulate.presets import PRESETS

    for enum, names in (
        (cli.ImportFormat, FORMATS),
        (cli.Platform, PLATFORMS),
        (cli.Preset, PRESETS),
        (cli_bench.Clock, CLOCKS),
        (cli_bench.Grid, GRIDS),
        (cli_models.ExportFormat, EXPORT_FORMATS),
    ):
        assert [e.value for e in enum] == list(names), enum


def test_corrupt_h5_is_one_line(tmp_path, monkeypatch, capsys):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"\x89HDF\r\n\x1a\n truncated")
    code, _, err = run(monkeypatch, capsys, "info", bad)
    assert code == 2 and err.count("\n") == 1 and "bad.h5" in err
