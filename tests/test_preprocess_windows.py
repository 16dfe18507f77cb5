import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wearnav.errors import ConfigError, ValidationError
from wearnav.preprocess import PreprocessConfig, align, common_span
from wearnav.preprocess.windows import WindowConfig, WindowDataset
from wearnav.recording import STANDARD_GRAVITY as GRAVITY
from wearnav.recording import DeviceStream, Recording, Trajectory


def rotating_device(rate, t0=0.0, t1=20.0, worn=None):
    """A device yawing at 0.5 rad/s, with a fixed tilt, under a known world-frame acceleration."""
    t = np.arange(t0, t1, 1.0 / rate)
    rot = Rotation.from_euler("z", (0.5 * t)[:, None]) * Rotation.from_euler("x", 0.3)
    acc_world = np.stack([0.5 * np.sin(2 * np.pi * 0.2 * t), 0.2 * np.ones_like(t), np.full_like(t, GRAVITY)], 1)
    gyro_world = np.tile([0.0, 0.0, 0.5], (t.size, 1))
    return DeviceStream(
        t=t,
        acc=rot.inv().apply(acc_world),
        gyro=rot.inv().apply(gyro_world),
        quat=rot.as_quat(scalar_first=True),
        worn=worn,
    ), acc_world


def walk(devices, duration=20.0):
    t = np.arange(0, duration + 1e-9, 0.01)
    truth = Trajectory(t, np.stack([1.2 * t, 0.3 * t], 1))
    return Recording("w", devices, truth=truth, labels=[(0, 10, "activity", "walk"), (10, 20, "activity", "stand")])


def test_world_frame_recovers_world_acceleration_at_25hz():
    phone, acc_world = rotating_device(100.0)
    a = align(walk({"phone": phone}), PreprocessConfig(devices=("phone",)))
    assert a.rate == pytest.approx(25.0)
    assert a.imu.shape == (1, len(a.t), 6)
    inner = slice(10, -10)  # away from filter edges
    expect = np.stack([np.interp(a.t, phone.t, acc_world[:, k]) for k in range(3)], 1)
    np.testing.assert_allclose(a.imu[0, inner, :3], expect[inner], atol=0.02)
    np.testing.assert_allclose(a.imu[0, inner, 5], 0.5, atol=1e-3)
    g = align(walk({"phone": phone}), PreprocessConfig(devices=("phone",), remove_gravity=True))
    assert abs(np.median(g.imu[0, :, 2])) < 0.01


def test_device_frame_option_keeps_raw_axes():
    phone, _ = rotating_device(50.0)
    a = align(walk({"phone": phone}), PreprocessConfig(devices=("phone",), frame="device", lowpass=False))
    np.testing.assert_allclose(a.imu[0, 5, :3], phone.acc[np.searchsorted(phone.t, a.t[5])], atol=1e-4)


def test_missing_device_is_zero_and_masked_not_dropped():
    phone, _ = rotating_device(100.0)
    a = align(walk({"phone": phone}))
    assert a.devices == ("phone", "watch", "earbuds")
    assert a.mask[0].all() and not a.mask[1:].any()
    assert np.all(a.imu[1:] == 0)


