"""Which rendered plaques a model can resolve, and which predictions lie on the others."""

from __future__ import annotations

import numpy as np
from skimage.draw import disk

from platesynth.segment.resolvable import lying_on, resolvable_plaques


def _plaques() -> np.ndarray:
    """Plaque 1: 9 px (3.4 px across, as a disc of equal area); plaque 2: 89 px (10.6 px across)."""
    mask = np.zeros((40, 40), np.uint16)
    mask[disk((10, 10), 1.5)] = 1
    mask[disk((25, 25), 5.2)] = 2
    return mask


def test_plaques_narrower_than_the_grid_cells_are_unresolvable():
    plaques = _plaques()
    assert np.bincount(plaques.ravel()).tolist()[1:] == [9, 89]
    resolved, unresolved = resolvable_plaques(plaques, scale=1.0, grid=2, min_cells=3)  # 3 cells of 2 px: 6 px
    assert unresolved.tolist() == [1]
    np.testing.assert_array_equal(resolved, np.where(plaques == 2, 2, 0))
    # at half the working size, the larger one spans 5.3 px: unresolvable too
    assert resolvable_plaques(plaques, scale=0.5, grid=2, min_cells=3)[1].tolist() == [1, 2]
    # a grid of 1 px resolves both, and 0 cells keep every plaque
    assert resolvable_plaques(plaques, scale=1.0, grid=1, min_cells=3)[1].size == 0
    kept, none = resolvable_plaques(plaques, scale=0.1, grid=2, min_cells=0)
    assert none.size == 0 and kept is plaques


def test_predictions_lying_mostly_on_ignored_plaques():
    truth = _plaques()
    predicted = np.zeros_like(truth)
    predicted[8:13, 8:13] = 1  # covers all 9 px of the ignored plaque
    predicted[22:29, 22:29] = 2  # on the kept plaque
    predicted[0:3, 30:33] = 3  # on no plaque: a false positive, never ignored
    predicted[11:14, 11:14] = 4  # 1 px on the ignored plaque, none on the kept one
    lying = lying_on(predicted, truth, np.array([1]), n_predicted=6)
    assert lying.tolist() == [False, True, False, False, True, False, False]
    # a prediction spread over both: more of it on the kept plaque than on the ignored one
    both = np.zeros_like(truth)
    both[9:28, 9:28] = 1
    assert lying_on(both, truth, np.array([1])).tolist() == [False, False]
    # nothing ignored: nothing lies on it
    assert not lying_on(predicted, truth, np.array([], int)).any()
