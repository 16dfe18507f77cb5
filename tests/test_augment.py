import dataclasses
import math

import numpy as np
import pytest
import torch

from wearnav.errors import ConfigError
from wearnav.preprocess import PreprocessConfig, align, augment
from wearnav.preprocess.windows import WindowConfig, WindowDataset
from wearnav.simulate import WalkConfig, simulate_recording


def batch(b=16, d=3, L=20, seed=0):
    g = torch.Generator().manual_seed(seed)
    return {
        "x": torch.randn(b, d, L, 6, generator=g),
        "mask": torch.ones(b, d),
        "vel": torch.randn(b, 2, generator=g),
        "disp": torch.randn(b, 2, generator=g),
        "label": torch.zeros(b, dtype=torch.long),
    }


def test_rotation_keeps_norms_and_vertical_channels():
    bt = batch()
    out = augment.apply(["rotate_yaw"], bt, torch.Generator().manual_seed(1))
    torch.testing.assert_close(out["vel"].norm(dim=1), bt["vel"].norm(dim=1))
    torch.testing.assert_close(out["disp"].norm(dim=1), bt["disp"].norm(dim=1))
    torch.testing.assert_close(out["x"][..., [2, 5]], bt["x"][..., [2, 5]])
    torch.testing.assert_close(out["x"][..., :2].norm(dim=-1), bt["x"][..., :2].norm(dim=-1))
    torch.testing.assert_close(out["x"][..., 3:5].norm(dim=-1), bt["x"][..., 3:5].norm(dim=-1))
    assert not torch.allclose(out["vel"], bt["vel"])  # it did rotate
    assert out["label"] is bt["label"]
    assert torch.equal(bt["x"], batch()["x"])  # input left untouched


def test_one_angle_per_sample_for_every_device_and_target():
    bt = batch()
    out = augment.rotate_yaw(bt, torch.Generator().manual_seed(3))

    def angle(v_new, v_old):  # signed angle from old to new, per vector
        return torch.atan2(v_old[..., 0] * v_new[..., 1] - v_old[..., 1] * v_new[..., 0], (v_old * v_new).sum(-1))

    a = angle(out["vel"], bt["vel"])
    for key in ("disp",):
        torch.testing.assert_close(angle(out[key], bt[key]), a, atol=1e-4, rtol=0)
    for i, j in ((0, 1), (3, 4)):  # acc xy, gyro xy
        per = angle(out["x"][..., [i, j]], bt["x"][..., [i, j]])  # (B, D, L)
        diff = torch.remainder(per - a[:, None, None] + math.pi, 2 * math.pi) - math.pi
        assert diff.abs().max() < 1e-3
    assert a.std() > 0.5  # different angles across samples


def test_known_rotation_direction_and_seeding():
    bt = {"x": torch.zeros(1, 1, 2, 6), "vel": torch.tensor([[1.0, 0.0]])}
    bt["x"][..., 0] = 1.0
    out = augment.rotate_batch(bt, torch.tensor([math.pi / 2]))
    torch.testing.assert_close(out["vel"], torch.tensor([[0.0, 1.0]]), atol=1e-6, rtol=0)
    torch.testing.assert_close(out["x"][0, 0, 0, :2], torch.tensor([0.0, 1.0]), atol=1e-6, rtol=0)
    b = batch()
    o1 = augment.rotate_yaw(b, torch.Generator().manual_seed(7))
    o2 = augment.rotate_yaw(b, torch.Generator().manual_seed(7))
    torch.testing.assert_close(o1["x"], o2["x"])


def test_registry():
    assert "rotate_yaw" in augment.AUGMENTATIONS
    with pytest.raises(ConfigError, match="unknown augmentation"):
        augment.get("nope")
    with pytest.raises(ConfigError, match="registered twice"):
        augment.register("rotate_yaw")(lambda b, g: b)


def test_scale_motion_scales_each_windows_motion_about_its_mean_and_keeps_the_targets():
    g = torch.Generator().manual_seed(0)
    x = torch.randn(64, 3, 100, 6, dtype=torch.float64) + torch.tensor([0, 0, 9.81, 0, 0, 0.1], dtype=torch.float64)
    b = {"x": x.clone(), "mask": torch.ones(64, 3), "vel": torch.randn(64, 2)}
    out = augment.get("scale_motion")(b, g)
    assert out["vel"] is b["vel"] and torch.equal(b["x"], x)  # targets kept, input untouched
    mean = x.mean(dim=2, keepdim=True)
    torch.testing.assert_close(out["x"].mean(dim=2, keepdim=True), mean)  # gravity, steady turn kept
    factor = (out["x"] - mean).std(dim=(1, 2, 3)) / (x - mean).std(dim=(1, 2, 3))
    # one factor per sample, the same for every device and channel, spread over MOTION_SCALE
    torch.testing.assert_close(out["x"] - mean, factor.view(-1, 1, 1, 1) * (x - mean))
    lo, hi = augment.MOTION_SCALE
    assert lo <= float(factor.min()) < 0.8 and 1.3 < float(factor.max()) <= hi


