"""COCO instance annotations of a dataset: categories ``well`` (1) and ``plaque`` (2).

Segmentations are *uncompressed RLE* (``{"size": [h, w], "counts": [...]}``, column-major runs starting
with background), which decodes to exactly the instance masks; ``pycocotools.mask.frPyObjects`` and
detectron2 read it. ``area`` is the instance's pixel count and ``bbox`` its ``[x, y, width, height]``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from platesynth import __version__
from platesynth.data.layout import COCO_NAME, DatasetItem, load_masks
from platesynth.data.writer import write_compact_json

WELL_CATEGORY = 1
PLAQUE_CATEGORY = 2
CATEGORIES = [
    {"id": WELL_CATEGORY, "name": "well", "supercategory": "plate"},
    {"id": PLAQUE_CATEGORY, "name": "plaque", "supercategory": "well"},
]


def _runs_from_sorted_positions(positions: np.ndarray, total: int) -> list[int]:
    """Alternating background/foreground run lengths of a flat mask given its sorted foreground positions."""
    if positions.size == 0:
        return [total]
    breaks = np.flatnonzero(np.diff(positions) != 1)
    starts = np.r_[positions[0], positions[breaks + 1]]
    ends = np.r_[positions[breaks], positions[-1]] + 1
    gaps = np.r_[starts[0], starts[1:] - ends[:-1]]
    runs = np.empty(2 * starts.size, dtype=np.int64)
    runs[0::2], runs[1::2] = gaps, ends - starts
    trailing = total - int(ends[-1])
    return runs.tolist() + ([trailing] if trailing else [])


def encode_rle(
    mask: np.ndarray, offset: tuple[int, int] = (0, 0), shape: tuple[int, int] | None = None
) -> dict[str, Any]:
    """Uncompressed COCO RLE of a boolean mask.

    Parameters
    ----------
    mask : (h, w) bool
        The object, or a crop of the image containing the whole object.
    offset : (row, col)
        Where the crop's top-left corner lies in the image.
    shape : (H, W)
        The image's shape; default the mask's own.

    Returns
    -------
    dict
        ``{"size": [H, W], "counts": [background, foreground, background, ...]}`` in column-major order.
    """
    height, width = shape if shape is not None else mask.shape
    cols, rows = np.nonzero(mask.T)  # column-major order: sorted by column, then row
    positions = (cols + offset[1]).astype(np.int64) * height + rows + offset[0]
    return {"size": [int(height), int(width)], "counts": _runs_from_sorted_positions(positions, height * width)}


def decode_rle(rle: dict[str, Any]) -> np.ndarray:
    """The boolean ``(H, W)`` mask of an uncompressed COCO RLE."""
    height, width = rle["size"]
    counts = np.asarray(rle["counts"], dtype=np.int64)
    values = np.arange(counts.size) % 2 == 1
    return np.repeat(values, counts).reshape((width, height)).T


def instance_annotations(mask: np.ndarray, category_id: int) -> list[dict[str, Any]]:
    """COCO annotations (without ``id`` and ``image_id``) of every instance of an instance mask.

    Each carries ``instance_id``, its value in the mask.
    """
    annotations = []
    areas = np.bincount(mask.ravel())
    for index, box in enumerate(ndimage.find_objects(mask), start=1):
        if box is None:
            continue
        rows, cols = box
        annotations.append(
            {
                "category_id": category_id,
                "instance_id": index,
                "segmentation": encode_rle(mask[box] == index, (rows.start, cols.start), mask.shape),
                "area": int(areas[index]),
                "bbox": [cols.start, rows.start, cols.stop - cols.start, rows.stop - rows.start],
                "iscrowd": 0,
            }
        )
    return annotations


def coco_dataset(items: list[DatasetItem]) -> dict[str, Any]:
    """The COCO dictionary of dataset items; image ids count from 1 in item order, as do annotation ids.

    ``file_name`` is relative to the dataset's ``images/`` folder.
    """
    images, annotations = [], []
    for image_id, item in enumerate(items, start=1):
        wells, plaques = load_masks(item)  # the image's size from its header: its pixels are not needed
        height, width = wells.shape
        images.append({"id": image_id, "file_name": item.image_path.name, "width": width, "height": height})
        for mask, category in ((wells, WELL_CATEGORY), (plaques, PLAQUE_CATEGORY)):
            for annotation in instance_annotations(mask, category):
                annotations.append({"id": len(annotations) + 1, "image_id": image_id, **annotation})
    return {
        "info": {"description": "platesynth synthetic plate images", "version": __version__},
        "licenses": [],
        "categories": CATEGORIES,
        "images": images,
        "annotations": annotations,
    }


def write_coco(directory: str | os.PathLike, items: list[DatasetItem]) -> Path:
    """Write ``annotations.coco.json`` of ``items`` into the dataset ``directory`` (compact JSON, atomically)."""
    path = Path(directory) / COCO_NAME
    write_compact_json(path, coco_dataset(items))
    return path
