"""Whether a well can be counted: a person leaves lysed and confluent wells blank, and so does the model.

A well is judged by how much of it is still stained: the share of its pixels whose colour saturation is at least
:data:`STAINED_SHARE` of the plate's intact stain (the :data:`INTACT_PERCENTILE` percentile of the saturation over
all its wells). An intact monolayer with countable plaques keeps most of its stain; a lysed well (pale, a lacy
residue) and a confluent one (merged clearings) keep little. The threshold on that share is tuned on synthetic
images whose renderer knows which wells are lysed (:func:`tune_threshold`) and stored with the model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy import ndimage

STAINED_SHARE = 0.5
"""A pixel is stained where its saturation is at least this share of the plate's intact stain."""
INTACT_PERCENTILE = 90.0
"""The plate's intact stain: this percentile of the saturation over all its wells' pixels."""
RIM_PIXELS = 3
"""Pixels along each well's rim (the wall's shadow, the meniscus) left out."""


def saturation(image: np.ndarray) -> np.ndarray:
    """HSV saturation ``(max - min) / max`` of an RGB image (0 where black)."""
    rgb = np.asarray(image, dtype=np.float32)
    high, low = rgb.max(axis=-1), rgb.min(axis=-1)
    return np.where(high > 0, (high - low) / np.maximum(high, 1e-6), 0.0)


def stained_fractions(image: np.ndarray, wells: np.ndarray) -> dict[int, float]:
    """Share of each well's pixels (rim left out) that are still stained.

    Parameters
    ----------
    image : numpy.ndarray
        ``(H, W, 3)`` RGB image.
    wells : numpy.ndarray
        ``(H, W)`` well instance mask (0: no well).

    Returns
    -------
    dict
        Well id -> stained share in [0, 1] (NaN for a well too small to judge).
    """
    inner = ndimage.binary_erosion(wells > 0, iterations=RIM_PIXELS) * wells
    sat = saturation(image)
    inside = inner > 0
    if not inside.any():
        return {int(i): math.nan for i in np.unique(wells) if i}
    intact = float(np.percentile(sat[inside], INTACT_PERCENTILE))
    stained = sat >= STAINED_SHARE * intact
    ids = np.unique(wells)
    ids = ids[ids > 0]
    totals = ndimage.sum_labels(inside, inner, ids)
    kept = ndimage.sum_labels(stained & inside, inner, ids)
    return {int(i): float(k / t) if t > 0 else math.nan for i, k, t in zip(ids, kept, totals)}


def judge_countable(fractions: dict[int, float], threshold: float) -> dict[int, bool]:
    """Countable wells: those whose stained share is at least ``threshold`` (a well that cannot be judged counts)."""
    return {well: bool(math.isnan(share) or share >= threshold) for well, share in fractions.items()}


def tune_threshold(fractions: Sequence[float], countable: Sequence[bool]) -> float:
    """The threshold on the stained share that best separates countable from uncountable wells.

    Maximises the balanced accuracy (the mean of the two classes' recalls); ties go to the lowest threshold.
    With one class only, returns 0 (every well countable).
    """
    share = np.asarray(fractions, dtype=np.float64)
    truth = np.asarray(countable, dtype=bool)
    keep = ~np.isnan(share)
    share, truth = share[keep], truth[keep]
    if truth.all() or not truth.any():
        return 0.0
    candidates = np.unique(np.concatenate([[0.0], (share[:-1] + share[1:]) / 2 if share.size > 1 else [], share]))
    best, best_score = 0.0, -1.0
    for threshold in np.sort(candidates):
        judged = share >= threshold
        score = 0.5 * ((judged & truth).sum() / truth.sum() + (~judged & ~truth).sum() / (~truth).sum())
        if score > best_score + 1e-12:
            best, best_score = float(threshold), score
    return best


def rendered_countable(item: Any) -> dict[int, bool]:
    """Per well id of a rendered dataset item, whether a person would count it: its renderer neither lysed nor
    emptied it (from the item's params; empty for an item without params, e.g. a hand-annotated photo)."""
    from platesynth.data.layout import read_params

    if item.params_path is None:
        return {}
    wells = read_params(item).get("scene", {}).get("wells", [])
    return {int(well["id"]): not (well["lysed"] or well["emptied"]) for well in wells}


def tune_on_items(items: Sequence[Any]) -> float:
    """:func:`tune_threshold` on rendered dataset items, whose params say which wells are lysed or emptied.

    Parameters
    ----------
    items : sequence of DatasetItem
        Rendered items (image, true well mask and params with the scene); items without params are skipped.
    """
    from platesynth.data.layout import load_item

    shares, countable = [], []
    for item in items:
        truth = rendered_countable(item)
        if not truth:
            continue
        image, wells, _ = load_item(item)
        fractions = stained_fractions(image, wells)
        for well_id, is_countable in truth.items():
            if well_id in fractions:
                shares.append(fractions[well_id])
                countable.append(is_countable)
    return tune_threshold(shares, countable)


class CountabilityMetrics:
    """Agreement of predicted with true countability per well (the positive class: uncountable).

    ``update(predicted, true)`` takes equal-length sequences of booleans (``True``: countable).
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget every well seen."""
        self.predicted: list[bool] = []
        self.true: list[bool] = []

    def update(self, predicted: Sequence[bool], true: Sequence[bool]) -> None:
        """Add wells."""
        predicted, true = [bool(v) for v in predicted], [bool(v) for v in true]
        if len(predicted) != len(true):
            raise ValueError(f"{len(predicted)} predicted flags but {len(true)} true flags")
        self.predicted += predicted
        self.true += true

    def compute(self) -> dict[str, float | int]:
        """``accuracy``, ``precision``, ``recall`` and ``f1`` of finding uncountable wells (NaN where undefined),
        ``n_wells`` and ``n_uncountable`` (true)."""
        predicted, true = ~np.asarray(self.predicted, dtype=bool), ~np.asarray(self.true, dtype=bool)
        n = len(true)
        hits = int((predicted & true).sum())
        found, present = int(predicted.sum()), int(true.sum())
        precision = hits / found if found else math.nan
        recall = hits / present if present else math.nan
        f1 = 2 * precision * recall / (precision + recall) if found and present and (precision + recall) > 0 else math.nan
        return {
            "accuracy": float((predicted == true).mean()) if n else math.nan,
            "precision": precision,
            "recall": recall,
            "f1": f1,
            "n_wells": n,
            "n_uncountable": present,
        }
