"""The velocity losses (wearnav.models.base.velocity_loss): a mean-squared error shrinks a velocity
whose direction the input leaves uncertain; the polar loss (L1 on log speed + speed-weighted
direction) keeps its length. Issue 34 §2, "The loss"."""

import math

import pytest
import torch
from torch.nn import functional as F

from wearnav.errors import ConfigError
from wearnav.models.base import VEL_LOSSES, instance_velocity_loss, velocity_loss

SPEED_M_S = 1.2


def _ambiguous_targets(n: int = 600, spread_deg: float = 60.0) -> torch.Tensor:
    """Velocities of one speed whose directions spread uniformly over ±spread around +x: what a
    model sees when the input cannot tell the direction more precisely than that."""
    g = torch.Generator().manual_seed(0)
    ang = (torch.rand(n, generator=g) * 2 - 1) * math.radians(spread_deg)
    return SPEED_M_S * torch.stack([torch.cos(ang), torch.sin(ang)], 1)


def _fit_constant(targets: torch.Tensor, loss_fn, steps: int = 1500) -> torch.Tensor:
    """The one velocity (2,) that minimises ``loss_fn`` over ``targets``: the best a model can do
    where its input says nothing about which of them is meant."""
    v = torch.tensor([0.3, 0.05], requires_grad=True)
    opt = torch.optim.Adam([v], lr=0.02)
    for _ in range(steps):
        opt.zero_grad()
        loss_fn(v.expand_as(targets), targets).backward()
        opt.step()
    return v.detach()


def test_mse_shrinks_an_uncertain_direction_and_polar_does_not():
    targets = _ambiguous_targets()
    mse = _fit_constant(targets, lambda p, t: velocity_loss(p, t, "mse"))
    polar = _fit_constant(targets, lambda p, t: velocity_loss(p, t, "polar"))
    # MSE's optimum is the mean vector: 1.2 · sin(60°)/60° (rad) = 0.99 m/s, 17 % short
    expected_mse = SPEED_M_S * math.sin(math.radians(60)) / math.radians(60)
    assert mse.norm().item() == pytest.approx(expected_mse, rel=0.03)
    assert mse.norm().item() < 0.9 * SPEED_M_S
    assert polar.norm().item() == pytest.approx(SPEED_M_S, rel=0.02)
    # both point along the mean direction (+x)
    assert abs(math.atan2(polar[1].item(), polar[0].item())) < math.radians(3)


def test_a_gaussian_nll_with_learned_variance_shrinks_as_mse_does():
    """Why the polar loss and not only TLIO's Gaussian NLL: with a learned (isotropic) variance the
    NLL's optimal mean is still the mean vector, so it shrinks exactly as MSE does; its σ grows
    instead of its length being kept."""
    targets = _ambiguous_targets()
    mean = torch.tensor([0.3, 0.05], requires_grad=True)
    log_var = torch.zeros(1, requires_grad=True)
    opt = torch.optim.Adam([mean, log_var], lr=0.02)
    for _ in range(2000):
        opt.zero_grad()
        var = log_var.exp().expand(len(targets), 2)
        F.gaussian_nll_loss(mean.expand_as(targets), targets, var).backward()
        opt.step()
    assert mean.norm().item() < 0.9 * SPEED_M_S


def test_a_small_network_trained_with_each_loss():
    """Input carries the speed (a gait amplitude) but nothing of the direction: MSE's network
    comes out short, the polar loss's network has the right speed."""
    g = torch.Generator().manual_seed(1)
    n = 2048
    speed = 0.6 + 1.0 * torch.rand(n, generator=g)  # 0.6–1.6 m/s
    ang = (torch.rand(n, generator=g) * 2 - 1) * math.radians(70)
    vel = speed[:, None] * torch.stack([torch.cos(ang), torch.sin(ang)], 1)
    x = torch.stack([speed, speed**2, torch.randn(n, generator=g)], 1)

    def train(kind: str) -> torch.Tensor:
        torch.manual_seed(0)
        net = torch.nn.Sequential(torch.nn.Linear(3, 32), torch.nn.ReLU(), torch.nn.Linear(32, 2))
        opt = torch.optim.Adam(net.parameters(), lr=1e-2)
        for _ in range(400):
            opt.zero_grad()
            velocity_loss(net(x), vel, kind).backward()
            opt.step()
        with torch.no_grad():
            return (net(x).norm(dim=1) / speed).median()

    assert train("mse").item() < 0.88  # sin(70°)/70° = 0.77 at the optimum
    assert train("polar").item() == pytest.approx(1.0, abs=0.05)


def test_polar_is_zero_at_the_truth_and_ignores_the_direction_of_standing_still():
    t = torch.tensor([[1.0, 0.0], [0.0, -0.5], [0.0, 0.0]])
    assert velocity_loss(t.clone(), t, "polar").item() == pytest.approx(0.0, abs=1e-3)
    # a window standing still: only its (near-zero) speed counts, whatever direction is predicted
    p = torch.tensor([[1.0, 0.0], [0.0, -0.5], [0.0, 1e-4]])
    assert velocity_loss(p, t, "polar").item() == pytest.approx(0.0, abs=1e-3)


def test_polar_gradients_are_finite_at_zero_prediction():
    p = torch.zeros(4, 2, requires_grad=True)
    t = torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0], [-1.0, 0.5]])
    velocity_loss(p, t, "polar").backward()
    assert torch.isfinite(p.grad).all()


def test_the_instance_losses_average_to_the_loss():
    gen = torch.Generator().manual_seed(0)
    p, t = torch.randn(16, 2, generator=gen), torch.randn(16, 2, generator=gen)
    for kind in VEL_LOSSES:
        each = instance_velocity_loss(p, t, kind)
        assert each.shape == (16,) and (each >= 0).all()
        assert each.mean().item() == pytest.approx(velocity_loss(p, t, kind).item(), rel=1e-5)
    # polar, by hand: half the speed → |log((0.5 + f) / (1 + f))|; 90° off at the mean speed → 1
    f = 0.1
    each = instance_velocity_loss(
        torch.tensor([[0.5, 0.0], [0.0, 1.0]]), torch.tensor([[1.0, 0.0], [1.0, 0.0]]), "polar"
    )
    assert each.tolist() == pytest.approx([math.log((1 + f) / (0.5 + f)), 1.0], abs=1e-4)


def test_unknown_loss_is_refused():
    assert "mse" in VEL_LOSSES and "polar" in VEL_LOSSES
    with pytest.raises(ConfigError, match="velocity loss"):
        velocity_loss(torch.zeros(1, 2), torch.zeros(1, 2), "l2")
    with pytest.raises(ConfigError, match="velocity loss"):
        instance_velocity_loss(torch.zeros(1, 2), torch.zeros(1, 2), "l2")


def test_the_command_lines_choices_are_the_losses():
    from wearnav.cli.common import VelLoss

    assert tuple(v.value for v in VelLoss) == VEL_LOSSES
