"""Training: datasets mixed by fraction, augmented patches, validation, checkpoints, resuming, threshold tuning.

A model directory being trained holds, besides the model itself (``weights.pt``: the weights with the lowest
validation loss so far, ``config.json``), ``train.json`` (the :class:`TrainConfig` and the network configuration
asked for), ``checkpoint.pt`` (the state at the end of the last finished epoch) and ``history.json`` (losses per
epoch). Running the same training again resumes from the checkpoint; every random draw is keyed by the seed, the
epoch and the sample's position, so a resumed run ends with the same weights as an uninterrupted one.

While a training runs, ``config.json`` says ``"complete": false`` and :func:`~platesynth.segment.model.load_model`
refuses the directory (predict, evaluate and demo say where the training stopped and how to resume it); the
training's very last write is ``config.json`` with the tuned thresholds and ``"complete": true``. The checkpoint holds
tensors and plain data only and is read with ``weights_only=True``
(:func:`~platesynth.segment.model.load_tensors`): a file holding other pickled objects is refused, never unpickled.
"""

from __future__ import annotations

import itertools
import json
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from platesynth import __version__
from platesynth.data.layout import DatasetItem, list_items, load_item, read_manifest
from platesynth.errors import DatasetError, ParameterError, PlatesynthError
from platesynth.io import atomic_path, image_size, write_json
from platesynth.limits import check_training
from platesynth.render.result import plaque_counts
from platesynth.segment.countability import rendered_countable
from platesynth.segment.countability import tune_on_items as tune_countability
from platesynth.segment.data import Augmentation, MixSampler, SegmentationDataset, working_scale
from platesynth.segment.loss import segmentation_loss
from platesynth.segment.matching import match_instances
from platesynth.segment.model import (
    BRANCHES,
    CONFIG_NAME,
    HISTORY_NAME,
    TRAIN_CONFIG_NAME,
    WEIGHTS_NAME,
    ModelConfig,
    StarDistTwoBranch,
    load_tensors,
    save_model,
    select_device,
)
from platesynth.segment.predict import nms_polygons, polygons_to_mask, predict_maps
from platesynth.segment.resolvable import lying_on, resolvable_plaques

CHECKPOINT_NAME = "checkpoint.pt"
PROB_THRESHOLDS = (0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.7)
NMS_THRESHOLDS = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7)


class TrainConfig(BaseModel):
    """What to train on and how; saved as ``train.json`` in the model directory."""

    model_config = ConfigDict(extra="forbid")

    data: list[str] = Field(min_length=1, description="dataset directories in the platesynth layout")
    mix: list[float] | None = Field(None, description="probability of drawing a sample from each dataset (default: by size)")
    epochs: int = Field(20, ge=1)
    steps_per_epoch: int = Field(50, ge=1, description="optimiser steps per epoch")
    batch_size: int = Field(4, ge=1)
    patch: tuple[int, int] = Field((256, 256), description="training patch (height, width) in working pixels")
    learning_rate: float = Field(1e-3, gt=0, description="Adam's learning rate, decayed to 5% along a cosine")
    val_fraction: float = Field(0.1, ge=0, lt=1, description="images of each dataset held out for validation")
    max_val_images: int = Field(24, ge=1, description="at most this many held-out images are evaluated, taken from the datasets in turn")
    seed: int = Field(0, ge=0)
    augment: bool = True
    lambda_dist: float = Field(0.2, ge=0, description="weight of the distance loss (StarDist: 0.2)")
    background_reg: float = Field(1e-4, ge=0, description="pull of background distances to 0 (StarDist: 1e-4)")
    within_well_weight: float = Field(0.0, ge=0, description="weight of the penalty on plaques predicted outside wells")
    scratch_weight: float = Field(
        0.0, ge=0, description="extra weight of the plaque probability loss where a rendered item's scratches "
        "scraped the stain off: pale lesions that are not plaques (0: none)"
    )
    tune_thresholds: bool = Field(True, description="choose probability and NMS thresholds on the validation images")
    min_resolved_cells: float = Field(
        0.0, ge=0, description="threshold tuning leaves out rendered plaques narrower than this many "
        "grid cells of the plaque branch, and the predictions lying on them (0: scores every plaque)"
    )
    num_workers: int = Field(0, ge=0, description="data-loading processes (0: in the training process)")

    @field_validator("data")
    @classmethod
    def _absolute(cls, value: list[str]) -> list[str]:
        return [str(Path(v).resolve()) for v in value]

    @model_validator(mode="after")
    def _mix_matches_data(self) -> TrainConfig:
        if self.mix is not None:
            if len(self.mix) != len(self.data):
                raise ValueError(f"--mix has {len(self.mix)} fractions for {len(self.data)} datasets")
            if any(f < 0 for f in self.mix) or sum(self.mix) <= 0:
                raise ValueError("--mix fractions must be >= 0 and not all 0")
        return self


