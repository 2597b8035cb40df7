"""Full-reference metrics of one synthetic image against one real image.

The four classical metrics follow granatpy 0.1.3's ``compute_all_metrics`` exactly: scikit-image's functions on the
arrays as they are (no conversion to float first), with ``channel_axis=-1`` for SSIM on colour images, and the MSE
divided by the squared data range (``255**2`` for uint8), i.e. the MSE of images scaled to 0..1. The data range is
the dtype's full range: 255 for uint8, 65535 for uint16, 1.0 for float images (which must lie in 0..1).

:func:`compare_pair` adds the naturalness factor of each image, their difference, LPIPS and patch Fréchet distances.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from skimage import metrics as skmetrics
from skimage.transform import resize as skimage_resize

from platesynth.errors import ImageReadError, MetricUndefinedError, ShapeMismatchError, WeightsNotFoundError
from platesynth.io import read_image, to_rgb_uint8
from platesynth.limits import check_pair

__all__ = [
    "MetricSkippedWarning",
    "ProgressCallback",
    "compare_pair",
    "mean_squared_error",
    "normalized_root_mse",
    "peak_signal_noise_ratio",
    "structural_similarity",
]

ImageOrPath = np.ndarray | str | os.PathLike

ProgressCallback = Callable[[str, int, int], None]
"""``progress(description, done, total)``: called with ``done=0`` when a long computation starts, then after each of
its ``total`` steps (``description`` names the step now running)."""

_SSIM_MIN_SIDE = 7
"""scikit-image's default SSIM window is 7x7."""
_ALEXNET_MIN_SIDE = 31
"""Smallest image side that AlexNet's convolutions and poolings accept (LPIPS and AlexNet features)."""


class MetricSkippedWarning(UserWarning):
    """An optional metric was left out of a result (e.g. its network weights are not available)."""


def _check_pair(real: np.ndarray, synthetic: np.ndarray) -> float:
    """Check that two arrays can be compared; return their data range."""
    if real.shape != synthetic.shape:
        raise ShapeMismatchError(f"real image has shape {real.shape} but synthetic image has shape {synthetic.shape}")
    if real.dtype != synthetic.dtype:
        raise ShapeMismatchError(f"real image is {real.dtype} but synthetic image is {synthetic.dtype}")
    if real.dtype in (np.uint8, np.uint16):
        return float(np.iinfo(real.dtype).max)
    if np.issubdtype(real.dtype, np.floating):
        return 1.0
    raise ImageReadError(f"unsupported pixel type {real.dtype} (expected uint8, uint16 or float in 0..1)")


def mean_squared_error(real: np.ndarray, synthetic: np.ndarray) -> float:
    """Mean squared error on a 0..1 scale: scikit-image's MSE divided by the squared data range.

    Parameters
    ----------
    real, synthetic : numpy.ndarray
        Images of equal shape and dtype (uint8, uint16, or float in 0..1).

    Returns
    -------
    float
        ``mean((real - synthetic)**2) / data_range**2``, in 0..1; granatpy's ``MSE`` for uint8 images.
    """
    data_range = _check_pair(real, synthetic)
    return float(skmetrics.mean_squared_error(real, synthetic) / data_range**2)


def normalized_root_mse(real: np.ndarray, synthetic: np.ndarray) -> float:
    """Root mean squared error divided by the root mean square of ``real`` (scikit-image's ``"euclidean"``).

    Parameters
    ----------
    real, synthetic : numpy.ndarray
        Images of equal shape and dtype; ``real`` is the reference.

    Returns
    -------
    float
        ``sqrt(mean((real - synthetic)**2)) / sqrt(mean(real**2))``; ``inf`` if ``real`` is all zeros.
    """
    _check_pair(real, synthetic)
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(skmetrics.normalized_root_mse(real, synthetic))


