"""Images and masks as network input and targets: normalisation, resizing, augmentation, a torch Dataset and a mixing sampler."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
import torch
from scipy import ndimage
from skimage.transform import resize

from platesynth.data.layout import DatasetItem, load_item
from platesynth.render.raster import scratch_map
from platesynth.scene import load_scene
from platesynth.segment.model import ModelConfig
from platesynth.segment.targets import branch_targets


def normalize_image(image: np.ndarray, percentile_low: float = 1.0, percentile_high: float = 99.8) -> np.ndarray:
    """Map an RGB image to float32 so that the given percentiles (over all channels together) become 0 and 1.

    Joint percentiles keep the colour balance, which tells stain from plastic. A constant image becomes all zeros.
    """
    image = image.astype(np.float32)
    low, high = np.percentile(image, [percentile_low, percentile_high])
    return (image - low) / max(float(high - low), 1e-6)


def working_scale(shape: Sequence[int], long_side: int) -> float:
    """Factor that brings an image of ``shape`` (H, W, ...) to ``long_side`` pixels along its longest side."""
    return long_side / max(shape[0], shape[1])


def resize_labels(labels: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Nearest-neighbour resize of an instance mask (pixel centres aligned as in :func:`skimage.transform.resize`)."""
    rows = np.minimum(((np.arange(shape[0]) + 0.5) * labels.shape[0] / shape[0]).astype(np.intp), labels.shape[0] - 1)
    cols = np.minimum(((np.arange(shape[1]) + 0.5) * labels.shape[1] / shape[1]).astype(np.intp), labels.shape[1] - 1)
    return labels[rows[:, None], cols[None, :]]


def pad_to_multiple(array: np.ndarray, multiple: int) -> np.ndarray:
    """Zero-pad the first two axes at the bottom/right up to multiples of ``multiple``."""
    pad = [(0, -s % multiple) for s in array.shape[:2]] + [(0, 0)] * (array.ndim - 2)
    return np.pad(array, pad) if any(p[1] for p in pad) else array


@dataclass(frozen=True)
class Augmentation:
    """Random changes applied to each training sample; every range is (low, high), drawn uniformly.

    ``scale`` is drawn log-uniformly; ``rotations`` are multiples of 90 degrees (only 180 for non-square patches).
    Intensity changes act on the normalised image: contrast about 0.5, brightness offset, per-channel gain, gamma.
    """

    flips: bool = True
    rotations: bool = True
    scale: tuple[float, float] = (0.8, 1.25)
    contrast: tuple[float, float] = (0.75, 1.3)
    brightness: tuple[float, float] = (-0.15, 0.15)
    channel_gain: tuple[float, float] = (0.85, 1.15)
    gamma: tuple[float, float] = (0.75, 1.35)
    blur_sigma: tuple[float, float] = (0.0, 1.2)
    noise_sigma: tuple[float, float] = (0.0, 0.04)


def _intensity(image: np.ndarray, aug: Augmentation, rng: np.random.Generator) -> np.ndarray:
    image = (image - 0.5) * rng.uniform(*aug.contrast) + 0.5 + rng.uniform(*aug.brightness)
    image = image * rng.uniform(*aug.channel_gain, size=3).astype(np.float32)
    image = np.clip(image, 0, None) ** rng.uniform(*aug.gamma)
    sigma = rng.uniform(*aug.blur_sigma)
    if sigma > 0.3:
        image = ndimage.gaussian_filter(image, (sigma, sigma, 0))
    image = image + rng.normal(0, rng.uniform(*aug.noise_sigma), image.shape)
    return image.astype(np.float32)


def crop_and_resize(
    arrays: Sequence[np.ndarray],
    scale: float,
    patch: tuple[int, int],
    rng: np.random.Generator,
) -> tuple[np.ndarray, ...]:
    """Cut a random window of ``patch / scale`` pixels out of (image, wells, plaques[, scratches]) and resize it to
    ``patch``: the image and the scratch map linearly, the masks to the nearest pixel.

    Windows larger than the image are zero-padded (background in the masks).
    """
    image = arrays[0]
    window = (max(1, round(patch[0] / scale)), max(1, round(patch[1] / scale)))
    starts = [int(rng.integers(min(0, s - w), max(0, s - w) + 1)) for s, w in zip(image.shape[:2], window)]
    out = []
    for array in arrays:
        padded = np.zeros(window + array.shape[2:], array.dtype)
        src = tuple(slice(max(0, a), min(s, a + w)) for a, s, w in zip(starts, array.shape[:2], window))
        dst = tuple(slice(sl.start - a, sl.stop - a) for sl, a in zip(src, starts))
        padded[dst] = array[src]
        out.append(padded)

    def linear(array: np.ndarray) -> np.ndarray:
        if window == patch:
            return array.astype(np.float32)
        return resize(array, patch, order=1, anti_aliasing=scale < 1, preserve_range=True).astype(np.float32)

    return (linear(out[0]), resize_labels(out[1], patch), resize_labels(out[2], patch), *(linear(a) for a in out[3:]))


