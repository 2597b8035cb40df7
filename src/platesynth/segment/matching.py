"""Instance matching and the paper's mask metrics: AP and IoU_R at IoU thresholds tau.

Per image, true and predicted objects are matched one-to-one (Hungarian) among the pairs with IoU >= tau, taking
the largest number of pairs and, among those, the largest total IoU. Then, with TP matched pairs, FP unmatched
predictions and FN unmatched true objects:

* ``AP = TP / (TP + FP + FN)``; 1 when there is neither a true nor a predicted object;
* ``IoU_R = (sum of IoU over matched pairs) / (number of true objects)``; undefined (NaN) without true objects.

Over a set of images, each metric is summarised by its mean and standard deviation over the images where it is
defined.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from platesynth.data.layout import list_items, load_item
from platesynth.errors import ShapeMismatchError
from platesynth.render.result import RenderResult


def iou_matrix(true: np.ndarray, pred: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IoU of every true object with every predicted object.

    Parameters
    ----------
    true, pred : (H, W) integer instance masks of equal shape (0 = background; ids need not be consecutive).

    Returns
    -------
    iou : (n_true, n_pred) float64
    true_ids, pred_ids : the object ids along each axis, ascending.
    """
    if true.shape != pred.shape:
        raise ShapeMismatchError(f"true mask {true.shape} and predicted mask {pred.shape} differ in size")
    true_ids, true_index = np.unique(true, return_inverse=True)
    pred_ids, pred_index = np.unique(pred, return_inverse=True)
    n_true, n_pred = len(true_ids), len(pred_ids)
    overlap = np.bincount(true_index.ravel() * n_pred + pred_index.ravel(), minlength=n_true * n_pred).reshape(n_true, n_pred)
    has_true_bg, has_pred_bg = true_ids[0] == 0, pred_ids[0] == 0
    area_true, area_pred = overlap.sum(axis=1), overlap.sum(axis=0)
    overlap = overlap[int(has_true_bg) :, int(has_pred_bg) :]
    area_true, area_pred = area_true[int(has_true_bg) :], area_pred[int(has_pred_bg) :]
    union = area_true[:, None] + area_pred[None, :] - overlap
    iou = np.divide(overlap, union, out=np.zeros(overlap.shape), where=union > 0)
    return iou, true_ids[int(has_true_bg) :], pred_ids[int(has_pred_bg) :]


@dataclass(frozen=True)
class MatchResult:
    """Outcome of matching one image's objects at one threshold ``tau``."""

    tau: float
    n_true: int
    n_pred: int
    tp: int
    iou_sum: float
    pairs: tuple[tuple[int, int], ...]
    """Matched ``(true_id, pred_id)`` pairs."""

    @property
    def fp(self) -> int:
        return self.n_pred - self.tp

    @property
    def fn(self) -> int:
        return self.n_true - self.tp

    @property
    def ap(self) -> float:
        """``TP / (TP + FP + FN)``; 1.0 where there is nothing to find and nothing was found."""
        denominator = self.tp + self.fp + self.fn
        return self.tp / denominator if denominator else 1.0

    @property
    def iou_r(self) -> float:
        """Sum of IoU over matched pairs divided by the number of true objects; NaN without true objects."""
        return self.iou_sum / self.n_true if self.n_true else math.nan


def match_from_iou(
    iou: np.ndarray, tau: float, true_ids: Sequence[int] | None = None, pred_ids: Sequence[int] | None = None
) -> MatchResult:
    """Optimal one-to-one matching of an IoU matrix at threshold ``tau`` (see the module docstring)."""
    if not 0 < tau <= 1:
        raise ValueError(f"tau must be in (0, 1], got {tau}")
    n_true, n_pred = iou.shape
    true_ids = np.arange(1, n_true + 1) if true_ids is None else np.asarray(true_ids)
    pred_ids = np.arange(1, n_pred + 1) if pred_ids is None else np.asarray(pred_ids)
    valid = iou >= tau
    if not valid.any():
        return MatchResult(tau, n_true, n_pred, 0, 0.0, ())
    rows_used, cols_used = np.flatnonzero(valid.any(axis=1)), np.flatnonzero(valid.any(axis=0))
    sub_valid, sub_iou = valid[np.ix_(rows_used, cols_used)], iou[np.ix_(rows_used, cols_used)]
    # A bonus above any possible total IoU makes the number of pairs come first, total IoU second.
    bonus = min(sub_valid.shape) + 1.0
    weight = np.where(sub_valid, bonus + sub_iou, 0.0)
    rows, cols = linear_sum_assignment(weight, maximize=True)
    keep = sub_valid[rows, cols]
    rows, cols = rows_used[rows[keep]], cols_used[cols[keep]]
    pairs = tuple((int(true_ids[r]), int(pred_ids[c])) for r, c in zip(rows, cols))
    return MatchResult(tau, n_true, n_pred, len(pairs), float(iou[rows, cols].sum()), pairs)


