"""The built-in simulator: physics consistency, streams, modes, label noise, presets and splits."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import cumulative_trapezoid

from wearnav.core.rotations import as_matrix as matrix_from_wxyz
from wearnav.dataset import Dataset
from wearnav.errors import ConfigError
from wearnav.fixlabels import LabelConfig, plausible_labels
from wearnav.metrics import label_noise, label_noise_correlation
from wearnav.recording import ACC_NORM_MEDIAN_RANGE, Recording
from wearnav.simulate import (
    LABEL_NOISE_MEDIAN_M,
    MODES,
    SCENES,
    FixNoise,
    SubjectParams,
    WalkConfig,
    plan_dataset,
    sample_subject,
    simulate_dataset,
    simulate_fixes,
    simulate_recording,
    simulate_walk,
)
from wearnav.simulate.geometry import angle_between, apply, exp_so3
from wearnav.simulate.imu import G_WORLD, IMU_SPECS
from wearnav.simulate.path import plan_route

G = np.array([0.0, 0.0, -9.81])
# (mode, placement, fine phone placement) covering every phone placement and mode
WALKS = [
    ("STW", "HD", "texting"),
    ("STW", "HD", "swinging"),
    ("STW", "PK", "front_pocket"),
    ("STW", "PK", "back_pocket"),
    ("STW", "BG", "bag"),
    ("PVW", "MP", None),
    ("MVW", "MP", None),
    ("DRW", "HD", None),
    ("DLW", "HD", None),
]


def _cfg(mode="STW", placement="HD", hold=None, **kw) -> WalkConfig:
    kw.setdefault("duration_s", 40.0)
    return WalkConfig(name="t", mode=mode, placement=placement, phone_hold=hold, **kw)


@pytest.fixture(scope="module")
def tiny(tiny_dataset) -> Dataset:
    return Dataset.open(tiny_dataset(0))  # simulate_dataset("tiny", seed=0), made once per test process


@pytest.fixture(scope="module")
def clean_walks():
    return {w: simulate_walk(_cfg(*w, imu_noise=False), seed=i) for i, w in enumerate(WALKS)}


@pytest.fixture(scope="module")
def noisy_walks():
    return {w: simulate_walk(_cfg(*w), seed=100 + i) for i, w in enumerate(WALKS[:6])}


def _windows(n: int, length: int, stride: int):
    return [(k, k + length) for k in range(0, n - length, stride)]


# ---- physics ---------------------------------------------------------------------------------


def test_world_specific_force_integrates_to_true_velocity_change(clean_walks):
    """Noise-free IMU: ∫ (R f + g) dt over 3 s equals the device's true velocity change."""
    for key, w in clean_walks.items():
        for dev, tru in w.devices.items():
            s = w.recording.devices[dev]
            R = matrix_from_wxyz(s.quat.astype(np.float64))
            a_world = apply(R, s.acc.astype(np.float64)) + G
            v = cumulative_trapezoid(a_world, s.t, axis=0, initial=0.0)
            tol = 0.01 if s.rate > 50 else 0.05  # trapezoid rule at 100 Hz vs 25 Hz
            worst = 0.0
            for k0, k1 in _windows(len(s.t), int(3 * s.rate), int(s.rate)):
                err = (v[k1] - v[k0]) - (tru.vel[k1] - tru.vel[k0])
                worst = max(worst, float(np.linalg.norm(err)))
            assert worst < tol, (key, dev, worst)
            # and the motion is not trivial: devices really accelerate
            assert np.abs(tru.acc).max() > 1.0, (key, dev)


def test_resting_device_reads_plus_g_on_its_up_axis():
    w = simulate_walk(_cfg(imu_noise=False), seed=3)
    for dev, s in w.recording.devices.items():
        tru = w.devices[dev]
        still = s.t < w.scenario.bouts[0][0] - 0.3  # standing before walking off
        up_in_device = np.einsum("nji,j->ni", tru.R[still], [0.0, 0.0, 1.0])
        f = s.acc[still].astype(np.float64)
        # a torso swaying slightly while standing still has ~zero acceleration
        np.testing.assert_allclose(f, 9.81 * up_in_device, atol=0.3, err_msg=dev)
        # and the device's own orientation output turns that reading into +g on world z
        f_world = apply(matrix_from_wxyz(s.quat[still].astype(np.float64)), f)
        np.testing.assert_allclose(f_world, np.tile(-G_WORLD, (len(f), 1)), atol=0.3, err_msg=dev)


