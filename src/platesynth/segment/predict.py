"""Prediction: network maps at the working size, star-convex polygon NMS, instance masks at the image's own size.

An image is normalised, resized so that its longest side is the model's ``input_long_side``, zero-padded to a
multiple of the network's deepest stride and passed through the network. In each branch the grid cells above the
probability threshold are candidate polygons; StarDist's non-maximum suppression keeps, from the most probable
down, those overlapping no kept polygon by more than the NMS threshold. The kept polygons are scaled back to the
image's own size and drawn (more probable on top) into the instance mask.

Photos are framed more loosely or tightly than the training images. A model that knows its training images' well
size (``ModelConfig.well_diameter``) measures the wells it found; where their median diameter differs from it by
more than ``WELL_SIZE_TOLERANCE``, the network runs again with the image resized so that the wells (and so the
plaques) have the size the model learnt.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
from skimage.transform import resize
from stardist.geometry import polygons_to_label
from stardist.nms import non_maximum_suppression

from platesynth.data.layout import item_paths
from platesynth.data.writer import write_item
from platesynth.errors import DatasetError, ParameterError
from platesynth.io import read_image, to_rgb_uint8
from platesynth.limits import check_prediction
from platesynth.render.result import RenderResult
from platesynth.segment.countability import judge_countable, stained_fractions
from platesynth.segment.counts import sort_wells, write_count_table
from platesynth.segment.data import normalize_image, pad_to_multiple, working_scale
from platesynth.segment.model import BRANCHES, WELL_RESCALE_RANGE, WELL_SIZE_TOLERANCE, ModelConfig, StarDistTwoBranch


@dataclass(frozen=True)
class BranchMaps:
    """One branch's output on its grid: probability ``(h, w)`` and distances ``(h, w, n_rays)`` in working pixels."""

    prob: np.ndarray
    dist: np.ndarray
    grid: int


@dataclass(frozen=True)
class Polygons:
    """Star-convex polygons kept by NMS: centres ``(n, 2)`` (y, x) and distances ``(n, n_rays)`` in working pixels."""

    points: np.ndarray
    dist: np.ndarray
    scores: np.ndarray


def largest_long_side(config: ModelConfig) -> int:
    """The longest side the network input may take in :func:`predict_image` (for memory checks before reading)."""
    if config.well_diameter is None:
        return config.input_long_side
    return round(config.input_long_side * WELL_RESCALE_RANGE[1])