@dataclass
class TrainSummary:
    """Where a training run ended."""

    model_dir: Path
    epochs_done: int
    best_val_loss: float
    history: list[dict[str, float | None]]
    thresholds: dict[str, tuple[float, float]]
    resumed_from_epoch: int


def split_items(items: Sequence[DatasetItem], val_fraction: float, seed: int) -> tuple[list[DatasetItem], list[DatasetItem]]:
    """Seeded split of one dataset into training and validation items (at least one of each where possible)."""
    n_val = 0 if val_fraction == 0 or len(items) < 2 else min(len(items) - 1, max(1, round(val_fraction * len(items))))
    order = np.random.default_rng(seed).permutation(len(items))
    val = set(order[:n_val].tolist())
    return [it for i, it in enumerate(items) if i not in val], [it for i, it in enumerate(items) if i in val]


def split_sources(
    datasets: Sequence[Sequence[DatasetItem]], val_fraction: float, seed: int
) -> list[tuple[list[DatasetItem], list[DatasetItem]]]:
    """Every dataset split by :func:`split_items`, the ``k``-th one with the seed ``seed + k``."""
    return [split_items(items, val_fraction, seed + number) for number, items in enumerate(datasets)]


def validation_items(val_sets: Sequence[Sequence[DatasetItem]], limit: int) -> list[DatasetItem]:
    """At most ``limit`` held-out items, taken from each dataset's in turn, so that every source is validated on
    (and the thresholds tuned on it) however small ``limit`` is."""
    interleaved = [item for group in itertools.zip_longest(*val_sets) for item in group if item is not None]
    return interleaved[:limit]


def tuning_items(
    model: StarDistTwoBranch, model_dir: str | os.PathLike, data: Sequence[str | os.PathLike] = ()
) -> list[DatasetItem]:
    """The held-out items a finished model's thresholds were tuned on, split and taken in turn as its training did.

    Parameters
    ----------
    model : the trained network (:func:`~platesynth.segment.model.load_model` of ``model_dir``).
    model_dir : its folder: ``train.json`` there, or for a model without one (such as the shipped one) the recipe and
        sources its ``config.json`` records.
    data : the training's datasets in the same order, where they are no longer where it read them (rendered again
        elsewhere: ``scripts/train_model.sh`` renders the same images); default the recorded folders.
    """
    saved = Path(model_dir) / TRAIN_CONFIG_NAME
    if saved.is_file():
        recipe = json.loads(saved.read_text())["train"]
    else:
        training = model.config.training or {}
        if "recipe" not in training:
            raise DatasetError(f"{model_dir}: neither {TRAIN_CONFIG_NAME} nor a training recipe in its config")
        recipe = {**training["recipe"], "data": [s["dir"] for s in training["sources"]], "mix": training["mix"]}
    config = TrainConfig(**{**recipe, **({"data": [str(d) for d in data]} if data else {})})
    splits = split_sources([list_items(directory) for directory in config.data], config.val_fraction, config.seed)
    return validation_items([held_out for _, held_out in splits], config.max_val_images)