def test_noisy_imu_integration_drifts_realistically(noisy_walks, clean_walks):
    """With consumer-grade errors and the device's own orientation output, integrated velocity
    drifts by a few tenths of m/s per second, not more (yaw-free comparison over 2-s windows: the
    orientation output has an arbitrary yaw). Bounds in m/s per second of integration; ten times
    the phone's error spec (0.3 m/s² bias, or a 3° tilt error) exceeds them."""
    bound = {"phone": 2 * 0.35, "watch": 2 * 0.5, "earbuds": 2 * 0.75}
    for key, w in noisy_walks.items():
        for dev, tru in w.devices.items():
            s = w.recording.devices[dev]
            R = matrix_from_wxyz(s.quat.astype(np.float64))
            v = cumulative_trapezoid(apply(R, s.acc.astype(np.float64)) + G, s.t, axis=0, initial=0.0)
            errs = []
            for k0, k1 in _windows(len(s.t), int(2 * s.rate), int(s.rate)):
                dv, dv_true = v[k1] - v[k0], tru.vel[k1] - tru.vel[k0]
                errs.append(max(abs(dv[2] - dv_true[2]), abs(np.linalg.norm(dv[:2]) - np.linalg.norm(dv_true[:2]))))
            assert max(errs) < bound[dev], (key, dev, max(errs))
            assert np.median(errs) > 1e-3, (key, dev)  # the errors are really there


def test_sensor_noise_matches_spec_and_earbuds_are_noisiest(noisy_walks):
    """While standing still before walking off, what is left after removing the true signal and
    the (constant) bias is white noise of the spec's size."""
    measured = {"acc": {}, "gyro": {}}
    for key, w in noisy_walks.items():
        for dev, tru in w.devices.items():
            s, spec = w.recording.devices[dev], IMU_SPECS[dev]
            still = s.t < w.scenario.bouts[0][0] - 0.2
            assert still.sum() >= 10
            for kind, meas, true, sigma in (
                ("acc", s.acc, tru.specific_force, spec.acc_noise),
                ("gyro", s.gyro, tru.omega, spec.gyro_noise),
            ):
                r = meas[still].astype(np.float64) - true[still]
                std = (r - r.mean(0)).std(0).mean()
                assert std == pytest.approx(sigma, rel=0.35), (key, dev, std, sigma)
                measured[kind].setdefault(dev, []).append(std)
    # measured, not the spec table: the earbuds' signals are the noisiest, the phone's the cleanest
    for kind, per_dev in measured.items():
        m = {dev: np.mean(v) for dev, v in per_dev.items()}
        assert m["earbuds"] > m["watch"] > m["phone"], (kind, m)


def _integrate_gyro(R0, gyro, t):
    R = R0.copy()
    for k in range(len(t) - 1):
        R = R @ exp_so3(0.5 * (gyro[k] + gyro[k + 1]) * (t[k + 1] - t[k]))
    return R


def test_gyro_integrates_to_orientation_change(clean_walks, noisy_walks):
    """Integrating the body rate reproduces the true orientation change over 3 s: to 0.1° for
    ideal sensors; for noisy ones within what bias, drift and a ≤ 5 % scale/misalignment error
    explain, and tighter once the per-recording bias the simulator drew (stored in meta) is
    removed."""
    for walks, noisy in ((clean_walks, False), (noisy_walks, True)):
        for key, w in walks.items():
            if key[0] == "MVW":
                continue  # vigorous wrist shakes: trapezoid integration itself errs by ~1° there
            for dev, tru in w.devices.items():
                s = w.recording.devices[dev]
                spec = IMU_SPECS[dev]
                g = s.gyro.astype(np.float64)
                drift_deg = np.rad2deg(3.0 * 4 * spec.gyro_bias_drift)
                cases = [(g, 0.1, 0.0)]
                if noisy:
                    bias_deg = np.rad2deg(3.0 * 4 * np.sqrt(3) * spec.gyro_bias)
                    bias = np.asarray(w.recording.meta["devices"][dev]["gyro_bias"])
                    cases = [(g, 0.5 + drift_deg + bias_deg, 0.05), (g - bias, 0.5 + drift_deg, 0.05)]
                for gyro, tol_deg, rel in cases:
                    for k0, k1 in _windows(len(s.t), int(3 * s.rate), int(2 * s.rate)):
                        R1 = _integrate_gyro(tru.R[k0], gyro[k0 : k1 + 1], s.t[k0 : k1 + 1])
                        err = float(np.rad2deg(angle_between(R1, tru.R[k1])))
                        turned = float(np.rad2deg(angle_between(tru.R[k0], tru.R[k1])))
                        assert err < tol_deg + rel * turned, (key, dev, noisy, err, tol_deg, turned)


