"""wearnav.bench.ipin_radio on a few real IPIN 2023 walks: the measurement runs end to end and its
numbers are in range (the full run over all 44 walks: ``python -m wearnav.bench.ipin_radio``)."""

from __future__ import annotations

import json

import pytest

from wearnav.bench import ipin_radio
from wearnav.importers import ipin2023

LOGS = "ipin2023_track3/01 Logfiles/01 IPIN2023_T3_TrainingTrials (training)"
WALKS = [
    "IPIN2023_T3_TrainingTrial51_repetition01.mat",
    "IPIN2023_T3_TrainingTrial51_repetition02.txt.xz",
    "IPIN2023_T3_TrainingTrial52_repetition01.txt.xz",
    "IPIN2023_T3_TrainingTrial03_repetition01.txt.xz",
    "IPIN2023_T3_TrainingTrial24_repetition03.txt.xz",
]


@pytest.mark.real_data
def test_measure_on_a_few_walks(shared_data):
    recs = [ipin2023.read_log(shared_data / LOGS / name) for name in WALKS]
    got = ipin_radio.measure(shared_data / "ipin2023_track3", recordings=recs)
    json.dumps(got)  # JSON-able
    assert got["walks"] == 5 and got["trials"] == ["3", "24", "51", "52"]
    pl = got["path_loss"]["fitted_on_all_walks"]
    assert 1.2 < pl["n"] < 2.5 and -75 < pl["p0_dbm"] < -55 and 4 < pl["sigma_db"] < 8
    loo = got["path_loss"]["leave_one_trial_out"]
    loud, quiet = loo["louder_than_-75_dbm"], loo["at_most_-75_dbm"]
    assert loud["median_abs_range_error_m"] < quiet["median_abs_range_error_m"]
    levels = got["floor_levels"]
    assert 0.3 < levels["levels_hpa"]["-1"] < 0.45 and 0.6 < levels["levels_hpa"]["-2"] < 0.75
    assert 2.5 < levels["floor_height_m"] < 3.3
    floors = got["floors"]
    assert floors["multi_floor_trials"]["a_truth_start"]["points"] == 44  # 16 + 16 + 12 surveyed points
    for k in ("a_truth_start", "b_no_truth"):
        assert floors["all_walks"][k]["right"] >= 0.95
    assert {w["walk"][-22:]: w["start_floor_b"] for w in floors["walks"]} == {
        "ngTrial03_repetition01": 0,
        "ngTrial24_repetition03": -2,
        "ngTrial51_repetition01": 0,
        "ngTrial51_repetition02": 0,
        "ngTrial52_repetition01": 0,
    }


def test_main_usage(capsys):
    assert ipin_radio.main([]) == 2
    assert "usage" in capsys.readouterr().err
