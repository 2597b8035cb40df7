"""The shapes of what the commands print with ``--json`` and what the MCP tools return: pydantic models, one place.

The command line (``platesynth ... --json``) and the MCP server (``platesynth mcp``, :mod:`platesynth.agent`) both
pass their results through these models, so the JSON a person reads and the output schema an agent is given are
the same. Results that come from the library as dicts (metrics, evaluation reports) are read by
:func:`from_result`, which turns non-finite floats into ``None`` (JSON has no infinity) and numpy scalars into
Python numbers.

The metric and report models list every key the library returns today, each optional where the library leaves it
out (a metric not asked for, weights not available); their ``extra="allow"`` keeps a key added later in the output
instead of failing, and ``tests/test_agent_mcp.py`` fails on such a key until it is listed here.
"""

from __future__ import annotations

import math
from typing import Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field

M = TypeVar("M", bound=BaseModel)

Number = float | int
"""A catalogue value: numbers, categories (strings) and switches (booleans)."""


def jsonable(value: Any) -> Any:
    """``value`` with numpy scalars as Python numbers, tuples as lists and non-finite floats as ``None``."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if hasattr(value, "item") and callable(value.item) and not isinstance(value, (list, dict, str)):
        return jsonable(value.item())
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    return value


def from_result(model: type[M], result: Any) -> M:
    """Validate a library result (dict or object) as ``model`` after :func:`jsonable`."""
    return model.model_validate(jsonable(result))


def dump(model: BaseModel) -> dict[str, Any]:
    """The JSON form of ``model``: the keys set (a metric left out stays out), in the model's order."""
    return model.model_dump(mode="json", exclude_unset=True)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class _Open(BaseModel):
    """A library report: known keys listed, later ones kept (see the module docstring)."""

    model_config = ConfigDict(extra="allow")


# --------------------------------------------------------------------------------------------------------- scene


class ParameterInfo(_Strict):
    """One scene parameter of the catalogue (``platesynth scene catalogue``)."""

    name: str = Field(description="dotted name, e.g. plaques.radius_mm; YAML: section: {parameter: value}")
    type: str = Field(description="kind of value: number, integer, probability or category")
    unit: str = Field(description="unit ('' for none)")
    range: list[Any] = Field(description="[low, high] for numbers, else the allowed choices or options")
    default: Any = Field(description="default value, in the form a configuration file takes")
    description: str


class Catalogue(_Strict):
    """Every scene parameter."""

    parameters: list[ParameterInfo]


class PresetInfo(_Strict):
    """A shipped preset (``platesynth scene presets``)."""

    name: str
    description: str = Field(description="the first comment line of the preset's YAML")
    path: str | None = Field(None, description="the preset's YAML file in the installed package")


class Presets(_Strict):
    """The shipped presets."""

    presets: list[PresetInfo]


def catalogue() -> Catalogue:
    """The parameter catalogue as a :class:`Catalogue` (from :func:`platesynth.scene.parameter_table`)."""
    from platesynth.scene import parameter_table

    return Catalogue(parameters=[ParameterInfo.model_validate(row) for row in parameter_table()])


def presets() -> Presets:
    """The shipped presets with their first comment line."""
    from platesynth.scene.loading import PRESET_DIR, list_presets

    rows = []
    for name in list_presets():
        first = (PRESET_DIR / f"{name}.yaml").read_text(encoding="utf-8").splitlines()[0].lstrip("# ").strip()
        rows.append(PresetInfo(name=name, description=first, path=str(PRESET_DIR / f"{name}.yaml")))
    return Presets(presets=rows)


# -------------------------------------------------------------------------------------------------------- render


class RenderSummary(_Strict):
    """What a render did (``platesynth render --json``; the result of a render job)."""

    directory: str = Field(description="the dataset folder written")
    count: int = Field(description="images the dataset holds")
    rendered: int = Field(description="images rendered by this run")
    skipped: int = Field(description="images already there (a resumed run)")
    failed: dict[str, str] = Field(description="item name -> error, for images that failed to render")
    seconds: float


# ------------------------------------------------------------------------------------------------------ optimise


class OptimiseSummary(_Open):
    """What an optimisation found (the result of an optimise job; its folder's ``report.json`` and more)."""

    out: str = Field(description="the optimisation's folder (study, trials, report.md, best.yaml, plots)")
    best_config: str | None = Field(description="the best configuration's YAML file, for `config` of the other tools")
    notes: list[str] = Field(description="what was left out (plots with too few trials, metrics without weights)")
    start: str = Field(description="the start configuration")
    best_trial: int
    best_params: dict[str, Any] = Field(description="the best trial's parameter values")
    n_trials: int
    n_complete: int
    n_failed: int
    pareto_trials: list[int] = Field(default_factory=list)
    objectives: list[str] | None = None
    weights: dict[str, float]
    split: dict[str, list[str]] = Field(description="the reference photos of the fit and check parts")
    evaluation: dict[str, Any] = Field(
        description="per part of the photos (fit, check), per configuration (start, best, compared): the terms"
    )
    importances: dict[str, float] = Field(default_factory=dict)
    eval_count: int
    seconds: float


def optimise_summary(result: Any, out: str, best_config: str | None) -> OptimiseSummary:
    """An :class:`~platesynth.optimise.OptimiseResult` as an :class:`OptimiseSummary` (paths as given)."""
    return from_result(OptimiseSummary, {**result.report, "out": out, "best_config": best_config,
                                         "notes": list(result.notes)})


# ------------------------------------------------------------------------------------------------------- metrics


