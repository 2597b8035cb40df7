"""Wells by grid position, plaques per well, and predicted counts against a person's counts.

Detected wells are sorted into rows and columns of the plate's grid from their centres, allowing for a slightly
rotated plate and for missing wells: the grid's angle is the median direction (modulo 90 degrees) from each well to
its nearest neighbour, and after undoing it rows (columns) are the clusters of centres along y (x), numbered from
the top (left) and skipping as many positions as the gaps between clusters span.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree
from skimage.measure import regionprops

from platesynth.data.layout import WellCount, read_counts_csv
from platesynth.errors import DatasetError, ParameterError
from platesynth.io import read_image, write_text
from platesynth.render.result import RenderResult, WellInfo
from platesynth.scene import plate_geometry
from platesynth.segment.countability import CountabilityMetrics

COUNT_TABLE_COLUMNS = ("image", "row", "col", "well", "count")


def plate_shape(plate_format: int) -> tuple[int, int]:
    """(rows, columns) of a plate format, e.g. 12 -> (3, 4).

    Raises
    ------
    ParameterError
        For a format the scene model does not know.
    """
    geometry = plate_geometry(plate_format)
    return geometry.rows, geometry.cols


def well_label(row: int, col: int, n_cols: int, from_below: bool = True) -> str:
    """The label embossed on the plate (``"A1"``...) of the well at image grid position (row, col).

    A plate photographed from below is mirrored left-right: its column numbers read ``n_cols .. 1``.
    """
    number = n_cols - col if from_below else col + 1
    return f"{chr(ord('A') + row)}{number}"


def _cluster_positions(values: np.ndarray, spacing: float) -> np.ndarray:
    order = np.argsort(values)
    steps = np.diff(values[order])
    increments = np.where(steps > spacing / 2, np.maximum(1, np.round(steps / spacing)), 0)
    positions = np.empty(len(values), np.int64)
    positions[order] = np.concatenate([[0], np.cumsum(increments)]).astype(np.int64)
    return positions


def grid_positions(centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column of each well in the plate grid from its centre (see the module docstring).

    Parameters
    ----------
    centres : (n, 2) array of (y, x) well centres in pixels.

    Returns
    -------
    rows, cols : (n,) int arrays, 0-based from the top-left.
    """
    centres = np.asarray(centres, float).reshape(-1, 2)
    if len(centres) < 2:
        return np.zeros(len(centres), np.int64), np.zeros(len(centres), np.int64)
    distances, neighbours = cKDTree(centres).query(centres, k=2)
    spacing = float(np.median(distances[:, 1]))
    vectors = centres[neighbours[:, 1]] - centres
    angles = np.mod(np.arctan2(vectors[:, 0], vectors[:, 1]) + np.pi / 4, np.pi / 2) - np.pi / 4
    angle = float(np.median(angles))
    cos, sin = math.cos(angle), math.sin(angle)
    relative = centres - centres.mean(axis=0)
    y = -sin * relative[:, 1] + cos * relative[:, 0]
    x = cos * relative[:, 1] + sin * relative[:, 0]
    return _cluster_positions(y, spacing), _cluster_positions(x, spacing)


def _best_window(positions: np.ndarray, size: int) -> int:
    """Start of the ``size``-long run of positions holding the most wells (the first such run on ties)."""
    counts = np.bincount(positions)
    if len(counts) <= size:
        return 0
    sums = np.convolve(counts, np.ones(size, int), mode="valid")
    return int(np.argmax(sums))


