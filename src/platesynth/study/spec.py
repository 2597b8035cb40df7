"""The study file: arms, the real reference and evaluation sets, the training recipe, the image size.

A study file is YAML (read without anchors or aliases, :func:`platesynth.limits.read_yaml_file`); relative paths in
it are relative to the file's folder. :func:`load_study` validates all of it, and builds every arm's dataset
request, before anything is written; every problem is one line naming the file and the field::

    studies/x.yaml: arms[1].mix: unknown arm 'hgih-L' (the arms are high-S, high-L)
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, field_validator, model_validator

from platesynth.errors import ParameterError, PlatesynthError
from platesynth.limits import read_yaml_file

REAL = "real"
"""The name a mix gives to the study's real training data (``real_training``)."""
NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]{0,63}$")
SIZE_PATTERN = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")


def _size(value: Any) -> tuple[int, int]:
    """``"512x384"`` or ``[512, 384]`` -> ``(512, 384)`` (width, height)."""
    if isinstance(value, str):
        match = SIZE_PATTERN.match(value)
        if match:
            value = (int(match[1]), int(match[2]))
    if isinstance(value, (list, tuple)) and len(value) == 2 and all(isinstance(v, int) and v > 0 for v in value):
        return int(value[0]), int(value[1])
    raise ValueError(f"expected WIDTHxHEIGHT in pixels, e.g. 512x384, got {value!r}")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Arm(_Strict):
    """One arm: a rendered dataset (``preset`` and/or ``config``, ``overrides``, ``count``) or a ``mix`` of arms and
    the real training data by fraction; ``seeds`` gives its replicates (a table shows mean ± sd over them)."""

    name: str = Field(description="short name, used in tables and file names")
    label: str | None = Field(None, description="name shown in tables and charts (default: name)")
    preset: str | None = Field(None, description="a shipped preset")
    config: str | None = Field(None, description="a YAML scene configuration (over the preset)")
    overrides: dict[str, Any] = Field(default_factory=dict, description="dotted parameter -> value, as --set")
    count: int | None = Field(None, ge=1, description="images rendered")
    seeds: list[int] = Field(default_factory=lambda: [0], min_length=1,
                             description="one replicate per seed: its dataset seed and its training seed")
    mix: dict[str, float] | None = Field(None, description="arm name (or 'real') -> fraction of training samples")

    @field_validator("name")
    @classmethod
    def _name(cls, value: str) -> str:
        if not NAME_PATTERN.match(value) or value == REAL:
            raise ValueError(f"{value!r}: a name of letters, digits and _.+- (at most 64, not '{REAL}')")
        return value

    @field_validator("seeds")
    @classmethod
    def _seeds(cls, value: list[int]) -> list[int]:
        if any(s < 0 for s in value) or len(set(value)) != len(value):
            raise ValueError(f"seeds must be distinct and >= 0, got {value}")
        return value

    @model_validator(mode="after")
    def _kind(self) -> Arm:
        if self.mix is not None:
            if self.preset or self.config or self.overrides or self.count:
                raise ValueError("a mix arm takes only mix, seeds and label (its data are the other arms')")
            if len(self.mix) < 2 or any(f < 0 for f in self.mix.values()) or sum(self.mix.values()) <= 0:
                raise ValueError("mix needs at least two sources with fractions >= 0, not all 0")
        else:
            if self.count is None:
                raise ValueError("count is required (images to render), or give a mix")
            if self.preset is None and self.config is None:
                raise ValueError("give a preset or a config (or a mix)")
        return self

    @property
    def title(self) -> str:
        """The name shown in tables and charts."""
        return self.label or self.name


class TestSet(_Strict):
    """The rendered test set: AP and IoU_R of every arm's model on it (the same images for every arm)."""

    preset: str = "high"
    config: str | None = None
    overrides: dict[str, Any] = Field(default_factory=dict)
    count: int = Field(20, ge=1)
    seed: int = Field(999, ge=0)


class Evaluation(_Strict):
    """Where each arm's model is evaluated."""

    images: str | None = Field(None, description="folder of real photos named in counts")
    counts: str | None = Field(None, description="a person's counts: image,row,col,well,count")
    masks: str | None = Field(None, description="real photos with masks (platesynth layout): AP/IoU_R on real data")
    test: TestSet | None = Field(default_factory=TestSet, description="rendered test set (null: none)")
    taus: list[float] = Field(default_factory=lambda: [0.5], min_length=1)

    @model_validator(mode="after")
    def _pairs(self) -> Evaluation:
        if (self.images is None) != (self.counts is None):
            raise ValueError("images and counts go together (the photos and the person's counts of them)")
        if any(not 0 < t <= 1 for t in self.taus):
            raise ValueError(f"taus must lie in (0, 1], got {self.taus}")
        return self


