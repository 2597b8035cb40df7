"""The dataset layout on disk, and reading a dataset back.

A dataset directory holds::

    manifest.json                what was asked for (configuration, seed, count, size, backend, version)
    images/000000.png            RGB image
    masks/wells/000000.tif       uint8 well instance mask (0 background, 1..n wells)
    masks/plaques/000000.tif     uint16 plaque instance mask (0 none, 1..m plaques)
    params/000000.json           the concrete scene, its seed and the package version (written last)
    counts.csv                   plaques per well: image,row,col,well,count
    annotations.coco.json        optional COCO instances (wells and plaques)

An item is finished when all four of its files exist; the params file is written last, so a run that was
killed leaves no finished-looking item behind, only temporary files (``.<name>.*.tmp.<ext>``) that the next
run removes.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from platesynth.errors import DatasetError, EmptyDatasetError
from platesynth.io import image_size, read_image, read_mask, to_rgb_uint8

MANIFEST_NAME = "manifest.json"
COUNTS_NAME = "counts.csv"
COCO_NAME = "annotations.coco.json"
IMAGES_DIR = "images"
WELLS_DIR = "masks/wells"
PLAQUES_DIR = "masks/plaques"
PARAMS_DIR = "params"
ITEM_DIRS = (IMAGES_DIR, WELLS_DIR, PLAQUES_DIR, PARAMS_DIR)
DATASET_FORMAT = "platesynth-dataset"
FORMAT_VERSION = 1
COUNTS_COLUMNS = ("image", "row", "col", "well", "count")

_ITEM_NAME = re.compile(r"^\d{6,}$")


def item_name(index: int) -> str:
    """File stem of item ``index``: zero-padded to six digits (``7`` -> ``"000007"``)."""
    if index < 0:
        raise ValueError(f"item index must be >= 0, got {index}")
    return f"{index:06d}"


@dataclass(frozen=True)
class DatasetItem:
    """The files of one dataset item.

    ``params_path`` is ``None`` for datasets made without params (e.g. hand-annotated real images).
    """

    image_path: Path
    wells_path: Path
    plaques_path: Path
    params_path: Path | None

    @property
    def name(self) -> str:
        """The item's file stem, e.g. ``"000007"``."""
        return self.image_path.stem

    def paths(self) -> tuple[Path, ...]:
        """All of the item's files, the params file last."""
        paths = (self.image_path, self.wells_path, self.plaques_path, self.params_path)
        return tuple(p for p in paths if p is not None)


def item_paths(directory: str | os.PathLike, name: str) -> DatasetItem:
    """Where item ``name`` of the dataset in ``directory`` lives (whether or not it exists yet)."""
    directory = Path(directory)
    return DatasetItem(
        image_path=directory / IMAGES_DIR / f"{name}.png",
        wells_path=directory / WELLS_DIR / f"{name}.tif",
        plaques_path=directory / PLAQUES_DIR / f"{name}.tif",
        params_path=directory / PARAMS_DIR / f"{name}.json",
    )


def is_finished(item: DatasetItem) -> bool:
    """Whether all of the item's files exist."""
    return all(path.is_file() for path in item.paths())


