"""Writing a dataset: items, manifest, counts.csv; deciding whether a directory may be resumed or replaced.

The writer knows nothing of rendering: it takes :class:`~platesynth.render.result.RenderResult` objects and
plain dictionaries. Every file is written atomically (a temporary name beside it, then a rename).
"""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from platesynth.data.layout import (
    COCO_NAME,
    COUNTS_COLUMNS,
    COUNTS_NAME,
    ITEM_DIRS,
    MANIFEST_NAME,
    DatasetItem,
    Manifest,
    is_finished,
    is_item_name,
    item_name,
    item_paths,
    read_manifest,
    read_params,
)
from platesynth.errors import DatasetError, ShapeMismatchError
from platesynth.io import write_json, write_png, write_text, write_tiff
from platesynth.outputs import LOCK_NAME, MARKER_NAME
from platesynth.render.result import RenderResult

_TOP_LEVEL_FILES = (MANIFEST_NAME, COUNTS_NAME, COCO_NAME)
IMAGE_PNG_LEVEL = 1
"""zlib level of the dataset's PNG images, lossless like every level. Pillow at its default level 6 took longer to
write a 1024x768 image than the raster renderer to draw it (130-170 ms); :func:`platesynth.io.encode_png` at level 1
takes about 20 ms, the file about 14 % larger."""


def _check_result(result: RenderResult, name: str) -> None:
    image, wells, plaques = result.image, result.wells, result.plaques
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise DatasetError(f"item {name}: image must be (H, W, 3) uint8, got {image.dtype} {image.shape}")
    if wells.dtype != np.uint8 or plaques.dtype != np.uint16:
        raise DatasetError(
            f"item {name}: masks must be uint8 wells and uint16 plaques, got {wells.dtype} and {plaques.dtype}"
        )
    if wells.shape != image.shape[:2] or plaques.shape != image.shape[:2]:
        raise ShapeMismatchError(
            f"item {name}: image {image.shape[:2]}, well mask {wells.shape} and plaque mask {plaques.shape} "
            "differ in size"
        )


def well_records(result: RenderResult) -> list[dict[str, Any]]:
    """Per well of a rendered plate: id, grid row/col, label, the plaques in the masks and the count a person
    would report (``None``, a blank, where the well is not countable: lysed or emptied)."""
    plaques = result.plaque_counts()
    counts = result.well_counts(plaques)
    return [
        {"id": w.id, "row": w.row, "col": w.col, "label": w.label, "plaques": plaques[w.id], "count": counts[w.id]}
        for w in sorted(result.well_info, key=lambda w: w.id)
    ]


def write_item(item: DatasetItem, result: RenderResult, params: dict[str, Any]) -> None:
    """Write one item: image, well mask, plaque mask, then the params JSON last.

    Parameters
    ----------
    item : where the files go (see :func:`platesynth.data.layout.item_paths`).
    result : the rendered image and masks.
    params : JSON-serialisable description of the scene; ``"wells"`` (per-well counts, see
        :func:`well_records`) is added to it.
    """
    _check_result(result, item.name)
    write_png(item.image_path, result.image, compress_level=IMAGE_PNG_LEVEL)
    write_tiff(item.wells_path, result.wells)
    write_tiff(item.plaques_path, result.plaques)
    if item.params_path is not None:
        write_compact_json(item.params_path, {**params, "wells": well_records(result)})


def write_compact_json(path: str | os.PathLike, obj: Any) -> None:
    """Write ``obj`` as JSON without whitespace, atomically (params and COCO files get large)."""
    write_text(path, json.dumps(obj, separators=(",", ":")) + "\n")


def _is_non_empty_dir(path: Path) -> bool:
    """Whether ``path`` is a folder holding anything but the output marker and lock (:mod:`platesynth.outputs`)."""
    return path.is_dir() and any(p.name not in (MARKER_NAME, LOCK_NAME) for p in path.iterdir())


