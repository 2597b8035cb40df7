"""The rendered plaques a model can resolve, and its predictions on the others left out of a score.

A rendered plaque mask holds every plaque the scene drew, down to specks a few pixels across at the model's working
size. The plaque branch predicts on a grid of ``grid`` working pixels, and a plaque only a cell or two across leaves
too little on that grid for a probability and a polygon: trained models find almost none of them (docs/segmentation.md,
"Thresholds against resolvable plaques"). Scored against them, every threshold candidate misses them alike, and the
lowest candidates win by finding a few of them while adding false positives everywhere else.

Threshold tuning can score such plaques as "don't care", as COCO's crowd regions and Cityscapes' ignore label are
scored (``platesynth train --min-resolved-cells``): they leave the truth, and a prediction lying mostly on one of them
leaves the prediction, neither found nor false. It is off by default: on the real plates it helped one training of
three and cost the other two, and the shipped model (docs/segmentation.md).
"""

from __future__ import annotations

import numpy as np


def resolvable_plaques(
    plaques: np.ndarray, scale: float, grid: int, min_cells: float
) -> tuple[np.ndarray, np.ndarray]:
    """Split a plaque instance mask into the plaques a model can resolve and those it cannot.

    Parameters
    ----------
    plaques : numpy.ndarray
        ``(H, W)`` plaque instance mask (0 background).
    scale : float
        Working size over the mask's size (1 where the mask is at the model's working size).
    grid : int
        Grid of the model's plaque branch, in working pixels.
    min_cells : float
        Smallest equivalent diameter kept (the diameter of a disc of the plaque's area), in grid cells of the
        plaque branch; 0 keeps every plaque.

    Returns
    -------
    resolved : numpy.ndarray
        ``plaques`` with the unresolvable plaques erased (same ids otherwise).
    unresolved : numpy.ndarray
        Ids of the erased plaques, ascending.
    """
    plaques = np.asarray(plaques)
    areas = np.bincount(plaques.ravel().astype(np.int64))
    ids = np.flatnonzero(areas)
    ids = ids[ids > 0]
    diameters = 2.0 * np.sqrt(areas[ids] / np.pi) * scale
    unresolved = ids[diameters < min_cells * grid]
    resolved = np.where(np.isin(plaques, unresolved), 0, plaques) if unresolved.size else plaques
    return resolved, unresolved


def lying_on(predicted: np.ndarray, truth: np.ndarray, ignored: np.ndarray, n_predicted: int = 0) -> np.ndarray:
    """Which predicted instances lie mostly on ignored true objects.

    A predicted instance lies on them when more of its pixels cover ignored objects than cover the other true
    objects; one that covers no ignored pixel never does.

    Parameters
    ----------
    predicted, truth : numpy.ndarray
        ``(H, W)`` instance masks of equal shape (0 background).
    ignored : numpy.ndarray
        Ids of the ignored objects in ``truth``.
    n_predicted : int
        Ids up to this one are answered even where absent from ``predicted`` (e.g. polygons drawn over entirely).

    Returns
    -------
    numpy.ndarray
        Boolean, indexed by predicted id (``0 .. max(n_predicted, predicted.max())``; entry 0, the background, is
        False).
    """
    predicted, truth = np.asarray(predicted), np.asarray(truth)
    size = max(int(n_predicted), int(predicted.max()) if predicted.size else 0) + 1
    on_ignored = np.isin(truth, ignored)
    on_kept = (truth > 0) & ~on_ignored
    ignored_pixels = np.bincount(predicted[on_ignored].astype(np.int64), minlength=size)
    kept_pixels = np.bincount(predicted[on_kept].astype(np.int64), minlength=size)
    lying = ignored_pixels > kept_pixels
    lying[0] = False
    return lying