class PairMetrics(_Open):
    """Pair metrics of a synthetic image against a real one (``platesynth metrics pair --json``)."""

    mse: float
    nrmse: float
    ssim: float
    psnr: float | None = Field(description="dB; null for identical images (infinite)")
    nf_real: float = Field(description="naturalness factor of the real image")
    nf_synthetic: float
    dnf: float = Field(description="|nf_real - nf_synthetic|")
    lpips: float | None = None
    fd_patches_alexnet: float | None = None
    fid_patches_inception: float | None = None


class DatasetMetrics(_Open):
    """Diversity and realism of a folder of images, optionally against a reference folder and per well crop
    (``platesynth metrics dataset --json``)."""

    n_images: int
    size: list[int] = Field(description="[height, width] the entropy and brightness variability were computed at")
    entropy: float | None = Field(None, description="per-pixel entropy, bits (at most log2 n_images)")
    brightness_variability: float | None = None
    nf_mean: float | None = None
    n_images_reference: int | None = None
    entropy_reference: float | None = None
    brightness_variability_reference: float | None = None
    nf_mean_reference: float | None = None
    dnf: float | None = None
    fd_alexnet: float | None = None
    kid_alexnet: float | None = None
    kid_alexnet_std: float | None = None
    fid_inception: float | None = None
    kid_inception: float | None = None
    kid_inception_std: float | None = None
    # the well-crop metrics (--wells)
    n_wells: int | None = None
    n_wells_reference: int | None = None
    wells_from: str | None = None
    wells_from_reference: str | None = None
    fd_wells: float | None = None
    kid_wells: float | None = None
    kid_wells_std: float | None = None
    nn_accuracy_wells: float | None = None
    nf_wells: float | None = None
    nf_wells_reference: float | None = None
    dnf_wells: float | None = None
    spectrum_distance_wells: float | None = None
    spectrum_distance_wells_with_plaques: float | None = None
    n_plaques: int | None = None
    n_plaques_reference: int | None = None
    plaque_area_fraction_median: float | None = None
    plaque_area_fraction_median_reference: float | None = None
    plaque_area_fraction_mean: float | None = None
    plaque_area_fraction_mean_reference: float | None = None
    plaque_area_mm2_median: float | None = None
    plaque_area_mm2_median_reference: float | None = None
    plaque_contrast_median: float | None = None
    plaque_contrast_median_reference: float | None = None
    plaque_contrast_mean: float | None = None
    plaque_contrast_mean_reference: float | None = None
    plaque_area_distance: float | None = None
    plaque_contrast_distance: float | None = None
    spectrum_frequencies: list[float] | None = None
    spectrum_wells: list[float | None] | None = None
    spectrum_wells_reference: list[float | None] | None = None
    spectrum_wells_with_plaques: list[float | None] | None = None
    spectrum_wells_with_plaques_reference: list[float | None] | None = None


# -------------------------------------------------------------------------------------------------- segmentation


class Thresholds(_Strict):
    """Probability and NMS thresholds of one branch."""

    prob: float
    nms: float


class TrainResult(_Strict):
    """Where a training ended (``platesynth train --json``; the result of a train job)."""

    model_dir: str
    epochs: int = Field(description="epochs done")
    resumed_from_epoch: int = Field(description="0 for a fresh training")
    best_val_loss: float | None = Field(description="null without validation images")
    thresholds: dict[str, Thresholds] = Field(description="per branch (wells, plaques)")


def train_result(summary: Any) -> TrainResult:
    """A :class:`~platesynth.segment.train.TrainSummary` as a :class:`TrainResult`."""
    return from_result(
        TrainResult,
        {
            "model_dir": str(summary.model_dir),
            "epochs": summary.epochs_done,
            "resumed_from_epoch": summary.resumed_from_epoch,
            "best_val_loss": summary.best_val_loss,
            "thresholds": {name: {"prob": p, "nms": n} for name, (p, n) in summary.thresholds.items()},
        },
    )


class InstanceSummary(_Open):
    """Instance-mask metrics of one class at one IoU threshold, over images."""

    ap_mean: float | None
    ap_std: float | None
    iou_r_mean: float | None
    iou_r_std: float | None
    n_images: int
    n_images_iou_r: int
    tp: int
    fp: int
    fn: int
    n_true: int
    n_pred: int


class MaskReport(_Open):
    """Instance masks against the truth (``platesynth evaluate masks --json``)."""

    n_images: int
    wells: dict[str, InstanceSummary] = Field(description="per IoU threshold tau (e.g. '0.5')")
    plaques: dict[str, InstanceSummary]


class CountabilityReport(_Open):
    """How well the model finds the wells a person left uncounted."""

    accuracy: float | None
    precision: float | None
    recall: float | None
    f1: float | None
    n_wells: int
    n_uncountable: int


class BaselineReport(_Open):
    """The training set's mean plaques per well, as a prediction."""

    count: float
    mae: float | None
    rmse: float | None
    pearson_r: float | None
    bias: float | None
    n_wells: int


class WellCount(_Open):
    """One well of a counts table with the model's count."""

    image: str
    row: int
    col: int
    well: str
    count: int | None = Field(description="the person's count; null for a well left uncounted")
    predicted: int
    detected: bool
    predicted_countable: bool


class CountReport(_Open):
    """Plaques per well against a person's counts (``platesynth evaluate counts --json``)."""

    mae: float | None
    rmse: float | None
    pearson_r: float | None
    bias: float | None
    n_wells: int
    n_images: int
    n_wells_not_detected: int
    countability: CountabilityReport
    baseline: BaselineReport | None = None
    wells: list[WellCount]