def mask_statistics(items: Sequence[DatasetItem], long_side: int) -> tuple[float, float | None]:
    """What prediction needs to know of the training images, read from every item's masks in one pass.

    Returns
    -------
    mean_plaques : mean number of plaques per well (the trivial baseline of a count predictor; NaN without wells).
    well_diameter : median equivalent diameter of the wells once their image is resized so that its longest side
        is ``long_side`` (``ModelConfig.well_diameter``; None without wells).
    """
    counts: list[int] = []
    diameters: list[np.ndarray] = []
    for item in items:
        image, wells, plaques = load_item(item)
        counts += plaque_counts(wells, plaques).values()
        areas = np.bincount(wells.ravel())[1:]
        diameters.append(2 * np.sqrt(areas[areas > 0] / np.pi) * working_scale(image.shape, long_side))
    diameters_all = np.concatenate(diameters) if diameters else np.zeros(0)
    return (
        float(np.mean(counts)) if counts else math.nan,
        float(np.median(diameters_all)) if len(diameters_all) else None,
    )


def _describe_data(config: TrainConfig, train_sets: list[list[DatasetItem]], val_sets: list[list[DatasetItem]]) -> dict[str, Any]:
    sources = []
    for directory, train_items, val_items in zip(config.data, train_sets, val_sets):
        manifest = read_manifest(directory)
        entry: dict[str, Any] = {"dir": directory, "n_train": len(train_items), "n_val": len(val_items)}
        if manifest is not None:
            entry.update(preset=manifest.preset, seed=manifest.seed, size=list(manifest.size), backend=manifest.backend)
        sources.append(entry)
    return {"sources": sources, "mix": _fractions(config, train_sets)}


def _fractions(config: TrainConfig, train_sets: list[list[DatasetItem]]) -> list[float]:
    weights = config.mix if config.mix is not None else [float(len(s)) for s in train_sets]
    total = float(sum(weights))
    return [w / total for w in weights]


def _identity(config: TrainConfig, model_config: ModelConfig) -> dict[str, Any]:
    """What a training directory is: the training settings and the network asked for (saved as ``train.json``)."""
    return {
        "train": config.model_dump(mode="json"),
        "model": model_config.model_dump(mode="json", exclude={"training", "version", "complete"}),
    }


def _check_model_dir(model_dir: Path, identity: dict[str, Any], overwrite: bool) -> bool:
    """Whether to resume; refuses a directory holding a different training unless ``overwrite``."""
    saved_path = model_dir / TRAIN_CONFIG_NAME
    if not saved_path.is_file():
        if model_dir.is_dir() and any(model_dir.iterdir()) and not overwrite:
            raise DatasetError(f"{model_dir}: not empty and not a training directory (use --overwrite to train there anyway)")
        return False
    try:
        saved = json.loads(saved_path.read_text())
    except (OSError, ValueError) as exc:
        if not overwrite:
            raise DatasetError(f"{saved_path}: unreadable ({exc.__class__.__name__}); use --overwrite to replace it") from None
        saved = None
    if isinstance(saved, dict) and isinstance(saved.get("train"), dict):  # settings added since, at their defaults
        later = {name: field.default for name, field in TrainConfig.model_fields.items() if name not in saved["train"]}
        saved["train"] = {**later, **saved["train"]}
    if saved == identity and (model_dir / CHECKPOINT_NAME).is_file():
        return True
    if saved is not None and saved != identity and not overwrite:
        changed = [
            f"{part} {key}"
            for part in ("train", "model")
            for key in identity[part]
            if not isinstance(saved.get(part), dict) or saved[part].get(key) != identity[part][key]
        ]
        raise DatasetError(
            f"{model_dir}: holds a different training (differs in {', '.join(changed) or 'format'}); "
            "use --overwrite to replace it"
        )
    for name in (CHECKPOINT_NAME, HISTORY_NAME, TRAIN_CONFIG_NAME):
        (model_dir / name).unlink(missing_ok=True)
    return False


_CHECKPOINT_KEYS = {"model": dict, "optimizer": dict, "scheduler": dict, "history": list, "best_val": float, "epoch": int}


def _read_checkpoint(path: Path, device: torch.device) -> dict[str, Any]:
    """The state saved at the end of the last finished epoch: tensors and plain data only (``weights_only=True``).

    Raises
    ------
    DatasetError
        If the file holds other objects, cannot be read, or lacks a part of the state.
    """
    state = load_tensors(path, device)
    if not isinstance(state, dict) or any(not isinstance(state.get(k), t) for k, t in _CHECKPOINT_KEYS.items()):
        raise DatasetError(f"{path}: not a platesynth training checkpoint; delete it (or use --overwrite) to start again")
    return state


