"""The four stages of an arm, each a plain function over library calls, and the picklable task that runs one.

- :func:`render_stage`: :func:`platesynth.data.render_dataset` into ``data/`` of the stage folder (resumes);
- :func:`measure_stage`: :func:`platesynth.metrics.dataset_metrics` against the reference photos, the size-matched
  entropy of both sets, and :func:`platesynth.metrics.wells.well_metrics`;
- :func:`train_stage`: :func:`platesynth.segment.train.train` into ``model/`` of the stage folder (resumes);
- :func:`evaluate_stage`: :func:`platesynth.segment.counts.evaluate_counts` against the person's counts (with the
  per-well table and crops of the worst wells) and :func:`platesynth.segment.matching.evaluate_masks` on the
  rendered test set and on real masks where given.

A :class:`StageTask` runs one of them on any executor's worker and returns a :class:`StageRecord`; a user error
(:class:`~platesynth.errors.PlatesynthError`, ``OSError``) is returned in the record, so the other arms go on.
"""

from __future__ import annotations

import contextlib
import functools
import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from platesynth.errors import PlatesynthError

DATA_DIR = "data"
MODEL_DIR = "model"
WELLS_TABLE = "wells.csv"
WORST_DIR = "worst"
WORST_WELLS = 8
"""Wells with the largest count errors kept, with crops, per evaluation."""
CROP_SIZE = 128
WELL_KEYS = ("fd_wells", "kid_wells", "nf_wells", "nf_wells_reference", "dnf_wells", "spectrum_distance_wells",
             "spectrum_distance_wells_with_plaques", "n_wells", "n_wells_reference")
"""The well-crop metrics a measurement keeps (the scalar ones)."""


@dataclass(frozen=True)
class StageTask:
    """One stage to run: its kind, key, folder and the keyword arguments of its function (plain data only)."""

    kind: str
    key: str
    directory: str
    options: dict[str, Any] = field(default_factory=dict)

    def __call__(self) -> StageRecord:
        return run_task(self)


@dataclass(frozen=True)
class StageRecord:
    """What a worker reports about a stage: its result (or error) and the seconds it took."""

    kind: str
    key: str
    result: dict[str, Any] | None
    error: str | None
    seconds: float


def run_task(task: StageTask) -> StageRecord:
    """Run a stage (module-level, so that executors can send it to their workers)."""
    function = {"render": render_stage, "measure": measure_stage, "train": train_stage,
                "evaluate": evaluate_stage}[task.kind]
    start = time.perf_counter()
    try:
        result = function(Path(task.directory), **task.options)
    except (PlatesynthError, OSError) as exc:
        from platesynth.cli._common import error_message

        return StageRecord(task.kind, task.key, None, " ".join(error_message(exc).split()), time.perf_counter() - start)
    return StageRecord(task.kind, task.key, result, None, time.perf_counter() - start)


# --- render -----------------------------------------------------------------------------------------------------


def render_stage(directory: Path, manifest: dict[str, Any]) -> dict[str, Any]:
    """Render (or finish) the dataset ``manifest`` describes into ``directory/data``.

    Raises
    ------
    RenderError
        If any image failed (the dataset would be incomplete); the next run renders the failed ones again.
    """
    from platesynth.data import Manifest, render_dataset
    from platesynth.errors import RenderError

    summary = render_dataset(directory / DATA_DIR, Manifest.model_validate(manifest))
    if summary.failed:
        name, error = next(iter(summary.failed.items()))
        raise RenderError(f"{directory / DATA_DIR}: {len(summary.failed)} image(s) failed, e.g. {name}: "
                          f"{error.splitlines()[0]}")
    return {"n_images": summary.count, "rendered": summary.rendered, "dataset": str(directory / DATA_DIR)}


# --- measure ----------------------------------------------------------------------------------------------------


def _extractor(frechet: bool) -> Any:
    if not frechet:
        return None
    from platesynth.metrics.frechet import get_feature_extractor

    return get_feature_extractor("alexnet")


@functools.lru_cache(maxsize=4)
def reference_crops(reference: str, grid: tuple[int, int], frechet: bool, fingerprint: str | None = None) -> Any:
    """The reference photos' well crops (:func:`~platesynth.metrics.wells.collect_well_crops`), once per process
    and ``fingerprint`` of the photos: fitting the plate grid takes about 0.6 s per photo, the same for every arm."""
    from platesynth.metrics.wells import collect_well_crops

    return collect_well_crops(reference, extractor=_extractor(frechet), grid=grid)


