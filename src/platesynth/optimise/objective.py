"""The objective: render a trial's images and measure how far they are from the reference photos, term by term.

Both sets are compared at one size (``compare_size``): the renders are made at ``size`` and resized to it (Lanczos;
well masks nearest-neighbour), the photos resized to it once. The terms (:data:`TERMS`), all "lower is better":

- ``fd_images``: Fréchet distance of the AlexNet features of the whole images (:func:`~platesynth.metrics.
  frechet.frechet_distance`, the ``fd_alexnet`` of :func:`~platesynth.metrics.dataset_metrics`);
- ``fd_wells``: the same of the well crops (``crop_size`` squared; renders' wells from their masks, the photos'
  from :func:`~platesynth.metrics.wells.fit_plate_grid`), the ``fd_wells`` of :mod:`platesynth.metrics.wells`;
- ``dnf``: ``|mean Nf of the photos - mean Nf of the renders|`` (naturalness factor, whole images);
- ``entropy_gap``: ``|size-matched pixel entropy of the renders - of the photos|`` in bits
  (:func:`~platesynth.metrics.size_matched_entropy`, subsets as large as the smaller set, so sizes do not matter);
- ``plaque_sizes``: :func:`~platesynth.metrics.wells.plaque_area_distance` (decades) between the plaques' area
  fractions of their wells in the renders and in the photos, only with a plaque model (``plaque_model``). The photos
  have no masks, so both sets are measured alike: by that segmentation model's wells and plaques
  (:func:`~platesynth.segment.predict.predict_image`), not by the renders' true masks, which hold plaques too small or
  faint for anyone to see;
- ``plaques_found``: ``|log10 of the ratio of plaques found per image, renders over photos|`` (decades), by the same
  model. The counts themselves are matched to a person's (the search leaves them out), so this measures how many of
  the plaques can be seen: without it a search may hide its plaques, leaving a few that happen to have the photos'
  sizes;
- ``fid_inception``: the Fréchet distance of InceptionV3 features, only where its weights are found locally.

The single objective is their weighted sum (:data:`DEFAULT_WEIGHTS`, :func:`weighted_sum`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any

import numpy as np
from PIL import Image

from platesynth.data.layout import Manifest
from platesynth.errors import MetricUndefinedError, ParameterError

PLAQUE_WEIGHT = 100.0
"""Weight of one decade of ``plaque_sizes`` and of ``plaques_found`` (plaques twice the photos' area, or half as
many found: 0.3 decades, 30 units)."""

TERMS = ("fd_images", "fd_wells", "dnf", "entropy_gap", "plaque_sizes", "plaques_found", "fid_inception")
"""The objective's terms, in the order they are reported (``plaque_sizes`` and ``plaques_found`` only with a plaque
model, ``fid_inception`` only with its weights)."""

DEFAULT_WEIGHTS = {"fd_images": 1.0, "fd_wells": 1.0, "dnf": 20.0, "entropy_gap": 20.0, "plaque_sizes": PLAQUE_WEIGHT,
                   "plaques_found": PLAQUE_WEIGHT, "fid_inception": 1.0}
"""Weights of the single objective: the Fréchet distances count as they are (tens to hundreds), one unit of dNf
and one bit of entropy gap as 20 of them, one decade of plaque sizes or counts as ``PLAQUE_WEIGHT``."""

PLAQUE_TERMS = ("plaque_sizes", "plaques_found")
"""The terms measured with a plaque model."""

OPTIONAL_TERMS = (*PLAQUE_TERMS, "fid_inception")
"""Terms measured only where what they need is given: a plaque model, the Inception weights."""

ENTROPY_SUBSETS = 10
"""Subsets drawn for the size-matched entropy of each set (seed 0, as :func:`size_matched_entropy`'s default)."""


@dataclass(frozen=True)
class MeasureSettings:
    """How a set of images is measured (the same for the photos and every trial).

    Attributes
    ----------
    compare_size : (width, height) both sets are resized to.
    crop_size : side of the well crops.
    grid : (rows, cols) of the plates in the photos (for :func:`~platesynth.metrics.wells.fit_plate_grid`).
    inception_weights : the InceptionV3 weight file where found locally, else None (no ``fid_inception``).
    plaque_model : a segmentation model's folder that measures the plaques, else None (no :data:`PLAQUE_TERMS`).
    """

    compare_size: tuple[int, int]
    crop_size: int = 128
    grid: tuple[int, int] = (3, 4)
    inception_weights: str | None = None
    plaque_model: str | None = None


@dataclass(frozen=True)
class MeasuredSet:
    """What a set of images is compared by: deep features of the images and of the well crops, mean Nf, the
    images in gray (for the entropy) and, with a plaque model, the area fractions of the plaques it finds."""

    features: np.ndarray
    well_features: np.ndarray
    nf_mean: float
    gray: tuple[np.ndarray, ...]
    inception: np.ndarray | None = None
    plaque_area_fractions: np.ndarray | None = None

    @property
    def count(self) -> int:
        """Number of images."""
        return len(self.gray)


@dataclass(frozen=True)
class Reference:
    """A measured set of reference photos, with its size-matched entropy for subsets of ``subset_size``."""

    name: str
    names: tuple[str, ...]
    measured: MeasuredSet
    subset_size: int
    entropy: float

    def without_images(self) -> Reference:
        """The same reference without the gray images (what the workers need: features and figures)."""
        measured = replace(self.measured, gray=())
        return Reference(self.name, self.names, measured, self.subset_size, self.entropy)


def resized(image: np.ndarray, size: tuple[int, int], nearest: bool = False) -> np.ndarray:
    """``image`` at ``size`` = (width, height): Lanczos for images, nearest neighbour for masks (``nearest``)."""
    if (image.shape[1], image.shape[0]) == tuple(size):
        return image
    method = Image.Resampling.NEAREST if nearest else Image.Resampling.LANCZOS
    return np.asarray(Image.fromarray(image).resize(tuple(size), method))


def _extractors(settings: MeasureSettings) -> tuple[Any, Any]:
    from platesynth.metrics.frechet import get_feature_extractor

    inception = None
    if settings.inception_weights is not None:
        inception = get_feature_extractor("inception", settings.inception_weights)
    return get_feature_extractor("alexnet"), inception


@lru_cache(maxsize=2)
def segmentation_model(model_dir: str) -> Any:
    """The segmentation model of ``model_dir``, loaded once per process (:func:`~platesynth.segment.model.load_model`:
    a missing or unfinished model is refused)."""
    from platesynth.segment.model import load_model

    return load_model(model_dir)


def plaque_area_fractions(images: Sequence[np.ndarray], model_dir: str) -> np.ndarray:
    """The area fraction of its well of every plaque a segmentation model finds in ``images`` (one array).

    Both masks are the model's (:func:`~platesynth.segment.predict.predict_image` at its stored thresholds), so
    photos and renders are measured alike; a plaque counts for the well holding most of it
    (:func:`~platesynth.metrics.wells.plaque_measurements`).
    """
    from platesynth.metrics.wells import plaque_measurements
    from platesynth.segment.predict import predict_image

    model = segmentation_model(model_dir)
    fractions = []
    for image in images:
        found = predict_image(model, image)
        fractions.append(plaque_measurements(image, found.wells, found.plaques)["area_fraction"])
    return np.concatenate(fractions) if fractions else np.empty(0)


def measure_set(
    images: Sequence[np.ndarray], settings: MeasureSettings, wells: Sequence[np.ndarray] | None = None
) -> MeasuredSet:
    """Measure images already at ``settings.compare_size``.

    Parameters
    ----------
    images : sequence of (H, W, 3) uint8
    settings : MeasureSettings
    wells : sequence of (H, W) well masks, optional
        The renders' true well masks; without them the wells are fitted (:func:`fit_plate_grid`).

    Raises
    ------
    MetricUndefinedError
        If fewer than 2 images, or fewer than 2 whole wells, are found; or an image's Nf is undefined.
    """
    from platesynth.metrics.diversity import grayscale
    from platesynth.metrics.naturalness import naturalness_factor
    from platesynth.metrics.wells import crop_well, fit_plate_grid, wells_from_mask

    if len(images) < 2:
        raise MetricUndefinedError(f"{len(images)} image(s): the Fréchet distances need at least 2")
    alexnet, inception = _extractors(settings)
    crops = []
    for index, image in enumerate(images):
        discs = wells_from_mask(wells[index]) if wells is not None else fit_plate_grid(image, settings.grid)
        crops += [crop_well(image, disc, settings.crop_size) for disc in discs]
    if len(crops) < 2:
        raise MetricUndefinedError(f"{len(crops)} whole well(s) in {len(images)} images: fd_wells needs at least 2")
    return MeasuredSet(
        features=alexnet(list(images)),
        well_features=alexnet(crops),
        nf_mean=float(np.mean([naturalness_factor(image) for image in images])),
        gray=tuple(grayscale(image) for image in images),
        inception=inception(list(images)) if inception is not None else None,
        plaque_area_fractions=(plaque_area_fractions(images, settings.plaque_model)
                               if settings.plaque_model is not None else None),
    )


def entropy_of(measured: MeasuredSet, subset_size: int) -> float:
    """Size-matched pixel entropy of a measured set (bits), over :data:`ENTROPY_SUBSETS` subsets."""
    from platesynth.metrics.diversity import size_matched_entropy

    return size_matched_entropy(list(measured.gray), subset_size, ENTROPY_SUBSETS)


def measure_reference(name: str, names: Sequence[str], images: Sequence[np.ndarray], settings: MeasureSettings,
                      subset_size: int) -> Reference:
    """Measure reference photos (resized to the compare size here) for subsets of ``subset_size`` images."""
    images = [resized(image, settings.compare_size) for image in images]
    measured = measure_set(images, settings)
    return Reference(name, tuple(names), measured, subset_size, entropy_of(measured, min(subset_size, len(images))))


def compare(measured: MeasuredSet, reference: Reference) -> dict[str, float]:
    """The objective's terms of a measured set against a reference (``fid_inception`` where both have it)."""
    from platesynth.metrics.frechet import frechet_distance
    from platesynth.metrics.wells import plaque_area_distance

    subset = min(reference.subset_size, measured.count)
    terms = {
        "fd_images": frechet_distance(measured.features, reference.measured.features),
        "fd_wells": frechet_distance(measured.well_features, reference.measured.well_features),
        "dnf": abs(reference.measured.nf_mean - measured.nf_mean),
        "entropy_gap": abs(entropy_of(measured, subset) - reference.entropy),
    }
    mine, theirs = measured.plaque_area_fractions, reference.measured.plaque_area_fractions
    if mine is not None and theirs is not None:
        terms["plaque_sizes"] = plaque_area_distance(mine, theirs)  # refuses a set without plaques
        per_image = (mine.size / measured.count) / (theirs.size / len(reference.names))
        terms["plaques_found"] = abs(math.log10(per_image))
    if measured.inception is not None and reference.measured.inception is not None:
        terms["fid_inception"] = frechet_distance(measured.inception, reference.measured.inception)
    return terms


def check_weights(weights: dict[str, float]) -> dict[str, float]:
    """:data:`DEFAULT_WEIGHTS` updated with ``weights``; refuses unknown terms and negative or non-finite weights."""
    for name, value in weights.items():
        if name not in TERMS:
            raise ParameterError(f"unknown objective term {name!r}: the terms are {', '.join(TERMS)}")
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise ParameterError(f"weight of {name}: expected a number >= 0, got {value!r}")
    merged = {**DEFAULT_WEIGHTS, **{k: float(v) for k, v in weights.items()}}
    if not any(merged[name] > 0 for name in TERMS if name not in OPTIONAL_TERMS):
        raise ParameterError("every weight is 0: give at least one term a positive weight")
    return merged


def weighted_sum(terms: dict[str, float], weights: dict[str, float]) -> float:
    """The single objective: the sum of ``weights[t] * terms[t]`` over the terms present."""
    return float(sum(weights[name] * value for name, value in terms.items() if name in weights))


# ------------------------------------------------------------------------------------------------ the task


@dataclass(frozen=True)
class TrialItem:
    """One configuration to render and measure: its trial number (or a label), its configuration (JSON) and the
    dataset items to render."""

    number: int | str
    config: dict[str, Any]
    indices: tuple[int, ...]


@dataclass(frozen=True)
class TrialRecord:
    """What a worker reports: the terms against each reference (by name), or the error, and the time taken."""

    number: int | str
    terms: dict[str, dict[str, float]] = field(default_factory=dict)
    error: str | None = None
    seconds: float = 0.0


@dataclass(frozen=True)
class TrialTask:
    """Render a :class:`TrialItem`'s images and measure them against every reference (picklable; runs on any
    worker of an executor). A renderer error, an undefined or non-finite metric is reported in the record."""

    manifest: Manifest
    settings: MeasureSettings
    references: tuple[Reference, ...]

    def render(self, item: TrialItem) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """The item's images and well masks at the compare size."""
        from platesynth.data.batch import render_item

        manifest = self.manifest.model_copy(update={"config": item.config})
        images, wells = [], []
        for index in item.indices:
            result, _ = render_item(manifest, index)
            images.append(resized(result.image, self.settings.compare_size))
            wells.append(resized(result.wells, self.settings.compare_size, nearest=True))
        return images, wells

    def __call__(self, item: TrialItem) -> TrialRecord:
        start = time.perf_counter()
        try:
            images, wells = self.render(item)
            measured = measure_set(images, self.settings, wells)
            terms = {reference.name: compare(measured, reference) for reference in self.references}
        except Exception as exc:  # noqa: BLE001 -- a failed trial is recorded as failed and the study goes on
            return TrialRecord(item.number, error=f"{type(exc).__name__}: {exc}", seconds=time.perf_counter() - start)
        for name, values in terms.items():
            bad = [key for key, value in values.items() if not math.isfinite(value)]
            if bad:
                message = f"{', '.join(bad)} not finite against the {name} photos"
                return TrialRecord(item.number, terms, message, time.perf_counter() - start)
        return TrialRecord(item.number, terms, None, time.perf_counter() - start)
