"""The baselines of Suite-IN++'s Table III added beside RoNIN: IONet*, IMUNet/IMUNet*, DeepIT*,
ReWF, DeepSense* (sizes: tests/test_models_size.py). Shapes, device layouts and masks, learning."""

from __future__ import annotations

import pytest
import torch

from wearnav.errors import ConfigError
from wearnav.models import build, get
from wearnav.models.deepit import masked_softmax

NEW = {
    "ionet*": "concat",
    "imunet": "single",
    "imunet*": "concat",
    "deepit*": "multi",
    "rewf": "multi",
    "deepsense*": "concat",
}
# Small widths of the same architectures, so the tests take seconds.
SMALL = {
    "ionet*": {"hidden": 16},
    "imunet": {"widths": (8, 16, 16, 16)},
    "imunet*": {"widths": (8, 16, 16, 16)},
    "deepit*": {"hidden": 8, "embed": 16},
    "rewf": {"lstm_hidden": 8, "fc_dim": 32},
    "deepsense*": {"local": 8, "global_": 8, "gru_hidden": 16},
}


def batch(B=6, D=3, L=100, seed=0):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(B, D, L, 6, generator=g)
    x[..., 2] += 9.81
    mask = torch.ones(B, D)
    mask[1, 0] = 0  # no phone
    mask[2] = torch.tensor([0.0, 0.0, 1.0])
    mask[3, 1] = 0  # no watch
    return x, mask


def small(name, **kw):
    torch.manual_seed(0)
    return build(name, n_devices=3, window=100, **{**SMALL[name], **kw})


@pytest.mark.parametrize("name", NEW)
def test_registered_with_its_layout(name):
    spec = get(name)
    assert (spec.task, spec.layout, spec.learned) == ("odometry", NEW[name], True)


@pytest.mark.parametrize("name", NEW)
@pytest.mark.parametrize("train", [False, True])
def test_shape_finite_and_absent_devices_change_nothing(name, train):
    """(B, 2), finite; replacing an absent device's data (large random values) changes no
    output, in inference and in training (same random draws)."""
    m = small(name).train(train)
    x, mask = batch()
    x2 = x + 50.0 * (1 - mask)[:, :, None, None] * torch.randn_like(x)
    torch.manual_seed(1)
    v1 = m(x, mask)
    torch.manual_seed(1)
    v2 = m(x2, mask)
    assert v1.shape == (6, 2) and torch.isfinite(v1).all()
    assert torch.allclose(v1, v2, atol=1e-5)
    # ... and a present device's data matters.
    x3 = x.clone()
    x3[0, 0 if NEW[name] == "single" else 2] += 3.0
    torch.manual_seed(1)
    assert not torch.allclose(m(x3, mask)[0], v1[0], atol=1e-5)


@pytest.mark.parametrize("name", NEW)
def test_one_optimizer_step_reduces_the_loss(name):
    m = small(name, **({"dropout": 0.0} if name in ("imunet", "imunet*", "rewf", "deepsense*") else {}))
    x, mask = batch(B=16, seed=2)
    vel = torch.randn(16, 2, generator=torch.Generator().manual_seed(3))
    b = {"x": x, "mask": mask, "vel": vel}
    opt = torch.optim.Adam(m.parameters(), lr=1e-3)

    def loss():
        torch.manual_seed(4)  # the same Gumbel draws for ReWF
        return m.loss(b)[0]

    m.train()
    before = loss()
    opt.zero_grad()
    before.backward()
    opt.step()
    with torch.no_grad():
        after = loss()
    assert after < before, (before.item(), after.item())


def test_fusion_weights_are_zero_for_absent_devices():
    w = masked_softmax(
        torch.tensor([[5.0, 1.0, -2.0], [0.0, 0.0, 0.0], [1.0, 2.0, 3.0]]),
        torch.tensor([[0.0, 1.0, 1.0], [1.0, 1.0, 1.0], [0.0, 0.0, 0.0]]),
    )
    assert w[0, 0] == 0 and torch.allclose(w[0, 1:], torch.softmax(torch.tensor([1.0, -2.0]), 0))
    assert torch.allclose(w[1], torch.full((3,), 1 / 3)) and torch.equal(w[2], torch.zeros(3))
    for name in ("deepit*", "rewf"):
        m = small(name).eval()
        x, mask = batch()
        with torch.no_grad():
            _, weights = m.weights(x, mask)
        assert torch.equal(weights == 0, mask == 0) and torch.allclose(weights.sum(1), torch.ones(6))


def test_rewf_gumbel_noise_only_in_training():
    m = small("rewf").eval()
    x, mask = batch()
    with torch.no_grad():
        assert torch.equal(m.weights(x, mask)[1], m.weights(x, mask)[1])
        m.train()
        torch.manual_seed(0)
        a = m.weights(x, mask)[1]
        torch.manual_seed(1)
        assert not torch.allclose(a, m.weights(x, mask)[1])


def test_imunet_is_depthwise_separable_and_imunet_star_reads_all_devices():
    m, star = small("imunet"), small("imunet*")
    assert m.input_block[0].in_channels == 6 and star.input_block[0].in_channels == 18
    assert any(c.groups == c.in_channels > 1 for c in m.modules() if isinstance(c, torch.nn.Conv1d))


def test_wrong_device_count_and_short_windows_are_config_errors():
    x, mask = torch.randn(2, 2, 100, 6), torch.ones(2, 2)
    for name in ("deepit*", "rewf", "deepsense*"):
        with pytest.raises(ConfigError):
            small(name)(x, mask)
    with pytest.raises(ConfigError):
        build("imunet", window=20)
    with pytest.raises(ConfigError):
        build("deepsense*", window=50)
