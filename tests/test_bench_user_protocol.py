"""wearnav.bench.user_protocol: the simulator table (per mode) and the path-length ratio."""

import numpy as np
import pytest

from wearnav.bench.user_protocol import score_path, simulator_rows


def test_score_path_errors_and_length_ratio():
    t = np.arange(0.0, 10.0, 0.1)
    truth_t = np.array([0.0, 5.0, 9.0])
    truth = np.array([[0.0, 0.0], [5.0, 0.0], [9.0, 0.0]])
    path = np.stack([0.5 * t, np.full_like(t, 1.0)], 1)  # half the speed, 1 m off to the side
    err, ratio = score_path(t, path, truth_t, truth)
    np.testing.assert_allclose(err, [np.hypot(2.5, 1), np.hypot(4.5, 1)])  # from the second point on
    assert abs(ratio - 0.5) < 1e-9


def test_simulator_rows_smoother_beats_the_users_odometry_and_the_fixes():
    """Four 4-minute simulated walks (seeded): the smoother's median error against the dense truth
    is below the odometry's as a user gets it (first-fix anchoring) and the fixes' alone. Four walks,
    not one: with the fixes' receiver-filter error (correlated over seconds, ramped multipath) the
    smoother wins on 2 of seeds 0-3 alone, and over the four by a thin margin (2.16 vs 2.20 m)."""
    rows = simulator_rows("pdr", duration_s=240.0, walks_per_mode=4, modes=("STW",))
    med = {r["path"]: r["median (m)"] for r in rows}
    assert set(med) == {"odometry alone (oracle rigid fit to truth)", "odometry alone (first-fix anchoring)",
                        "fixes alone", "smoother"}
    print(med)
    assert med["smoother"] < med["fixes alone"]
    assert med["smoother"] < med["odometry alone (first-fix anchoring)"]


def test_bench_fusion_writes_a_page_that_results_stitches(tmp_path, monkeypatch, capsys):
    """`wearnav bench fusion` on a simulated dataset of two test walks and a training walk (the
    smoother calibrated on it, not scored): results.md with the per-mode table
    and the smoother's seconds per hour, results.json with every path per mode and over all, and
    `wearnav results` takes the page in under its suite marker; --live-min times the fixed-lag
    smoother on a simulated walk."""
    import json

    from conftest import run_cli
    from wearnav.bench.results import collect
    from wearnav.dataset import write_dataset
    from wearnav.simulate.config import WalkConfig
    from wearnav.simulate.walk import simulate_recording

    recs = [(simulate_recording(WalkConfig(name=f"{m}_{split}", mode=m, placement="HD", duration_s=60.0), seed=k), split)
            for k, (m, split) in enumerate((("STW", "test"), ("DLW", "test"), ("STW", "train")))]
    write_dataset(tmp_path / "sim", recs)
    code, out, err = run_cli(monkeypatch, capsys, "bench", "fusion", "--data", tmp_path / "sim", "--out", tmp_path / "fusion",
                             "--live-min", "2")
    assert code == 0, err
    page = (tmp_path / "fusion" / "results.md").read_text()
    table = json.loads((tmp_path / "fusion" / "results.json").read_text())
    assert "| STW " in page and "| DLW " in page and "s per hour of walk" in page
    assert {(r["mode"], r["path"]) for r in table["rows"]} == {
        (m, p) for m in ("DLW", "STW", "all") for p in ("odometry alone (oracle rigid fit to truth)",
                                                         "odometry alone (first-fix anchoring)", "fixes alone", "smoother")}
    assert table["smooth_s_per_hour"] > 0 and table["walk_s"] > 100
    # calibrated on the training walk, which is not scored
    assert table["calibration"]["walks"] == 1 and table["calibration"]["odometry_walk_m_per_sqrt_s"] > 0
    assert table["config"]["odometry_walk_m_per_sqrt_s"] == table["calibration"]["odometry_walk_m_per_sqrt_s"]
    assert {r["walks"] for r in table["rows"] if r["mode"] == "all"} == {2} and table["split"] == "test"
    assert "calibrated on the dataset's training walks (1)" in page
    # a shipped learned model as the odometry: calibrated on its own (a steadier path than PDR's)
    from wearnav.bench.user_protocol import fusion_table
    learned = fusion_table(tmp_path / "sim", "phone")
    assert learned["model"] == "phone" and {r["walks"] for r in learned["rows"] if r["mode"] == "all"} == {2}
    assert learned["calibration"]["odometry_walk_m_per_sqrt_s"] != table["calibration"]["odometry_walk_m_per_sqrt_s"]
    live = table["live"]  # a 2-min walk: shorter than the 300-s window, so the batch solve, updated
    assert live["updates"] >= 10 and live["gap_to_batch_median_m"] < 0.5 and "ms per update" in page
    assert all(np.isfinite(r["median (m)"]) and r["walks"] == (2 if r["mode"] == "all" else 1) for r in table["rows"])
    stitched = collect([tmp_path / "fusion"], tmp_path / "docs" / "results.md").read_text()
    assert "Fusion on the simulator" in stitched and "<!-- suite: fusion -->" in stitched