def test_gyro_is_body_rate_not_world_rate(clean_walks):
    """A swinging phone rotates a lot; integrating its rate as a world-frame rate must fail, so
    the previous test can tell the two conventions apart."""
    w = clean_walks[("STW", "HD", "swinging")]
    tru = w.devices["phone"]
    k0, k1 = 2000, 2300
    R = tru.R[k0].copy()
    for k in range(k0, k1):
        R = exp_so3(0.5 * (tru.omega[k] + tru.omega[k + 1]) * 0.01) @ R  # world-frame update
    assert np.rad2deg(angle_between(R, tru.R[k1])) > 5.0


def test_wrist_shake_and_head_tilt_disturb_watch_and_earbuds():
    w = simulate_walk(_cfg("MVW", "MP", duration_s=80, imu_noise=False), seed=4)
    labels = w.recording.labels
    shakes = labels[(labels.kind == "disturbance") & (labels.value == "wrist_shake")]
    tilts = labels[(labels.kind == "disturbance") & (labels.value == "head_tilt")]
    assert len(shakes) and len(tilts)
    watch = w.recording.devices["watch"]
    gy = np.linalg.norm(watch.gyro, axis=1)
    in_shake = w.recording.label_at("disturbance", watch.t) == "wrist_shake"
    assert np.percentile(gy[in_shake], 90) > 2 * np.percentile(gy[~in_shake], 90)
    # head tilts turn the head against the torso by about their amplitude (15–35°); slow
    # looking-around adds or subtracts a little
    ratios = []
    for d in w.scenario.disturbances:
        if d.kind == "head_tilt":
            st = w.body.evaluate(np.array([d.start, 0.5 * (d.start + d.end)]))
            rel = np.swapaxes(st.R_torso, 1, 2) @ st.R_head
            ratios.append(angle_between(rel[0], rel[1]) / abs(d.amp))
    assert min(ratios) > 0.3 and np.mean(ratios) > 0.7, ratios


# ---- streams ---------------------------------------------------------------------------------


def test_rates_and_clocks(tiny):
    rec = tiny.load(tiny.filter(mode="STW").names[0])
    rates = {d: s.rate for d, s in rec.devices.items()}
    assert rates["phone"] == pytest.approx(100, rel=0.01)
    assert rates["watch"] == pytest.approx(100, rel=0.01)
    assert rates["earbuds"] == pytest.approx(25, rel=0.01)
    for s in rec.devices.values():
        assert np.all(np.diff(s.t) > 0)
        # the sampling interval jitters only slightly around the nominal period
        dt = np.diff(s.t) * s.rate
        assert dt.min() > 0.4 and dt.max() < 1.6 and np.median(np.abs(dt - 1)) < 0.1
    starts = [s.t[0] for s in rec.devices.values()]
    assert len(set(np.round(starts, 6))) == 3  # streams start at slightly different times
    assert rec.truth.pos.shape[1] == 3 and rec.truth.quat is not None
    # 1-s fixes; an outage (FixNoise.outage_rate_hz) leaves a gap of whole seconds
    gaps = np.diff(rec.fixes.t)
    assert rec.fixes.pos.shape[1] == 2 and np.allclose(gaps, np.round(gaps)) and gaps.min() == pytest.approx(1.0)


