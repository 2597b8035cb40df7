"""Training targets of a StarDist branch: object probability and star-convex radial distances.

Both come from an instance mask (0 background, 1..n objects) and are sampled on the branch's grid: cell ``(i, j)``
stands for pixel ``(i * grid, j * grid)``, as in StarDist.
"""

from __future__ import annotations

import numpy as np
from stardist.geometry import star_dist
from stardist.utils import edt_prob


def _as_label_image(labels: np.ndarray) -> np.ndarray:
    if labels.ndim != 2:
        raise ValueError(f"expected a 2-D instance mask, got shape {labels.shape}")
    if not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"expected an integer instance mask, got {labels.dtype}")
    return np.ascontiguousarray(labels.astype(np.uint16 if labels.max() <= 65535 else np.int32, copy=False))


def star_distances(labels: np.ndarray, n_rays: int = 32, grid: int = 1) -> np.ndarray:
    """Distance from each grid cell to its object's boundary along ``n_rays`` equally spaced rays.

    Parameters
    ----------
    labels : (H, W) integer array
        Instance mask, 0 = background.
    n_rays : int
        Number of rays; ray ``k`` points at angle ``2 pi k / n_rays`` (``dy = sin``, ``dx = cos``).
    grid : int
        Subsampling step of the output.

    Returns
    -------
    numpy.ndarray
        ``(ceil(H / grid), ceil(W / grid), n_rays)`` float32 distances in pixels of ``labels``; 0 on background.
    """
    return star_dist(_as_label_image(labels), n_rays=n_rays, grid=(grid, grid), mode="cpp").astype(np.float32, copy=False)


def object_probability(labels: np.ndarray, grid: int = 1) -> np.ndarray:
    """Per-object distance transform normalised to 1 at each object's innermost pixel (StarDist's probability target).

    Returns
    -------
    numpy.ndarray
        ``(ceil(H / grid), ceil(W / grid))`` float32 in [0, 1]; 0 on background.
    """
    labels = _as_label_image(labels)
    if not labels.any():
        return np.zeros(labels[::grid, ::grid].shape, np.float32)
    return edt_prob(labels)[::grid, ::grid].astype(np.float32, copy=False)


def branch_targets(labels: np.ndarray, n_rays: int = 32, grid: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(probability, distances)`` of :func:`object_probability` and :func:`star_distances` for one branch."""
    return object_probability(labels, grid), star_distances(labels, n_rays, grid)
