"""The `wearnav` command end to end on the tiny simulated preset."""

import json

import matplotlib.image as mpimg
import pytest

from conftest import run_cli


run = run_cli


def test_simulate_info_plot(tmp_path, monkeypatch, capsys):
    code, out, _ = run(monkeypatch, capsys, "simulate", "--preset", "tiny", "--out", tmp_path / "sim", "--seed", "3")
    assert code == 0
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


@pytest.mark.parametrize("args, needle", [
    (["info", "missing.h5"], "missing.h5: no such file"),
    (["simulate", "--preset", "huge", "--out", "x"], "huge"),
    (["import", "nonsense", ".", "--out", "x"], "unknown format"),
])
def test_bad_input_is_one_line_exit_2(tmp_path, monkeypatch, capsys, args, needle):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(monkeypatch, capsys, *args)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0]


def test_corrupt_h5_is_one_line(tmp_path, monkeypatch, capsys):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"\x89HDF\r\n\x1a\n truncated")
    code, _, err = run(monkeypatch, capsys, "info", bad)
    assert code == 2 and err.count("\n") == 1 and "bad.h5" in err


def test_simulated_dataset_records_what_made_it(tmp_path, monkeypatch, capsys):
    from wearnav.dataset import Dataset

    run(monkeypatch, capsys, "simulate", "--preset", "tiny", "--out", tmp_path / "sim", "--seed", "5")
    prov = Dataset.open(tmp_path / "sim").provenance
    assert prov["generator"] == "wearnav.simulate" and prov["seed"] == 5 and prov["preset"]["name"] == "tiny"
