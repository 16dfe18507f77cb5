"""wearnav.metrics.segment_speed_heading: an odometry error split into speed and heading between
consecutive surveyed points (issue 34 §1)."""

import numpy as np
import pytest

from wearnav.metrics import segment_speed_heading


def _walk(speed_m_s: float, heading_deg: float, scale: float = 1.0, turn_deg: float = 0.0):
    """A straight truth walk at ``speed_m_s`` along ``heading_deg``, surveyed every 5 s, and an
    estimate ``scale`` times as long turned by ``turn_deg``, sampled at 10 Hz."""
    t = np.arange(0, 30.01, 0.1)
    h = np.radians(heading_deg)
    truth = speed_m_s * t[:, None] * np.array([np.cos(h), np.sin(h)])
    g = np.radians(turn_deg)
    rot = np.array([[np.cos(g), -np.sin(g)], [np.sin(g), np.cos(g)]])
    est = scale * truth @ rot.T
    k = np.arange(0, len(t), 50)
    return t, est, t[k], truth[k]


def test_a_short_path_turned_left_gives_its_ratio_and_angle():
    seg = segment_speed_heading(*_walk(1.2, 30.0, scale=0.8, turn_deg=10.0))
    assert len(seg["t0_s"]) == 6
    np.testing.assert_allclose(seg["true_speed_m_s"], 1.2, rtol=1e-6)
    np.testing.assert_allclose(seg["speed_ratio"], 0.8, rtol=1e-6)
    np.testing.assert_allclose(seg["heading_error_deg"], 10.0, atol=1e-6)  # estimate left (CCW) of truth: +


def test_heading_error_wraps_to_plus_minus_180():
    seg = segment_speed_heading(*_walk(1.0, 170.0, turn_deg=-350.0))  # -350° is +10°
    np.testing.assert_allclose(seg["heading_error_deg"], 10.0, atol=1e-6)


def test_segments_shorter_than_the_minimum_are_left_out():
    t, est, tt, truth = _walk(0.1, 0.0)  # 0.5 m between surveyed points
    assert len(segment_speed_heading(t, est, tt, truth, min_length_m=1.0)["t0_s"]) == 0
    assert len(segment_speed_heading(t, est, tt, truth, min_length_m=0.2)["t0_s"]) == 6


def test_points_outside_the_estimates_span_are_not_scored():
    t, est, tt, truth = _walk(1.0, 0.0)
    seg = segment_speed_heading(t[t <= 12.0], est[t <= 12.0], tt, truth)
    assert len(seg["t0_s"]) == 2  # 0–5, 5–10; 10–15 leaves the estimate
    assert seg["t0_s"].tolist() == pytest.approx([0.0, 5.0])