class Manifest(BaseModel):
    """``manifest.json``: what a dataset was asked to be.

    Two manifests describe the same dataset when :meth:`identity` is equal; ``count`` may then grow
    (the run extends the dataset) and ``failed`` records the items whose rendering failed in the last run.
    """

    model_config = ConfigDict(extra="forbid")

    format: str = DATASET_FORMAT
    format_version: int = FORMAT_VERSION
    platesynth_version: str
    preset: str | None = None
    config_file: str | None = None
    overrides: dict[str, Any] = Field(default_factory=dict)
    config: dict[str, Any]
    seed: int
    count: int = Field(gt=0)
    size: tuple[int, int]
    backend: str
    renderer: dict[str, Any] = Field(default_factory=dict)
    coco: bool = False
    failed: dict[str, str] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _renderer_of_the_backend(self) -> Manifest:
        if not self.renderer and self.backend == "raster":  # written before the renderer was recorded
            self.renderer = {"backend": "raster", "version": self.platesynth_version}
        if self.renderer and self.renderer.get("backend") != self.backend:
            raise ValueError(f"renderer {self.renderer.get('backend')!r} is not the backend {self.backend!r}")
        return self

    def identity(self) -> dict[str, Any]:
        """The fields that decide what every item looks like (everything but count, outputs and failures)."""
        return self.model_dump(
            mode="json",
            include={"format", "format_version", "platesynth_version", "config", "seed", "size", "backend", "renderer"},
        )

    def differences(self, other: Manifest) -> list[str]:
        """Names of the identity fields in which ``other`` differs from this manifest.

        The renderer's settings are named one by one (``renderer.samples``), unless the backend itself differs.
        """
        mine, theirs = self.identity(), other.identity()
        names = []
        for key in mine:
            if mine[key] == theirs.get(key) or (key == "renderer" and "backend" in names):
                continue
            if key == "renderer":
                settings = {**mine[key], **theirs[key]}
                names += [f"renderer.{k}" for k in settings if mine[key].get(k) != theirs[key].get(k)]
            else:
                names.append(key)
        return names


def read_manifest(directory: str | os.PathLike) -> Manifest | None:
    """The manifest of the dataset in ``directory``, or ``None`` where there is none.

    Raises
    ------
    DatasetError
        If ``manifest.json`` exists but is not valid JSON or not a platesynth manifest.
    """
    path = Path(directory) / MANIFEST_NAME
    if not path.is_file():
        return None
    try:
        return Manifest.model_validate_json(path.read_text())
    except (ValidationError, ValueError, OSError) as exc:
        first = exc.errors()[0]["msg"] if isinstance(exc, ValidationError) else str(exc)
        raise DatasetError(f"{path}: not a valid platesynth manifest ({first})") from None


def _natural_key(path: Path) -> tuple[int, str]:
    return len(path.stem), path.stem


def list_items(directory: str | os.PathLike) -> list[DatasetItem]:
    """The items of a dataset: every ``images/*.png`` with its two masks, in name order.

    Parameters
    ----------
    directory : str or path-like
        A dataset directory (see the module docstring for the layout).

    Returns
    -------
    list of DatasetItem
        ``params_path`` is ``None`` where an image has no params file.

    Raises
    ------
    EmptyDatasetError
        If the directory or its ``images/`` folder does not exist or holds no PNG image.
    DatasetError
        If an image has no well or plaque mask.
    """
    directory = Path(directory)
    images_dir = directory / IMAGES_DIR
    if not images_dir.is_dir():
        raise EmptyDatasetError(f"{directory}: not a dataset (no {IMAGES_DIR}/ folder)")
    images = sorted((p for p in images_dir.glob("*.png") if not p.name.startswith(".")), key=_natural_key)
    if not images:
        raise EmptyDatasetError(f"{images_dir}: no images (*.png) found")
    items = []
    for image in images:
        item = item_paths(directory, image.stem)
        for mask in (item.wells_path, item.plaques_path):
            if not mask.is_file():
                raise DatasetError(f"{mask}: missing mask for image {image}")
        params = item.params_path if item.params_path is not None and item.params_path.is_file() else None
        items.append(DatasetItem(item.image_path, item.wells_path, item.plaques_path, params))
    return items