def sort_wells(
    wells: np.ndarray, plate_format: int | None = 12, from_below: bool = True, min_area_fraction: float = 0.5
) -> tuple[np.ndarray, list[WellInfo]]:
    """Renumber a well instance mask by grid position and describe each well.

    Parameters
    ----------
    wells : (H, W) integer well instance mask.
    plate_format : wells per plate; where more rows or columns are found than the plate has, the block of the
        plate's size holding the most wells is kept and the others are dropped. ``None`` keeps all.
    from_below : whether the plate was photographed from below (for the labels).
    min_area_fraction : wells smaller than this fraction of the median well area are dropped.

    Returns
    -------
    wells : (H, W) uint8 mask with ids ``1..n`` in reading order (row by row).
    info : one :class:`~platesynth.render.result.WellInfo` per kept well.
    """
    regions = regionprops(np.asarray(wells, np.int32))
    if regions:
        median_area = float(np.median([r.area for r in regions]))
        regions = [r for r in regions if r.area >= min_area_fraction * median_area]
    if not regions:
        return np.zeros(wells.shape, np.uint8), []
    rows, cols = grid_positions(np.array([r.centroid for r in regions]))
    n_rows, n_cols = plate_shape(plate_format) if plate_format is not None else (rows.max() + 1, cols.max() + 1)
    rows = rows - _best_window(rows, n_rows)
    cols = cols - _best_window(cols, n_cols)
    keep = (rows >= 0) & (rows < n_rows) & (cols >= 0) & (cols < n_cols)
    order = sorted(np.flatnonzero(keep), key=lambda i: (rows[i], cols[i]))
    if len(order) > 255:
        raise ParameterError(f"{len(order)} wells found; a uint8 well mask holds at most 255")
    lookup = np.zeros(int(wells.max()) + 1, np.uint8)
    info = []
    for new_id, i in enumerate(order, start=1):
        lookup[regions[i].label] = new_id
        info.append(WellInfo(new_id, int(rows[i]), int(cols[i]), well_label(int(rows[i]), int(cols[i]), int(n_cols), from_below)))
    return lookup[wells], info