def check_directory(directory: str | os.PathLike, manifest: Manifest, overwrite: bool = False) -> Manifest | None:
    """Decide whether ``manifest`` may be written into ``directory``, changing nothing.

    Returns
    -------
    Manifest or None
        The manifest already there when the run resumes (or extends) that same dataset, with or without
        ``overwrite``; ``None`` when the directory is missing or empty, or its content will be replaced
        (``overwrite``).

    Raises
    ------
    DatasetError
        If ``directory`` is a file; or, without ``overwrite``, if it holds other files but no manifest, holds a
        different dataset, or holds more images than asked for.
    """
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise DatasetError(f"{directory}: exists and is not a directory")
    if not _is_non_empty_dir(directory):
        return None
    try:
        existing = read_manifest(directory)
    except DatasetError:
        if not overwrite:
            raise
        existing = None
    if existing is None:
        problem = f"not empty and holds no platesynth dataset ({MANIFEST_NAME}); choose another directory"
    elif differences := existing.differences(manifest):
        settings = [
            f"{name} {existing.renderer.get(key)!r} there, {manifest.renderer.get(key)!r} asked"
            for name in differences
            if name.startswith("renderer.") and (key := name.removeprefix("renderer."))
        ]
        detail = f": {'; '.join(settings)}" if settings else ""
        problem = f"holds a different dataset ({', '.join(differences)} differ{detail}); choose another directory"
    elif manifest.count < existing.count:
        problem = (
            f"holds a dataset of {existing.count} images, asked for {manifest.count}; "
            "a dataset can be extended but not shrunk"
        )
    else:
        return existing
    if overwrite:
        return None
    raise DatasetError(f"{directory}: {problem} or pass --overwrite to replace it")


def remove_temporary_files(directory: str | os.PathLike) -> int:
    """Delete the temporary files that killed runs left in a dataset directory; returns how many."""
    directory = Path(directory)
    removed = 0
    for folder in (directory, *(directory / d for d in ITEM_DIRS)):
        if not folder.is_dir():
            continue
        for path in folder.iterdir():
            if path.is_file() and path.name.startswith(".") and ".tmp" in path.name:
                path.unlink()
                removed += 1
    return removed


def remove_dataset_files(directory: str | os.PathLike) -> None:
    """Delete this layout's files (manifest, tables, item files, temporary files) and nothing else.

    Folders of the layout that end up empty are removed too.
    """
    directory = Path(directory)
    remove_temporary_files(directory)
    for name in _TOP_LEVEL_FILES:
        (directory / name).unlink(missing_ok=True)
    for folder_name in ITEM_DIRS:
        folder = directory / folder_name
        if not folder.is_dir():
            continue
        for path in folder.iterdir():
            if path.is_file() and path.suffix in (".png", ".tif", ".json") and is_item_name(path.stem):
                path.unlink()
    for folder in (directory / d for d in (*ITEM_DIRS, "masks")):
        if folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()


def prepare_directory(
    directory: str | os.PathLike, manifest: Manifest, overwrite: bool = False
) -> tuple[Manifest, list[int]]:
    """Make ``directory`` ready for ``manifest``.

    Checks with :func:`check_directory`; then, with ``overwrite``, removes the previous dataset's files;
    removes temporary files of killed runs; creates the folders; writes the manifest.

    Returns
    -------
    manifest : Manifest
        The manifest written: when resuming, the previous run's ``failed`` is kept until this run ends, and
        ``coco`` stays on once a run asked for it (so the annotations never go stale).
    todo : list of int
        The indices of the items not yet finished.
    """
    directory = Path(directory)
    existing = check_directory(directory, manifest, overwrite)
    if existing is None and _is_non_empty_dir(directory):
        remove_dataset_files(directory)
    remove_temporary_files(directory)
    for folder in ITEM_DIRS:
        (directory / folder).mkdir(parents=True, exist_ok=True)
    if existing is not None:
        manifest = manifest.model_copy(update={"failed": existing.failed, "coco": manifest.coco or existing.coco})
    write_manifest(directory, manifest)
    todo = [i for i in range(manifest.count) if not is_finished(item_paths(directory, item_name(i)))]
    return manifest, todo


def write_manifest(directory: str | os.PathLike, manifest: Manifest) -> None:
    """Write ``manifest.json`` atomically."""
    write_json(Path(directory) / MANIFEST_NAME, manifest.model_dump(mode="json"))


def finished_items(directory: str | os.PathLike, count: int) -> list[DatasetItem]:
    """The finished items among the first ``count`` of a dataset, in index order."""
    items = (item_paths(directory, item_name(i)) for i in range(count))
    return [item for item in items if is_finished(item)]


def write_counts_csv(directory: str | os.PathLike, items: list[DatasetItem]) -> Path:
    """Write ``counts.csv`` (``image,row,col,well,count``; one row per well per image, the count blank where a
    person would not count: a lysed or emptied well) from the items' params.

    The per-well counts in the params files were derived from the masks when the item was written
    (:func:`well_records`). Rows are ordered by image, then grid row and column.
    """
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(COUNTS_COLUMNS)
    for item in items:
        params = read_params(item)
        if "wells" not in params:
            raise DatasetError(f"{item.params_path}: no per-well counts ('wells')")
        for well in sorted(params["wells"], key=lambda w: (w["row"], w["col"])):
            count = "" if well["count"] is None else well["count"]
            writer.writerow((item.image_path.name, well["row"], well["col"], well["label"], count))
    path = Path(directory) / COUNTS_NAME
    write_text(path, buffer.getvalue())
    return path