def load_item(item: DatasetItem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read an item's image and masks.

    Returns
    -------
    image : (H, W, 3) uint8
    wells : (H, W) well instance mask, as stored (uint8 for datasets written by platesynth)
    plaques : (H, W) plaque instance mask, as stored (uint16 for datasets written by platesynth)

    Raises
    ------
    ImageReadError
        If a file is missing or cannot be read, or a mask is not a 2-D integer array.
    DatasetError
        If a mask's size differs from the image's.
    """
    image = to_rgb_uint8(read_image(item.image_path))
    return (image, *load_masks(item, (image.shape[1], image.shape[0])))


def load_masks(item: DatasetItem, size: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Read an item's two masks (not its image), checking that they have the image's ``size`` = (width, height).

    ``size`` defaults to the image file's, read from its header. Raises as :func:`load_item`.
    """
    width, height = size if size is not None else image_size(item.image_path)
    masks = read_mask(item.wells_path), read_mask(item.plaques_path)
    for path, mask in zip((item.wells_path, item.plaques_path), masks, strict=True):
        if mask.shape != (height, width):
            raise DatasetError(
                f"{path}: mask size {mask.shape[1]}x{mask.shape[0]} differs from image "
                f"{item.image_path} size {width}x{height}"
            )
    return masks


def read_params(item: DatasetItem) -> dict[str, Any]:
    """The parsed params JSON of an item (see :func:`platesynth.data.batch.rerender`).

    Raises
    ------
    DatasetError
        If the item has no params file or it is not valid JSON.
    """
    if item.params_path is None or not item.params_path.is_file():
        raise DatasetError(f"{item.image_path}: no params file")
    try:
        return json.loads(item.params_path.read_text())
    except (ValueError, OSError) as exc:
        raise DatasetError(f"{item.params_path}: cannot read params ({exc})") from None


class WellCount(NamedTuple):
    """One row of a ``counts.csv``: plaques counted in one well of one image (``None`` where uncountable)."""

    image: str
    row: int
    col: int
    well: str
    count: int | None


def read_counts_csv(path: str | os.PathLike) -> list[WellCount]:
    """Read a per-well plaque count table (``image,row,col,well,count``).

    Blank counts (wells judged uncountable) become ``None``. Extra columns are ignored. The file is UTF-8 (a byte
    order mark is allowed).

    Raises
    ------
    DatasetError
        If the file is missing or not UTF-8 text, lacks a column, has a row with fewer fields than its header (a
        missing count is not a blank one: write ``a.png,0,0,A4,``), or a row holds a value that is not a
        non-negative integer.
    """
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: no such file")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DatasetError(f"{path}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at position {exc.start}); "
                           "save the table as UTF-8 CSV") from None
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read ({exc.strerror or exc})") from None
    rows = []
    reader = csv.DictReader(io.StringIO(text, newline=""))
    try:
        missing = [c for c in COUNTS_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise DatasetError(f"{path}: missing column(s) {', '.join(missing)} (expected {','.join(COUNTS_COLUMNS)})")
        for record in reader:
            line = reader.line_num
            if None in record.values():
                given = sum(value is not None for value in record.values())
                raise DatasetError(
                    f"{path}, line {line}: {given} field(s), the header has {len(reader.fieldnames or ())}; "
                    "leave a count blank, not out (e.g. a.png,0,0,A4,)"
                )
            try:
                row, col = int(record["row"]), int(record["col"])
                count = None if not (record["count"] or "").strip() else int(record["count"])
            except (TypeError, ValueError):
                raise DatasetError(f"{path}, line {line}: row, col and count must be integers") from None
            if min(row, col) < 0 or (count is not None and count < 0):
                raise DatasetError(f"{path}, line {line}: row, col and count must be >= 0")
            if not record["image"]:
                raise DatasetError(f"{path}, line {line}: empty image name")
            rows.append(WellCount(record["image"], row, col, record["well"] or "", count))
    except csv.Error as exc:
        raise DatasetError(f"{path}, line {reader.line_num}: not a CSV table ({exc})") from None
    return rows


def is_item_name(name: str) -> bool:
    """Whether ``name`` is a file stem that platesynth writes (six or more digits)."""
    return bool(_ITEM_NAME.match(name))