def write_count_table(
    path: str | os.PathLike, rows: Sequence[Sequence[Any]], columns: Sequence[str] = COUNT_TABLE_COLUMNS
) -> Path:
    """Write rows (by default ``image,row,col,well,count``) as CSV, atomically."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    writer.writerows(rows)
    path = Path(path)
    write_text(path, buffer.getvalue())
    return path


class CountMetrics:
    """Streaming agreement of predicted with true per-well counts: MAE, RMSE, Pearson r, mean error.

    ``update(predicted, true)`` takes equal-length sequences of counts (one entry per scored well).
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget every well seen."""
        self.predicted: list[float] = []
        self.true: list[float] = []

    def update(self, predicted: Sequence[float], true: Sequence[float]) -> None:
        """Add scored wells."""
        predicted, true = list(map(float, predicted)), list(map(float, true))
        if len(predicted) != len(true):
            raise ValueError(f"{len(predicted)} predicted counts but {len(true)} true counts")
        self.predicted += predicted
        self.true += true

    def compute(self) -> dict[str, float | int]:
        """``mae``, ``rmse``, ``pearson_r`` (NaN with fewer than two wells or a constant side), ``bias``
        (mean of predicted - true) and ``n_wells``; the errors are NaN without wells."""
        predicted, true = np.asarray(self.predicted), np.asarray(self.true)
        n = len(true)
        if n == 0:
            return {"mae": math.nan, "rmse": math.nan, "pearson_r": math.nan, "bias": math.nan, "n_wells": 0}
        error = predicted - true
        if n >= 2 and np.ptp(predicted) > 0 and np.ptp(true) > 0:
            pearson = float(np.corrcoef(predicted, true)[0, 1])
        else:
            pearson = math.nan
        return {
            "mae": float(np.abs(error).mean()),
            "rmse": float(np.sqrt((error**2).mean())),
            "pearson_r": pearson,
            "bias": float(error.mean()),
            "n_wells": n,
        }


def _inside_folder(name: str) -> bool:
    """Whether an image name from a table stays inside the folder it is relative to (no absolute path, no '..')."""
    if not name or name.startswith(("/", "\\")) or os.path.isabs(name) or (len(name) > 1 and name[1] == ":"):
        return False
    parts = name.replace("\\", "/").split("/")
    return ".." not in parts and "\0" not in name


def evaluate_counts(
    predict: Callable[[np.ndarray], RenderResult],
    images_dir: str | os.PathLike,
    counts_csv: str | os.PathLike,
    plate_format: int = 12,
    baseline_count: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Predicted plaques per well against a person's counts.

    Parameters
    ----------
    predict : maps an image to a :class:`~platesynth.render.result.RenderResult` whose ``well_info`` gives each
        predicted well's grid row and column (e.g. ``functools.partial(predict_image, model)``).
    images_dir : folder holding the images named in the table's ``image`` column.
    counts_csv : ``image,row,col,well,count`` table; blank counts (uncountable wells) are not scored for the
        counts, but they are for countability.
    plate_format : wells per plate; every (row, col) of the table must lie in its grid.
    baseline_count : if given, also report the errors of predicting this count for every well.
    progress : called with (images done, total) after each image.

    Returns
    -------
    dict
        The :meth:`CountMetrics.compute` figures over the wells a person counted, ``n_images``,
        ``n_wells_not_detected`` (counted wells where no well was found: predicted 0), ``countability`` (the
        :class:`~platesynth.segment.countability.CountabilityMetrics` of the model's judgement against the blanks,
        over the detected wells), ``baseline`` (when asked) and ``wells``: one record per listed well
        (``image, row, col, well, count, predicted, detected, predicted_countable``).

    Raises
    ------
    DatasetError
        If the table is unreadable, lists no well or no count (every count blank: nothing to score), names a well
        outside the plate or twice, an image outside ``images_dir`` (an absolute name, or one leading out with
        ``..``) or an image missing from it.
    """
    counts_csv, images_dir = Path(counts_csv), Path(images_dir)
    n_rows, n_cols = plate_shape(plate_format)
    records = read_counts_csv(counts_csv)
    if not records:
        raise DatasetError(f"{counts_csv}: lists no well (only a header?): nothing to score")
    if all(record.count is None for record in records):
        raise DatasetError(
            f"{counts_csv}: all {len(records)} counts are blank (uncountable wells): nothing to score; "
            "fill in the counts of the wells a person counted"
        )
    by_image: dict[str, dict[tuple[int, int], WellCount]] = {}
    for line, record in enumerate(records, start=2):
        if not _inside_folder(record.image):
            raise DatasetError(
                f"{counts_csv}, line {line}: image {record.image!r} lies outside --images; name images relative to "
                "that folder, without '..'"
            )
        if record.row >= n_rows or record.col >= n_cols:
            raise DatasetError(
                f"{counts_csv}, line {line}: unknown well {record.well or '?'} at row {record.row}, col {record.col}: "
                f"a {plate_format}-well plate has rows 0..{n_rows - 1} and columns 0..{n_cols - 1}"
            )
        wells = by_image.setdefault(record.image, {})
        if (record.row, record.col) in wells:
            raise DatasetError(f"{counts_csv}, line {line}: {record.image} row {record.row}, col {record.col} listed twice")
        wells[(record.row, record.col)] = record
    missing = [name for name in by_image if not (images_dir / name).is_file()]
    if missing:
        raise DatasetError(f"{counts_csv}: {len(missing)} image(s) not found in {images_dir}, e.g. {missing[0]}")
    table = []
    for done, (name, wells) in enumerate(by_image.items(), start=1):
        result = predict(read_image(images_dir / name))
        predicted = result.plaque_counts()
        info = {(w.row, w.col): w for w in result.well_info}
        for well in sorted(wells.values(), key=lambda w: (w.row, w.col)):
            found = info.get((well.row, well.col))
            table.append(
                {
                    "image": name,
                    "row": well.row,
                    "col": well.col,
                    "well": well.well,
                    "count": well.count,
                    "predicted": predicted[found.id] if found is not None else 0,
                    "detected": found is not None,
                    "predicted_countable": found.countable if found is not None else True,
                }
            )
        if progress is not None:
            progress(done, len(by_image))
    scored = [w for w in table if w["count"] is not None]
    metric = CountMetrics()
    metric.update([w["predicted"] for w in scored], [w["count"] for w in scored])
    report: dict[str, Any] = metric.compute()
    report["n_images"] = len({w["image"] for w in scored})
    report["n_wells_not_detected"] = sum(not w["detected"] for w in scored)
    countability = CountabilityMetrics()
    detected = [w for w in table if w["detected"]]
    countability.update([w["predicted_countable"] for w in detected], [w["count"] is not None for w in detected])
    report["countability"] = countability.compute()
    if baseline_count is not None:
        baseline = CountMetrics()
        baseline.update([baseline_count] * len(scored), [w["count"] for w in scored])
        report["baseline"] = {"count": baseline_count, **baseline.compute()}
    report["wells"] = table
    return report