def test_device_removed_midwalk_is_masked_and_does_not_cut_the_clock():
    phone, _ = rotating_device(100.0)
    watch, _ = rotating_device(100.0, t1=8.0)  # stream stops at 8 s
    n = int(20 * 25)
    worn = np.ones(n, bool)
    worn[n // 2 :] = False  # earbuds taken off and left lying there at 10 s
    ear, _ = rotating_device(25.0, worn=worn)
    a = align(walk({"phone": phone, "watch": watch, "earbuds": ear}))
    assert a.t[-1] > 19.0
    assert a.mask[1, a.t < 7.9].all() and not a.mask[1, a.t > 8.1].any()
    assert a.mask[2, a.t < 9.9].all() and not a.mask[2, a.t > 10.1].any()
    assert np.all(a.imu[1, a.t > 8.1] == 0)


def test_small_clock_offsets_are_cut_to_the_overlap():
    phone, _ = rotating_device(100.0, t0=0.0, t1=20.0)
    ear, _ = rotating_device(25.0, t0=0.4, t1=19.7)
    rec = walk({"phone": phone, "earbuds": ear})
    t0, t1 = common_span(rec, ("phone", "earbuds"), tol=2.0)
    assert t0 == pytest.approx(0.4) and t1 == pytest.approx(ear.t[-1])
    with pytest.raises(ValidationError, match="none of the devices"):
        common_span(rec, ("watch",), tol=2.0)


def test_world_frame_needs_orientation():
    s = DeviceStream(t=np.arange(100) / 50, acc=np.tile([0, 0, 9.8], (100, 1)))
    with pytest.raises(ConfigError, match="orientation"):
        align(Recording("r", {"phone": s}), PreprocessConfig(devices=("phone",)))


def test_window_targets_and_masks():
    phone, _ = rotating_device(100.0)
    watch, _ = rotating_device(100.0, t1=8.0)
    rec = walk({"phone": phone, "watch": watch})
    ds = WindowDataset.from_recordings([rec], wcfg=WindowConfig(window=100, stride=25, label_kind="activity"))
    a = ds.sequences[0]
    assert len(ds) == (len(a) - 100) // 25 + 1
    item = ds[0]
    assert item["x"].shape == (3, 100, 6)
    np.testing.assert_allclose(item["vel"].numpy(), [1.2, 0.3], atol=1e-4)
    dt = float(item["t"][1] - item["t"][0])
    assert dt == pytest.approx(99 / 25)
    np.testing.assert_allclose(item["disp"].numpy(), np.array([1.2, 0.3]) * dt, atol=1e-4)
    assert item["mask"].tolist() == [1.0, 1.0, 0.0]
    last = ds[len(ds) - 1]
    assert last["mask"].tolist() == [1.0, 0.0, 0.0] and float(last["x"][1].abs().sum()) == 0.0
    assert ds.classes == ["stand", "walk"]
    assert item["label"].item() == 1 and last["label"].item() == 0


def test_windows_without_truth():
    phone, _ = rotating_device(100.0)
    rec = Recording("r", {"phone": phone})
    assert len(WindowDataset.from_recordings([rec], wcfg=WindowConfig())) == 0
    ds = WindowDataset.from_recordings([rec], wcfg=WindowConfig(target=None))
    assert len(ds) > 0 and np.isnan(ds[0]["vel"].numpy()).all()
    with pytest.raises(ConfigError):
        WindowConfig(target="class")


def test_from_seconds():
    c = WindowConfig.from_seconds(4.0, 0.4, 25.0)
    assert (c.window, c.stride) == (100, 10)


def test_batched_fetch_equals_single_items(small_recording):
    import torch

    from wearnav.preprocess import PreprocessConfig
    from wearnav.preprocess.windows import WindowConfig, WindowDataset

    wds = WindowDataset.from_recordings(
        [small_recording],
        PreprocessConfig(frame="device", devices=("phone", "earbuds")),
        WindowConfig(window=10, stride=3),
    )
    assert len(wds) > 3
    batch = wds[[2, 0, 1]]
    for j, k in enumerate([2, 0, 1]):
        item = wds[k]
        for key in item:
            assert torch.equal(batch[key][j], item[key]) or (
                torch.isnan(item[key]).all() and torch.isnan(batch[key][j]).all()
            )
    seen = [k for b in wds.loader(2, shuffle_seed=0) for k in b["t"][:, 0].tolist()]
    assert sorted(seen) == sorted(wds[list(range(len(wds)))]["t"][:, 0].tolist())


def test_device_resident_copy_fetches_the_same_batches():
    """WindowDataset.to(device) (issue 37: the GPU's data path) gathers on the device what the host
    fetch makes, bit for bit: two sequences end to end, a device that stops mid-walk (zeroed where
    absent). Checked on the CPU device, which CI has."""
    import torch

    phone, _ = rotating_device(100.0)
    watch, _ = rotating_device(100.0, t1=8.0)
    ear, _ = rotating_device(25.0, t1=12.0)
    a = align(walk({"phone": phone, "watch": watch, "earbuds": ear}))
    b = align(walk({"phone": rotating_device(50.0)[0]}, duration=15.0))
    cfg = WindowConfig(window=20, stride=7, target=None)
    host = WindowDataset([a, b], cfg)
    resident = WindowDataset([a, b], cfg).to("cpu", chunk=5)
    assert len(host) > 40
    for k in ([3, 0, len(host) - 1, 17], list(range(len(host)))):
        want, got = host[k], resident[k]
        assert list(got) == list(want)
        for key in want:
            assert got[key].dtype == want[key].dtype and got[key].shape == want[key].shape, key
            torch.testing.assert_close(got[key], want[key], rtol=0, atol=0, equal_nan=True)
    assert not resident[list(range(len(host)))]["mask"].all()  # the watch's absence was exercised


def test_gap_rules_of_streams_and_truth():
    phone, _ = rotating_device(100.0)
    keep = (phone.t < 5.0) | (phone.t >= 5.03) & ((phone.t < 10.0) | (phone.t >= 10.05))
    holes = DeviceStream(t=phone.t[keep], acc=phone.acc[keep], gyro=phone.gyro[keep], quat=phone.quat[keep])
    rec = walk({"phone": holes})
    rec.truth = Trajectory(
        np.r_[np.arange(0, 12, 0.1), 14.0, 20.0], np.zeros((122, 2))
    )  # dense to 12 s, then waypoints 2 and 6 s apart
    a = align(rec, PreprocessConfig(devices=("phone",)))
    # 3 dropped samples (a 0.04 s interval, 4 periods) is a hole; 2 (0.03 s, 3 periods) is not
    assert a.mask[0, (a.t > 5.0) & (a.t < 5.03)].all()
    assert not a.mask[0, (a.t > 10.0) & (a.t < 10.04)].any()
    assert np.all(a.imu[0, ~a.mask[0]] == 0)
    # between the waypoints nothing is interpolated; on one (t = 14 s exactly) the truth is known
    assert np.isfinite(a.pos[a.t < 11.9]).all() and np.isnan(a.pos[(a.t > 12.0) & (a.t != 14.0)]).all()
    assert np.isfinite(a.pos[a.t == 14.0]).all() and (a.t == 14.0).sum() == 1


def phone_pointing(yaw: float, pitch: float, rate: float = 50.0, duration: float = 20.0):
    """A phone whose top edge points at ``yaw`` (rad, counter-clockwise from +x), pitched up by
    ``pitch`` (0: flat, screen up; π/2: upright, screen to the walker)."""
    t = np.arange(0, duration, 1.0 / rate)
    # body y forward: about z by yaw − π/2 takes +y to the yaw; about x by pitch tilts +y up
    rot = Rotation.from_euler("z", yaw - np.pi / 2) * Rotation.from_euler("x", pitch)
    rots = Rotation.from_quat(np.tile(rot.as_quat(), (t.size, 1)))
    acc = rots.inv().apply(np.tile([0.0, 0.0, GRAVITY], (t.size, 1)))
    return DeviceStream(t=t, acc=acc, gyro=np.zeros_like(acc), quat=rots.as_quat(scalar_first=True))


@pytest.mark.parametrize("pitch", [0.0, 0.6, np.pi / 2])
def test_device_heading_is_where_the_phone_points_flat_or_upright(pitch):
    from wearnav.preprocess import device_heading

    for yaw in (0.3, 2.0, -2.5):
        phone = phone_pointing(yaw, pitch)
        h = device_heading(phone, np.arange(1.0, 19.0, 0.04))
        np.testing.assert_allclose(np.angle(h * np.exp(-1j * yaw)), 0.0, atol=1e-6)


def test_heading_frame_windows_see_travel_ahead_and_predictions_turn_back():
    """issue 34: a phone pointing where its walker goes gives targets (speed, 0) in the heading frame
    whatever the direction of travel; predict_sequence turns a model's velocity back by ψ."""
    import torch

    from wearnav.evaluate import predict_sequence

    direction = np.arctan2(0.3, 1.2)
    rec = walk({"phone": phone_pointing(direction, 0.5)})
    cfg = PreprocessConfig(devices=("phone",), frame_align="none", heading_frame=True)
    a = align(rec, cfg)
    assert a.yaw is not None and np.allclose(a.yaw, direction, atol=1e-6)
    plain = WindowDataset([align(rec, PreprocessConfig(devices=("phone",), frame_align="none"))], WindowConfig(20, 10))
    heading = WindowDataset([a], WindowConfig(20, 10))
    assert heading.heading and not plain.heading and "yaw" not in plain[[0]]
    b, w = heading[list(range(len(heading)))], plain[list(range(len(plain)))]
    speed = np.hypot(1.2, 0.3)
    np.testing.assert_allclose(b["vel"].numpy(), np.tile([speed, 0.0], (len(heading), 1)), atol=1e-4)
    np.testing.assert_allclose(b["yaw"].numpy(), direction, atol=1e-6)
    # the input turned by −ψ: the horizontal acceleration is that of the world frame turned back
    hx = w["x"][..., 0].numpy() + 1j * w["x"][..., 1].numpy()
    np.testing.assert_allclose(
        b["x"][..., 0].numpy() + 1j * b["x"][..., 1].numpy(), hx * np.exp(-1j * direction), atol=1e-4
    )
    np.testing.assert_allclose(b["x"][..., 2].numpy(), w["x"][..., 2].numpy())

    class Ahead(torch.nn.Module):  # says "straight ahead at 1 m/s" for every window
        def predict(self, x, mask):
            return torch.tensor([[1.0, 0.0]]).repeat(x.shape[0], 1)

    _, vel, _ = predict_sequence(Ahead(), a, 20, 10)
    np.testing.assert_allclose(vel, np.tile([np.cos(direction), np.sin(direction)], (len(vel), 1)), atol=1e-6)


def test_heading_frame_is_left_out_of_configs_until_used_and_refuses_random_yaw():
    from wearnav import runs
    from wearnav.train.odometry import TrainConfig, run_record

    old = run_record(TrainConfig(model="suitein++", data="d"))
    assert "heading_frame" not in old["train"] and "heading_frame" not in old["preprocess"]
    new = run_record(TrainConfig(model="suitein++", data="d", heading_frame=True, augment=()))
    assert (
        new["train"]["heading_frame"] and new["preprocess"]["heading_frame"] and new["eval_preprocess"]["heading_frame"]
    )
    assert runs.config_hash(old) != runs.config_hash(new)
    with pytest.raises(ConfigError, match="rotate_yaw"):
        TrainConfig(model="suitein++", data="d", heading_frame=True)
    with pytest.raises(ConfigError, match="frame='world'"):
        PreprocessConfig(frame="device", heading_frame=True)


def test_time_warp_plays_a_walk_faster_along_the_same_path():
    """issue 34, the speed time-warp expansion: k times faster, the same path (positions at t' are
    the original's at k·t'), window speeds × k, gyroscope × k, linear acceleration × k², the
    heading frame's ψ carried along; k = 1 changes nothing."""
    from wearnav.preprocess import time_warped
    from wearnav.simulate import WalkConfig, simulate_recording

    rec = simulate_recording(WalkConfig(mode="STW", placement="HD", duration_s=60), seed=4)
    a = align(rec, PreprocessConfig(devices=("phone",), frame_align="none", heading_frame=True))
    same = time_warped(a, 1.0)
    np.testing.assert_allclose(same.imu, a.imu, atol=1e-4)
    np.testing.assert_allclose(same.pos, a.pos, atol=1e-9)
    k = 1.25
    f = time_warped(a, k)
    assert abs((f.t[-1] - f.t[0]) - (a.t[-1] - a.t[0]) / k) < 1.0 / a.rate and f.rate == pytest.approx(a.rate)
    src = a.t[0] + k * (f.t - f.t[0])
    for c in (0, 1):
        np.testing.assert_allclose(f.pos[:, c], np.interp(src, a.t, a.pos[:, c]), atol=1e-9)
    ok = np.isfinite(f.yaw)
    turned = np.exp(1j * f.yaw[ok]) * np.exp(-1j * np.interp(src[ok], a.t, np.unwrap(a.yaw)))
    assert np.abs(np.angle(turned)).max() < 0.05

    def rms(x):
        return float(np.sqrt(np.mean((x - x.mean(axis=0)) ** 2)))

    assert rms(f.imu[0, :, 3:]) == pytest.approx(k * rms(a.imu[0, :, 3:]), rel=0.05)
    assert rms(f.imu[0, :, 2]) == pytest.approx(k * k * rms(a.imu[0, :, 2]), rel=0.05)
    windows = [WindowDataset([s], WindowConfig(100, 10)) for s in (a, f)]
    speed = [np.median(np.linalg.norm(w[list(range(len(w)))]["vel"].numpy(), axis=1)) for w in windows]
    assert speed[1] == pytest.approx(k * speed[0], rel=0.03)
    with pytest.raises(ConfigError, match="factor > 0"):
        time_warped(a, 0.0)
    # in a training config: left out of its record (and hash) while empty, bounded when given
    from wearnav.bench.real import RealBench
    from wearnav.train.odometry import TrainConfig, run_record

    assert "speed_warp" not in run_record(TrainConfig(model="suitein++", data="d"))["train"]
    assert run_record(TrainConfig(model="suitein++", data="d", speed_warp=(0.8, 1.25)))["train"]["speed_warp"]
    for make in (
        lambda: TrainConfig(model="suitein++", data="d", speed_warp=(9.0,)),
        lambda: RealBench(speed_warp=(0.1,)),
    ):
        with pytest.raises(ConfigError, match="speed-warp factors"):
            make()
