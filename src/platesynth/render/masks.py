"""Instance-mask helpers: renumbering the ids a renderer drew (both renderers), and the clean-up of masks from
renderers that anti-alias their labels."""

from __future__ import annotations

import numpy as np
from numba import njit

from platesynth.errors import ShapeMismatchError


@njit(cache=True, nogil=True)
def renumber(ids):
    """Renumber the non-zero ids present in the C-contiguous integer mask ``ids`` to 1..m in increasing order, in
    place (hidden objects leave no gap); returns ``ids``."""
    top = 0
    for value in ids.ravel():
        if value > top:
            top = value
    lookup = np.zeros(top + 1, dtype=ids.dtype)
    flat = ids.ravel()
    for value in flat:
        lookup[value] = 1
    lookup[0] = 0
    next_id = 0
    for value in range(1, top + 1):
        if lookup[value]:
            next_id += 1
            lookup[value] = next_id
    for i in range(flat.shape[0]):
        flat[i] = lookup[flat[i]]
    return ids


_OFFSETS = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0)]


def clean_isolated_pixels(mask: np.ndarray) -> np.ndarray:
    """Give each isolated pixel the most common value among its 8 neighbours.

    A pixel is isolated when none of its 8 neighbours has its value (e.g. a stray anti-aliased label).
    Ties go to the smallest value; pixels at the border see only their existing neighbours. All isolated
    pixels are decided from the input mask at once.

    Parameters
    ----------
    mask : (H, W) integer instance mask.

    Returns
    -------
    numpy.ndarray
        The cleaned mask, same shape and dtype.
    """
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ShapeMismatchError(f"expected a 2-D mask, got shape {mask.shape}")
    height, width = mask.shape
    if mask.size == 0:
        return mask.copy()
    sentinel = -1
    padded = np.pad(mask.astype(np.int64), 1, constant_values=sentinel)
    neighbours = np.stack([padded[1 + dy : 1 + dy + height, 1 + dx : 1 + dx + width] for dy, dx in _OFFSETS])
    isolated = ~(neighbours == mask[None].astype(np.int64)).any(axis=0)
    if not isolated.any():
        return mask.copy()
    candidates = neighbours[:, isolated]  # (8, n)
    valid = candidates != sentinel
    # votes[i, j]: how many neighbours of isolated pixel j equal its neighbour i
    votes = ((candidates[:, None, :] == candidates[None, :, :]) & valid[None, :, :]).sum(axis=1)
    votes = np.where(valid, votes, -1)
    best = votes.max(axis=0)
    # among the most voted, the smallest value
    chosen = np.where(votes == best[None, :], candidates, np.iinfo(np.int64).max).min(axis=0)
    out = mask.copy()
    out[isolated] = chosen.astype(mask.dtype)
    return out