def _resume_from(state: dict[str, Any], path: Path, model: StarDistTwoBranch, optimizer: Any, scheduler: Any) -> None:
    try:
        model.load_state_dict(state["model"])
        optimizer.load_state_dict(state["optimizer"])
        scheduler.load_state_dict(state["scheduler"])
    except (RuntimeError, KeyError, ValueError, TypeError, IndexError, AttributeError) as exc:
        first = (str(exc).strip().splitlines() or [exc.__class__.__name__])[0]
        raise DatasetError(f"{path}: does not fit this training ({first}); delete it (or use --overwrite) to start again") from None


def _largest_image(datasets: Sequence[Sequence[DatasetItem]]) -> int:
    """Pixels of the largest first image of the datasets (from the headers; 0 where unreadable: reported later)."""
    pixels = 0
    for items in datasets:
        try:
            width, height = image_size(items[0].image_path)
        except (PlatesynthError, IndexError, OSError, ValueError):
            continue
        pixels = max(pixels, width * height)
    return pixels


def _collate(samples: list[dict[str, torch.Tensor]]) -> dict[str, torch.Tensor]:
    return {key: torch.stack([s[key] for s in samples]) for key in samples[0]}


def _loss_terms(config: TrainConfig) -> dict[str, float]:
    return {
        "lambda_dist": config.lambda_dist,
        "background_reg": config.background_reg,
        "within_well_weight": config.within_well_weight,
    }


def validation_loss(model: StarDistTwoBranch, dataset: SegmentationDataset, config: TrainConfig, device: torch.device) -> float:
    """Mean loss over whole validation images (NaN without any)."""
    if len(dataset) == 0:
        return math.nan
    model.eval()
    total = 0.0
    with torch.no_grad():
        for index in range(len(dataset)):
            batch = {k: v[None].to(device) for k, v in dataset[index].items()}
            _, parts = segmentation_loss(model(batch["image"]), batch, **_loss_terms(config))
            total += parts["total"]
    model.train()
    return total / len(dataset)


@dataclass
class ThresholdScores:
    """What the validation items say of every candidate (probability, NMS) threshold pair, indexed ``[i, j]`` by
    ``prob_thresholds[i]`` and ``nms_thresholds[j]``."""

    prob_thresholds: tuple[float, ...]
    nms_thresholds: tuple[float, ...]
    mean_ap: dict[str, np.ndarray]
    """Per branch, the mean AP over the items at the matching IoU ``tau``."""
    count_errors: np.ndarray
    """``(P, N, wells)``: predicted minus true plaques of every countable well of the items."""
    true_counts: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """``(wells,)``: the true plaques of those wells, in the same order."""