def measure_stage(directory: Path, dataset: str, reference: str, frechet: bool = True, wells: bool = True,
                  grid: tuple[int, int] = (3, 4), entropy_subset: int = 50, entropy_subsets: int = 10,
                  reference_fingerprint: str | None = None) -> dict[str, Any]:
    """Size, realism and diversity of a rendered dataset against the reference photos.

    The reference's well crops are collected once per process and ``reference_fingerprint``
    (:func:`reference_crops`).

    Returns
    -------
    dict
        The :func:`~platesynth.metrics.dataset_metrics` figures, ``entropy_matched`` and
        ``entropy_matched_reference`` (:func:`~platesynth.metrics.size_matched_entropy` over subsets of
        ``entropy_matched_subset`` images, at the dataset's image size), the scalar well-crop metrics
        (:data:`WELL_KEYS`) when ``wells``, and ``notes`` (metrics left out and why).
    """
    from platesynth.io import list_images
    from platesynth.metrics import dataset_metrics, size_matched_entropy
    from platesynth.metrics.pair import MetricSkippedWarning

    images = Path(dataset) / "images"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MetricSkippedWarning)
        result = dataset_metrics(images, reference, frechet=frechet)
        synthetic, real = list_images(images), list_images(reference)
        subset = min(entropy_subset, len(synthetic), len(real))
        size = tuple(result["size"])
        result["entropy_matched_subset"] = subset
        result["entropy_matched"] = size_matched_entropy(synthetic, subset, entropy_subsets, size=size)
        result["entropy_matched_reference"] = size_matched_entropy(real, subset, entropy_subsets, size=size)
        if wells:
            from platesynth.metrics.wells import collect_well_crops, compare_well_crops

            synthetic = collect_well_crops(dataset, extractor=_extractor(frechet), grid=grid)
            crops = compare_well_crops(synthetic, reference_crops(reference, tuple(grid), frechet,
                                                                            reference_fingerprint))
            result.update({key: crops.get(key) for key in WELL_KEYS if key in crops})
    result["notes"] = sorted({str(w.message) for w in caught if issubclass(w.category, MetricSkippedWarning)})
    return result


# --- train ------------------------------------------------------------------------------------------------------


@contextlib.contextmanager
def torch_threads(threads: int):
    """Let torch use ``threads`` threads while the block runs (spin-waiting threads on busy cores are slow)."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def train_stage(directory: Path, train: dict[str, Any], model: dict[str, Any], threads: int = 1,
                device: str = "cpu") -> dict[str, Any]:
    """Train (or finish training) one model into ``directory/model`` with the study's recipe, on ``device``."""
    from platesynth.segment.model import ModelConfig
    from platesynth.segment.train import TrainConfig
    from platesynth.segment.train import train as run_training

    with torch_threads(threads):
        summary = run_training(TrainConfig.model_validate(train), directory / MODEL_DIR, ModelConfig.model_validate(model),
                               device=device)
    best = summary.best_val_loss
    return {
        "model": str(directory / MODEL_DIR),
        "epochs": summary.epochs_done,
        "best_val_loss": best if math.isfinite(best) else None,
        "thresholds": {name: list(pair) for name, pair in summary.thresholds.items()},
        "history": summary.history,
    }


# --- evaluate ---------------------------------------------------------------------------------------------------


class RecordingPredictor:
    """``predict_image`` with the model, remembering a crop of every predicted well with its plaques outlined.

    ``crops[call][(row, col)]`` is the (``CROP_SIZE``, ``CROP_SIZE``, 3) crop of that well in the ``call``-th image.
    An image on which the prediction is refused (a poorly trained model finding more wells than a mask holds) counts
    as one where nothing was found; ``refused`` keeps the errors.
    """

    def __init__(self, model: Any, crop_size: int = CROP_SIZE) -> None:
        self.model = model
        self.crop_size = crop_size
        self.crops: list[dict[tuple[int, int], np.ndarray]] = []
        self.refused: list[str] = []

    def __call__(self, image: np.ndarray) -> Any:
        from platesynth.render.result import RenderResult
        from platesynth.segment.predict import predict_image

        try:
            result = predict_image(self.model, image)
        except PlatesynthError as exc:
            self.refused.append(str(exc))
            self.crops.append({})
            rgb = np.asarray(image)
            return RenderResult(rgb, np.zeros(rgb.shape[:2], np.uint8), np.zeros(rgb.shape[:2], np.uint16), [])
        self.crops.append({(w.row, w.col): self._crop(result, w.id) for w in result.well_info})
        return result

    def _crop(self, result: Any, well_id: int) -> np.ndarray:
        from PIL import Image
        from skimage.segmentation import find_boundaries

        ys, xs = np.nonzero(result.wells == well_id)
        cy, cx = (ys.min() + ys.max()) / 2, (xs.min() + xs.max()) / 2
        half = max(ys.max() - ys.min(), xs.max() - xs.min()) / 2 + 2
        height, width = result.wells.shape
        y0, y1 = int(max(0, cy - half)), int(min(height, cy + half + 1))
        x0, x1 = int(max(0, cx - half)), int(min(width, cx + half + 1))
        crop = result.image[y0:y1, x0:x1].copy()
        plaques = result.plaques[y0:y1, x0:x1] * (result.wells[y0:y1, x0:x1] == well_id)
        crop[find_boundaries(plaques, mode="inner")] = (255, 215, 0)
        return np.asarray(Image.fromarray(crop).resize((self.crop_size, self.crop_size), Image.Resampling.LANCZOS))


