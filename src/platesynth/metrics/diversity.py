"""Streaming diversity metrics of an image dataset: pixel entropy and brightness variability.

Both metrics look at one pixel position at a time across the whole dataset: the grayscale values that the
images take at that position form a sample, and the metric summarises that sample (its Shannon entropy, or
its variance), then averages over positions. They reproduce granatpy 0.1.3's ``dataset_entropy`` and
``brightness_var`` (to about 1e-12) without holding the dataset in memory:

* grayscale conversion is Pillow's ``convert("L")`` (ITU-R 601-2 luma, ``(19595 R + 38470 G + 7471 B + 2**15) >> 16``),
  alpha is ignored;
* images whose size differs from the common size are resized with Pillow's bicubic filter (what
  ``Image.resize`` does by default), after the grayscale conversion;
* 16-bit images are first scaled to 8 bits with ``round(v * 255 / 65535)`` (:func:`platesynth.io.to_rgb_uint8`).
  granatpy differs there (Pillow keeps the high byte of 16-bit RGB PNGs and clips 16-bit grayscale to 255),
  so parity with granatpy holds for 8-bit images only.

Sizes in this module are ``(height, width)`` like numpy shapes; granatpy's and Pillow's ``size`` is ``(width, height)``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numba
import numpy as np
from PIL import Image

from platesynth.errors import EmptyDatasetError, ImageReadError, ParameterError
from platesynth.io import read_image, to_rgb_uint8
from platesynth.limits import entropy_bytes, require_memory

__all__ = ["BrightnessVariability", "PixelEntropy", "grayscale", "size_matched_entropy"]

ImageOrPath = np.ndarray | str | os.PathLike


_BATCH_IMAGES = 128
_BATCH_BYTES = 64 << 20
"""Gray images are buffered (at most 128 of them, 64 MB) and counted together in one pass over the histograms."""
_TILE_POSITIONS = 256


@numba.njit(cache=True, nogil=True)
def _count_values(counts: np.ndarray, grays: np.ndarray, bin_of_value: np.ndarray) -> None:
    """``counts[i, bin_of_value[grays[k, i]]] += 1`` for every image ``k`` and position ``i``; position-major counts.

    A tile of positions of every image is first copied position-major, then counted position by position, so that
    each position's histogram stays in cache while the whole batch of images is counted into it.
    """
    n_images, n_positions = grays.shape
    bins = counts.size // n_positions
    tile = np.empty((_TILE_POSITIONS, n_images), dtype=np.uint8)
    for start in range(0, n_positions, _TILE_POSITIONS):
        stop = min(start + _TILE_POSITIONS, n_positions)
        for image in range(n_images):
            for position in range(start, stop):
                tile[position - start, image] = grays[image, position]
        for position in range(start, stop):
            first = position * bins
            for image in range(n_images):
                counts[first + bin_of_value[tile[position - start, image]]] += 1


@numba.njit(cache=True, nogil=True)
def _sum_count_log_count(counts: np.ndarray, n_positions: int, count_log_count: np.ndarray) -> np.ndarray:
    """Per position, the sum over its bins of ``c * log2(c)`` (looked up in ``count_log_count``)."""
    bins = counts.size // n_positions
    total = np.zeros(n_positions, dtype=np.float64)
    for position in range(n_positions):
        start = position * bins
        for bin_index in range(bins):
            count = counts[start + bin_index]
            if count > 1:
                total[position] += count_log_count[count]
    return total


@numba.njit(cache=True, nogil=True)
def _add_values_and_squares(sums: np.ndarray, sums_of_squares: np.ndarray, gray: np.ndarray) -> None:
    """``sums += gray`` and ``sums_of_squares += gray**2`` in one pass (int64 sums)."""
    for position in range(gray.size):
        value = np.int64(gray[position])
        sums[position] += value
        sums_of_squares[position] += value * value


def grayscale(image: np.ndarray, size: tuple[int, int] | None = None) -> np.ndarray:
    """Convert an image to 8-bit grayscale as Pillow's ``convert("L")`` does, optionally resizing it.

    Parameters
    ----------
    image : numpy.ndarray
        ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)`` array of dtype uint8 or uint16. Alpha is ignored; 16-bit values
        are scaled to 8 bits with ``round(v * 255 / 65535)`` first.
    size : (int, int), optional
        ``(height, width)`` of the result. Images of another size are resized with Pillow's bicubic filter.

    Returns
    -------
    numpy.ndarray
        ``(height, width)`` uint8 array.

    Raises
    ------
    ImageReadError
        If the array is not an 8- or 16-bit grayscale, RGB or RGBA image.
    """
    image = np.asarray(image)
    if image.dtype not in (np.uint8, np.uint16):
        raise ImageReadError(f"unsupported pixel type {image.dtype} (expected uint8 or uint16)")
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[-1] in (3, 4))) or image.size == 0:
        raise ImageReadError(f"unsupported image shape {image.shape} (expected (H, W), (H, W, 3) or (H, W, 4))")
    if image.dtype == np.uint16:
        image = to_rgb_uint8(image)
    if image.ndim == 3:
        image = np.asarray(Image.fromarray(np.ascontiguousarray(image[..., :3])).convert("L"))
    if size is not None and image.shape != tuple(size):
        height, width = size
        image = np.asarray(Image.fromarray(image).resize((width, height), Image.Resampling.BICUBIC))
    return image


def _check_size(size: tuple[int, int] | None) -> tuple[int, int] | None:
    if size is None:
        return None
    if len(size) != 2 or any(int(s) != s or s < 1 for s in size):
        raise ParameterError(f"size must be (height, width) with positive integers, got {size!r}")
    return int(size[0]), int(size[1])


def _as_image(item: ImageOrPath) -> np.ndarray:
    return item if isinstance(item, np.ndarray) else read_image(item)


class _PerPositionMetric:
    """Shared state of the per-position metrics: the common size and the number of images seen."""

    def __init__(self, size: tuple[int, int] | None = None) -> None:
        self._requested_size = _check_size(size)
        self.reset()

    def reset(self) -> None:
        """Forget every image seen so far (the size given at construction is kept)."""
        self.size: tuple[int, int] | None = self._requested_size
        self.n_images = 0

    def _gray(self, image: np.ndarray) -> np.ndarray:
        gray = grayscale(image, self.size)
        if self.size is None:
            self.size = gray.shape
        return gray

    def _check_not_empty(self) -> None:
        if self.n_images == 0:
            raise EmptyDatasetError(f"{type(self).__name__}: no image was given to update()")


class PixelEntropy(_PerPositionMetric):
    """Mean over pixel positions of the Shannon entropy (bits) of the grayscale values at that position.

    Equals granatpy 0.1.3 ``dataset_entropy(paths, size=(width, height), bins=bins)``. The state is one histogram
    per position, ``height * width * bins`` counts whose integer type grows with the number of images (uint8 up
    to 255 images, then uint16 up to 65535, ...): 10,000 images of 1024x768 need 400 MB. Images are counted in
    batches (up to 128 buffered gray images, 64 MB), each in one pass over the histograms.

    The entropy at a position is at most ``log2(min(n_images, bins))``, so it grows with the number of images:
    compare datasets of equal size, or use :func:`size_matched_entropy`.

    Parameters
    ----------
    size : (int, int), optional
        ``(height, width)`` that every image is brought to; by default the size of the first image.
    bins : int
        Number of equal-width bins over ``[0, 256)``, as in granatpy.

    Examples
    --------
    >>> metric = PixelEntropy()
    >>> metric.update(np.zeros((2, 2), np.uint8))
    >>> metric.update(np.array([[0, 0], [255, 255]], np.uint8))
    >>> metric.compute()  # 1 bit where the two images differ, 0 where they agree
    0.5
    """

    def __init__(self, size: tuple[int, int] | None = None, bins: int = 256) -> None:
        if int(bins) != bins or not 1 <= bins <= 256:
            raise ParameterError(f"bins must be an integer in 1..256, got {bins!r}")
        self.bins = int(bins)
        # np.histogram's binning of the values 0..255 with granatpy's edges linspace(0, 256, bins + 1)
        edges = np.linspace(0, 256, self.bins + 1)
        self._bin_of_value = np.minimum(np.searchsorted(edges, np.arange(256), side="right") - 1, self.bins - 1)
        super().__init__(size)

    def reset(self) -> None:
        super().reset()
        self._counts: np.ndarray | None = None  # (height * width, bins), flattened
        self._pending: np.ndarray | None = None  # (batch, height * width) gray images not counted yet
        self._n_pending = 0

    def update(self, image: np.ndarray) -> None:
        """Add one image (``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)``; uint8 or uint16)."""
        gray = self._gray(image)
        if self._counts is None:
            require_memory(entropy_bytes(*gray.shape, 255, self.bins), f"computing the pixel entropy at {gray.shape[1]}x{gray.shape[0]}")
            self._counts = np.zeros(gray.size * self.bins, dtype=np.uint8)
            batch = max(1, min(_BATCH_IMAGES, _BATCH_BYTES // gray.size))
            self._pending = np.empty((batch, gray.size), dtype=np.uint8)
        self._pending[self._n_pending] = gray.ravel()
        self._n_pending += 1
        self.n_images += 1
        if self._n_pending == len(self._pending):
            self._count_pending()

    def _count_pending(self) -> None:
        if self._n_pending == 0:
            return
        if self.n_images > np.iinfo(self._counts.dtype).max:
            wider = np.promote_types(self._counts.dtype, np.min_scalar_type(self.n_images))
            self._counts = self._counts.astype(wider)
        _count_values(self._counts, self._pending[: self._n_pending], self._bin_of_value)
        self._n_pending = 0

    def histograms(self) -> np.ndarray:
        """Per-position histograms so far, ``(bins, height, width)`` counts (a view of the state)."""
        self._check_not_empty()
        self._count_pending()
        return np.moveaxis(self._counts.reshape(*self.size, self.bins), -1, 0)

    def entropy_map(self) -> np.ndarray:
        """Entropy in bits at every pixel position, ``(height, width)`` float64."""
        self._check_not_empty()
        self._count_pending()
        n = self.n_images
        count_values = np.arange(n + 1, dtype=np.float64)
        count_log_count = count_values * np.log2(np.maximum(count_values, 1.0))
        # H = -sum p log2 p with p = c / n  ==  log2 n - sum(c log2 c) / n
        sums = _sum_count_log_count(self._counts, self.size[0] * self.size[1], count_log_count)
        return np.maximum(np.log2(n) - sums / n, 0.0).reshape(self.size)

    def compute(self) -> float:
        """Mean entropy over pixel positions, in bits."""
        return float(self.entropy_map().mean())


class BrightnessVariability(_PerPositionMetric):
    """Mean over pixel positions of the variance of the grayscale values at that position.

    Equals granatpy 0.1.3 ``brightness_var(paths, size=(width, height))`` (population variance, ``ddof=0``).
    The state is exact integer sums of the values and of their squares at every position.

    Parameters
    ----------
    size : (int, int), optional
        ``(height, width)`` that every image is brought to; by default the size of the first image.
    """

    def reset(self) -> None:
        super().reset()
        self._sum: np.ndarray | None = None
        self._sum_of_squares: np.ndarray | None = None

    def update(self, image: np.ndarray) -> None:
        """Add one image (``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)``; uint8 or uint16)."""
        gray = self._gray(image)
        if self._sum is None:
            self._sum = np.zeros(gray.shape, dtype=np.int64)
            self._sum_of_squares = np.zeros(gray.shape, dtype=np.int64)
        _add_values_and_squares(self._sum.ravel(), self._sum_of_squares.ravel(), gray.ravel())
        self.n_images += 1

    def variance_map(self) -> np.ndarray:
        """Variance of the grayscale values at every pixel position, ``(height, width)`` float64."""
        self._check_not_empty()
        n = self.n_images
        if n < 10**7:  # n * sum_of_squares <= n**2 * 255**2 stays below 2**63: exact
            return (n * self._sum_of_squares - self._sum**2) / float(n) ** 2
        mean = self._sum / n
        return self._sum_of_squares / n - mean**2

    def compute(self) -> float:
        """Mean variance over pixel positions (grayscale values 0..255, so at most 255**2 / 4)."""
        return float(self.variance_map().mean())


def size_matched_entropy(
    images: Sequence[ImageOrPath],
    subset_size: int,
    n_subsets: int = 10,
    seed: int = 0,
    *,
    size: tuple[int, int] | None = None,
    bins: int = 256,
) -> float:
    """Mean :class:`PixelEntropy` over random subsets of ``subset_size`` images.

    The pixel entropy of ``N`` images is at most ``log2 N``, so datasets of different sizes cannot be compared
    directly. Drawing subsets of one fixed size from each dataset (``subset_size`` at most the smaller dataset's
    size) makes them comparable.

    Parameters
    ----------
    images : sequence of numpy.ndarray or path-like
        The dataset; paths are read when needed (once per subset they fall in), so memory holds one histogram set.
    subset_size : int
        Images per subset, ``1 <= subset_size <= len(images)``.
    n_subsets : int
        Number of subsets, each drawn without replacement.
    seed : int
        Seed of the generator that draws the subsets.
    size : (int, int), optional
        ``(height, width)``; by default the size of the first image of ``images``.
    bins : int
        Histogram bins, as in :class:`PixelEntropy`.

    Returns
    -------
    float
        Mean over the subsets of the pixel entropy, in bits.
    """
    if not images:
        raise EmptyDatasetError("size_matched_entropy: no images")
    if int(subset_size) != subset_size or not 1 <= subset_size <= len(images):
        raise ParameterError(
            f"subset_size must be an integer in 1..{len(images)} (the number of images), got {subset_size!r}"
        )
    if int(n_subsets) != n_subsets or n_subsets < 1:
        raise ParameterError(f"n_subsets must be a positive integer, got {n_subsets!r}")
    if size is None:
        size = grayscale(_as_image(images[0])).shape
    rng = np.random.default_rng(seed)
    metric = PixelEntropy(size=size, bins=bins)
    entropies = []
    for _ in range(int(n_subsets)):
        metric.reset()
        for index in rng.choice(len(images), size=int(subset_size), replace=False):
            metric.update(_as_image(images[index]))
        entropies.append(metric.compute())
    return float(np.mean(entropies))
