"""Numba kernels of the photographic post-processing (:mod:`platesynth.render.postprocess`): separable blur,
block-mean down- and bilinear upsampling, sensor noise, per-channel scaling (chromatic aberration) and line blur.

Images are ``(H, W, C)`` float32; every kernel is row-parallel and gives the same result for any thread count.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from platesynth.render.look import NOISE_FLOOR, NOISE_MID_GREY, NOISE_OWN, NOISE_SHARED


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def blur_separable(image, taps, out):
    """Convolve ``image`` (H, W, C) with the symmetric 1-D kernel ``taps`` (centre first) along both axes,
    repeating the border pixels."""
    height, width, channels = image.shape
    radius = taps.shape[0] - 1
    row_len = width * channels
    tmp = np.empty((height, row_len), dtype=np.float32)
    for y in prange(height):
        line = np.empty(row_len + 2 * radius * channels, dtype=np.float32)
        src = image[y].reshape(row_len)
        line[radius * channels : radius * channels + row_len] = src
        for r in range(radius):
            for c in range(channels):
                line[r * channels + c] = src[c]
                line[radius * channels + row_len + r * channels + c] = src[row_len - channels + c]
        for i in range(row_len):
            centre = i + radius * channels
            acc = taps[0] * line[centre]
            for r in range(1, radius + 1):
                acc += taps[r] * (line[centre - r * channels] + line[centre + r * channels])
            tmp[y, i] = acc
    for y in prange(height):
        dst = out[y].reshape(row_len)
        for i in range(row_len):
            dst[i] = taps[0] * tmp[y, i]
        for r in range(1, radius + 1):
            above = tmp[max(y - r, 0)]
            below = tmp[min(y + r, height - 1)]
            weight = taps[r]
            for i in range(row_len):
                dst[i] += weight * (above[i] + below[i])


@njit(cache=True, nogil=True, inline="always")
def _hash64(x):
    """SplitMix64 finaliser: a well-mixed 64-bit hash of ``x``."""
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def add_sensor_noise(image, sd, seed):
    """Add signal-dependent, approximately Gaussian noise (sd ``sd`` at mid grey) in place; each pixel's noise
    is a hash of its index and ``seed``, so it is the same on every run and for any thread count."""
    height, width, channels = image.shape
    scale = np.float32(1.0 / 65535.0)
    base = np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15)
    for y in prange(height):
        for x in range(width):
            index = np.uint64(y * width + x) * np.uint64(4)
            common_bits = _hash64(base + index)
            # a sum of four 16-bit uniforms is close to Gaussian (Irwin-Hall): mean 2, variance 1/3
            common = (
                np.float32(common_bits & np.uint64(0xFFFF)) + np.float32((common_bits >> np.uint64(16)) & np.uint64(0xFFFF))
                + np.float32((common_bits >> np.uint64(32)) & np.uint64(0xFFFF)) + np.float32(common_bits >> np.uint64(48))
            ) * scale - np.float32(2.0)
            for c in range(channels):
                bits = _hash64(base + index + np.uint64(c + 1))
                own = (
                    np.float32(bits & np.uint64(0xFFFF)) + np.float32((bits >> np.uint64(16)) & np.uint64(0xFFFF))
                    + np.float32((bits >> np.uint64(32)) & np.uint64(0xFFFF)) + np.float32(bits >> np.uint64(48))
                ) * scale - np.float32(2.0)
                value = image[y, x, c]
                level = math.sqrt(min(max(value, np.float32(NOISE_FLOOR)), np.float32(1.0)) / np.float32(NOISE_MID_GREY))
                image[y, x, c] = value + sd * level * np.float32(1.7320508) * (np.float32(NOISE_SHARED) * common + np.float32(NOISE_OWN) * own)


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def scale_channels(image, scales, out):
    """Resample each channel scaled by ``scales[c]`` about the image centre (bilinear, clamped at borders)."""
    height, width, channels = image.shape
    cx = width / 2.0
    cy = height / 2.0
    for y in prange(height):
        for x in range(width):
            for c in range(channels):
                s = scales[c]
                if s == 1.0:
                    out[y, x, c] = image[y, x, c]
                    continue
                sx = min(max((x + 0.5 - cx) / s + cx - 0.5, 0.0), width - 1.001)
                sy = min(max((y + 0.5 - cy) / s + cy - 0.5, 0.0), height - 1.001)
                j = int(sx)
                i = int(sy)
                fx = sx - j
                fy = sy - i
                top = image[i, j, c] * (1.0 - fx) + image[i, j + 1, c] * fx
                bottom = image[i + 1, j, c] * (1.0 - fx) + image[i + 1, j + 1, c] * fx
                out[y, x, c] = top * (1.0 - fy) + bottom * fy


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def line_blur(image, dx, dy, samples, out):
    """Average ``samples`` bilinear samples along the segment from ``-(dx, dy)/2`` to ``+(dx, dy)/2`` (pixels)."""
    height, width, channels = image.shape
    for y in prange(height):
        for x in range(width):
            for c in range(channels):
                out[y, x, c] = 0.0
            for k in range(samples):
                t = (k / (samples - 1) - 0.5) if samples > 1 else 0.0
                sx = min(max(x + t * dx, 0.0), width - 1.001)
                sy = min(max(y + t * dy, 0.0), height - 1.001)
                j = int(sx)
                i = int(sy)
                fx = sx - j
                fy = sy - i
                for c in range(channels):
                    top = image[i, j, c] * (1.0 - fx) + image[i, j + 1, c] * fx
                    bottom = image[i + 1, j, c] * (1.0 - fx) + image[i + 1, j + 1, c] * fx
                    out[y, x, c] += (top * (1.0 - fy) + bottom * fy) / samples


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def downsample_mean(image, factor):
    """Mean over ``factor`` x ``factor`` blocks (the last partial blocks average what they hold)."""
    height, width, channels = image.shape
    small_h = (height + factor - 1) // factor
    small_w = (width + factor - 1) // factor
    small = np.zeros((small_h, small_w, channels), dtype=np.float32)
    for i in prange(small_h):
        for y in range(i * factor, min((i + 1) * factor, height)):
            for x in range(width):
                for c in range(channels):
                    small[i, x // factor, c] += image[y, x, c]
        for j in range(small_w):
            count = (min((i + 1) * factor, height) - i * factor) * (min((j + 1) * factor, width) - j * factor)
            for c in range(channels):
                small[i, j, c] /= count
    return small


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def upsample_bilinear(small, factor, out):
    """Bilinear upsampling of block means made by :func:`downsample_mean` back to ``out``'s size."""
    height, width, channels = out.shape
    small_h, small_w = small.shape[0], small.shape[1]
    for y in prange(height):
        sy = min(max((y + 0.5) / factor - 0.5, 0.0), small_h - 1.0)
        i = min(int(sy), small_h - 2) if small_h > 1 else 0
        fy = sy - i if small_h > 1 else 0.0
        i1 = i + 1 if small_h > 1 else 0
        for x in range(width):
            sx = min(max((x + 0.5) / factor - 0.5, 0.0), small_w - 1.0)
            j = min(int(sx), small_w - 2) if small_w > 1 else 0
            fx = sx - j if small_w > 1 else 0.0
            j1 = j + 1 if small_w > 1 else 0
            for c in range(channels):
                top = small[i, j, c] * (1.0 - fx) + small[i, j1, c] * fx
                bottom = small[i1, j, c] * (1.0 - fx) + small[i1, j1, c] * fx
                out[y, x, c] = top * (1.0 - fy) + bottom * fy
