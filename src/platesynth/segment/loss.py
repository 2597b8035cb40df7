"""StarDist's loss per branch, and the optional within-well penalty on plaques."""

from __future__ import annotations

import torch
import torch.nn.functional as F

_EPS = 1e-7


def branch_loss(
    prob_logits: torch.Tensor,
    dist_pred: torch.Tensor,
    prob_true: torch.Tensor,
    dist_true: torch.Tensor,
    lambda_dist: float = 0.2,
    background_reg: float = 1e-4,
    prob_weight: torch.Tensor | None = None,
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """StarDist's loss of one branch.

    ``BCE(prob) + lambda_dist * [mean(p * |d - d_pred|) / mean(p) + background_reg * mean((1 - p) * |d_pred|)]``
    with ``p`` the true object probability, means over pixels and rays.

    Parameters
    ----------
    prob_logits : (B, 1, h, w) tensor
        Predicted object probability as logits.
    dist_pred : (B, R, h, w) tensor
        Predicted radial distances in pixels.
    prob_true : (B, 1, h, w) tensor
        Target probability in [0, 1] (normalised distance transform).
    dist_true : (B, R, h, w) tensor
        Target radial distances.
    lambda_dist : float
        Weight of the distance term (StarDist's default 0.2).
    background_reg : float
        Weight of the pull of predicted distances towards 0 on background (StarDist's default 1e-4).
    prob_weight : (B, 1, h, w) tensor, optional
        Per-pixel weights of the BCE term (the mean of the weighted terms); ``None`` weighs every pixel 1.

    Returns
    -------
    loss : scalar tensor
    parts : dict with the detached ``prob``, ``dist`` and ``reg`` terms.
    """
    prob_term = F.binary_cross_entropy_with_logits(prob_logits, prob_true, weight=prob_weight)
    abs_error = (dist_true - dist_pred).abs()
    dist_term = (prob_true * abs_error).mean() / (prob_true.mean() + _EPS)
    reg_term = ((1 - prob_true) * dist_pred.abs()).mean()
    loss = prob_term + lambda_dist * (dist_term + background_reg * reg_term)
    return loss, {"prob": prob_term.detach(), "dist": dist_term.detach(), "reg": reg_term.detach()}


def outside_well_penalty(plaque_logits: torch.Tensor, well_mask: torch.Tensor) -> torch.Tensor:
    """Mean predicted plaque probability on pixels outside every well.

    Parameters
    ----------
    plaque_logits : (B, 1, h, w) tensor
        Plaque probability logits.
    well_mask : (B, 1, h, w) tensor
        1 inside a (true) well, 0 outside, on the plaque grid.
    """
    return (torch.sigmoid(plaque_logits) * (1 - well_mask)).mean()


def segmentation_loss(
    outputs: dict[str, tuple[torch.Tensor, torch.Tensor]],
    targets: dict[str, torch.Tensor],
    lambda_dist: float = 0.2,
    background_reg: float = 1e-4,
    within_well_weight: float = 0.0,
) -> tuple[torch.Tensor, dict[str, float]]:
    """Sum of :func:`branch_loss` over the branches, plus ``within_well_weight`` x :func:`outside_well_penalty`.

    Parameters
    ----------
    outputs : the network's ``{branch: (prob_logits, distances)}``.
    targets : ``{"<branch>_prob", "<branch>_dist"}`` for every branch, optionally ``"<branch>_weight"`` (the
        per-pixel weights of its probability loss), and ``"well_mask"`` (on the plaque grid) when
        ``within_well_weight > 0``.

    Returns
    -------
    loss : scalar tensor
    parts : float of every term, keyed ``"<branch>_<term>"``, ``"outside_well"`` and ``"total"``.
    """
    total = torch.zeros((), device=next(iter(outputs.values()))[0].device)
    parts: dict[str, float] = {}
    for name, (prob_logits, dist_pred) in outputs.items():
        loss, terms = branch_loss(
            prob_logits, dist_pred, targets[f"{name}_prob"], targets[f"{name}_dist"], lambda_dist, background_reg,
            targets.get(f"{name}_weight"),
        )
        total = total + loss
        parts.update({f"{name}_{key}": float(value) for key, value in terms.items()})
    if within_well_weight > 0:
        penalty = outside_well_penalty(outputs["plaques"][0], targets["well_mask"])
        total = total + within_well_weight * penalty
        parts["outside_well"] = float(penalty.detach())
    parts["total"] = float(total.detach())
    return total, parts