def augment(
    image: np.ndarray,
    wells: np.ndarray,
    plaques: np.ndarray,
    base_scale: float,
    patch: tuple[int, int],
    aug: Augmentation | None,
    rng: np.random.Generator,
    scratches: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """A random training patch: crop at ``base_scale`` x a random scale, flips, rotations and intensity changes.

    Parameters
    ----------
    image : (H, W, 3) float32 normalised image.
    wells, plaques : (H, W) instance masks.
    base_scale : factor bringing the image to the network's working size.
    patch : output (height, width).
    aug : the random changes; ``None`` for a plain random crop at ``base_scale``.
    rng : the random draws (the same ones whether or not ``scratches`` is given).
    scratches : (H, W) float map (:func:`platesynth.render.raster.scratch_map`), cut and turned with the masks.

    Returns
    -------
    image, wells, plaques, scratches : the patch's (``scratches`` ``None`` where none was given).
    """
    scale = base_scale
    if aug is not None:
        scale *= math.exp(rng.uniform(math.log(aug.scale[0]), math.log(aug.scale[1])))
    arrays = (image, wells, plaques) + (() if scratches is None else (scratches,))
    arrays = crop_and_resize(arrays, scale, patch, rng)
    if aug is not None:
        if aug.flips and rng.random() < 0.5:
            arrays = tuple(a[:, ::-1] for a in arrays)
        if aug.flips and rng.random() < 0.5:
            arrays = tuple(a[::-1] for a in arrays)
        if aug.rotations:
            k = int(rng.integers(4)) if patch[0] == patch[1] else 2 * int(rng.integers(2))
            arrays = tuple(np.rot90(a, k) for a in arrays)
        arrays = (_intensity(arrays[0], aug, rng), *arrays[1:])
    image, wells, plaques, *rest = (np.ascontiguousarray(a) for a in arrays)
    return image, wells, plaques, (rest[0] if rest else None)


def scratch_weights(scratches: np.ndarray, grid: int, weight: float) -> np.ndarray:
    """Per-cell weights of the plaque branch's probability loss: ``1 + weight`` x the share of stain scraped off
    within a cell of the cell (so that a thin scratch keeps its weight on a coarse grid).

    Parameters
    ----------
    scratches : (H, W) float map in [0, 1] (:func:`platesynth.render.raster.scratch_map`).
    grid : the branch's subsampling step.
    weight : extra weight where the stain is scraped off entirely.

    Returns
    -------
    numpy.ndarray
        ``(ceil(H / grid), ceil(W / grid))`` float32, 1 away from scratches.
    """
    near = ndimage.maximum_filter(scratches, size=2 * grid - 1, mode="constant") if grid > 1 else scratches
    return (1.0 + weight * near[::grid, ::grid]).astype(np.float32)


def make_targets(
    wells: np.ndarray,
    plaques: np.ndarray,
    config: ModelConfig,
    scratches: np.ndarray | None = None,
    scratch_weight: float = 0.0,
) -> dict[str, torch.Tensor]:
    """Network targets of both branches from the two instance masks (see :mod:`platesynth.segment.targets`).

    Returns ``{"wells_prob": (1, h, w), "wells_dist": (R, h, w), "plaques_prob", "plaques_dist", "well_mask"}``,
    ``well_mask`` being 1 inside any well, on the plaque grid; with ``scratches`` and a ``scratch_weight`` above 0
    also ``"plaques_weight"`` (:func:`scratch_weights`), which :func:`platesynth.segment.loss.segmentation_loss`
    applies to the plaque branch's probability loss.
    """
    targets = {}
    for name, labels in (("wells", wells), ("plaques", plaques)):
        prob, dist = branch_targets(labels, config.n_rays, config.branches[name].grid)
        targets[f"{name}_prob"] = torch.from_numpy(prob[None])
        targets[f"{name}_dist"] = torch.from_numpy(np.ascontiguousarray(dist.transpose(2, 0, 1)))
    grid = config.branches["plaques"].grid
    targets["well_mask"] = torch.from_numpy((wells[::grid, ::grid] > 0).astype(np.float32)[None])
    if scratches is not None and scratch_weight > 0:
        targets["plaques_weight"] = torch.from_numpy(scratch_weights(scratches, grid, scratch_weight)[None])
    return targets


def item_scratches(item: DatasetItem, shape: tuple[int, int]) -> np.ndarray:
    """Where the item's scene scraped the stain off (:func:`platesynth.render.raster.scratch_map`) at ``shape``
    (height, width); zeros for an item without a scene (a photo)."""
    if item.params_path is None or not item.params_path.is_file():
        return np.zeros(shape, np.float32)
    return scratch_map(load_scene(item.params_path), (shape[1], shape[0]))


class SegmentationDataset(torch.utils.data.Dataset):
    """Dataset items as ``{"image": (3, h, w) tensor, **targets}`` samples for :class:`StarDistTwoBranch`.

    Parameters
    ----------
    items : dataset items (:func:`platesynth.data.layout.list_items`).
    config : the model configuration (working size, normalisation, rays, grids).
    patch : training patch (height, width), multiples of ``config.size_multiple``; ``None`` gives whole images at
        the working size, zero-padded to a multiple.
    augmentation : random changes for training; ``None`` for none.
    seed : seeds the random crops and changes together with the key.
    scratch_weight : extra weight of the plaque probability loss where an item's scene scraped the stain off
        (:func:`scratch_weights`); 0 for none.

    Keys are an item index, or ``(index, draw)`` to get a different random patch of the same item (see
    :class:`MixSampler`); a key always gives the same sample.
    """

    def __init__(
        self,
        items: Sequence[DatasetItem],
        config: ModelConfig,
        patch: tuple[int, int] | None = None,
        augmentation: Augmentation | None = None,
        seed: int = 0,
        scratch_weight: float = 0.0,
    ):
        multiple = config.size_multiple
        if patch is not None and (patch[0] % multiple or patch[1] % multiple):
            raise ValueError(f"patch size {patch} must be a multiple of {multiple}")
        self.items = list(items)
        self.config = config
        self.patch = patch
        self.augmentation = augmentation
        self.seed = seed
        self.scratch_weight = scratch_weight

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, key: int | tuple[int, int]) -> dict[str, torch.Tensor]:
        index, draw = key if isinstance(key, tuple) else (key, 0)
        image, wells, plaques = load_item(self.items[index])
        scratches = item_scratches(self.items[index], image.shape[:2]) if self.scratch_weight > 0 else None
        config = self.config
        normalised = normalize_image(image, config.percentile_low, config.percentile_high)
        base_scale = working_scale(image.shape, config.input_long_side)
        if self.patch is None:
            shape = tuple(round(s * base_scale) for s in image.shape[:2])
            if shape != image.shape[:2]:
                normalised = resize(normalised, shape, order=1, anti_aliasing=base_scale < 1, preserve_range=True)
                wells, plaques = resize_labels(wells, shape), resize_labels(plaques, shape)
                if scratches is not None:
                    scratches = resize(scratches, shape, order=1, anti_aliasing=base_scale < 1, preserve_range=True)
            multiple = config.size_multiple
            normalised, wells, plaques = (pad_to_multiple(a, multiple) for a in (normalised, wells, plaques))
            if scratches is not None:
                scratches = pad_to_multiple(scratches, multiple)
        else:
            rng = np.random.default_rng([self.seed, index, draw])
            normalised, wells, plaques, scratches = augment(
                normalised, wells, plaques, base_scale, self.patch, self.augmentation, rng, scratches
            )
        sample = make_targets(wells, plaques, config, scratches, self.scratch_weight)
        sample["image"] = torch.from_numpy(np.ascontiguousarray(normalised.transpose(2, 0, 1), dtype=np.float32))
        return sample