def test_step_frequency_in_spectrum_matches_cadence():
    # no speed changes and no step-to-step timing variability: the cadence is exactly the subject's
    cfg = _cfg(hold="texting", duration_s=75, speed_variation=0.0, subject=SubjectParams(step_time_cv=0.0))
    w = simulate_walk(cfg, seed=8)
    assert w.cadence_hz == pytest.approx(cfg.subject.cadence_hz, rel=1e-6)
    a, b = w.scenario.bouts[0]

    def peak(s, x, lo, hi):
        m = (s.t > a + 3) & (s.t < b - 3)
        x = x[m] - x[m].mean()
        n = 1 << 16  # zero-padding only interpolates; the resolution is 1 / window length
        f = np.fft.rfftfreq(n, 1 / s.rate)
        p = np.abs(np.fft.rfft(x * np.hanning(len(x)), n))
        band = (f > lo) & (f < hi)
        return f[band][np.argmax(p[band])], 1.0 / (s.t[m][-1] - s.t[m][0])

    for dev in ("phone", "earbuds"):
        s = w.recording.devices[dev]
        fp, res = peak(s, np.linalg.norm(s.acc, axis=1), 1.0, 3.5)
        assert abs(fp - w.cadence_hz) <= res, (dev, fp, w.cadence_hz)
    # the torso bounces once per step
    tr = w.recording.truth
    m = (tr.t > a + 3) & (tr.t < b - 3)
    z = tr.pos[m, 2] - tr.pos[m, 2].mean()
    f = np.fft.rfftfreq(1 << 16, tr.t[1] - tr.t[0])
    p = np.abs(np.fft.rfft(z * np.hanning(len(z)), 1 << 16))
    band = (f > 0.5) & (f < 3.5)
    assert abs(f[band][np.argmax(p[band])] - w.cadence_hz) <= 1.0 / (tr.t[m][-1] - tr.t[m][0])
    # the watch swings with the arm: its gyro peaks at the stride frequency (half the cadence)
    s = w.recording.devices["watch"]
    fp, res = peak(s, s.gyro[:, np.argmax(s.gyro.std(0))], 0.5, 3.5)
    assert abs(fp - w.cadence_hz / 2) <= res, (fp, w.cadence_hz / 2)


def test_game_rotation_vector_is_gravity_aligned_with_yaw_offset(noisy_walks):
    w = noisy_walks[("STW", "HD", "texting")]
    for dev, s in w.recording.devices.items():
        tru = w.devices[dev]
        R = matrix_from_wxyz(s.quat.astype(np.float64))
        z_rep, z_true = R[:, 2, :], tru.R[:, 2, :]  # world z axis seen in the device frame
        tilt = np.rad2deg(np.arccos(np.clip(np.einsum("ij,ij->i", z_rep, z_true), -1, 1)))
        assert tilt.max() < 4.0, dev
        # the yaw differs from the truth by an offset that drifts only slowly
        D = R @ np.swapaxes(tru.R, 1, 2)
        yaw = np.unwrap(np.arctan2(D[:, 1, 0], D[:, 0, 0]))
        assert np.ptp(np.rad2deg(yaw)) < 8.0, dev
        offset = w.recording.meta["devices"][dev]["quat_yaw_offset_deg"]
        assert abs((np.rad2deg(yaw[0]) - offset + 180) % 360 - 180) < 3.0, dev


# ---- walking modes ---------------------------------------------------------------------------


@pytest.mark.parametrize("removal", ["watch:table", "earbuds:stop", "earbuds:table", "watch:stop"])
def test_removed_device_is_flagged(removal):
    w = simulate_walk(_cfg("DRW", "HD", duration_s=40, removal=removal), seed=5)
    dev, variant = removal.split(":")
    rem = w.scenario.removal
    rows = w.recording.labels[w.recording.labels.kind == "removed"]
    assert list(rows.value) == [dev] and rows.start.iloc[0] == pytest.approx(rem.start)
    s, tru = w.recording.devices[dev], w.devices[dev]
    other = w.recording.devices["phone"]
    if variant == "stop":
        assert s.t[-1] <= rem.start + 1e-9 and other.t[-1] - s.t[-1] > 10
        assert s.worn.all()
        return
    assert s.worn[s.t < rem.start].all() and not s.worn[s.t >= rem.start].any()
    still = s.t > rem.end + 0.05
    assert still.sum() > 100
    # lying on the table: no walking motion at all, the IMU sees gravity and noise only
    assert np.abs(tru.vel[still]).max() < 1e-6 and np.abs(tru.omega[still]).max() < 1e-6
    assert np.linalg.norm(s.acc[still], axis=1).std() < 0.1
    assert np.median(np.linalg.norm(s.acc[still], axis=1)) == pytest.approx(9.81, abs=0.2)
    assert np.abs(s.gyro[still]).max() < 0.1
    walking = s.t < rem.start - 1
    assert np.linalg.norm(s.acc[walking], axis=1).std() > 0.5


