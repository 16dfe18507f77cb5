"""CoAdapt's small-loss selection diagnosed, and amended inside its own idea (issue 59).

Faithful CoAdapt (paper 004, eqs. 14–18; :mod:`wearnav.train.noisy`) keeps the R_s = max(R_τ, R_δ)
share of each batch with the smallest loss, weights the last 20 % of them 0.1, and sets R_δ from
the share of instances whose displacement error is below δ = 0.24 m. On the simulator it costs
accuracy where labels are nearly clean (issue 59: EasyTrack 63.0 cm ADE on L1 against BaseModel
48.9). Each cause the issue names has a diagnostic here, a function of one batch that returns a
number (the training loop logs each per epoch, :func:`wearnav.train.noisy.fit_noisy`):

* the selection's bias by segment length (:func:`length_bias`): an absolute loss ‖d̂ − d̃‖ grows
  with the segment's length wherever the model errs in proportion to speed, so the smallest losses
  are the slow segments, and the peer learns to walk slow;
* δ's absolute scale (:func:`delta_scale`): δ = 0.24 m against the batch's median error; the paper's
  models err four times less than these, so the same δ marks far fewer instances clean;
* the 0.1 weight on the last 20 % of the selected (:func:`weighting_length_bias`): those are the
  largest losses, i.e. again the longer segments;
* the ensemble (:func:`ensemble_shrinkage`): the mean of two predictions is shorter than either
  where they disagree in direction.

The amended rule (method ``easytrack-amended``) keeps CoAdapt's idea (drop the instances whose
loss says their label is noisy, weight the doubtful ones down, each model teaching its peer) and
removes the scale from it:

* selection within length strata (:func:`select_stratified`): the batch is cut into ``strata``
  (8: 8 segments each in a batch of 64) groups by label length ‖d̃‖ and each group keeps its own
  R_s share of smallest losses (and weights its own last 20 %), so the selected segments are about
  as long as the batch's;
* δ from the data (:func:`outlier_share`): an instance counts as clean when its *relative* error
  ‖d̂ − d̃‖ / max(‖d̃‖, floor) is not an outlier of the batch's own relative errors (at most the
  median + ``k``·MAD; k = 3 is ~2σ for a normal, fixed a priori, not tuned), so R_δ is near 1 where
  the losses are homogeneous (labels nearly clean, or the model's own error dominating) and falls
  where a tail of label errors stands out, in any unit and at any model accuracy.

Decision: docs/decisions/0047-easytrack-amended-and-table-v-power.md.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

# the relative error's floor on the label length (m): a 1-s segment standing still would otherwise
# have an unbounded relative error; the polar loss's log floor is the same 0.1 m (models.base)
REL_FLOOR_M = 0.1


# ---- diagnostics: one number per cause --------------------------------------------------------------


def length_bias(idx: Tensor, length: Tensor) -> float:
    """Mean length of the selected instances ``idx`` over the batch's mean ``length`` (B,): 1 is
    unbiased, below 1 the selection prefers short (slow) segments."""
    mean = float(length.mean())
    return float(length[idx].mean()) / mean if mean > 0 and idx.numel() else float("nan")


def delta_scale(err: Tensor, delta: float) -> float:
    """δ (m) over the batch's median displacement error ``err`` (B,) (m): near 1, δ sits amid the
    errors and R_δ near 0.5; well below 1, δ is strict for this model and R_δ small. In the paper's
    regime (model 11.2 cm, label noise 21.6 cm median) δ = 0.24 m is ~1× the median error."""
    med = float(err.median()) if err.numel() else float("nan")
    return delta / med if med > 0 else float("nan")


def weighting_length_bias(idx: Tensor, w: Tensor, length: Tensor) -> float:
    """The selected instances' weighted mean length over their unweighted mean: below 1, the low
    weight of the last ``low_share`` falls on the longer segments."""
    sel = length[idx]
    plain = float(sel.mean()) if sel.numel() else float("nan")
    return float((w * sel).sum() / w.sum()) / plain if plain > 0 and float(w.sum()) > 0 else float("nan")


def ensemble_shrinkage(p1: Tensor, p2: Tensor) -> float:
    """Mean length of the ensemble (p1 + p2)/2 (eq. 11) over the mean of the two models' lengths,
    predictions (B, 2): 1 where the models agree in direction, below 1 where averaging shortens."""
    each = 0.5 * float((p1.norm(dim=1) + p2.norm(dim=1)).mean())
    return float((0.5 * (p1 + p2)).norm(dim=1).mean()) / each if each > 0 else float("nan")


# ---- the amended rule -------------------------------------------------------------------------------


def relative_error(pred: Tensor, target: Tensor, floor: float = REL_FLOOR_M) -> Tensor:
    """‖pred − target‖ / max(‖target‖, floor) per instance (B,): the error as a share of the label."""
    return (pred - target).norm(dim=1) / target.norm(dim=1).clamp_min(floor)


def outlier_share(rel: Tensor, k: float = 3.0) -> float:
    """p_δ of the amended rule: the share of relative errors ``rel`` (B,) at most median + k·MAD of
    the batch's own (MAD: median absolute deviation). No unit, no model scale."""
    if not rel.numel():
        return 0.0
    med = rel.median()
    mad = (rel - med).abs().median()
    return float((rel <= med + k * mad).float().mean())