def threshold_scores(
    model: StarDistTwoBranch,
    items: Sequence[DatasetItem],
    prob_thresholds: Sequence[float] = PROB_THRESHOLDS,
    nms_thresholds: Sequence[float] = NMS_THRESHOLDS,
    tau: float = 0.5,
    min_resolved_cells: float = 0.0,
) -> ThresholdScores:
    """Score every candidate threshold pair on rendered items (:class:`ThresholdScores`).

    With ``min_resolved_cells`` > 0, the plaques narrower than that many grid cells of the plaque branch at the
    working size (:func:`~platesynth.segment.resolvable.resolvable_plaques`) are "don't care": left out of the true
    plaques and counts, and so is every predicted plaque lying mostly on one of them. 0 scores every plaque.

    NMS runs once per NMS threshold, at the lowest probability threshold, and its polygons are drawn once: a
    polygon is only ever suppressed by a more probable one and drawn under it, so the mask at a higher probability
    threshold is that mask with the less probable polygons erased. That is what NMS at the higher threshold gives,
    up to how stardist's NMS orders equal scores and searches for neighbours among the candidates it is given (in
    ``benchmarks/bench_tuning.py``, one plaque in one well of 16 images, at two of the 54 pairs).
    """
    prob_thresholds, nms_thresholds = tuple(prob_thresholds), tuple(nms_thresholds)
    shape = (len(prob_thresholds), len(nms_thresholds))
    mean_ap = {name: np.zeros(shape) for name in BRANCHES}
    errors: list[list[list[int]]] = [[[] for _ in nms_thresholds] for _ in prob_thresholds]
    truths: list[int] = []
    grid = model.config.branches["plaques"].grid
    for item in items:
        image, wells, plaques = load_item(item)
        rendered = rendered_countable(item)
        counted = [int(i) for i in np.unique(wells) if i != 0 and rendered.get(int(i), True)]
        maps, working_shape = predict_maps(model, image)
        scale = working_scale(plaques.shape, model.config.input_long_side)  # as predict_maps resizes the image
        resolved, unresolved = resolvable_plaques(plaques, scale, grid, min_resolved_cells)
        true_counts = plaque_counts(wells, resolved, counted)
        truths += [true_counts[w] for w in counted]
        for name, truth in (("wells", wells), ("plaques", resolved)):
            for j, nms in enumerate(nms_thresholds):
                kept = nms_polygons(maps[name], min(prob_thresholds), nms)
                drawn = polygons_to_mask(kept, working_shape, truth.shape)
                ids = np.arange(1, len(kept.scores) + 1)
                if name == "plaques" and unresolved.size:
                    ids[lying_on(drawn, plaques, unresolved, len(ids))[1:]] = 0
                for i, prob in enumerate(prob_thresholds):
                    erase = np.concatenate([[0], np.where(kept.scores > prob, ids, 0)])
                    predicted = erase[drawn]
                    mean_ap[name][i, j] += match_instances(truth, predicted, tau).ap / len(items)
                    if name == "plaques":
                        found = plaque_counts(wells, predicted, counted)
                        errors[i][j] += [found[w] - true_counts[w] for w in counted]
    return ThresholdScores(prob_thresholds, nms_thresholds, mean_ap, np.array(errors, dtype=float).reshape(*shape, -1),
                           np.array(truths, dtype=float))


def choose_thresholds(scores: ThresholdScores) -> dict[str, tuple[float, float]]:
    """Per branch, the (probability, NMS) threshold pair to keep.

    Wells: the pair with the highest mean AP. Plaques: the probability threshold of the best-AP pair, then, at that
    probability, the NMS threshold for the plaques per countable well: the smallest one whose mean absolute count
    error is within one standard error of the smallest error (:func:`one_standard_error_choice`: among thresholds
    the validation images cannot tell apart, the one that suppresses most). The probability threshold decides which
    candidates are plaques at all, which AP measures; the NMS threshold decides how far neighbouring plaques may
    overlap and still count as two, which a count needs and AP hardly sees in crowded wells. Ties go to the first
    candidate in the order of the lists.
    """
    best = {}
    for name, table in scores.mean_ap.items():
        i, j = np.unravel_index(np.argmax(table), table.shape)
        if name == "plaques":
            j = one_standard_error_choice(np.abs(scores.count_errors[i]), j)
        best[name] = (float(scores.prob_thresholds[i]), float(scores.nms_thresholds[j]))
    return best


def one_standard_error_choice(errors: Sequence[Sequence[float]] | np.ndarray, default: int) -> int:
    """Index of the first candidate whose mean error is within one standard error of the smallest mean error.

    ``errors[k]`` are candidate ``k``'s errors over the same cases; ``default`` is returned where there are none.
    """
    if not len(errors) or not len(errors[0]):
        return int(default)
    means = np.array([np.mean(e) for e in errors])
    lowest = int(np.argmin(means))
    spread = np.std(errors[lowest], ddof=1) / np.sqrt(len(errors[lowest])) if len(errors[lowest]) > 1 else 0.0
    return int(np.flatnonzero(means <= means[lowest] + spread)[0])


def validation_at(scores: ThresholdScores, prob: float, nms: float) -> dict[str, float | int | None]:
    """How the plaques of the validation images' countable wells fare at one threshold pair (kept with the model)."""
    i, j = scores.prob_thresholds.index(prob), scores.nms_thresholds.index(nms)
    errors = scores.count_errors[i, j]
    return {
        "count_mae": float(np.mean(np.abs(errors))) if errors.size else None,
        "count_bias": float(np.mean(errors)) if errors.size else None,
        "countable_wells": int(errors.size),
    }