def test_daily_living_stops_and_lowers_the_body():
    w = simulate_walk(_cfg("DLW", "HD", duration_s=150), seed=6)
    rec = w.recording
    act = rec.labels[rec.labels.kind == "activity"]
    kinds = set(act.value)
    assert {"walk", "stand", "sit", "squat"} <= kinds, kinds
    tr = rec.truth
    speed = np.linalg.norm(np.gradient(tr.pos[:, :2], tr.t, axis=0), axis=1)
    z_walk = np.median(tr.pos[rec.label_at("activity", tr.t) == "walk", 2])
    for row in act.itertuples():
        m = (tr.t > row.start) & (tr.t < row.end)
        if row.value in ("sit", "squat", "stand"):
            assert speed[m].max() < 0.05, row
        if row.value in ("sit", "squat"):
            assert z_walk - tr.pos[m, 2].mean() > 0.3, row  # the torso goes down
        if row.value.endswith("_to_stand") or row.value.startswith("stand_to_"):
            z = tr.pos[m, 2]
            assert np.all(np.abs(np.diff(z)) < 0.02)  # smooth: < 2 m/s at 100 Hz
    walking = rec.label_at("activity", tr.t) == "walk"
    assert 0.6 < speed[walking].mean() < 1.8
    # the smoothness check above ran: the walk has transitions into and out of standing
    transitions = act.value.str.endswith("_to_stand") | act.value.str.startswith("stand_to_")
    assert transitions.sum() >= 2, kinds


def test_phone_placement_changes_are_smooth_motions(clean_walks):
    w = clean_walks[("PVW", "MP", None)]
    rec, tru = w.recording, w.devices["phone"]
    pl = rec.labels[rec.labels.kind == "placement"]
    assert (pl.value == "transition").sum() >= 1 and pl.value.nunique() >= 3
    moves = pl[pl.value == "transition"]
    assert ((moves.end - moves.start).between(0.9, 2.5)).all()
    assert np.linalg.norm(np.diff(tru.pos, axis=0), axis=1).max() < 0.04  # < 4 m/s at 100 Hz
    assert np.linalg.norm(tru.acc, axis=1).max() < 40.0
    assert np.linalg.norm(tru.omega, axis=1).max() < 15.0


def test_route_stays_inside_the_area():
    for area in (18.0, 30.0, 50.0, 120.0):
        for seed in range(6):
            r = plan_route(np.random.default_rng(seed), area, 250.0)
            assert r.xy.min() >= 0 and r.xy.max() <= area
    extent = {}
    for scene, (lo, hi) in SCENES.items():
        w = simulate_walk(_cfg(scene=scene, duration_s=60, devices=("phone",)), seed=9)
        a = w.recording.meta["area_m"]
        assert lo <= a <= hi
        xy = w.recording.truth.pos[:, :2]
        assert xy.min() > -0.5 and xy.max() < a + 0.5
        extent[scene] = np.ptp(xy, axis=0).max()
    # the scene really sets the space walked: in a large one the same minute goes further than
    # the whole side of any small one
    assert extent["large"] > SCENES["small"][1] > extent["small"], extent


def test_subjects_and_gait_ranges():
    rng = np.random.default_rng(0)
    subjects = [sample_subject(rng, f"s{i}") for i in range(300)]
    speed = np.array([s.speed_mps for s in subjects])
    cad = np.array([s.cadence_hz for s in subjects])
    assert speed.min() >= 0.8 and speed.max() <= 1.6 and np.ptp(speed) > 0.4
    assert cad.min() >= 1.6 and cad.max() <= 2.0 and np.ptp(cad) > 0.2
    # calibrated to the real walkers in ../shared/data (docs/realism.md): median ≈ 1.77 steps/s,
    # most between 1.66 and 1.88
    assert np.median(cad) == pytest.approx(1.76, abs=0.02)
    lo, hi = np.percentile(cad, [10, 90])
    assert 1.66 <= lo and hi <= 1.88
    # gait follows speed: cadence rises with it, and the bounce with the step (inverted pendulum),
    # keeping the 2.5–5 cm of typical walkers
    step = np.array([s.step_length_m for s in subjects])
    bounce = np.array([s.bounce_m for s in subjects])
    assert np.corrcoef(speed, cad)[0, 1] > 0.5 and np.corrcoef(step, bounce)[0, 1] > 0.8
    assert 0.025 < np.median(bounce) < 0.05 and bounce.min() > 0.01 and bounce.max() < 0.08
    w = simulate_walk(_cfg(duration_s=40, imu_noise=False, hold="texting"), seed=2)
    tr = w.recording.truth
    m = (tr.t > w.scenario.bouts[0][0] + 3) & (tr.t < w.scenario.bouts[0][1] - 3)
    z = tr.pos[m, 2]
    # vertical bounce of a few cm (peak-to-peak per step, after removing slow trends)
    k = int(round(100 / w.cadence_hz))
    ptp = np.median([np.ptp(z[i : i + k]) for i in range(0, len(z) - k, k)])
    assert 0.015 < ptp < 0.07


