"""Naturalness factor Nf of an image (Gong & Sbalzarini's gradient-prior naturalness), as granatpy 0.1.3 computes it.

For each colour channel the Laplacian (5-point stencil) and the forward-difference gradients of the pixel values are
histogrammed over the interior pixels and turned into cumulative distributions. An arctangent ``atan(T * i)`` is
fitted by ternary search to each of them: the fitted slopes, divided by the slopes of natural images, give

* ``t1``: from the horizontal and vertical gradient distributions, ``(T_x + T_y) / (2 * 0.3754)``;
* ``t2``: from the Laplacian distribution, ``T_lap / prior`` with a per-channel prior
  (red 0.2474, green 0.2550, blue 0.2421, grayscale 0.24816666);
* ``nf = (t1 + t2) / 2``: 1 for natural image statistics, above 1 for an image whose gradients are more
  concentrated (smoother, lower contrast) than natural, below 1 for harsher gradients.

The results equal granatpy 0.1.3's ``naturalize_rgb_image`` bit for bit (granatpy is a port of MosaicSuite's Java
code), with the same conventions, quirks included: float32 histograms built by adding ``1 / n`` once per pixel, the
gradient marginals taken as sums of the two-dimensional CDF divided by 255, a channel whose values are all 0 or 1
first multiplied by 255, and an error function summed in float64 in index order with the C library's ``atan``.
Only the way of computing differs: one compiled pass over the pixels for the histograms, compiled loops for the
cumulative sums and the search, numpy for the rest.

Accepted images are uint8 or uint16, ``(H, W)`` grayscale or ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA (alpha is
ignored). uint16 images are first brought to 8 bits with ``round(v * 255 / 65535)``
(:func:`platesynth.io.to_rgb_uint8`), so their Nf is that of the 8-bit image. Nf is undefined, and
:class:`~platesynth.errors.MetricUndefinedError` is raised, for images smaller than 3x3 pixels and for channels where
the Laplacian or either gradient takes one single value over the whole image (a constant image, a flat channel, a
linear ramp): the fitted slope would then be the end of the search interval, not a property of the image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from platesynth.errors import MetricUndefinedError, ParameterError
from platesynth.io import to_rgb_uint8

__all__ = ["NaturalnessResult", "naturalize", "naturalness", "naturalness_factor", "naturalness_map"]

_LAPLACIAN_BINS = 2041
_LAPLACIAN_OFFSET = 1020
_GRADIENT_BINS = 512
_GRADIENT_OFFSET = 256
_SEARCH_PRECISION = 1e-4
_GRADIENT_PRIOR = 0.3754
_LAPLACIAN_PRIORS = {"red": 0.2474, "green": 0.2550, "blue": 0.2421, "gray": 0.24816666}
_RGB = ("red", "green", "blue")
_LAPLACIAN_WEIGHT = 0.5
"""Weight of t2 in nf (granatpy's ``theta``); t1 gets the rest."""


@dataclass(frozen=True, eq=False)
class NaturalnessResult:
    """Naturalness of one image, per channel (red, green, blue; or the single gray channel).

    Compare results through their arrays (``np.array_equal(a.nf, b.nf)``); ``==`` is identity.

    Attributes
    ----------
    nf : numpy.ndarray
        Naturalness factor per channel, ``(t1 + t2) / 2``; float64, read-only.
    t1 : numpy.ndarray
        Gradient term per channel (fitted gradient slope over the natural-image prior).
    t2 : numpy.ndarray
        Laplacian term per channel (fitted Laplacian slope over the channel's natural-image prior).
    """

    nf: np.ndarray
    t1: np.ndarray
    t2: np.ndarray

    @property
    def nf_mean(self) -> float:
        """Mean of ``nf`` over the channels: the image's Nf (granatpy's ``_compute_nf``)."""
        return float(np.mean(self.nf))


def naturalness(image: np.ndarray) -> NaturalnessResult:
    """Naturalness factor Nf and its terms T1, T2 of each channel of an image.

    Parameters
    ----------
    image : numpy.ndarray
        uint8 or uint16 image, ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)`` (alpha ignored), at least 3x3 pixels.

    Returns
    -------
    NaturalnessResult
        Per-channel ``nf``, ``t1``, ``t2`` (one value for grayscale, three for colour) and ``nf_mean``.

    Raises
    ------
    ParameterError
        If the image has another dtype or shape.
    MetricUndefinedError
        If Nf is undefined: image smaller than 3x3, or a channel whose Laplacian or gradient is single-valued
        (e.g. a constant image).
    """
    pixels, channel_names = _as_uint8_channels(image)
    return _naturalness_of_channels(pixels, channel_names)


def naturalness_factor(image: np.ndarray) -> float:
    """Naturalness factor Nf of an image: the mean over its channels (see :func:`naturalness`)."""
    return naturalness(image).nf_mean


def naturalize(image: np.ndarray) -> np.ndarray:
    """Naturalized image: each channel's contrast about its mean scaled by the channel's Nf.

    ``round((v - mean) * nf + mean)`` clipped to 0..255, per channel, as granatpy's ``naturalize_rgb_image``.

    Parameters
    ----------
    image : numpy.ndarray
        As for :func:`naturalness`.

    Returns
    -------
    numpy.ndarray
        uint8, ``(H, W)`` for a grayscale image, ``(H, W, 3)`` otherwise (alpha dropped; uint16 input is
        returned in 8 bits).

    Raises
    ------
    ParameterError, MetricUndefinedError
        As :func:`naturalness`.
    """
    pixels, channel_names = _as_uint8_channels(image)
    nf = _naturalness_of_channels(pixels, channel_names).nf
    mean = pixels.mean(axis=(0, 1))
    naturalized = np.clip(np.round((pixels - mean) * nf + mean), 0, 255).astype(np.uint8)
    return naturalized[..., 0] if len(channel_names) == 1 else naturalized


def naturalness_map(image: np.ndarray, grid: tuple[int, int] = (10, 15)) -> np.ndarray:
    """Nf of each cell of a regular grid laid over the image.

    The cells are those of granatpy's ``overlay_naturalness_heatmap``: ``H // rows`` by ``W // cols`` pixels from
    the top-left corner (the remainder at the bottom and right is left out), each cell's value the mean of its
    channels' Nf.

    Parameters
    ----------
    image : numpy.ndarray
        As for :func:`naturalness`.
    grid : tuple of int
        ``(rows, cols)`` of the grid.

    Returns
    -------
    numpy.ndarray
        float64 ``(rows, cols)``; NaN where Nf is undefined (a flat cell, or cells under 3x3 pixels) where
        granatpy would put 0 or a value at the end of its search interval.

    Raises
    ------
    ParameterError
        If the image has another dtype or shape, or ``grid`` is not two positive integers.
    """
    if len(grid) != 2 or not all(isinstance(n, (int, np.integer)) and n > 0 for n in grid):
        raise ParameterError(f"naturalness map grid must be two positive integers (rows, cols), got {grid!r}")
    pixels, channel_names = _as_uint8_channels(image)
    rows, cols = grid
    cell_height, cell_width = pixels.shape[0] // rows, pixels.shape[1] // cols
    values = np.full((rows, cols), np.nan)
    for row in range(rows):
        for col in range(cols):
            cell = pixels[row * cell_height : (row + 1) * cell_height, col * cell_width : (col + 1) * cell_width]
            try:
                values[row, col] = _naturalness_of_channels(cell, channel_names).nf_mean
            except MetricUndefinedError:
                pass
    return values


def _as_uint8_channels(image: np.ndarray) -> tuple[np.ndarray, tuple[str, ...]]:
    """``(H, W, C)`` uint8 view or copy of the image's colour channels, and the channels' names."""
    image = np.asarray(image)
    if image.dtype not in (np.uint8, np.uint16):
        raise ParameterError(f"naturalness needs a uint8 or uint16 image, got {image.dtype}")
    if image.ndim == 2:
        gray = to_rgb_uint8(image)[..., 0] if image.dtype == np.uint16 else image
        return gray[..., np.newaxis], ("gray",)
    if image.ndim == 3 and image.shape[-1] in (3, 4):
        return to_rgb_uint8(image), _RGB
    raise ParameterError(f"naturalness needs an (H, W), (H, W, 3) or (H, W, 4) image, got shape {image.shape}")


def _naturalness_of_channels(pixels: np.ndarray, channel_names: tuple[str, ...]) -> NaturalnessResult:
    height, width = pixels.shape[:2]
    if height < 3 or width < 3:
        raise MetricUndefinedError(
            f"naturalness is undefined for a {height}x{width} image (it needs at least 3x3 pixels)"
        )
    terms = np.array([_channel_terms(pixels[..., index], name) for index, name in enumerate(channel_names)])
    t1, t2 = terms[:, 0], terms[:, 1]
    nf = (1 - _LAPLACIAN_WEIGHT) * t1 + _LAPLACIAN_WEIGHT * t2
    for values in (nf, t1, t2):
        values.flags.writeable = False
    return NaturalnessResult(nf=nf, t1=t1, t2=t2)


def _channel_terms(channel: np.ndarray, name: str) -> tuple[float, float]:
    """``(t1, t2)`` of one channel (at least 3x3 pixels)."""
    laplacian_counts, gradient_counts = _derivative_counts(channel)
    pixel_count = (channel.shape[0] - 2) * (channel.shape[1] - 2)
    _require_spread(laplacian_counts, "Laplacian", pixel_count, name)
    _require_spread(gradient_counts.sum(axis=0), "horizontal gradient", pixel_count, name)
    _require_spread(gradient_counts.sum(axis=1), "vertical gradient", pixel_count, name)

    # granatpy adds float32(1/n) to a bin once per pixel; the k-th partial sum is the value of a bin holding k pixels.
    weight = np.float32(1.0 / pixel_count)
    bin_values = _repeated_float32_sums(weight, max(laplacian_counts.max(), gradient_counts.max()))
    laplacian_cdf = np.cumsum(bin_values[laplacian_counts], dtype=np.float32)
    gradient_cdf_2d = bin_values[gradient_counts]
    _cumulative_sum_rows_then_columns(gradient_cdf_2d)
    # Marginals as granatpy forms them: sums (not maxima) of the 2D CDF, over 255; axis 0 of the 2D CDF is dy.
    gradient_x_cdf = np.sum(gradient_cdf_2d, axis=0, dtype=np.float32) / np.float32(255.0)
    gradient_y_cdf = np.sum(gradient_cdf_2d, axis=1, dtype=np.float32) / np.float32(255.0)

    slope_x = _fit_arctan_slope(_arctan_targets(gradient_x_cdf), _GRADIENT_OFFSET)
    slope_y = _fit_arctan_slope(_arctan_targets(gradient_y_cdf), _GRADIENT_OFFSET)
    slope_laplacian = _fit_arctan_slope(_arctan_targets(laplacian_cdf), _LAPLACIAN_OFFSET)
    t1 = (slope_x + slope_y) / (2 * _GRADIENT_PRIOR)
    t2 = slope_laplacian / _LAPLACIAN_PRIORS[name]
    return t1, t2


def _require_spread(counts: np.ndarray, quantity: str, pixel_count: int, channel_name: str) -> None:
    if counts.max() == pixel_count:
        where = "the image" if channel_name == "gray" else f"the {channel_name} channel"
        raise MetricUndefinedError(
            f"naturalness is undefined: the {quantity} of {where} takes a single value everywhere "
            "(e.g. a constant image)"
        )


def _arctan_targets(cdf: np.ndarray) -> np.ndarray:
    """The CDF shifted and scaled to the range of ``atan``, rounded to float32 as granatpy stores it."""
    return ((cdf.astype(np.float64) - 0.5) * math.pi).astype(np.float32)


@numba.njit(cache=True, nogil=True)
def _derivative_counts(channel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Histogram counts of the 5-point Laplacian and of the forward-difference gradient pairs ``[dy, dx]``.

    Taken over the interior pixels; a channel whose values are all 0 or 1 is first multiplied by 255 (granatpy
    takes it for a 0..1 image).
    """
    height, width = channel.shape
    scale = 255 if channel.max() <= 1 else 1
    laplacian_counts = np.zeros(_LAPLACIAN_BINS, np.int64)
    gradient_counts = np.zeros((_GRADIENT_BINS, _GRADIENT_BINS), np.int64)
    for y in range(1, height - 1):
        for x in range(1, width - 1):
            centre = np.int64(channel[y, x]) * scale
            right = np.int64(channel[y, x + 1]) * scale
            below = np.int64(channel[y + 1, x]) * scale
            left = np.int64(channel[y, x - 1]) * scale
            above = np.int64(channel[y - 1, x]) * scale
            laplacian_counts[right + left + below + above - 4 * centre + _LAPLACIAN_OFFSET] += 1
            gradient_counts[below - centre + _GRADIENT_OFFSET, right - centre + _GRADIENT_OFFSET] += 1
    return laplacian_counts, gradient_counts


@numba.njit(cache=True, nogil=True)
def _repeated_float32_sums(weight: np.float32, count: int) -> np.ndarray:
    """``sums[k]``: ``weight`` added ``k`` times, one at a time, in float32 (0 <= k <= count)."""
    sums = np.zeros(count + 1, np.float32)
    for k in range(1, count + 1):
        sums[k] = sums[k - 1] + weight
    return sums


@numba.njit(cache=True, nogil=True)
def _cumulative_sum_rows_then_columns(values: np.ndarray) -> None:
    """In place, in float32 and in index order: ``np.cumsum(axis=0)`` then ``np.cumsum(axis=1)``."""
    rows, cols = values.shape
    for row in range(1, rows):
        for col in range(cols):
            values[row, col] += values[row - 1, col]
    for row in range(rows):
        for col in range(1, cols):
            values[row, col] += values[row, col - 1]


@numba.njit(cache=True, nogil=True)
def _arctan_fit_error(targets: np.ndarray, offset: int, slope: float) -> float:
    """Sum over bins ``i`` of ``(atan(slope * i) - target_i) ** 2``, accumulated in float64 in index order."""
    error = 0.0
    for k in range(targets.size):
        difference = math.atan(slope * (k - offset)) - targets[k]
        error += difference * difference
    return error


@numba.njit(cache=True, nogil=True)
def _fit_arctan_slope(targets: np.ndarray, offset: int) -> float:
    """Slope in [0, 1] minimising :func:`_arctan_fit_error`: ternary search to ``_SEARCH_PRECISION``, as granatpy."""
    left, right = 0.0, 1.0
    lower = upper = 0.0
    while right - left >= _SEARCH_PRECISION:
        lower = left + (right - left) / 3
        upper = right - (right - left) / 3
        if _arctan_fit_error(targets, offset, lower) <= _arctan_fit_error(targets, offset, upper):
            right = upper
        else:
            left = lower
    return (lower + upper) / 2