def predict_maps(
    model: StarDistTwoBranch, image: np.ndarray, long_side: int | None = None
) -> tuple[dict[str, BranchMaps], tuple[int, int]]:
    """Run the network on one RGB image resized so that its longest side is ``long_side`` (default: the model's
    working size, ``input_long_side``).

    Returns
    -------
    maps : per branch, its probability and distance maps.
    working_shape : (height, width) of the resized image the maps refer to.
    """
    config = model.config
    long_side = long_side or config.input_long_side
    check_prediction(config, image.shape, long_side=long_side)
    normalised = normalize_image(to_rgb_uint8(image), config.percentile_low, config.percentile_high)
    scale = working_scale(image.shape, long_side)
    shape = (max(1, round(image.shape[0] * scale)), max(1, round(image.shape[1] * scale)))
    if shape != normalised.shape[:2]:
        normalised = resize(normalised, shape, order=1, anti_aliasing=scale < 1, preserve_range=True)
    padded = pad_to_multiple(normalised.astype(np.float32), config.size_multiple)
    device = next(model.parameters()).device
    batch = torch.from_numpy(np.ascontiguousarray(padded.transpose(2, 0, 1)))[None].to(device)
    was_training = model.training
    model.eval()
    with torch.no_grad():
        outputs = model(batch)
    model.train(was_training)
    maps = {}
    for name, (logits, dist) in outputs.items():
        grid = config.branches[name].grid
        rows, cols = -(-shape[0] // grid), -(-shape[1] // grid)
        prob = torch.sigmoid(logits[0, 0, :rows, :cols]).cpu().numpy()
        distances = dist[0, :, :rows, :cols].permute(1, 2, 0).cpu().numpy()
        maps[name] = BranchMaps(prob, distances, grid)
    return maps, shape


def nms_polygons(maps: BranchMaps, prob_thresh: float, nms_thresh: float) -> Polygons:
    """Candidates above ``prob_thresh``, thinned by StarDist's star-convex polygon non-maximum suppression.

    A polygon is suppressed when its intersection with a more probable kept polygon exceeds ``nms_thresh`` times the
    smaller polygon's area.
    """
    if not 0 < prob_thresh < 1 or not 0 <= nms_thresh <= 1:
        raise ParameterError(f"thresholds must satisfy 0 < prob < 1 and 0 <= nms <= 1, got {prob_thresh}, {nms_thresh}")
    n_rays = maps.dist.shape[-1]
    dist = np.maximum(maps.dist, 1e-3).astype(np.float32)
    if not (maps.prob > prob_thresh).any():
        return Polygons(np.zeros((0, 2), np.float64), np.zeros((0, n_rays), np.float32), np.zeros(0, np.float32))
    points, scores, dist = non_maximum_suppression(
        dist, maps.prob, grid=(maps.grid, maps.grid), b=2, nms_thresh=nms_thresh, prob_thresh=prob_thresh
    )
    return Polygons(points.astype(np.float64), dist, scores)


def polygon_diameters(polygons: Polygons) -> np.ndarray:
    """Equivalent diameters (of the disc of equal area) of star-convex polygons, in working pixels."""
    n_rays = polygons.dist.shape[-1]
    if len(polygons.dist) == 0:
        return np.zeros(0)
    areas = 0.5 * np.sin(2 * np.pi / n_rays) * (polygons.dist * np.roll(polygons.dist, -1, axis=-1)).sum(-1)
    return 2 * np.sqrt(areas / np.pi)


def rescaled_long_side(config: ModelConfig, wells: Polygons) -> int | None:
    """The working size that brings the median of the found wells to the model's ``well_diameter``, or ``None``
    where no rescaling is due (the model has no ``well_diameter``, no well was found, or the wells are within
    ``WELL_SIZE_TOLERANCE`` of it). The factor is kept within ``WELL_RESCALE_RANGE``."""
    if config.well_diameter is None or len(wells.dist) == 0:
        return None
    factor = config.well_diameter / float(np.median(polygon_diameters(wells)))
    if abs(factor - 1) <= WELL_SIZE_TOLERANCE:
        return None
    return round(config.input_long_side * float(np.clip(factor, *WELL_RESCALE_RANGE)))


def polygons_to_mask(polygons: Polygons, working_shape: tuple[int, int], shape: tuple[int, int]) -> np.ndarray:
    """Draw polygons found at ``working_shape`` into an int32 instance mask of ``shape`` (ids 1..n, more probable on top)."""
    if len(polygons.points) == 0:
        return np.zeros(shape, np.int32)
    scale = np.array([shape[0] / working_shape[0], shape[1] / working_shape[1]])
    points = (polygons.points + 0.5) * scale - 0.5
    return polygons_to_label(polygons.dist, points, shape, prob=polygons.scores, scale_dist=tuple(scale))


def predict_image(
    model: StarDistTwoBranch,
    image: np.ndarray,
    thresholds: dict[str, tuple[float, float]] | None = None,
    plate_format: int | None = None,
    from_below: bool = True,
) -> RenderResult:
    """Well and plaque instance masks of one plate image, at the image's own size.

    Parameters
    ----------
    model : a trained network (:func:`platesynth.segment.model.load_model`).
    image : (H, W) or (H, W, 3|4) uint8/uint16 image.
    thresholds : per branch ``(prob_thresh, nms_thresh)``; default: those stored with the model.
    plate_format : wells per plate for sorting wells into the grid; default: the model's.
    from_below : whether the plate was photographed from below (only changes the well labels).

    Returns
    -------
    RenderResult
        The same container the renderers return: the RGB image, wells (uint8, ids in reading order of the grid),
        plaques (uint16) and a :class:`~platesynth.render.result.WellInfo` (id, row, col, label) per well;
        ``plaque_counts()`` gives plaques per well, ``well_counts()`` the same with ``None`` for the wells judged
        uncountable (:mod:`platesynth.segment.countability`, with the model's threshold).
    """
    rgb = to_rgb_uint8(image)

    def kept(maps: dict[str, BranchMaps], name: str) -> Polygons:
        prob_thresh, nms_thresh = (thresholds or {}).get(name, model.config.thresholds[name])
        return nms_polygons(maps[name], prob_thresh, nms_thresh)

    maps, working_shape = predict_maps(model, rgb)
    wells = kept(maps, "wells")
    long_side = rescaled_long_side(model.config, wells)
    if long_side is not None:  # the wells decide the scale; plaques are only looked for at the final one
        maps, working_shape = predict_maps(model, rgb, long_side)
        wells = kept(maps, "wells")
    polygons = {"wells": wells, "plaques": kept(maps, "plaques")}
    masks = {name: polygons_to_mask(polygons[name], working_shape, rgb.shape[:2]) for name in BRANCHES}
    if masks["plaques"].max() > np.iinfo(np.uint16).max:
        raise ParameterError(f"{masks['plaques'].max()} plaques found; a uint16 plaque mask holds at most 65535")
    wells, info = sort_wells(masks["wells"], plate_format or model.config.plate_format, from_below)
    if model.config.countable_min_stained > 0:  # 0: every well countable (models trained before countability)
        countable = judge_countable(stained_fractions(rgb, wells), model.config.countable_min_stained)
        info = [replace(w, countable=countable.get(w.id, True)) for w in info]
    return RenderResult(rgb, wells, masks["plaques"].astype(np.uint16), info)


def _unique_stems(paths: Sequence[Path]) -> None:
    seen: dict[str, Path] = {}
    for path in paths:
        if path.stem in seen:
            raise DatasetError(f"{path}: same name as {seen[path.stem]}; outputs are named by file stem")
        seen[path.stem] = path


def predict_files(
    model: StarDistTwoBranch,
    paths: Sequence[str | os.PathLike],
    out_dir: str | os.PathLike,
    thresholds: dict[str, tuple[float, float]] | None = None,
    plate_format: int | None = None,
    from_below: bool = True,
    progress: Callable[[Path], None] | None = None,
    before_writing: Callable[[], None] | None = None,
) -> Path:
    """Predict every image and write the results in the dataset layout, plus ``counts.csv``.

    Writes ``out_dir/images/<stem>.png`` (the input as RGB), ``masks/wells/<stem>.tif``, ``masks/plaques/<stem>.tif``,
    ``params/<stem>.json`` (source file, model thresholds and per-well records) and ``counts.csv`` (``image`` is the
    input's file name, then grid row, column, well label, plaques; blank for a well judged uncountable). Every
    input is read once before anything is written, so an unreadable file leaves no output; ``before_writing`` is
    called then, right before the first write (the command line claims ``out_dir`` there, see
    :func:`platesynth.outputs.claim_output`).

    Returns
    -------
    Path of the counts table.
    """
    paths = [Path(p) for p in paths]
    if not paths:
        raise DatasetError("no images given")
    _unique_stems(paths)
    for path in paths:
        check_prediction(model.config, read_image(path).shape, str(path), largest_long_side(model.config))
    if before_writing is not None:
        before_writing()
    out_dir = Path(out_dir)
    rows = []
    for path in paths:
        result = predict_image(model, read_image(path), thresholds, plate_format, from_below)
        counts = result.well_counts()
        params = {
            "source": str(path),
            "thresholds": thresholds or model.config.thresholds,
        }
        write_item(item_paths(out_dir, path.stem), result, params)
        rows += [(path.name, w.row, w.col, w.label, "" if counts[w.id] is None else counts[w.id]) for w in result.well_info]
        if progress is not None:
            progress(path)
    return write_count_table(out_dir / "counts.csv", rows)
