"""wearnav.bench.user_protocol: the simulator table (per mode) and the path-length ratio."""

import numpy as np

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
    """One 4-minute simulated walk (seeded): the smoother's median error against the dense truth
    is below the odometry's as a user gets it (first-fix anchoring) and the fixes' alone."""
    rows = simulator_rows("pdr", duration_s=240.0, walks_per_mode=1, modes=("STW",))
    med = {r["path"]: r["median (m)"] for r in rows}
    assert set(med) == {"odometry alone (oracle rigid fit to truth)", "odometry alone (first-fix anchoring)",
                        "fixes alone", "smoother"}
    print(med)
    assert med["smoother"] < med["fixes alone"]
    assert med["smoother"] < med["odometry alone (first-fix anchoring)"]
