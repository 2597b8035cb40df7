"""Segmentation: a two-branch StarDist model (wells, plaques), its training, prediction and evaluation.

Modules, one concern each: :mod:`~platesynth.segment.targets` (star distances, object probability),
:mod:`~platesynth.segment.model` (network, :class:`ModelConfig`, model directories), :mod:`~platesynth.segment.loss`,
:mod:`~platesynth.segment.data` (normalisation, augmentation, torch Dataset), :mod:`~platesynth.segment.train`,
:mod:`~platesynth.segment.predict` (polygon NMS, masks), :mod:`~platesynth.segment.matching` (AP, IoU_R) and
:mod:`~platesynth.segment.counts` (wells by grid position, counts evaluation).

Training is ``platesynth.segment.train.train(TrainConfig(...), model_dir)``; it is not re-exported here, where its
name would hide the module.
"""

from platesynth.segment.counts import CountMetrics, evaluate_counts, grid_positions, sort_wells
from platesynth.segment.matching import InstanceMetrics, MatchResult, evaluate_masks, iou_matrix, match_instances
from platesynth.segment.model import ModelConfig, StarDistTwoBranch, load_model, save_model
from platesynth.segment.predict import nms_polygons, predict_files, predict_image
from platesynth.segment.targets import branch_targets, object_probability, star_distances
from platesynth.segment.train import TrainConfig, tune_thresholds

__all__ = [
    "CountMetrics",
    "InstanceMetrics",
    "MatchResult",
    "ModelConfig",
    "StarDistTwoBranch",
    "TrainConfig",
    "branch_targets",
    "evaluate_counts",
    "evaluate_masks",
    "grid_positions",
    "iou_matrix",
    "load_model",
    "match_instances",
    "nms_polygons",
    "object_probability",
    "predict_files",
    "predict_image",
    "save_model",
    "sort_wells",
    "star_distances",
    "tune_thresholds",
]