def tune_thresholds(
    model: StarDistTwoBranch,
    items: Sequence[DatasetItem],
    prob_thresholds: Sequence[float] = PROB_THRESHOLDS,
    nms_thresholds: Sequence[float] = NMS_THRESHOLDS,
    tau: float = 0.5,
) -> dict[str, tuple[float, float]]:
    """Per branch, the (probability, NMS) threshold pair tuned on rendered items: :func:`choose_thresholds` of
    :func:`threshold_scores`. Without items the model's thresholds stay."""
    if not items:
        return model.config.thresholds
    return choose_thresholds(threshold_scores(model, items, prob_thresholds, nms_thresholds, tau))


def train(
    config: TrainConfig,
    model_dir: str | os.PathLike,
    model_config: ModelConfig | None = None,
    overwrite: bool = False,
    device: str = "auto",
    progress: Callable[[dict[str, Any]], None] | None = None,
    before_writing: Callable[[], None] | None = None,
) -> TrainSummary:
    """Train a two-branch StarDist model, or resume the same training, into ``model_dir``.

    Parameters
    ----------
    config : data, schedule, augmentation and loss settings.
    model_dir : output directory (see the module docstring).
    model_config : architecture and input convention; default :class:`ModelConfig` defaults. Its thresholds are
        replaced by tuned ones when ``config.tune_thresholds``; its ``training`` field is filled in.
    overwrite : replace a different training found in ``model_dir``.
    device : ``"auto"`` (CUDA where available), ``"cpu"``, ``"cuda"``...
    progress : called after every step with ``{"epoch", "step", "steps", "loss"}``, and after every epoch with
        ``{"epoch", "train_loss", "val_loss"}`` (``val_loss`` None without validation images).
    before_writing : called once everything is validated, right before the first write into ``model_dir`` (the
        command line claims the folder there, see :func:`platesynth.outputs.claim_output`).

    Raises
    ------
    DatasetError, EmptyDatasetError
        If a dataset is missing or inconsistent, or ``model_dir`` holds a different training.
    ParameterError
        If the patch size does not suit the architecture, or the device is not available.
    """
    model_dir = Path(model_dir)
    model_config = (model_config or ModelConfig()).model_copy(deep=True)
    multiple = model_config.size_multiple
    if min(config.patch) < 1 or config.patch[0] % multiple or config.patch[1] % multiple:
        raise ParameterError(f"patch {config.patch[0]}x{config.patch[1]} must be a positive multiple of {multiple} on both sides")
    torch_device = select_device(device)  # validated before anything is written
    datasets = [list_items(directory) for directory in config.data]
    check_training(model_config, config.patch, config.batch_size, _largest_image(datasets), config.num_workers)
    splits = split_sources(datasets, config.val_fraction, config.seed)
    train_sets, val_sets = [s[0] for s in splits], [s[1] for s in splits]
    train_items = [item for items in train_sets for item in items]
    sources = [number for number, items in enumerate(train_sets) for _ in items]
    val_items = validation_items(val_sets, config.max_val_images)
    # reads every item once before anything is written: a broken dataset leaves no model directory behind
    baseline, model_config.well_diameter = mask_statistics(train_items, model_config.input_long_side)
    for item in val_items:
        load_item(item)
    identity = _identity(config, model_config)
    resume = _check_model_dir(model_dir, identity, overwrite)
    checkpoint = _read_checkpoint(model_dir / CHECKPOINT_NAME, torch_device) if resume else None
    if before_writing is not None:
        before_writing()
    model_dir.mkdir(parents=True, exist_ok=True)
    if not resume:  # a model left by an earlier training must not pass for this one while it runs
        for name in (CONFIG_NAME, WEIGHTS_NAME):
            (model_dir / name).unlink(missing_ok=True)
    write_json(model_dir / TRAIN_CONFIG_NAME, identity)
    model_config.complete = False  # every config.json written before the end says so

    torch.manual_seed(config.seed)
    model = StarDistTwoBranch(model_config).to(torch_device)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.learning_rate)
    total_steps = config.epochs * config.steps_per_epoch
    scheduler = torch.optim.lr_scheduler.LambdaLR(
        optimizer, lambda step: 0.05 + 0.95 * 0.5 * (1 + math.cos(math.pi * min(step, total_steps) / total_steps))
    )
    history: list[dict[str, float | None]] = []
    best_val, start_epoch = math.inf, 0
    if checkpoint is not None:
        _resume_from(checkpoint, model_dir / CHECKPOINT_NAME, model, optimizer, scheduler)
        history, best_val, start_epoch = checkpoint["history"], checkpoint["best_val"], checkpoint["epoch"]

    augmentation = Augmentation() if config.augment else None
    train_data = SegmentationDataset(
        train_items, model_config, config.patch, augmentation, seed=config.seed, scratch_weight=config.scratch_weight
    )
    val_data = SegmentationDataset(val_items, model_config, scratch_weight=config.scratch_weight)
    fractions = _fractions(config, train_sets)
    model.train()
    for epoch in range(start_epoch, config.epochs):
        sampler = MixSampler(sources, fractions, config.steps_per_epoch * config.batch_size, config.seed, epoch)
        loader = torch.utils.data.DataLoader(
            train_data, batch_size=config.batch_size, sampler=sampler, collate_fn=_collate, num_workers=config.num_workers
        )
        losses = []
        for step, batch in enumerate(loader, start=1):
            batch = {k: v.to(torch_device) for k, v in batch.items()}
            loss, parts = segmentation_loss(model(batch["image"]), batch, **_loss_terms(config))
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            scheduler.step()
            losses.append(parts["total"])
            if progress is not None:
                progress({"epoch": epoch + 1, "step": step, "steps": config.steps_per_epoch, "loss": parts["total"]})
        val_loss = validation_loss(model, val_data, config, torch_device)
        history.append(
            {"epoch": epoch + 1, "train_loss": float(np.mean(losses)), "val_loss": None if math.isnan(val_loss) else val_loss}
        )
        if math.isnan(val_loss) or val_loss < best_val:
            best_val = val_loss if not math.isnan(val_loss) else best_val
            save_model(model, model_dir)
        with atomic_path(model_dir / CHECKPOINT_NAME) as tmp:
            torch.save(
                {
                    "model": model.state_dict(),
                    "optimizer": optimizer.state_dict(),
                    "scheduler": scheduler.state_dict(),
                    "history": history,
                    "best_val": best_val,
                    "epoch": epoch + 1,
                },
                tmp,
            )
        write_json(model_dir / HISTORY_NAME, history)
        if progress is not None:
            progress(dict(history[-1]))

    best = StarDistTwoBranch(model_config)
    best.load_state_dict(load_tensors(model_dir / WEIGHTS_NAME))
    best = best.to(torch_device)
    thresholds = model_config.thresholds
    at_thresholds = None
    if config.tune_thresholds and val_items:
        scores = threshold_scores(best, val_items, min_resolved_cells=config.min_resolved_cells)
        thresholds = choose_thresholds(scores)
        at_thresholds = validation_at(scores, *thresholds["plaques"])
    best.config.set_thresholds(thresholds)
    if config.tune_thresholds:
        best.config.countable_min_stained = tune_countability(val_items)
    best.config.training = {
        **_describe_data(config, train_sets, val_sets),
        "recipe": config.model_dump(mode="json", exclude={"data", "mix"}),
        "epochs_done": len(history),
        "best_val_loss": best_val if math.isfinite(best_val) else None,
        "mean_plaques_per_well": baseline,
        "thresholds_tuned_on": len(val_items) if config.tune_thresholds else 0,
        "validation_at_thresholds": at_thresholds,
    }
    best.config.version = __version__
    best.config.complete = True
    write_json(model_dir / CONFIG_NAME, best.config.model_dump(mode="json"))  # the last write: the model is complete
    return TrainSummary(model_dir, len(history), best_val, history, thresholds, start_epoch)


def read_history(model_dir: str | os.PathLike) -> list[dict[str, float]]:
    """The per-epoch losses of a training directory (empty if none)."""
    path = Path(model_dir) / HISTORY_NAME
    return json.loads(path.read_text()) if path.is_file() else []
