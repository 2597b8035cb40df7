"""Small numba helpers shared by the raster kernels: the camera mapping and texture lookups.

Every kernel maps pixel centres ``(x + 0.5, y + 0.5)`` to plate millimetres ``(u, v)`` with an inverse homography
``hinv`` (:func:`to_plate`), so shapes are evaluated exactly in plate space whatever the camera. The same kernels
draw a plate-space texture when ``hinv`` maps texels to millimetres (a diagonal matrix).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def to_plate(hinv, px, py):
    """Plate millimetres ``(u, v)`` of the image point ``(px, py)``."""
    w = hinv[2, 0] * px + hinv[2, 1] * py + hinv[2, 2]
    u = (hinv[0, 0] * px + hinv[0, 1] * py + hinv[0, 2]) / w
    v = (hinv[1, 0] * px + hinv[1, 1] * py + hinv[1, 2]) / w
    return u, v


@njit(cache=True, nogil=True, inline="always")
def clip01(x):
    """``x`` clamped to [0, 1]."""
    return min(max(x, 0.0), 1.0)


@njit(cache=True, nogil=True)
def grid_sample(grid, s, t):
    """Bilinear sample of ``grid`` at fractional index (s = column, t = row), clamped at the border."""
    h, w = grid.shape
    s = min(max(s, 0.0), w - 1.001)
    t = min(max(t, 0.0), h - 1.001)
    i = int(t)
    j = int(s)
    fs = s - j
    ft = t - i
    top = grid[i, j] * (1.0 - fs) + grid[i, j + 1] * fs
    bottom = grid[i + 1, j] * (1.0 - fs) + grid[i + 1, j + 1] * fs
    return top * (1.0 - ft) + bottom * ft


@njit(cache=True, nogil=True)
def tile_sample(tile, s, t):
    """Bilinear sample of a periodic ``tile`` (power-of-two sides) at fractional index (s = column, t = row)."""
    h, w = tile.shape
    fj = math.floor(s)
    fi = math.floor(t)
    fs = s - fj
    ft = t - fi
    j = int(fj) & (w - 1)
    i = int(fi) & (h - 1)
    j1 = (j + 1) & (w - 1)
    i1 = (i + 1) & (h - 1)
    top = tile[i, j] * (1.0 - fs) + tile[i, j1] * fs
    bottom = tile[i1, j] * (1.0 - fs) + tile[i1, j1] * fs
    return top * (1.0 - ft) + bottom * ft


@njit(cache=True, nogil=True)
def ring(dist, radius, half_width, pixel_mm):
    """Coverage of a thin anti-aliased ring."""
    return clip01((half_width - abs(dist - radius)) / pixel_mm + 0.5)


@njit(cache=True, nogil=True, inline="always")
def smeared_ring(dist, radius, half_width, width):
    """Coverage of a ring of ``half_width`` smeared over ``width`` (a box of that width averaged across it): as dark
    in all, the wider the fainter."""
    offset = dist - radius
    overlap = min(offset + 0.5 * width, half_width) - max(offset - 0.5 * width, -half_width)
    return max(overlap, 0.0) / width


def boxes_from_extents(corners_px: np.ndarray, height: int, width: int) -> np.ndarray:
    """Pixel boxes ``(y0, y1, x0, x1)`` (clipped, int64) from the projected corners ``(n, 4, 2)`` of each object."""
    lo = np.floor(corners_px.min(axis=1)) - 1
    hi = np.ceil(corners_px.max(axis=1)) + 2
    boxes = np.stack([lo[:, 1], hi[:, 1], lo[:, 0], hi[:, 0]], axis=1)
    boxes[:, :2] = np.clip(boxes[:, :2], 0, height)
    boxes[:, 2:] = np.clip(boxes[:, 2:], 0, width)
    return boxes.astype(np.int64)
