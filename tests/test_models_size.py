"""Model sizes against Suite-IN++'s Table VI (paper 000, lines ~432–446 of
/work/shared/papers/000_772d43a4e87196df.txt) and the multiply-accumulate counter that measures
them (bench.efficiency.macs_per_window: the paper's "FLOPs (G)" are MACs, its RoNIN 0.021 G =
FlopCounterMode's 42.1 MFLOPs / 2).

Tolerances: parameters within 5 %, MACs within 15 % of the paper, at 3 devices × 100 samples."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from wearnav.bench.efficiency import macs_per_window, recurrent_macs
from wearnav.models import build
from wearnav.models.base import OdometryModel
from wearnav.models.registry import n_parameters

# Table VI ("Model Efficiency and Complexity of various methods", paper 000 lines 432–444):
# registered name, build kwargs, parameters (K), FLOPs (G) = MACs, line of the paper.
TABLE_VI = [
    ("ionet", {"bidirectional": False}, 114.6, 0.004, 434),  # IONet (ours defaults to Bi-LSTM)
    ("ionet*", {}, 119.2, 0.004, 435),
    ("ronin", {}, 4438.2, 0.021, 436),
    ("ronin*", {}, 4443.7, 0.021, 437),
    ("imunet", {}, 4068.2, 0.020, 438),
    ("imunet*", {}, 4073.6, 0.020, 439),
    ("deepit*", {}, 317.3, 0.005, 440),
    ("rewf", {}, 14049.1, 0.223, 441),
    ("deepsense*", {}, 318.2, 0.007, 442),
    ("suitein", {}, 104.3, 0.026, 443),
    ("suitein++", {}, 498.8, 0.020, 444),
]

# MACs the described architecture cannot reach. IONet: Table VI's parameters are exactly a
# one-direction 2-layer LSTM of 96 + a linear head (114,626; IONet* 119,234 with 18 inputs), and
# such an LSTM needs 4·(in·96 + 96²) + 4·(2·96²) = 112,896 (IONet*: 115,200) MACs per time step:
# 11.3 M (11.5 M) for a 100-sample window, 2.8× the table's 0.004 G. The table's MACs would
# need ≈ 35 steps; its parameters fix the widths, so we keep them and count honestly.
UNREACHABLE_MACS = {
    "ionet": 100 * (4 * (6 * 96 + 96 * 96) + 4 * (2 * 96 * 96)) + 96 * 2,
    "ionet*": 100 * (4 * (18 * 96 + 96 * 96) + 4 * (2 * 96 * 96)) + 96 * 2,
}


@pytest.mark.parametrize("name,kw,params_k,gmacs,line", TABLE_VI, ids=[r[0] for r in TABLE_VI])
def test_size_matches_table_vi(name, kw, params_k, gmacs, line):
    torch.manual_seed(0)
    model = build(name, n_devices=3, window=100, **kw)
    params = n_parameters(model)
    assert abs(params / (params_k * 1e3) - 1) <= 0.05, (name, params, params_k)
    macs = macs_per_window(model)
    if name in UNREACHABLE_MACS:
        assert macs == UNREACHABLE_MACS[name]
    else:
        assert abs(macs / (gmacs * 1e9) - 1) <= 0.15, (name, macs, gmacs)


def test_suitein_extractor_readings_and_ablations_share_the_widths():
    """Both extractor readings at the paper's size (498.8 K parameters, 0.020 G MACs; the default
    mixes the six axes in block 1, suitein++-rows keeps them as rows); the Table V ablations are
    built from the default's extractors."""
    pp, rows = build("suitein++"), build("suitein++-rows")
    for m in (pp, rows):
        assert abs(n_parameters(m) / 498.8e3 - 1) < 0.05 and abs(macs_per_window(m) / 20e6 - 1) < 0.15
    assert pp.cfg.extractor == "mixed" and rows.cfg.extractor == "paper"
    for n in range(1, 6):
        abl = build(f"suitein++-abl{n}")
        assert abl.cfg.widths == pp.cfg.widths and abl.cfg.extractor == "mixed"


# --- the MAC counter --------------------------------------------------------------------------


class _Wrap(OdometryModel):
    """(B, D, L, 6) → module over time (B, L, D·6) → last step → (B, 2)."""

    def __init__(self, inner: nn.Module, out: int):
        super().__init__()
        self.inner, self.fc = inner, nn.Linear(out, 2, bias=False)

    def forward(self, x, mask):
        h = self.inner(x.permute(0, 2, 1, 3).flatten(2))
        h = h[0] if isinstance(h, tuple) else h
        return self.fc(h[:, -1])


@pytest.mark.parametrize("cls,gates", [(nn.LSTM, 4), (nn.GRU, 3)])
@pytest.mark.parametrize("layers,bidirectional", [(1, False), (2, True)])
def test_recurrent_layers_count_analytically(cls, gates, layers, bidirectional):
    """per step, direction and layer gates·(in·h + h·h); layer 2 reads h·directions inputs."""
    h, dirs = 8, 2 if bidirectional else 1
    rnn = cls(18, h, num_layers=layers, batch_first=True, bidirectional=bidirectional)
    expected = gates * (18 * h + h * h) * dirs
    if layers == 2:
        expected += gates * (h * dirs * h + h * h) * dirs
    assert recurrent_macs(rnn, steps=1) == expected
    model = _Wrap(rnn, h * dirs)
    assert macs_per_window(model, n_devices=3, window=100) == 100 * expected + h * dirs * 2


def test_linear_is_in_times_out():
    model = _Wrap(nn.Linear(18, 5), 5)
    # the Linear runs on each of the 100 steps; the head once
    assert macs_per_window(model, n_devices=3, window=100) == 100 * 18 * 5 + 5 * 2
    with pytest.raises(TypeError):
        recurrent_macs(nn.Linear(3, 3), steps=1)
