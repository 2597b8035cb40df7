"""Realism and diversity metrics, flat like ``skimage.metrics``.

Pair metrics (one synthetic image against one real image): :func:`mean_squared_error`, :func:`normalized_root_mse`,
:func:`peak_signal_noise_ratio`, :func:`structural_similarity`, :func:`naturalness_factor`, :func:`lpips_distance`,
:func:`patch_frechet_distance`, and :func:`compare_pair` for all of them at once.

Dataset metrics: the streaming :class:`PixelEntropy` and :class:`BrightnessVariability`
(``update(image)`` / ``compute()`` / ``reset()``), :func:`size_matched_entropy`, :class:`FeatureStatistics` with
:func:`frechet_distance_from_stats`, :func:`kernel_distance` and :func:`nearest_neighbour_accuracy`, and
:func:`dataset_metrics` for a whole folder.

Well-crop metrics (:mod:`platesynth.metrics.wells`): :func:`fit_plate_grid`, :func:`wells_from_mask`,
:func:`crop_well`, :func:`radial_power_spectrum`, :func:`plaque_measurements`, the streaming :class:`WellCrops`,
:func:`compare_well_crops` and :func:`well_metrics` for a dataset against real photos.

The torch-based names (LPIPS, Fréchet and kernel distances) are imported on first use, so that
``import platesynth.metrics`` does not load torch.
"""

from __future__ import annotations

import importlib
from typing import Any

from platesynth.metrics.dataset import dataset_metrics
from platesynth.metrics.diversity import BrightnessVariability, PixelEntropy, grayscale, size_matched_entropy
from platesynth.metrics.naturalness import (
    NaturalnessResult,
    naturalize,
    naturalness_factor,
    naturalness_map,
)
from platesynth.metrics.pair import (
    MetricSkippedWarning,
    compare_pair,
    mean_squared_error,
    normalized_root_mse,
    peak_signal_noise_ratio,
    structural_similarity,
)
from platesynth.metrics.wells import (
    WellCrops,
    WellDisc,
    collect_well_crops,
    compare_well_crops,
    crop_well,
    fit_plate_grid,
    plaque_measurements,
    radial_power_spectrum,
    well_metrics,
    wells_from_mask,
)

_LAZY_EXPORTS = {
    "lpips": ("LPIPS", "lpips_distance"),
    "frechet": (
        "FeatureStatistics",
        "frechet_distance",
        "frechet_distance_from_stats",
        "get_feature_extractor",
        "kernel_distance",
        "nearest_neighbour_accuracy",
        "patch_frechet_distance",
        "split_into_patches",
    ),
}
_MODULE_OF = {name: module for module, names in _LAZY_EXPORTS.items() for name in names}

__all__ = [
    "BrightnessVariability",
    "MetricSkippedWarning",
    "NaturalnessResult",
    "PixelEntropy",
    "WellCrops",
    "WellDisc",
    "collect_well_crops",
    "compare_pair",
    "compare_well_crops",
    "crop_well",
    "dataset_metrics",
    "fit_plate_grid",
    "grayscale",
    "mean_squared_error",
    "naturalize",
    "naturalness_factor",
    "naturalness_map",
    "normalized_root_mse",
    "peak_signal_noise_ratio",
    "plaque_measurements",
    "radial_power_spectrum",
    "size_matched_entropy",
    "structural_similarity",
    "well_metrics",
    "wells_from_mask",
    *sorted(_MODULE_OF),
]


def __getattr__(name: str) -> Any:
    if name not in _MODULE_OF:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_MODULE_OF[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