def test_drop_devices_leaves_devices_out_but_never_all_and_keeps_the_targets():
    b = batch(b=4000, d=3)
    b["mask"][:1000, 2] = 0  # some samples already lack a device
    b["x"][:1000, 2] = 0
    before = {k: v.clone() for k, v in b.items()}
    out = augment.get("drop_devices")(b, torch.Generator().manual_seed(0))
    assert all(torch.equal(b[k], before[k]) for k in b)  # the input is not modified
    assert torch.equal(out["vel"], b["vel"]) and torch.equal(out["disp"], b["disp"])
    m = out["mask"]
    assert bool((m <= b["mask"]).all()) and bool((m.sum(dim=1) >= 1).all())  # never added, never all gone
    assert torch.equal(out["x"], b["x"] * m[:, :, None, None])  # a dropped device's inputs are zeros
    kept = m[1000:].sum(dim=1)  # three present: each kept with 1 − p; none kept → all kept
    p = augment.DROP_DEVICE_P
    phone_only = ((m[1000:, 0] == 1) & (kept == 1)).float().mean()
    assert abs(float(phone_only) - p * p * (1 - p)) < 0.03
    assert abs(float((kept == 3).float().mean()) - ((1 - p) ** 3 + p**3)) < 0.03
    again = augment.get("drop_devices")(b, torch.Generator().manual_seed(0))
    assert torch.equal(again["mask"], m)  # seeded: reproducible


def test_leaving_out_the_carrier_turns_a_heading_frame_window_into_the_next_devices_frame():
    """issue 34: a model framed by the earbuds (the first of earbuds, phone, watch) must meet the
    phone's frame where the earbuds are absent; training that leaves the earbuds out turns the
    window as aligning the recording without them would have framed it."""
    rec = simulate_recording(WalkConfig(mode="STW", placement="PK", duration_s=30), seed=2)
    cfg = PreprocessConfig(devices=("earbuds", "phone", "watch"), frame_align="none", heading_frame=True)
    full = align(rec, cfg)
    no_buds = dataclasses.replace(rec, devices={k: v for k, v in rec.devices.items() if k != "earbuds"})
    alone = align(no_buds, cfg, full.t)
    wcfg = WindowConfig(100, 25)
    b = WindowDataset([full], wcfg)[list(range(5))]
    want = WindowDataset([alone], wcfg)[list(range(5))]
    assert b["yaws"].shape == (5, 3) and bool(torch.isfinite(b["yaws"]).all())
    # the earbuds point ~125° off the walk here, the pocketed phone elsewhere: the frames differ
    assert float((b["yaw"] - want["yaw"]).abs().min()) > 0.3
    keep = torch.tensor([[0.0, 1.0, 1.0]]).repeat(5, 1)
    out = augment.leave_out(b, keep)
    torch.testing.assert_close(out["yaw"], want["yaw"], atol=1e-5, rtol=0)
    torch.testing.assert_close(out["vel"], want["vel"], atol=1e-5, rtol=0)
    torch.testing.assert_close(out["disp"], want["disp"], atol=1e-4, rtol=0)
    torch.testing.assert_close(out["x"][:, 1:], want["x"][:, 1:], atol=1e-4, rtol=1e-4)
    assert bool((out["x"][:, 0] == 0).all()) and torch.equal(out["mask"], keep)
    # leaving out a device that is not the carrier keeps the frame; a world-frame batch has no turn
    same = augment.leave_out(b, torch.tensor([[1.0, 0.0, 1.0]]).repeat(5, 1))
    assert torch.equal(same["yaw"], b["yaw"]) and torch.equal(same["vel"], b["vel"])
    plain = {k: v for k, v in b.items() if k not in ("yaw", "yaws")}
    assert torch.equal(augment.leave_out(plain, keep)["vel"], b["vel"])
    assert np.isfinite(out["x"].numpy()).all()