def test_site_calibration_uses_walks_the_model_never_trained_on(tmp_path, monkeypatch):
    """A learned model on its own building: its validation walks; anywhere else (another building,
    PDR): the site's training walks. Stored per site, reused, redone when the walks change."""
    from wearnav.bench import user_protocol

    calls = []

    def fake(run, data, split):
        calls.append((str(data), split))
        return {"odometry_walk_m_per_sqrt_s": 0.5, "walks": 3, "sigma_scale": 1.2, "sigma_points": 40}

    monkeypatch.setattr(user_protocol, "calibrate", fake)
    site, other = tmp_path / "ipin", tmp_path / "mix"
    run = tmp_path / "run"
    run.mkdir()
    c = user_protocol.site_calibration(run, "main", site, site)
    assert calls == [(str(site), "val")] and c["split"] == "val"
    assert (run / "fuse_calibration_main.json").is_file()
    user_protocol.site_calibration(run, "main", site, site)
    assert len(calls) == 1  # reused
    c = user_protocol.site_calibration(run, "main", site, other)
    assert calls[-1] == (str(site), "train") and "not trained on" in c["method"]
    user_protocol.site_calibration(run, "test", site, None)
    assert calls[-1] == (str(site), "train") and (run / "fuse_calibration_test.json").is_file()


def test_user_protocol_keeps_each_walks_errors_and_pairs_the_smoother_by_walk(monkeypatch):
    """Per trace: every anchoring's errors and the raw fixes' at the same surveyed points; the
    concatenated errors are those traces'; the paired rows give the smoother minus each other path."""
    from wearnav import fuse
    from wearnav.bench import user_protocol as up
    from wearnav.simulate.config import WalkConfig
    from wearnav.simulate.walk import simulate_recording

    recs = [simulate_recording(WalkConfig(name=f"w{k}", mode="STW", placement="HD", duration_s=120.0), seed=k)
            for k in range(3)]

    def paths(run, data, split):
        for k, rec in enumerate(recs):
            t = rec.truth.t[::10]
            xy = rec.truth.pos[::10, :2] - rec.truth.pos[0, :2]
            c, s = np.cos(0.3 + 0.1 * k), np.sin(0.3 + 0.1 * k)
            drift = np.stack([0.02 * (t - t[0]), np.zeros_like(t)], axis=1)
            yield rec, t, 0.9 * xy @ np.array([[c, -s], [s, c]]).T + drift

    monkeypatch.setattr(up, "_paths", paths)
    r = up.user_protocol("unused", "unused", cfg=fuse.FuseConfig())
    names = [rec.name for rec in recs]
    for a in fuse.ANCHORS:
        assert list(r[a]["by_trace"]) == names
        np.testing.assert_allclose(np.concatenate([r[a]["by_trace"][n] for n in names]), r[a]["errors"])
    np.testing.assert_allclose(r[up.RAW_FIXES]["by_trace"][names[1]], up.fix_point_errors(recs[1]), atol=1e-3)
    # whether each point's error is inside the 68 % radius of the smoother's σ, at the scored points
    inside = r["smooth"]["inside_68"]
    assert len(inside) == len(r["smooth"]["errors"]) and 0.0 < np.mean(inside) <= 1.0
    rows = up.paired_rows({"pdr": r})
    assert [row["smoother minus"] for row in rows] == [up.RAW_FIXES, up.ANCHOR_LABEL["first-fixes"], up.ANCHOR_LABEL["rigid"]]
    smooth = np.concatenate([r["smooth"]["by_trace"][n] for n in names])
    rigid = np.concatenate([r["rigid"]["by_trace"][n] for n in names])
    expect = np.nanpercentile(smooth, 50) - np.nanpercentile(rigid, 50)
    point, low, high = (float(x.strip("[],")) for x in rows[2]["median (m)"].split())
    assert point == pytest.approx(expect, abs=0.006) and low <= point <= high and rows[2]["walks"] == 3