def _weinberg_and_step_rate(w) -> tuple[float, float]:
    """From the phone's IMU alone: Weinberg's step feature, the median over steps of
    (a_max − a_min)^¼ of the band-passed vertical world-frame acceleration between successive
    peaks, and the step frequency (steps/s, from the median peak interval)."""
    s = w.recording.devices["phone"]
    vert = np.einsum("nij,nj->ni", matrix_from_wxyz(s.quat.astype(np.float64)), s.acc.astype(np.float64))[:, 2]
    rate = 1.0 / float(np.median(np.diff(s.t)))
    a, b = w.scenario.bouts[0]
    m = (s.t > a + 2.0) & (s.t < b - 2.0)
    v = signal.sosfiltfilt(signal.butter(2, (0.8, 4.0), btype="band", fs=rate, output="sos"), vert[m])
    peaks, _ = signal.find_peaks(v, distance=int(0.35 * rate))
    weinberg = np.median([np.ptp(v[i:j]) ** 0.25 for i, j in zip(peaks[:-1], peaks[1:])])
    return float(weinberg), float(rate / np.median(np.diff(peaks)))


def test_walker_speed_is_observable_from_the_phone_imu():
    """Fast walkers take longer steps at a higher cadence, and a longer step lifts the body higher
    (inverted pendulum), so the hand-held phone's vertical acceleration tells the walk's speed:
    over 40 walkers, Weinberg's feature and the step frequency explain most of the spread of the
    mean true speed (a linear fit's R²: 0.71 here, 0.61–0.84 over five other seeds). With speed
    drawn independently of cadence and bounce the same fit gave R² = 0.07."""
    rng = np.random.default_rng(7)
    feats, speed = [], []
    for i in range(40):
        cfg = WalkConfig(
            name="g",
            subject=sample_subject(rng, f"g{i}"),
            mode="STW",
            placement="HD",
            phone_hold="texting",
            duration_s=20.0,
            devices=("phone",),
        )
        w = simulate_walk(cfg, seed=100 + i)
        feats.append(_weinberg_and_step_rate(w))
        speed.append(w.recording.meta["speed_mps"])
    X = np.column_stack([np.ones(len(speed)), np.array(feats)])
    y = np.array(speed)
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    r2 = 1.0 - np.sum((y - X @ coef) ** 2) / np.sum((y - y.mean()) ** 2)
    assert r2 > 0.55, r2


# ---- location fixes --------------------------------------------------------------------------


@pytest.mark.parametrize("level", ["L1", "L2", "L3"])
def test_label_noise_median_matches_easytrack(level):
    noise = FixNoise.from_level(level)
    t = np.arange(0.0, 30000.0)
    truth = np.stack([1.3 * t, np.zeros_like(t)], 1)
    fix = truth + noise.sample_error(t, np.random.default_rng(1))
    med = np.median(label_noise(t, fix, t, truth))
    assert med == pytest.approx(LABEL_NOISE_MEDIAN_M[level], rel=0.10)
    err = fix - truth
    # a correlated process with a stationary std of metres, not white noise
    assert 0.7 * noise.sigma < err.std() < 1.3 * noise.sigma and noise.sigma > 1.0
    lag = 60
    r = np.corrcoef(err[:-lag, 0], err[lag:, 0])[0, 1]
    assert r == pytest.approx(np.exp(-lag / noise.correlation_s), abs=0.2)


