"""Countability of wells: the stained share, the tuned threshold and the agreement metrics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from platesynth.segment.countability import (
    CountabilityMetrics,
    judge_countable,
    saturation,
    stained_fractions,
    tune_threshold,
)


def plate_with_wells(pale_share: dict[int, float], size: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Two wells side by side: stained purple, with the left ``pale_share`` of the columns of each well grey."""
    wells = np.zeros((size, 2 * size), np.uint8)
    image = np.full((size, 2 * size, 3), 200, np.uint8)
    for well, share in pale_share.items():
        cols = slice((well - 1) * size, well * size)
        wells[:, cols] = well
        block = image[:, cols]
        block[:] = (120, 10, 220)  # stained: saturated
        pale = int(round(share * size))
        block[:, :pale] = (190, 180, 200)  # lysed: pale
    return image, wells


def test_saturation_of_grey_and_colour():
    sat = saturation(np.array([[[100, 100, 100], [200, 0, 100], [0, 0, 0]]], np.uint8))
    assert sat.ravel().tolist() == pytest.approx([0.0, 1.0, 0.0])


def test_stained_fraction_counts_the_pale_part():
    image, wells = plate_with_wells({1: 0.0, 2: 0.75})
    fractions = stained_fractions(image, wells)
    assert fractions[1] == pytest.approx(1.0)
    # 3 px along the plate's edge are left out (the wells touch, so not between them): of well 2's columns
    # 40..76, the stained ones are 70..76
    assert fractions[2] == pytest.approx(7 / 37)
    assert judge_countable(fractions, 0.5) == {1: True, 2: False}
    assert judge_countable({3: math.nan}, 0.5) == {3: True}


def test_tuned_threshold_separates_the_classes():
    shares = [0.95, 0.9, 0.85, 0.3, 0.2, 0.6]
    countable = [True, True, True, False, False, True]
    threshold = tune_threshold(shares, countable)
    assert 0.3 < threshold <= 0.6
    assert tune_threshold([0.9, 0.8], [True, True]) == 0.0


def test_metrics_of_uncountable_wells():
    metric = CountabilityMetrics()
    metric.update([True, False, False, True], [True, False, True, False])
    result = metric.compute()
    # uncountable found: well 2 (right), well 3 (wrong); missed: well 4
    assert result["precision"] == 0.5 and result["recall"] == 0.5 and result["accuracy"] == 0.5
    assert result["n_uncountable"] == 2 and result["n_wells"] == 4
    with pytest.raises(ValueError):
        metric.update([True], [])