def peak_signal_noise_ratio(real: np.ndarray, synthetic: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB, with the dtype's data range (255 for uint8).

    Parameters
    ----------
    real, synthetic : numpy.ndarray
        Images of equal shape and dtype.

    Returns
    -------
    float
        ``10 log10(data_range**2 / MSE)``; ``inf`` for identical images (JSON output writes it as ``null``).
    """
    data_range = _check_pair(real, synthetic)
    if np.array_equal(real, synthetic):
        return float("inf")
    return float(skmetrics.peak_signal_noise_ratio(real, synthetic, data_range=data_range))


def structural_similarity(real: np.ndarray, synthetic: np.ndarray) -> float:
    """Mean structural similarity (scikit-image defaults: 7x7 uniform window), channels averaged.

    Parameters
    ----------
    real, synthetic : numpy.ndarray
        ``(H, W)`` or ``(H, W, C)`` images of equal shape and dtype, at least 7x7 pixels. The last axis of a
        3-D array is the channel axis (granatpy's ``channel_axis=-1``).

    Returns
    -------
    float
        SSIM in -1..1, 1 for identical images.

    Raises
    ------
    MetricUndefinedError
        If the images are smaller than the 7x7 window.
    """
    data_range = _check_pair(real, synthetic)
    if min(real.shape[:2]) < _SSIM_MIN_SIDE:
        raise MetricUndefinedError(
            f"SSIM needs images of at least {_SSIM_MIN_SIDE}x{_SSIM_MIN_SIDE} pixels, "
            f"got {real.shape[1]}x{real.shape[0]}"
        )
    channel_axis = -1 if real.ndim == 3 else None
    return float(skmetrics.structural_similarity(real, synthetic, channel_axis=channel_axis, data_range=data_range))


def _load(image: ImageOrPath, default_name: str) -> tuple[str, np.ndarray]:
    if isinstance(image, np.ndarray):
        return default_name, image
    return str(image), read_image(image)


def _naturalness_factor(image: np.ndarray, name: str) -> float:
    from platesynth.metrics.naturalness import naturalness_factor

    try:
        return naturalness_factor(image)
    except MetricUndefinedError as exc:
        raise MetricUndefinedError(f"{name}: {exc}") from None


def _resize_like(image: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    resized = skimage_resize(image, shape, order=1, mode="reflect", anti_aliasing=True, preserve_range=True)
    return np.clip(np.round(resized), 0, 255).astype(np.uint8)


def compare_pair(
    real: ImageOrPath,
    synthetic: ImageOrPath,
    *,
    lpips: bool = True,
    frechet: bool = True,
    resize: bool = False,
    progress: ProgressCallback | None = None,
) -> dict[str, float]:
    """All pair metrics of a synthetic image against a real one.

    Both images are first brought to ``(H, W, 3)`` uint8 (:func:`platesynth.io.to_rgb_uint8`: gray repeated,
    alpha dropped, 16-bit scaled by 255/65535).

    Parameters
    ----------
    real, synthetic : numpy.ndarray or path-like
        The reference (real) image and the image to judge, as arrays or image files.
    lpips : bool
        Compute the LPIPS distance (AlexNet).
    frechet : bool
        Compute the Fréchet distance between the distributions of patch features of the two images (AlexNet;
        also Inception when its weights are available, else left out with a :class:`MetricSkippedWarning`).
    resize : bool
        If the sizes differ, resize the synthetic image to the real one (scikit-image ``resize``, bilinear with
        anti-aliasing, rounded to uint8) instead of raising :class:`ShapeMismatchError`.
    progress : callable, optional
        ``progress(description, done, total)`` after each step (images, naturalness, LPIPS, Fréchet).

    Returns
    -------
    dict
        ``mse, nrmse, ssim, psnr`` (see the functions of the same names; ``psnr`` is ``inf`` for identical images),
        ``nf_real, nf_synthetic`` (mean naturalness factor over RGB channels) and ``dnf = |nf_real - nf_synthetic|``
        (granatpy's ``dNf`` is signed, ``nf_synthetic - nf_real``), then ``lpips``, ``fd_patches_alexnet`` and
        ``fid_patches_inception`` as requested and available.

    Raises
    ------
    ImageReadError
        If a file is missing, unreadable or not an image.
    ShapeMismatchError
        If the sizes differ and ``resize`` is False.
    MetricUndefinedError
        If an image is constant (naturalness undefined), smaller than 7x7, or too small for LPIPS (31x31) or
        for the patch Fréchet distance (about 84x58).
    """
    steps = ["reading images", "naturalness"] + ["LPIPS"] * lpips + ["Fréchet distance"] * frechet
    done = 0

    def step_done() -> None:
        nonlocal done
        done += 1
        if progress:
            progress(steps[min(done, len(steps) - 1)], done, len(steps))

    if progress:
        progress(steps[0], 0, len(steps))
    real_name, real_image = _load(real, "real image")
    synthetic_name, synthetic_image = _load(synthetic, "synthetic image")
    check_pair(*max(real_image.shape[:2], synthetic_image.shape[:2], key=lambda shape: shape[0] * shape[1]))
    real_rgb = to_rgb_uint8(real_image)
    synthetic_rgb = to_rgb_uint8(synthetic_image)
    if real_rgb.shape != synthetic_rgb.shape:
        if not resize:
            raise ShapeMismatchError(
                f"{synthetic_name} is {synthetic_rgb.shape[1]}x{synthetic_rgb.shape[0]} but {real_name} is "
                f"{real_rgb.shape[1]}x{real_rgb.shape[0]} (width x height); use resize=True (--resize) to resize "
                "the synthetic image to the real one"
            )
        synthetic_rgb = _resize_like(synthetic_rgb, real_rgb.shape)
    step_done()

    nf_real = _naturalness_factor(real_rgb, real_name)
    nf_synthetic = _naturalness_factor(synthetic_rgb, synthetic_name)
    result: dict[str, Any] = {
        "mse": mean_squared_error(real_rgb, synthetic_rgb),
        "nrmse": normalized_root_mse(real_rgb, synthetic_rgb),
        "ssim": structural_similarity(real_rgb, synthetic_rgb),
        "psnr": peak_signal_noise_ratio(real_rgb, synthetic_rgb),
        "nf_real": nf_real,
        "nf_synthetic": nf_synthetic,
        "dnf": abs(nf_real - nf_synthetic),
    }
    step_done()
    if lpips:
        from platesynth.metrics.lpips import lpips_distance

        if min(real_rgb.shape[:2]) < _ALEXNET_MIN_SIDE:
            raise MetricUndefinedError(
                f"LPIPS needs images of at least {_ALEXNET_MIN_SIDE}x{_ALEXNET_MIN_SIDE} pixels, the images are "
                f"{real_rgb.shape[1]}x{real_rgb.shape[0]}; leave it out with lpips=False (--no-lpips)"
            )
        result["lpips"] = float(lpips_distance(real_rgb, synthetic_rgb, net="alex"))
        step_done()
    if frechet:
        from platesynth.metrics.frechet import get_feature_extractor, patch_frechet_distance

        try:
            result["fd_patches_alexnet"] = float(
                patch_frechet_distance(real_rgb, synthetic_rgb, get_feature_extractor("alexnet"))
            )
        except MetricUndefinedError as exc:
            raise MetricUndefinedError(
                f"fd_patches_alexnet: {exc} (each image is cut into 6 patches); leave it out with frechet=False "
                "(--no-frechet)"
            ) from None
        try:
            inception = get_feature_extractor("inception")
        except WeightsNotFoundError as exc:
            warnings.warn(f"fid_patches_inception left out: {exc}", MetricSkippedWarning, stacklevel=2)
        else:
            result["fid_patches_inception"] = float(patch_frechet_distance(real_rgb, synthetic_rgb, inception))
        step_done()
    return result
