"""wearnav.preprocess.frames: one horizontal frame for all devices, and its alignment to the truth frame."""

import numpy as np
import pytest
from scipy import signal
from scipy.spatial.transform import Rotation

from wearnav.dataset import Dataset
from wearnav.errors import ConfigError
from wearnav.preprocess import PreprocessConfig, align, frames
from wearnav.recording import STANDARD_GRAVITY, DeviceStream, Recording, Trajectory

RATE = 25.0
DEVICES = ("phone", "watch", "earbuds")


def walk(duration=120.0, rate=RATE, seed=0):
    """A walk with random turns and a step-frequency speed oscillation: time, truth positions
    (T, 2), horizontal acceleration (complex, T) as second differences of those positions, and the
    yaw rate (T,)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, duration, 1.0 / rate)
    sos = signal.butter(2, 0.15, fs=rate, output="sos")
    omega = signal.sosfiltfilt(sos, rng.standard_normal(t.size))
    omega *= 0.5 / omega.std()
    heading = np.cumsum(omega) / rate
    speed = 1.3 + 0.15 * np.sin(2 * np.pi * 0.1 * t) + 0.2 * np.sin(2 * np.pi * 1.8 * t)
    z = np.cumsum(speed * np.exp(1j * heading)) / rate
    pos = np.stack([z.real, z.imag], 1)
    acc, _ = frames.truth_acceleration(pos, rate)
    return t, pos, acc, omega


def imu_of(acc_truth, omega, yaw):
    """(T, 6) world-frame IMU of a device whose frame has ``yaw`` (scalar or (T,)) relative to the
    truth frame: a_dev = Rz(yaw) a_truth."""
    z = acc_truth * np.exp(1j * np.asarray(yaw))
    x = np.zeros((acc_truth.size, 6))
    x[:, 0], x[:, 1], x[:, 2], x[:, 5] = z.real, z.imag, STANDARD_GRAVITY, omega
    return x


def inner(t, margin=3.0):
    return (t > t[0] + margin) & (t < t[-1] - margin)


def err_deg(a, b):
    return np.rad2deg(np.abs(frames.wrap(np.asarray(a) - np.asarray(b))))


def test_known_constant_rotations_are_recovered_exactly():
    t, pos, acc, omega = walk()
    yaws = np.deg2rad([20.0, 95.0, -150.0])
    imu = np.stack([imu_of(acc, omega, y) for y in yaws])
    mask = np.ones((3, t.size), bool)
    cf = frames.common_frame(imu, mask, DEVICES, RATE)
    assert cf.reference == 0
    m = inner(t)
    for d in range(3):
        assert err_deg(cf.yaw[d][m], yaws[d] - yaws[0]).max() < 0.01
    assert np.all(cf.info[1:, m] > 0)
    # The rotated data agrees with the reference, and the truth alignment finds the phone's yaw.
    out, rec = frames.align_frames(imu.astype(np.float32), mask, DEVICES, RATE, pos, "truth")
    assert rec["frame"] == "truth" and rec["reference"] == "phone"
    assert rec["devices"]["watch"]["yaw_deg"] == pytest.approx(75.0, abs=0.01)
    assert rec["devices"]["earbuds"]["yaw_deg"] == pytest.approx(-170.0, abs=0.01)
    assert rec["truth"]["yaw_deg"] == pytest.approx(20.0, abs=0.01)
    for d in range(3):
        np.testing.assert_allclose(out[d, m, 0], acc.real[m], atol=1e-3)
        np.testing.assert_allclose(out[d, m, 1], acc.imag[m], atol=1e-3)
        np.testing.assert_allclose(out[d, :, 2], STANDARD_GRAVITY, atol=1e-5)  # vertical untouched
        np.testing.assert_allclose(out[d, :, 5], omega, atol=1e-5)


def test_slow_yaw_walk_is_tracked_not_averaged():
    t, pos, acc, omega = walk(duration=180.0, seed=1)
    drift = np.deg2rad(40.0) + np.deg2rad(8.0) * t / t[-1]  # 8° over 3 min, a fast yaw walk
    imu = np.stack([imu_of(acc, omega, 0.0), imu_of(acc, omega, drift)])
    cf = frames.common_frame(imu, np.ones((2, t.size), bool), ("phone", "watch"), RATE)
    m = inner(t, 30.0)
    e = err_deg(cf.yaw[1][m], drift[m])
    assert e.max() < 1.0, e.max()
    # A constant yaw would be off by ~4° at the ends; the track follows the drift.
    assert err_deg(cf.yaw[1][t < 35].mean(), drift[t > 145].mean()) > 6.0


def test_masked_samples_are_ignored():
    t, pos, acc, omega = walk(seed=2)
    imu = np.stack([imu_of(acc, omega, 0.0), imu_of(acc, omega, np.deg2rad(60.0))])
    mask = np.ones((2, t.size), bool)
    half = t > 60.0
    mask[1, half] = False
    imu[1, half] = imu_of(acc, omega, np.deg2rad(-90.0))[half]  # off the wrist: another frame
    cf = frames.common_frame(imu, mask, ("phone", "watch"), RATE)
    m = inner(t) & ~half & (t < 57.0)
    assert err_deg(cf.yaw[1][m], np.deg2rad(60.0)).max() < 0.01
    out, _ = frames.align_frames(imu.astype(np.float32), mask, ("phone", "watch"), RATE, pos, "common")
    assert np.all(out[1, half] == 0)  # not-worn samples stay zero


def test_one_two_three_devices_and_reference_choice():
    t, pos, acc, omega = walk(seed=3)
    yaws = np.deg2rad([10.0, -40.0, 130.0])
    full = np.stack([imu_of(acc, omega, y) for y in yaws]).astype(np.float32)
    for present in ([0], [1], [0, 2], [1, 2], [0, 1, 2]):
        mask = np.zeros((3, t.size), bool)
        mask[present] = True
        imu = np.where(mask[..., None], full, 0).astype(np.float32)
        out, rec = frames.align_frames(imu, mask, DEVICES, RATE, None, "truth")
        assert rec["frame"] == "common"  # no truth given
        ref = present[0]  # the phone when present, else the first present device
        assert rec["reference"] == DEVICES[ref]
        assert set(rec["devices"]) == {DEVICES[d] for d in present if d != ref}
        for d in present:
            assert rec["devices"].get(DEVICES[d], {"yaw_deg": 0.0})["yaw_deg"] == pytest.approx(
                np.rad2deg(frames.wrap(yaws[d] - yaws[ref])), abs=0.01
            )
            np.testing.assert_allclose(out[d, inner(t), :2], full[ref, inner(t), :2], atol=2e-3)
        absent = [d for d in range(3) if d not in present]
        assert np.all(out[absent] == 0)
    none = np.zeros((3, t.size), bool)
    _, rec = frames.align_frames(full, none, DEVICES, RATE, None, "common")
    assert rec["frame"] == "none"


def test_truth_without_acceleration_leaves_the_common_frame():
    t, pos, acc, omega = walk(seed=4)
    imu = np.stack([imu_of(acc, omega, 0.3)]).astype(np.float32)
    straight = np.stack([1.2 * t, 0.4 * t], 1)  # constant velocity: no yaw information
    out, rec = frames.align_frames(imu, np.ones((1, t.size), bool), ("phone",), RATE, straight, "truth")
    assert rec["frame"] == "common"
    np.testing.assert_array_equal(out, imu)
    with pytest.raises(ConfigError, match="frame_align"):
        frames.align_frames(imu, np.ones((1, t.size), bool), ("phone",), RATE, None, "bogus")


def recording(yaws_deg, with_truth=True, seed=5):
    """A Recording whose devices are aligned with the true world except for a reported yaw
    (quat = Rz(yaw)), at 100 Hz, like a game rotation vector on a device held level."""
    t, pos, acc, omega = walk(duration=100.0, rate=100.0, seed=seed)
    devices = {}
    for name, y in yaws_deg.items():
        f_world = np.stack([acc.real, acc.imag, np.full(t.size, STANDARD_GRAVITY)], 1)
        gyro = np.stack([np.zeros_like(t), np.zeros_like(t), omega], 1)
        q = Rotation.from_euler("z", np.full(t.size, np.deg2rad(y))[:, None])
        devices[name] = DeviceStream(t=t, acc=f_world, gyro=gyro, quat=q.as_quat(scalar_first=True))
    truth = Trajectory(t, pos) if with_truth else None
    return Recording("synthetic", devices, truth=truth), acc


def test_preprocess_frame_align_modes_and_sign():
    rec, acc = recording({"phone": 35.0, "watch": -80.0, "earbuds": 170.0})
    m = slice(100, -100)
    a = align(rec)  # default: truth frame when there is truth
    assert a.meta["frame"]["frame"] == "truth"
    assert a.meta["frame"]["devices"]["watch"]["yaw_deg"] == pytest.approx(-115.0, abs=0.2)
    assert a.meta["frame"]["devices"]["earbuds"]["yaw_deg"] == pytest.approx(135.0, abs=0.2)
    assert a.meta["frame"]["truth"]["yaw_deg"] == pytest.approx(35.0, abs=0.2)
    truth25 = np.interp(a.t, rec.truth.t, acc.real), np.interp(a.t, rec.truth.t, acc.imag)
    for d in range(3):
        assert np.corrcoef(a.imu[d, m, 0], truth25[0][m])[0, 1] > 0.99
        assert np.corrcoef(a.imu[d, m, 1], truth25[1][m])[0, 1] > 0.99
    c = align(rec, PreprocessConfig(frame_align="common"))
    assert c.meta["frame"]["frame"] == "common"
    np.testing.assert_allclose(c.imu[1, m, :2], c.imu[0, m, :2], atol=0.02)
    n = align(rec, PreprocessConfig(frame_align="none"))
    assert "frame" not in n.meta
    no_truth, _ = recording({"phone": 35.0, "watch": -80.0}, with_truth=False)
    assert align(no_truth).meta["frame"]["frame"] == "common"
    with pytest.raises(ConfigError, match="frame_align"):
        PreprocessConfig(frame_align="world")


@pytest.fixture(scope="module")
def tiny(tiny_dataset):
    return Dataset.open(tiny_dataset(0))


@pytest.mark.slow
def test_alignment_accuracy_on_the_tiny_preset(tiny):
    """Error against the simulator's reported-orientation yaw (drawn offset + yaw walk, recovered
    by re-simulating), RMS over the time a device is worn, per recording. Measured with seed 0 and
    preprocess/frames.py's defaults (scripts/frame_alignment_report.py --data <tiny>): relative to the phone,
    median 1.3° (earbuds) / 1.9° (watch), p90 3.9° / 3.9°, max 4.9° / 7.4°; in the truth frame
    medians 0.7–1.0°, p90 ≤ 3.1°, max 6.7°. The naive Procrustes baseline on the same data:
    relative medians 3.5° / 3.6°, max 13.0° / 11.1°. The thresholds leave ~1.5× room."""
    from wearnav.simulate.walk import reported_yaw_offset

    rel = {"watch": [], "earbuds": []}
    absolute = []
    drawn = []
    for name in tiny.manifest["name"]:
        rec = tiny.load(name)
        a = align(rec, PreprocessConfig(frame_align="none"))
        psi = reported_yaw_offset(rec, a.t)
        cf = frames.common_frame(a.imu, a.mask, a.devices, a.rate)
        common = np.stack([frames.rotate_stacked(a.imu[d], -cf.yaw[d]) for d in range(3)])
        tr = frames.truth_yaw(common, a.mask, a.pos, a.rate)
        assert a.devices[cf.reference] == "phone"
        for d, dev in enumerate(a.devices):
            m = a.mask[d]
            if not m.any():
                continue
            # the reconstruction agrees with the drawn offset at the stream's start
            drawn.append(err_deg(psi[dev][0], np.deg2rad(rec.meta["devices"][dev]["quat_yaw_offset_deg"])))
            e_abs = err_deg(cf.yaw[d] + tr.yaw, psi[dev])[m]
            absolute.append(np.sqrt(np.mean(e_abs**2)))
            if dev != "phone":
                e = err_deg(cf.yaw[d], psi[dev] - psi["phone"])[m]
                rel[dev].append(np.sqrt(np.mean(e**2)))
    assert max(drawn) < 1.0
    for dev, v in rel.items():
        v = np.array(v)
        assert len(v) >= 20
        assert np.median(v) < 3.0 and np.percentile(v, 90) < 6.0 and v.max() < 11.0, (dev, np.median(v), v.max())
    absolute = np.array(absolute)
    assert np.median(absolute) < 2.0 and np.percentile(absolute, 90) < 5.0 and absolute.max() < 10.0


def test_initial_mode_is_one_constant_yaw_from_the_first_seconds_only():
    """The honest test frame (issue 16 §1): the common frame turned by ONE yaw, estimated from the
    truth's first 10 s; the truth after them is never read (replacing it changes nothing), and the
    yaw applied does not follow the truth over time (unlike "truth")."""
    rec, acc = recording({"phone": 35.0, "watch": -80.0, "earbuds": 170.0})
    a = align(rec, PreprocessConfig(frame_align="initial"))
    assert a.meta["frame"]["frame"] == "initial"
    assert a.meta["frame"]["truth"]["yaw_deg"] == pytest.approx(35.0, abs=1.0)
    assert a.meta["frame"]["truth"]["from_s"] == 10.0
    # Truth after the first 10 s turned by 60° and shifted: the "initial" input is unchanged,
    # the "truth" input follows it.
    late = rec.truth.t > rec.truth.t[0] + 12.0
    z = rec.truth.pos[:, 0] + 1j * rec.truth.pos[:, 1]
    z = np.where(late, (z - z[late][0]) * np.exp(1j * np.deg2rad(60.0)) + z[late][0] + 5.0, z)
    bent = Recording(rec.name, rec.devices, truth=Trajectory(rec.truth.t, np.stack([z.real, z.imag], 1)))
    np.testing.assert_array_equal(align(bent, PreprocessConfig(frame_align="initial")).imu, a.imu)
    truth_mode = align(bent, PreprocessConfig(frame_align="truth"))
    assert np.abs(truth_mode.imu - a.imu).max() > 1.0
    # one yaw for the whole walk: the "initial" input is the "common" input turned by a constant
    c = align(rec, PreprocessConfig(frame_align="common"))
    m = slice(100, -100)
    zc, za = frames.horizontal(c.imu[0, m]), frames.horizontal(a.imu[0, m])
    turn = np.angle(za / zc)[np.abs(zc) > 0.1]
    assert np.ptp(np.rad2deg(turn)) < 1e-3
    assert np.rad2deg(-turn[0]) == pytest.approx(35.0, abs=1.0)


def test_initial_truth_window():
    pos = np.full((100, 2), np.nan)
    pos[20:] = 1.0
    w = frames.initial_truth(pos, 10.0, 2.0)
    assert w.sum() == 21 and w[20] and w[40] and not w[41] and not w[19]
    assert not frames.initial_truth(np.full((5, 2), np.nan), 10.0, 2.0).any()