def match_instances(true: np.ndarray, pred: np.ndarray, tau: float = 0.5) -> MatchResult:
    """Match the objects of two instance masks at IoU threshold ``tau``."""
    iou, true_ids, pred_ids = iou_matrix(true, pred)
    return match_from_iou(iou, tau, true_ids, pred_ids)


def _summary(values: list[float]) -> tuple[float, float, int]:
    defined = np.asarray([v for v in values if not math.isnan(v)], float)
    if defined.size == 0:
        return math.nan, math.nan, 0
    return float(defined.mean()), float(defined.std()), int(defined.size)


class InstanceMetrics:
    """Streaming AP and IoU_R over images, at one or more thresholds.

    Examples
    --------
    >>> metric = InstanceMetrics(taus=(0.5, 0.75))
    >>> metric.update(true_mask, predicted_mask)  # doctest: +SKIP
    >>> metric.compute()["0.5"]["ap_mean"]  # doctest: +SKIP
    """

    def __init__(self, taus: Sequence[float] = (0.5,)):
        if not taus:
            raise ValueError("need at least one tau")
        for tau in taus:
            if not 0 < tau <= 1:
                raise ValueError(f"tau must be in (0, 1], got {tau}")
        self.taus = tuple(float(t) for t in taus)
        self.reset()

    def reset(self) -> None:
        """Forget every image seen."""
        self.results: list[list[MatchResult]] = []

    def update(self, true: np.ndarray, pred: np.ndarray) -> list[MatchResult]:
        """Match one image's objects at every threshold; returns the per-threshold results."""
        iou, true_ids, pred_ids = iou_matrix(true, pred)
        results = [match_from_iou(iou, tau, true_ids, pred_ids) for tau in self.taus]
        self.results.append(results)
        return results

    def compute(self) -> dict[str, dict[str, float | int]]:
        """Per threshold (keyed ``str(tau)``): mean and std over images of AP and IoU_R, with the images counted.

        Also the totals ``tp``, ``fp``, ``fn`` and ``n_true``/``n_pred`` over all images.
        """
        summary: dict[str, dict[str, float | int]] = {}
        for position, tau in enumerate(self.taus):
            at_tau = [image[position] for image in self.results]
            ap_mean, ap_std, ap_n = _summary([r.ap for r in at_tau])
            iou_mean, iou_std, iou_n = _summary([r.iou_r for r in at_tau])
            summary[f"{tau:g}"] = {
                "ap_mean": ap_mean,
                "ap_std": ap_std,
                "iou_r_mean": iou_mean,
                "iou_r_std": iou_std,
                "n_images": ap_n,
                "n_images_iou_r": iou_n,
                "tp": sum(r.tp for r in at_tau),
                "fp": sum(r.fp for r in at_tau),
                "fn": sum(r.fn for r in at_tau),
                "n_true": sum(r.n_true for r in at_tau),
                "n_pred": sum(r.n_pred for r in at_tau),
            }
        return summary


def evaluate_masks(
    predict: Callable[[np.ndarray], RenderResult],
    data_dir: str | os.PathLike,
    taus: Sequence[float] = (0.5,),
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """AP and IoU_R of predicted well and plaque masks against a dataset's masks.

    Parameters
    ----------
    predict : maps an image to a :class:`~platesynth.render.result.RenderResult` holding the predicted masks at
        the image's size (e.g. ``functools.partial(predict_image, model)``).
    data_dir : a dataset in the platesynth layout (images with well and plaque masks).
    taus : IoU thresholds.
    progress : called with (images done, total) after each image.

    Returns
    -------
    dict
        ``{"n_images": n, "wells": {tau: summary}, "plaques": {tau: summary}}`` (see :meth:`InstanceMetrics.compute`).
    """
    items = list_items(data_dir)
    metrics = {"wells": InstanceMetrics(taus), "plaques": InstanceMetrics(taus)}
    for done, item in enumerate(items, start=1):
        image, wells, plaques = load_item(item)
        result = predict(image)
        metrics["wells"].update(wells, result.wells)
        metrics["plaques"].update(plaques, result.plaques)
        if progress is not None:
            progress(done, len(items))
    return {"n_images": len(items), **{name: metric.compute() for name, metric in metrics.items()}}