class Recipe(_Strict):
    """The one training recipe every arm's model is trained with (see ``platesynth train``)."""

    epochs: int = Field(10, ge=1)
    steps: int = Field(50, ge=1, description="optimiser steps per epoch")
    batch_size: int = Field(4, ge=1)
    patch: tuple[int, int] = Field((256, 256), description="training patch WIDTHxHEIGHT in working pixels")
    learning_rate: float = Field(2e-3, gt=0)
    val_fraction: float = Field(0.05, ge=0, lt=1)
    max_val: int = Field(16, ge=1)
    seed: int = Field(0, ge=0, description="added to each replicate's seed")
    augment: bool = True
    tune_thresholds: bool = True
    threads: int = Field(1, ge=1, description="torch threads of one training")
    device: str = Field("cpu", description="where models train: cpu, cuda, or auto (CUDA where available)")
    model: dict[str, Any] = Field(default_factory=dict, description="ModelConfig fields (architecture, working size)")

    @field_validator("patch", mode="before")
    @classmethod
    def _patch(cls, value: Any) -> tuple[int, int]:
        width, height = _size(value)
        return height, width  # stored as TrainConfig's (height, width)


class Metrics(_Strict):
    """What each arm's dataset is measured with against the reference photos."""

    frechet: bool = Field(True, description="Fréchet/kernel distances of AlexNet (and Inception) features")
    wells: bool = Field(True, description="the well-crop metrics (fd_wells, dnf_wells, ...)")
    entropy_subset: int = Field(50, ge=2, description="images per subset of the size-matched entropy (at most the "
                                                        "smallest set's size is used)")
    entropy_subsets: int = Field(10, ge=1)


class StudySpec(_Strict):
    """A whole study file (see docs/study.md)."""

    name: str = "study"
    description: str = ""
    reference: str = Field(description="folder of real photos: the realism reference")
    evaluation: Evaluation = Field(default_factory=Evaluation)
    real_training: str | None = Field(None, description="real photos with masks (platesynth layout) for mix arms")
    size: tuple[int, int] = Field((512, 384), description="image size WIDTHxHEIGHT of every rendered set")
    plate: int = Field(12, description="plate format of every rendered set")
    backend: str = "raster"
    recipe: Recipe = Field(default_factory=Recipe)
    metrics: Metrics = Field(default_factory=Metrics)
    arms: list[Arm] = Field(min_length=1)
    _source: str = PrivateAttr("study")

    @property
    def source(self) -> str:
        """Where the study came from (its file), for messages."""
        return self._source

    @field_validator("size", mode="before")
    @classmethod
    def _size(cls, value: Any) -> tuple[int, int]:
        return _size(value)

    @model_validator(mode="after")
    def _arms(self) -> StudySpec:
        names = [arm.name for arm in self.arms]
        seen: set[str] = set()
        for number, arm in enumerate(self.arms):
            if arm.name in seen:
                raise ValueError(f"arms[{number}].name: {arm.name!r} appears twice")
            seen.add(arm.name)
        rendered = {arm.name for arm in self.arms if arm.mix is None}
        for number, arm in enumerate(self.arms):
            for source in arm.mix or {}:
                if source == REAL:
                    if self.real_training is None:
                        raise ValueError(
                            f"arms[{number}].mix: 'real' needs real_training (a folder of real photos with masks "
                            "in the platesynth layout); none is given"
                        )
                elif source not in rendered:
                    known = ", ".join(n for n in names if n in rendered)
                    raise ValueError(f"arms[{number}].mix: unknown arm {source!r} (the rendered arms are {known})")
        return self

    def arm(self, name: str) -> Arm:
        """The arm called ``name``."""
        return next(arm for arm in self.arms if arm.name == name)


def _location(loc: tuple[Any, ...]) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        elif not str(part).startswith(("function-", "value_error")):
            text += f".{part}" if text else str(part)
    return text