def _worst_wells(table: list[dict[str, Any]], crops: list[dict[tuple[int, int], np.ndarray]], directory: Path,
                 limit: int = WORST_WELLS) -> list[dict[str, Any]]:
    """The scored wells with the largest |predicted - count|, their crops written to ``directory/worst/``."""
    from platesynth.io import write_png

    images = list(dict.fromkeys(row["image"] for row in table))  # the order evaluate_counts predicted them in
    scored = [row for row in table if row["count"] is not None]
    scored.sort(key=lambda row: (-abs(row["predicted"] - row["count"]), row["image"], row["row"], row["col"]))
    worst = []
    for rank, row in enumerate(scored[:limit]):
        entry = {k: row[k] for k in ("image", "row", "col", "well", "count", "predicted", "detected")}
        crop = crops[images.index(row["image"])].get((row["row"], row["col"])) if row["detected"] else None
        if crop is not None:
            name = f"{WORST_DIR}/{rank:02d}.png"
            write_png(directory / name, crop)
            entry["crop"] = name
        worst.append(entry)
    return worst


def evaluate_stage(directory: Path, model: str, counts: dict[str, str] | None = None, test: str | None = None,
                   masks: str | None = None, taus: tuple[float, ...] = (0.5,), plate: int = 12,
                   threads: int = 1) -> dict[str, Any]:
    """Evaluate a trained model: counts per well against a person's, AP and IoU_R on the test set and real masks.

    Parameters
    ----------
    counts : ``{"images": folder, "counts": csv}`` or None.
    test : a rendered dataset (the study's test set) or None.
    masks : real photos with masks (platesynth layout) or None.

    Returns
    -------
    dict
        ``counts`` (the :func:`~platesynth.segment.counts.evaluate_counts` figures without the per-well table,
        which goes to ``wells.csv``; ``worst``: the worst wells with their crops), ``test`` and ``real_masks``
        (the :func:`~platesynth.segment.matching.evaluate_masks` figures), each None where not asked for, and
        ``notes`` where images counted as nothing found (:class:`RecordingPredictor`).
    """
    from platesynth.segment.counts import evaluate_counts, write_count_table
    from platesynth.segment.matching import evaluate_masks
    from platesynth.segment.model import load_model

    result: dict[str, Any] = {"counts": None, "test": None, "real_masks": None}
    with torch_threads(threads):
        network = load_model(model)
        predictor = RecordingPredictor(network)
        if counts is not None:
            baseline = network.config.training.get("mean_plaques_per_well")
            report = evaluate_counts(predictor, counts["images"], counts["counts"], plate_format=plate,
                                     baseline_count=baseline if baseline is not None and math.isfinite(baseline) else None)
            table = report.pop("wells")
            columns = list(table[0]) if table else []
            write_count_table(directory / WELLS_TABLE, [[row[c] if row[c] is not None else "" for c in columns]
                                                        for row in table], columns)
            report["worst"] = _worst_wells(table, predictor.crops, directory)
            report["table"] = WELLS_TABLE
            result["counts"] = report
        predictor.crops.clear()
        if test is not None:
            result["test"] = evaluate_masks(predictor, test, taus)
            predictor.crops.clear()
        if masks is not None:
            result["real_masks"] = evaluate_masks(predictor, masks, taus)
    if predictor.refused:
        result["notes"] = [f"{len(predictor.refused)} image(s) counted as nothing found, their prediction refused: "
                           f"{predictor.refused[0]}"]
    return result