def r_delta_amended(r_prev: float, pred: Tensor, target: Tensor, k: float, floor: float, beta: float) -> float:
    """R_δ = (1 − β) R_δ + β p_δ (eq. 14) with the data's p_δ (:func:`outlier_share`) on relative errors."""
    return (1 - beta) * r_prev + beta * outlier_share(relative_error(pred, target, floor), k)


def select_stratified(
    losses: Tensor, length: Tensor, ratio: float, strata: int = 8, low_share: float = 0.2, low_weight: float = 0.1
) -> tuple[Tensor, Tensor]:
    """CoAdapt's selection (:func:`wearnav.train.noisy.select_small_loss`) within ``strata`` groups
    of the batch cut by ``length`` (B,) (sorted, split into near-equal parts): the ⌈ratio·B⌉ kept
    are shared among the groups in proportion to their sizes, each group keeps
    its share of smallest ``losses`` and weights the last ``low_share`` of them ``low_weight``.
    Returns indices into the batch and their weights."""
    B = losses.numel()
    groups = [g for g in torch.tensor_split(torch.argsort(length.detach()), max(1, min(strata, B))) if g.numel()]
    k_total = min(B, max(1, int(math.ceil(ratio * B - 1e-9))))
    # each group's share of k_total by rounding the cumulative quota (ties to even): the remainders
    # spread over short and long groups alike, and the shares add up to k_total
    cum = [0, *(round(k_total * c / B) for c in torch.cumsum(torch.tensor([g.numel() for g in groups]), 0).tolist())]
    ks = [b - a for a, b in zip(cum, cum[1:])]
    idx, w = [], []
    for g, k in zip(groups, ks):
        if not k:
            continue
        pick = g[torch.argsort(losses.detach()[g])[:k]]
        wg = torch.ones(k, dtype=losses.dtype, device=losses.device)
        n_low = int(math.floor(low_share * k + 1e-9))
        if n_low:
            wg[k - n_low :] = low_weight
        idx.append(pick)
        w.append(wg)
    return torch.cat(idx), torch.cat(w)


def coadapt_losses_stratified(
    l1: Tensor,
    l2: Tensor,
    length: Tensor,
    ratio: float,
    strata: int = 8,
    low_share: float = 0.2,
    low_weight: float = 0.1,
) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor, Tensor]:
    """Eq. 18 with :func:`select_stratified`: (L_pre1, L_pre2, D_s1, D_s2, w1, w2); model 1 learns
    on its peer's selection with its peer's weights and vice versa; sums over the batch size."""
    B = l1.numel()
    s1, w1 = select_stratified(l1, length, ratio, strata, low_share, low_weight)
    s2, w2 = select_stratified(l2, length, ratio, strata, low_share, low_weight)
    return (w2 * l1[s2]).sum() / B, (w1 * l2[s1]).sum() / B, s1, s2, w1, w2
