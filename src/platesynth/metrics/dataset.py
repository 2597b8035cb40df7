"""Metrics of a whole image folder, optionally against a reference (real) folder, in one pass over each.

Every image is read once and fed to every streaming metric: pixel entropy and brightness variability
(:mod:`platesynth.metrics.diversity`), the naturalness factor, and with a reference the AlexNet (and Inception,
when its weights are available) feature statistics for the Fréchet and kernel distances.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from platesynth.errors import ImageReadError, PlatesynthError, WeightsNotFoundError
from platesynth.io import image_size, list_images, read_image, to_rgb_uint8
from platesynth.limits import check_dataset_metrics
from platesynth.metrics.diversity import BrightnessVariability, PixelEntropy, grayscale
from platesynth.metrics.pair import MetricSkippedWarning, ProgressCallback

__all__ = ["dataset_metrics"]


def _feature_extractors() -> dict[str, Any]:
    """AlexNet's feature extractor, and Inception's when its weights are found (else a warning says why)."""
    from platesynth.metrics.frechet import get_feature_extractor

    extractors = {"alexnet": get_feature_extractor("alexnet")}
    try:
        extractors["inception"] = get_feature_extractor("inception")
    except WeightsNotFoundError as exc:
        warnings.warn(f"fid_inception and kid_inception left out: {exc}", MetricSkippedWarning, stacklevel=3)
    return extractors


def _scan_folder(
    directory: Path,
    size: tuple[int, int] | None,
    extractors: dict[str, Any],
    progress: ProgressCallback | None,
    description: str,
) -> dict[str, Any]:
    """Read every image of ``directory`` once and feed all metrics; return their states and values."""
    from platesynth.metrics.naturalness import naturalness_factor

    paths = list_images(directory)
    entropy, variability = PixelEntropy(size=size), BrightnessVariability(size=size)
    statistics = {}
    if extractors:
        from platesynth.metrics.frechet import FeatureStatistics

        statistics = {name: FeatureStatistics(extractor) for name, extractor in extractors.items()}
    batch_size = min((extractor.batch_size for extractor in extractors.values()), default=1)
    nf_values = []
    pending: list[np.ndarray] = []  # images waiting for the next feature batch

    def flush() -> None:
        try:
            for stats in statistics.values():
                stats.update(pending)
        except PlatesynthError as exc:
            raise type(exc)(f"{directory}: {exc}") from None
        pending.clear()

    if progress:
        progress(description, 0, len(paths))
    for done, path in enumerate(paths, start=1):
        image = read_image(path)
        try:
            gray = grayscale(image, entropy.size)
            entropy.update(gray)
            variability.update(gray)
            nf_values.append(naturalness_factor(image))
        except PlatesynthError as exc:
            raise type(exc)(f"{path}: {exc}") from None
        if statistics:
            pending.append(to_rgb_uint8(image))
            if len(pending) == batch_size:
                flush()
        if progress:
            progress(description, done, len(paths))
    if pending:
        flush()
    return {
        "n_images": len(paths),
        "size": entropy.size,
        "entropy": entropy.compute(),
        "brightness_variability": variability.compute(),
        "nf_mean": float(np.mean(nf_values)),
        "statistics": statistics,
    }


def _distances(real: dict[str, Any], synthetic: dict[str, Any]) -> dict[str, float]:
    from platesynth.metrics.frechet import frechet_distance, kernel_distance

    distances: dict[str, float] = {}
    for name, real_stats in real["statistics"].items():
        synthetic_stats = synthetic["statistics"][name]
        prefix = "fd" if name == "alexnet" else "fid"
        if real_stats.count < 2 or synthetic_stats.count < 2:
            warnings.warn(
                f"{prefix}_{name} and kid_{name} left out: they need at least 2 images in each folder "
                f"(got {synthetic_stats.count} and {real_stats.count} in the reference)",
                MetricSkippedWarning,
                stacklevel=3,
            )
            continue
        # from the kept features rather than the moments: exact and fast when there are fewer images than dimensions
        distances[f"{prefix}_{name}"] = frechet_distance(synthetic_stats.features, real_stats.features)
        kid_mean, kid_std = kernel_distance(synthetic_stats.features, real_stats.features)
        distances[f"kid_{name}"] = kid_mean
        distances[f"kid_{name}_std"] = kid_std
    return distances


def dataset_metrics(
    directory: str | os.PathLike,
    reference: str | os.PathLike | None = None,
    *,
    size: tuple[int, int] | None = None,
    frechet: bool = True,
    progress: ProgressCallback | None = None,
) -> dict[str, Any]:
    """Diversity and realism metrics of the images directly inside a folder.

    Parameters
    ----------
    directory : str or path-like
        Folder of images (typically synthetic).
    reference : str or path-like, optional
        Folder of reference (real) images to compare with.
    size : (int, int), optional
        ``(height, width)`` that images are resized to for entropy and brightness variability (Pillow bicubic,
        after grayscale conversion); by default the size of the first image of ``directory`` (sorted by name), for
        the reference folder too.
    frechet : bool
        With a reference, compute the Fréchet and kernel distances of deep features (AlexNet, and Inception when
        its weights are available; otherwise those keys are left out with a :class:`MetricSkippedWarning`).
    progress : callable, optional
        ``progress(description, done, total)``: called with the folder's name before its first image and after each
        image.

    Returns
    -------
    dict
        ``n_images``, ``size`` (``[height, width]``), ``entropy`` (bits), ``brightness_variability``, ``nf_mean``
        (mean naturalness factor over the images). With ``reference`` also ``n_images_reference``,
        ``entropy_reference``, ``brightness_variability_reference``, ``nf_mean_reference``,
        ``dnf = |nf_mean_reference - nf_mean|`` and, with ``frechet``, ``fd_alexnet``, ``kid_alexnet``,
        ``kid_alexnet_std``, ``fid_inception``, ``kid_inception``, ``kid_inception_std``. Entropy grows with the
        number of images (at most ``log2 n_images``): compare folders of equal size.

    Raises
    ------
    EmptyDatasetError
        If a folder is missing or holds no image.
    ImageReadError
        If an image cannot be read (the message names the file).
    MetricUndefinedError
        If the naturalness of an image is undefined, e.g. a constant image (the message names the file).
    WeightsNotFoundError
        If the AlexNet weights are needed and cannot be found.
    ResourceLimitError
        If the per-position metrics at ``size`` (or the first image's) would need more memory than the limit.
    """
    directory = Path(directory)
    paths = list_images(directory)  # refuse a missing or empty folder before loading any network
    n_images = len(paths)
    if reference is not None:
        n_images = max(n_images, len(list_images(reference)))
    if size is None:  # the first image's, from its header (else PixelEntropy checks it before allocating)
        with contextlib.suppress(ImageReadError):
            width, height = image_size(paths[0])
            check_dataset_metrics((height, width), n_images)
    else:
        check_dataset_metrics(size, n_images)
    extractors = _feature_extractors() if reference is not None and frechet else {}
    scanned = _scan_folder(directory, size, extractors, progress, str(directory))
    result: dict[str, Any] = {
        "n_images": scanned["n_images"],
        "size": list(scanned["size"]),
        "entropy": scanned["entropy"],
        "brightness_variability": scanned["brightness_variability"],
        "nf_mean": scanned["nf_mean"],
    }
    if reference is None:
        return result
    scanned_reference = _scan_folder(Path(reference), scanned["size"], extractors, progress, str(reference))
    result.update(
        {
            "n_images_reference": scanned_reference["n_images"],
            "entropy_reference": scanned_reference["entropy"],
            "brightness_variability_reference": scanned_reference["brightness_variability"],
            "nf_mean_reference": scanned_reference["nf_mean"],
            "dnf": abs(scanned_reference["nf_mean"] - scanned["nf_mean"]),
        }
    )
    result.update(_distances(scanned_reference, scanned))
    return result