def test_recording_fixes_have_the_configured_label_noise():
    meds = {}
    for level in ("L1", "L3"):
        w = simulate_walk(_cfg(duration_s=600, noise_level=level, devices=("phone",)), seed=12)
        fx = w.recording.fixes
        true_xy = w.body.evaluate(fx.t).chest[:, :2]
        meds[level] = np.median(label_noise(fx.t, fx.pos, fx.t, true_xy))
        assert meds[level] == pytest.approx(LABEL_NOISE_MEDIAN_M[level], rel=0.10)
        assert np.all(fx.accuracy > 1.0)
    assert meds["L3"] > meds["L1"]


# ---- determinism, presets, splits --------------------------------------------------------------


def _same(r1: Recording, r2: Recording) -> bool:
    if set(r1.devices) != set(r2.devices):
        return False
    for d in r1.devices:
        for k in ("t", "acc", "gyro", "quat", "worn"):
            a, b = getattr(r1.devices[d], k), getattr(r2.devices[d], k)
            if (a is None) != (b is None):
                return False
            # DeviceStream re-normalises quaternions when it is built (also on load): 1 ulp
            equal = np.allclose(a, b, rtol=0, atol=1e-6) if k == "quat" else np.array_equal(a, b)
            if a is not None and not equal:
                return False
    return (
        np.array_equal(r1.truth.pos, r2.truth.pos)
        and np.array_equal(r1.fixes.pos, r2.fixes.pos)
        and r1.labels.equals(r2.labels)
    )


def test_deterministic_per_seed():
    cfg = _cfg("MVW", "MP", duration_s=30)
    a, b, c = simulate_recording(cfg, 11), simulate_recording(cfg, 11), simulate_recording(cfg, 12)
    assert _same(a, b) and a.meta == b.meta
    assert not _same(a, c)


def test_tiny_preset_covers_modes_devices_and_placements(tiny):
    m = tiny.manifest
    assert set(m["mode"]) == set(MODES)
    assert set(m["placement"]) == {"HD", "MP", "PK", "BG"}
    assert (m["devices"] == "phone;watch;earbuds").all()
    assert (m["source"] == "simulator").all()
    lo, hi = ACC_NORM_MEDIAN_RANGE
    for rec in tiny:
        assert rec.meta["seed"] >= 0 and rec.meta["dataset_seed"] == 0
        assert rec.meta["mode"] in MODES and rec.meta["cadence_hz"] > 1.5
        for s in rec.devices.values():
            assert lo <= np.median(np.linalg.norm(s.acc, axis=1)) <= hi


def test_dataset_round_trip_and_regeneration(tiny, tmp_path):
    name = tiny.filter(mode="DRW").names[0]
    rec = tiny.load(name)
    again = simulate_recording(WalkConfig.from_dict(rec.meta["config"]), rec.meta["seed"])
    assert _same(rec, again)
    path = rec.save(tmp_path / "copy.h5")
    back = Recording.load(path)
    assert _same(rec, back) and back.meta == rec.meta


def test_splits_follow_the_paper(tiny):
    m = tiny.manifest
    u1 = m[m["subject"] == "u1"]
    seen = u1[~u1["placement"].isin(["PK", "BG"])]
    for split in ("train", "val", "test"):
        assert set(seen[seen["split"] == split]["mode"]) == set(MODES), split
    for mode in MODES:
        counts = seen[seen["mode"] == mode]["split"].value_counts().to_dict()
        assert counts == {"train": 3, "val": 1, "test": 1}, mode
    unseen = m[m["placement"].isin(["PK", "BG"])]
    assert len(unseen) >= 2 and (unseen["split"] == "test_unseen").all()
    assert not tiny.split("train").manifest["placement"].isin(["PK", "BG"]).any()
    others = m[m["subject"] != "u1"]
    assert len(others) and (others["split"] == "cross_subject").all()
    assert set(others["mode"]) == set(MODES)
    # the benchmark preset: exactly 6:2:2 per mode for u1, four other subjects
    plan = plan_dataset("default", seed=0)
    for mode in MODES:
        splits = [
            p.split
            for p in plan
            if p.config.subject.name == "u1" and p.config.mode == mode and p.config.placement not in ("PK", "BG")
        ]
        assert sorted(splits).count("train") == 6 and splits.count("val") == 2 and splits.count("test") == 2
    assert len({p.config.subject.name for p in plan}) == 5
    hours = sum(p.config.duration_s for p in plan) / 3600
    assert hours >= 2.0