def validation_line(exc: ValidationError, source: str) -> str:
    """The first error of a pydantic validation as one line: ``source: field: message``."""
    error = exc.errors()[0]
    message = str(error.get("msg", "invalid")).removeprefix("Value error, ")
    if error.get("type") == "extra_forbidden":
        message = "unknown field"
    elif error.get("type") == "missing":
        message = "required field missing"
    where = _location(tuple(error.get("loc", ())))
    return f"{source}: {where}: {message}" if where else f"{source}: {message}"


def _resolve(base: Path, value: str | None) -> str | None:
    if value is None:
        return None
    path = Path(os.path.expanduser(value))
    return str(path if path.is_absolute() else (base / path).resolve())


def _resolved(spec: StudySpec, base: Path) -> StudySpec:
    """The spec with every path made absolute (relative to ``base``, the study file's folder)."""
    evaluation = spec.evaluation
    test = evaluation.test
    return spec.model_copy(update={
        "reference": _resolve(base, spec.reference),
        "real_training": _resolve(base, spec.real_training),
        "evaluation": evaluation.model_copy(update={
            "images": _resolve(base, evaluation.images),
            "counts": _resolve(base, evaluation.counts),
            "masks": _resolve(base, evaluation.masks),
            "test": test.model_copy(update={"config": _resolve(base, test.config)}) if test is not None else None,
        }),
        "arms": [arm.model_copy(update={"config": _resolve(base, arm.config)}) for arm in spec.arms],
    })


def parse_study(data: Any, source: str = "study", base: str | os.PathLike = ".") -> StudySpec:
    """Validate study data (a mapping, e.g. read from YAML); relative paths are taken from ``base``.

    Raises
    ------
    ParameterError
        One line naming ``source`` and the field at fault.
    """
    if not isinstance(data, dict):
        raise ParameterError(f"{source}: expected a mapping (name, reference, evaluation, recipe, arms...), "
                             f"got {type(data).__name__}")
    try:
        spec = StudySpec.model_validate(data)
    except ValidationError as exc:
        raise ParameterError(validation_line(exc, source)) from None
    spec = _resolved(spec, Path(base).resolve())
    spec._source = source
    return spec


def load_study(path: str | os.PathLike) -> StudySpec:
    """Read and validate a study file (paths in it relative to its folder); checks its inputs exist too.

    Raises
    ------
    ParameterError
        For a file that cannot be read, bad YAML, an unknown or invalid field, or a missing input (one line).
    """
    path = Path(path)
    data = read_yaml_file(path, ParameterError)
    spec = parse_study(data, str(path), path.parent)
    check_inputs(spec, str(path))
    return spec


def check_inputs(spec: StudySpec, source: str) -> None:
    """Refuse, in one line, a reference or evaluation input that is missing or empty."""
    from platesynth.data.layout import list_items
    from platesynth.io import list_images

    def check(name: str, value: str | None, reader: Any) -> None:
        if value is None:
            return
        try:
            reader(value)
        except PlatesynthError as exc:
            raise ParameterError(f"{source}: {name}: {exc}") from None

    check("reference", spec.reference, list_images)
    check("evaluation.images", spec.evaluation.images, list_images)
    check("evaluation.masks", spec.evaluation.masks, list_items)
    check("real_training", spec.real_training, list_items)
    counts = spec.evaluation.counts
    if counts is not None:
        check_counts(Path(counts), Path(spec.evaluation.images or "."), spec.plate, source)


def check_counts(counts: Path, images: Path, plate: int, source: str) -> None:
    """Refuse, in one line, a counts table that is missing, empty, all blank, names a well outside the plate or an
    image missing from ``images``: found now rather than after every training."""
    from platesynth.data.layout import read_counts_csv
    from platesynth.segment.counts import plate_shape

    if not counts.is_file():
        raise ParameterError(f"{source}: evaluation.counts: {counts}: no such file")
    try:
        records = read_counts_csv(counts)
    except PlatesynthError as exc:
        raise ParameterError(f"{source}: evaluation.counts: {exc}") from None
    if not records or all(r.count is None for r in records):
        raise ParameterError(f"{source}: evaluation.counts: {counts}: no counted well (nothing to score)")
    rows, cols = plate_shape(plate)
    for line, record in enumerate(records, start=2):
        if record.row >= rows or record.col >= cols:
            raise ParameterError(f"{source}: evaluation.counts: {counts}, line {line}: row {record.row}, col "
                                 f"{record.col} lies outside a {plate}-well plate")
        if not (images / record.image).is_file():
            raise ParameterError(f"{source}: evaluation.counts: {counts}, line {line}: {record.image} not found in "
                                 f"{images}")
