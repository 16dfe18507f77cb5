"""The realism report's statistics on signals with known answers, its walking-stretch picker,
and the calibrated simulator against the real bands recorded in docs/realism.json."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from wearnav.realism import (
    CLAIMED,
    GROUPS,
    RATE_HZ,
    SourceResult,
    detect_walking,
    labelled_walking,
    recording_segments,
    resample,
    segment_stats,
    segments,
    simulate_realism_walks,
)
from wearnav.recording import DeviceStream, Recording
from wearnav.simulate import FixNoise, simulate_fixes
from wearnav.simulate.imu import IMU_SPECS, antialiased, true_imu

G = 9.81
DOCS_JSON = Path(__file__).resolve().parents[1] / "docs" / "realism.json"


def _tone(f_hz: float, amp: float, dur: float = 10.0, rate: float = RATE_HZ):
    t = np.arange(0.0, dur, 1.0 / rate)
    acc = np.zeros((t.size, 3))
    acc[:, 2] = G + amp * np.sin(2 * np.pi * f_hz * t)
    return t, acc


def test_sinusoid_gives_its_frequency_and_no_variability():
    t, acc = _tone(1.8, 2.0)
    gyro = np.tile([0.3, 0.4, 0.0], (t.size, 1))  # |gyro| = 0.5
    st = segment_stats(acc, gyro)
    assert st["f_dom"] == pytest.approx(1.8, abs=0.02)
    assert st["cadence"] == pytest.approx(1.8, abs=0.03)
    assert st["step_cv"] < 0.01 and st["amp_cv"] < 0.02
    assert st["step_reg"] > 0.9
    assert st["acc_std"] == pytest.approx(2.0 / np.sqrt(2), rel=0.02)
    assert st["gyro_mean"] == pytest.approx(0.5, rel=1e-6)
    assert st["band_1.2_2.6"] > 0.95


def test_horizontal_vertical_ratio():
    t, acc = _tone(1.8, 2.0)
    world = acc.copy()
    world[:, 0] = 1.0 * np.sin(2 * np.pi * 0.9 * t)  # horizontal half the vertical amplitude
    assert segment_stats(acc, None, world)["hv_ratio"] == pytest.approx(0.5, rel=0.03)


def test_step_period_variability_is_measured():
    """Steps whose periods have a known CV (10 %) and amplitudes a known CV (20 %)."""
    rng = np.random.default_rng(0)
    periods = 0.55 * (1 + 0.10 * rng.standard_normal(60))
    amps = 2.0 * (1 + 0.20 * rng.standard_normal(60))
    edges = np.concatenate([[0.0], np.cumsum(periods)])
    t = np.arange(0.0, edges[-1], 1.0 / RATE_HZ)
    k = np.searchsorted(edges, t, side="right") - 1
    phase = (t - edges[k]) / periods[k]
    acc = np.zeros((t.size, 3))
    acc[:, 2] = G + amps[k] * 0.5 * (1 - np.cos(2 * np.pi * phase))  # one smooth bump per step
    cvs = [segment_stats(acc[i : i + 250]) for i in range(0, t.size - 250, 250)]
    step_cv = np.median([c["step_cv"] for c in cvs])
    amp_cv = np.median([c["amp_cv"] for c in cvs])
    assert 0.06 < step_cv < 0.14
    assert 0.12 < amp_cv < 0.28


def test_resample_keeps_gait_band_and_removes_aliases():
    t = np.arange(0.0, 20.0, 0.01)
    slow = np.sin(2 * np.pi * 1.8 * t)
    fast = np.sin(2 * np.pi * 20.0 * t)  # above 12.5 Hz: must not fold into the 25 Hz signal
    y = resample(t, np.stack([slow, fast], 1), 0.0, 20.0)
    assert y.shape[0] == pytest.approx(20.0 * RATE_HZ, abs=1)
    inner = slice(25, -25)
    assert np.std(y[inner, 0]) == pytest.approx(np.std(slow), rel=0.03)
    assert np.std(y[inner, 1]) < 0.05


def test_labelled_walking_merges_turns_and_segments_trim():
    labels = [
        (0.0, 2.0, "activity", "SEATED"),
        (2.0, 6.0, "activity", "WALKING"),
        (6.0, 7.5, "activity", "TURNING"),
        (7.5, 12.0, "activity", "WALKING"),
        (12.0, 14.0, "activity", "SITTING_DOWN"),
        (0.0, 14.0, "activity_watch", "WALKING"),
    ]
    t, acc = _tone(1.8, 2.0, dur=14.0, rate=50.0)
    rec = Recording(
        "u", {"phone": DeviceStream(t, acc, np.zeros_like(acc))}, labels=labels, meta={"source": "uji-phone-watch"}
    )
    assert labelled_walking(rec, "phone") == [(2.0, 12.0)]
    assert segments([(2.0, 12.0)]) == [(3.0, 11.0)]  # trimmed by 1 s each end, one 8-s segment
    assert segments([(0.0, 27.0)]) == [(1.0, 11.0), (11.0, 21.0), (21.0, 26.0)]
    assert segments([(0.0, 5.0)]) == []  # 3 s after trimming: too short
    rows, _, how = recording_segments(rec, "phone")
    assert how == "labels" and len(rows) == 1 and rows[0]["f_dom"] == pytest.approx(1.8, abs=0.03)


def test_detector_finds_the_walk_between_still_stretches():
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 40.0, 0.02)
    acc = np.zeros((t.size, 3))
    walk = (t >= 10) & (t < 30)
    acc[:, 2] = G + rng.normal(0, 0.05, t.size) + walk * 2.5 * np.sin(2 * np.pi * 1.8 * t)
    found = detect_walking(t, acc)
    assert len(found) == 1
    a, b = found[0]
    # whole 2-s windows are marked, so the edges are good to one window (TRIM_S removes 1 s of it)
    assert a == pytest.approx(10.0, abs=2.0) and b == pytest.approx(30.0, abs=2.0)
    assert b - a > 19.0


def test_earbud_antialias_filter_attenuates_above_the_gait_band():
    spec = IMU_SPECS["earbuds"]

    def pose(f_hz):
        def p(t):
            pos = np.zeros((t.size, 3))
            pos[:, 2] = 0.001 * np.sin(2 * np.pi * f_hz * t)
            return pos, np.broadcast_to(np.eye(3), (t.size, 3, 3)).copy()

        return p

    t = np.arange(1.0, 5.0, 1.0 / spec.rate_hz)
    gain = {}
    for f in (2.0, 11.0):
        raw = true_imu(pose(f), t)
        filt = antialiased(pose(f), raw, spec)
        gain[f] = np.std(filt.specific_force[:, 2]) / np.std(raw.specific_force[:, 2])
    assert gain[2.0] > 0.9 and gain[11.0] < 0.5


def test_fix_jumps_and_outages_with_accuracy_tracking_the_error():
    noise = FixNoise(jump_rate_hz=0.02, outage_rate_hz=0.01)
    t = np.arange(0.0, 4000.0, 1.0)
    fx = simulate_fixes(t, np.zeros((t.size, 2)), noise, np.random.default_rng(3))
    gaps = np.diff(fx.t)
    assert (gaps > 2.5).sum() > 10  # outages
    step = np.linalg.norm(np.diff(fx.pos, axis=0), axis=1)
    assert (step > 4.0).sum() > 20  # multipath jumps
    err = np.linalg.norm(fx.pos, axis=1)
    big = err > np.percentile(err, 90)
    assert np.median(fx.accuracy[big]) > 1.5 * np.median(fx.accuracy[~big])


@pytest.mark.slow
@pytest.mark.skipif(not DOCS_JSON.exists(), reason="docs/realism.json not generated")
def test_calibrated_simulator_within_the_real_bands():
    """A fresh simulation (12 walkers × 40 s per placement, another seed than the report's)
    against the real bands that `wearnav realism` recorded from the shipped recordings."""
    bands = json.loads(DOCS_JSON.read_text())["groups"]
    sims = {}
    for key, stats in CLAIMED.items():
        g = next(g for g in GROUPS if g.key == key)
        if g.sim_hold not in sims:
            sims[g.sim_hold] = simulate_realism_walks(g.sim_hold, 12, seed=5, duration_s=40.0)
        res = SourceResult("sim", "sim", "")
        for rec in sims[g.sim_hold]:
            res.rows += recording_segments(rec, g.sim_device)[0]
        for stat in stats:
            lo, hi = bands[key]["compare"][stat]["band"]
            med = float(np.median(res.values(stat)))
            assert lo <= med <= hi, (key, stat, med, (lo, hi))


def test_report_end_to_end_on_a_small_slice(shared_data, tmp_path):
    """`realism_report` on Oxford's hand-held recordings and two short simulated walks: the
    Markdown table, the PNG and a JSON holding the numbers behind the figure."""
    from wearnav.realism import Group, RealSource, realism_report

    group = Group(
        "phone_hand",
        "phone held in the hand",
        "phone",
        "texting",
        (RealSource("Oxford hand", "oxford-steps", "oxford_step_counter", "phone", r"_hand_"),),
    )
    out = tmp_path / "docs" / "realism.md"
    res = realism_report(
        shared_data, out, tmp_path / "work", n_sim=2, limit=1, sim_duration_s=30.0, groups=(group,), fix_source=None
    )
    text = out.read_text()
    assert "|cadence (steps/s)|" in re.sub(r" *\| *", "|", text) and "Oxford hand" in text  # a table row
    png = out.parent / "img" / "realism_phone_hand.png"
    assert png.exists() and png.stat().st_size > 10_000
    data = json.loads(out.with_suffix(".json").read_text())
    cmp = data["groups"]["phone_hand"]["compare"]
    assert cmp["cadence"]["sim"]["n"] > 0 and cmp["cadence"]["real"]["n"] > 0
    assert 1.5 < cmp["cadence"]["real"]["median"] < 2.1  # people walk at 1.5–2.1 steps/s
    assert data["figures"]["phone_hand"]["statistics"]["acc_std"]["density"]["Oxford hand"]
    assert res["groups"]["phone_hand"]["real"][0]["how"] == "labels"
