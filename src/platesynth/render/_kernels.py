"""Numba kernels of the raster renderer: per-object work inside each object's pixel bounding box.

Every kernel reads the plate coordinates ``u, v`` (mm) of each pixel centre, so shapes are exact in plate space
whatever the camera; bounding boxes are ``(y0, y1, x0, x1)`` pixel ranges (end exclusive).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def draw_plaques(u, v, wells, plaque_well, params, fourier, boxes, pixel_mm, clear, ids):
    """Draw plaques in order (later on top).

    ``params[p] = (cx, cy, radius, edge_width, clearness)`` in mm; ``fourier[p, k] = (a, b)`` for harmonic k + 2.
    ``clear`` (float32) receives the union of the plaques' clearing (0..1); ``ids`` (uint16) receives ``p + 1``
    where the pixel centre is inside plaque p and inside its well (``wells == plaque_well[p]``).
    """
    n_harmonics = fourier.shape[1]
    for p in range(params.shape[0]):
        cx, cy, radius, edge, clearness = params[p, 0], params[p, 1], params[p, 2], params[p, 3], params[p, 4]
        amplitude = 0.0
        for k in range(n_harmonics):
            amplitude += abs(fourier[p, k, 0]) + abs(fourier[p, k, 1])
        reach = radius * (1.0 + amplitude) + 2.0 * edge + pixel_mm
        width = max(edge, pixel_mm)
        well = plaque_well[p]
        y0, y1, x0, x1 = boxes[p, 0], boxes[p, 1], boxes[p, 2], boxes[p, 3]
        for y in range(y0, y1):
            for x in range(x0, x1):
                du = u[y, x] - cx
                dv = v[y, x] - cy
                dist = math.sqrt(du * du + dv * dv)
                if dist > reach:
                    continue
                outline = 1.0
                if dist > 0.0:
                    cos1 = du / dist
                    sin1 = dv / dist
                    cos_k = cos1 * cos1 - sin1 * sin1  # harmonic 2
                    sin_k = 2.0 * sin1 * cos1
                    for k in range(n_harmonics):
                        outline += fourier[p, k, 0] * cos_k + fourier[p, k, 1] * sin_k
                        cos_k, sin_k = cos_k * cos1 - sin_k * sin1, sin_k * cos1 + cos_k * sin1
                signed = dist - radius * outline
                if signed < 0.0 and wells[y, x] == well:
                    ids[y, x] = p + 1
                t = 0.5 - signed / (2.0 * width)
                if t <= 0.0:
                    continue
                if t > 1.0:
                    t = 1.0
                c = clearness * t * t * (3.0 - 2.0 * t)
                clear[y, x] = 1.0 - (1.0 - clear[y, x]) * (1.0 - c)


@njit(cache=True, nogil=True)
def draw_capsules(u, v, segments, values, boxes, pixel_mm, out):
    """Max-combine anti-aliased capsules (thick line segments) into ``out``.

    ``segments[s] = (x0, y0, x1, y1, half_width)`` in mm; ``values[s]`` the value at full coverage.
    """
    for s in range(segments.shape[0]):
        ax, ay, bx, by, half = segments[s, 0], segments[s, 1], segments[s, 2], segments[s, 3], segments[s, 4]
        ex = bx - ax
        ey = by - ay
        length2 = ex * ex + ey * ey
        value = values[s]
        y0, y1, x0, x1 = boxes[s, 0], boxes[s, 1], boxes[s, 2], boxes[s, 3]
        for y in range(y0, y1):
            for x in range(x0, x1):
                px = u[y, x] - ax
                py = v[y, x] - ay
                t = 0.0
                if length2 > 0.0:
                    t = min(max((px * ex + py * ey) / length2, 0.0), 1.0)
                dx = px - t * ex
                dy = py - t * ey
                coverage = 0.5 - (math.sqrt(dx * dx + dy * dy) - half) / pixel_mm
                if coverage <= 0.0:
                    continue
                coverage = min(coverage, 1.0) * value
                if coverage > out[y, x]:
                    out[y, x] = coverage


@njit(cache=True, nogil=True)
def sample_bilinear(texture, u, v, texels_per_mm, out):
    """Sample ``texture`` (h, w, c), whose texel (0, 0) covers plate mm [0, 1/texels_per_mm), at ``(u, v)``.

    Pixels outside the texture receive zeros (``out`` must start at zero).
    """
    h, w, channels = texture.shape
    for y in range(u.shape[0]):
        for x in range(u.shape[1]):
            tx = u[y, x] * texels_per_mm - 0.5
            ty = v[y, x] * texels_per_mm - 0.5
            if tx < 0.0 or ty < 0.0 or tx >= w - 1 or ty >= h - 1:
                continue
            ix = int(tx)
            iy = int(ty)
            fx = tx - ix
            fy = ty - iy
            for c in range(channels):
                top = texture[iy, ix, c] * (1.0 - fx) + texture[iy, ix + 1, c] * fx
                bottom = texture[iy + 1, ix, c] * (1.0 - fx) + texture[iy + 1, ix + 1, c] * fx
                out[y, x, c] = top * (1.0 - fy) + bottom * fy


def boxes_from_extents(corners_px: np.ndarray, height: int, width: int) -> np.ndarray:
    """Pixel boxes ``(y0, y1, x0, x1)`` (clipped, int64) from the projected corners ``(n, 4, 2)`` of each object."""
    lo = np.floor(corners_px.min(axis=1)) - 1
    hi = np.ceil(corners_px.max(axis=1)) + 2
    boxes = np.stack([lo[:, 1], hi[:, 1], lo[:, 0], hi[:, 0]], axis=1)
    boxes[:, :2] = np.clip(boxes[:, :2], 0, height)
    boxes[:, 2:] = np.clip(boxes[:, 2:], 0, width)
    return boxes.astype(np.int64)