def test_bad_configuration_is_rejected(tmp_path):
    with pytest.raises(ConfigError, match="unknown simulator preset"):
        simulate_dataset("huge", tmp_path / "x", progress=False)
    with pytest.raises(ConfigError):
        WalkConfig(mode="RUN")
    with pytest.raises(ConfigError):
        WalkConfig(mode="STW", placement="MP")
    with pytest.raises(ConfigError):
        WalkConfig(mode="STW", placement="HD", removal="watch:table")
    with pytest.raises(ConfigError):
        FixNoise.from_level("L9")


# ---- phone-like label noise: correlated neighbours, a heavy tail, Table I medians (issue #17 §3) ----


def _label_chain(level: str, seed: int, n: int = 6000):
    """Phone labels of an n-segment 1-s fix chain of a walker at 1.3 m/s (turning slowly), passed
    through the labeller's jump filter: (noise vectors d_e (m, 2), consecutive indices, dropped)."""
    t = np.arange(0.0, n + 1.0)
    ang = 0.3 * np.sin(t / 60.0)
    truth = np.cumsum(1.3 * np.stack([np.cos(ang), np.sin(ang)], 1), axis=0)
    fx = simulate_fixes(t, truth, FixNoise.from_level(level), np.random.default_rng(seed))
    true_at = truth[np.searchsorted(t, fx.t)]
    label, d_true, dt = np.diff(fx.pos, axis=0), np.diff(true_at, axis=0), np.diff(fx.t)
    ok = (dt == 1.0) & plausible_labels(label, dt, LabelConfig().max_speed)
    noise = (d_true - label)[ok]
    idx = np.flatnonzero(ok)
    consecutive = np.flatnonzero(idx[1:] == idx[:-1] + 1)
    return noise, consecutive, int(((dt == 1.0) & ~ok).sum())


@pytest.fixture(scope="module")
def label_chains():
    return {lv: _label_chain(lv, seed=7) for lv in ("L1", "L2", "L3")}


@pytest.mark.parametrize("level", ["L1", "L2", "L3"])
def test_label_noise_medians_after_the_jump_filter_match_table_one(label_chains, level):
    noise, _, _ = label_chains[level]
    assert noise.shape[0] > 5000
    med = np.median(np.linalg.norm(noise, axis=1))
    assert med == pytest.approx(LABEL_NOISE_MEDIAN_M[level], abs=0.01)


@pytest.mark.parametrize("level", ["L1", "L2", "L3"])
def test_label_noise_of_neighbours_is_positively_correlated(label_chains, level):
    """A phone's filtered fixes carry a velocity error that lasts seconds, so consecutive labels'
    noises share a sign (IPIN T01-02 phone fixes: lag-1 r 0.15-0.45 by two estimators, docs/design.md)."""
    noise, consecutive, _ = label_chains[level]
    rx, ry = label_noise_correlation(noise, consecutive)
    assert 0.2 <= rx <= 0.45 and 0.2 <= ry <= 0.45


@pytest.mark.parametrize("level", ["L1", "L2", "L3"])
def test_label_noise_has_a_heavy_tail_that_survives_the_filter(label_chains, level):
    """Fig. 1a: phone-label noise over 200 cm exists; ramped multipath episodes make it."""
    noise, _, dropped = label_chains[level]
    mag = np.linalg.norm(noise, axis=1)
    assert np.mean(mag > 1.0) >= 0.01 and np.mean(mag > 2.0) >= 0.002
    assert dropped / (dropped + mag.size) < 0.005  # the filter drops only gross jumps


def test_simulate_dataset_select_makes_those_walks_as_the_whole_preset_would(tmp_path):
    """``select``: only the chosen planned walks are simulated, each the walk the whole preset makes
    (same config and seed, so the same data), and the provenance says how many of the plan were."""
    import yaml

    plan = plan_dataset("tiny", 4)
    ds = simulate_dataset("tiny", tmp_path / "part", seed=4, progress=False, select=lambda p: p[3:5])
    assert set(ds.names) == {w.config.name for w in plan[3:5]} and len(ds.names) == 2
    want = simulate_walk(plan[3].config, plan[3].seed).recording
    got = ds.load(plan[3].config.name)
    np.testing.assert_array_equal(got.devices["phone"].acc, want.devices["phone"].acc)
    assert got.meta["split"] == plan[3].split
    made_by = yaml.safe_load((tmp_path / "part" / "dataset.yaml").read_text())
    assert made_by["walks_simulated"] == f"2 of {len(plan)}"