class MixSampler(torch.utils.data.Sampler):
    """Keys ``(index, draw)`` of one epoch, drawing each sample's source dataset with the given probabilities.

    Parameters
    ----------
    sources : source dataset number of every item.
    fractions : probability of each source (normalised to sum 1).
    samples_per_epoch : keys per epoch.
    seed, epoch : the keys depend only on these (so a resumed run sees the same samples).
    """

    def __init__(self, sources: Sequence[int], fractions: Sequence[float], samples_per_epoch: int, seed: int = 0, epoch: int = 0):
        self.sources = np.asarray(sources)
        self.fractions = np.asarray(fractions, float) / float(np.sum(fractions))
        self.samples_per_epoch = samples_per_epoch
        self.seed = seed
        self.epoch = epoch
        self._members = [np.flatnonzero(self.sources == s) for s in range(len(self.fractions))]
        for number, members in enumerate(self._members):
            if len(members) == 0 and self.fractions[number] > 0:
                raise ValueError(f"source {number} has no items but a mixing fraction of {self.fractions[number]:.3g}")

    def __len__(self) -> int:
        return self.samples_per_epoch

    def __iter__(self) -> Iterator[tuple[int, int]]:
        rng = np.random.default_rng([self.seed, self.epoch])
        chosen = rng.choice(len(self.fractions), size=self.samples_per_epoch, p=self.fractions)
        for position, source in enumerate(chosen):
            members = self._members[source]
            yield int(members[rng.integers(len(members))]), self.epoch * self.samples_per_epoch + position
