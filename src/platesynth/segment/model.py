"""The two-branch StarDist network: one shared U-Net encoder, one decoder per object class (wells, plaques).

Each branch predicts, on its own grid, an object probability (as a logit) and ``n_rays`` radial distances in pixels of
the network input. A model directory holds ``weights.pt`` (a torch state_dict) and ``config.json`` (:class:`ModelConfig`).

A model directory says whether the training that wrote it finished: ``config.json``'s ``complete`` is false while
``platesynth train`` runs and true once it has written everything (the last write of a training). :func:`load_model`
refuses an unfinished training with a message saying where it stopped and how to resume it. Files are loaded with
``torch.load(..., weights_only=True)`` only (:func:`load_tensors`): tensors and plain data, never other pickled objects.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator
from torch import nn

from platesynth import __version__
from platesynth.errors import DatasetError, ParameterError
from platesynth.io import atomic_path, write_json
from platesynth.limits import RefusedFileError, load_torch_file

BRANCHES = ("wells", "plaques")
CONFIG_NAME = "config.json"
WEIGHTS_NAME = "weights.pt"
TRAIN_CONFIG_NAME = "train.json"
"""A training's settings, in a model directory that ``platesynth train`` writes (see :mod:`platesynth.segment.train`)."""
HISTORY_NAME = "history.json"
"""A training's losses per finished epoch."""


WELL_SIZE_TOLERANCE = 0.1
"""Relative difference between a photo's median well diameter and the model's ``well_diameter`` above which
prediction runs again at the training images' scale (the training augmentation covers scales 0.8 to 1.25)."""
WELL_RESCALE_RANGE = (0.5, 2.0)
"""Smallest and largest factor on the working size that bringing wells to the training size may apply."""


class UnfinishedModelError(DatasetError):
    """A model directory holds a training that has not finished (interrupted, or still running)."""


class BranchConfig(BaseModel):
    """One output branch: its grid, distance scale and post-processing thresholds."""

    model_config = ConfigDict(extra="forbid")

    grid: int = Field(1, description="output subsampling step (a power of two below 2**levels)")
    dist_scale: float = Field(8.0, gt=0, description="pixels per unit of raw distance output (eases learning large radii)")
    prob_thresh: float = Field(0.5, gt=0, lt=1, description="minimum object probability of a polygon candidate")
    nms_thresh: float = Field(0.4, ge=0, le=1, description="overlap above which the less probable polygon is suppressed")


class ModelConfig(BaseModel):
    """Everything needed to rebuild a model and use it: architecture, input convention, thresholds, provenance."""

    model_config = ConfigDict(extra="forbid")

    n_rays: int = Field(32, ge=3, description="radial distances per pixel")
    channels: tuple[int, ...] = Field((16, 24, 32, 64), description="encoder channels per level (level i has stride 2**i)")
    context_dilations: tuple[int, ...] = Field((2, 4), description="dilated 3x3 convolutions at the deepest level")
    branches: dict[str, BranchConfig] = Field(
        default_factory=lambda: {
            "wells": BranchConfig(grid=4, dist_scale=32.0, prob_thresh=0.5, nms_thresh=0.3),
            "plaques": BranchConfig(grid=2, dist_scale=8.0, prob_thresh=0.5, nms_thresh=0.4),
        }
    )
    input_long_side: int = Field(512, ge=64, description="images are resized so that their longest side is this")
    well_diameter: float | None = Field(
        None, gt=0, description="median equivalent diameter of the training images' wells at the working size, in "
        "pixels; prediction brings a photo whose wells differ from it by more than WELL_SIZE_TOLERANCE to this size "
        "(platesynth.segment.predict; None: no rescaling, as for models trained before this field)")
    percentile_low: float = Field(1.0, ge=0, lt=100, description="intensity mapped to 0 (percentile over all channels)")
    percentile_high: float = Field(99.8, gt=0, le=100, description="intensity mapped to 1")
    plate_format: int = Field(12, description="wells per plate the model was trained for (grid shape for counting)")
    countable_min_stained: float = Field(
        0.0, ge=0.0, le=1.0, description="a well is countable where at least this share of it is still stained "
        "(platesynth.segment.countability; tuned on synthetic validation images; 0: every well)")
    training: dict[str, Any] = Field(default_factory=dict, description="description of the training data and recipe")
    complete: bool | None = Field(
        None, description="whether the training that wrote the model finished (false while it runs; see "
        "is_complete for models written before this field)")
    version: str = Field(__version__, description="platesynth version that wrote the model")

    @field_validator("branches")
    @classmethod
    def _known_branches(cls, value: dict[str, BranchConfig]) -> dict[str, BranchConfig]:
        if set(value) != set(BRANCHES):
            raise ValueError(f"branches must be exactly {list(BRANCHES)}, got {sorted(value)}")
        return value

    @model_validator(mode="after")
    def _grids_fit_levels(self) -> ModelConfig:
        if len(self.channels) < 2:
            raise ValueError("channels needs at least two levels")
        for name, branch in self.branches.items():
            level = math.log2(branch.grid)
            if branch.grid < 1 or level != int(level) or level >= len(self.channels):
                raise ValueError(f"{name} grid {branch.grid} must be a power of two below {2 ** len(self.channels)}")
        if self.percentile_low >= self.percentile_high:
            raise ValueError("percentile_low must be below percentile_high")
        return self

    @property
    def size_multiple(self) -> int:
        """Input height and width must be multiples of this (the deepest stride)."""
        return 2 ** (len(self.channels) - 1)

    @property
    def thresholds(self) -> dict[str, tuple[float, float]]:
        """Per branch, the stored (probability, NMS) threshold pair."""
        return {name: (branch.prob_thresh, branch.nms_thresh) for name, branch in self.branches.items()}

    def set_thresholds(self, thresholds: dict[str, tuple[float, float]]) -> None:
        """Store a (probability, NMS) threshold pair per named branch (those not named keep theirs)."""
        for name, (prob, nms) in thresholds.items():
            self.branches[name].prob_thresh, self.branches[name].nms_thresh = prob, nms


def _conv_block(in_channels: int, out_channels: int, dilations: tuple[int, ...] = (1, 1)) -> nn.Sequential:
    layers: list[nn.Module] = []
    for dilation in dilations:
        layers += [
            nn.Conv2d(in_channels, out_channels, 3, padding=dilation, dilation=dilation, bias=False),
            nn.BatchNorm2d(out_channels),
            nn.ReLU(inplace=True),
        ]
        in_channels = out_channels
    return nn.Sequential(*layers)


class _Decoder(nn.Module):
    """Upsampling path from the deepest level down to the level of the branch's grid, then the two heads.

    Each level has a single convolution after the skip concatenation: the decoders are most of the network's cost.
    """

    def __init__(self, channels: tuple[int, ...], level: int, n_rays: int, dist_scale: float):
        super().__init__()
        self.blocks = nn.ModuleList(
            _conv_block(channels[i + 1] + channels[i], channels[i], (1,)) for i in range(len(channels) - 2, level - 1, -1)
        )
        width = channels[level]
        self.features = nn.Sequential(nn.Conv2d(width, width, 3, padding=1), nn.ReLU(inplace=True))
        self.prob = nn.Conv2d(width, 1, 1)
        self.dist = nn.Conv2d(width, n_rays, 1)
        self.dist_scale = dist_scale

    def forward(self, skips: list[torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
        x = skips[-1]
        for block, skip in zip(self.blocks, reversed(skips[:-1])):
            x = F.interpolate(x, size=skip.shape[-2:], mode="bilinear", align_corners=False)
            x = block(torch.cat([x, skip], dim=1))
        x = self.features(x)
        return self.prob(x), self.dist(x) * self.dist_scale


class StarDistTwoBranch(nn.Module):
    """Shared U-Net encoder with a wells and a plaques StarDist decoder.

    ``forward(images)`` takes ``(B, 3, H, W)`` float images (H and W multiples of ``config.size_multiple``) and returns
    ``{branch: (prob_logits (B, 1, H/g, W/g), distances (B, n_rays, H/g, W/g))}`` with ``g`` the branch's grid.
    """

    def __init__(self, config: ModelConfig):
        super().__init__()
        self.config = config
        channels = config.channels
        self.encoder = nn.ModuleList(
            _conv_block(3 if i == 0 else channels[i - 1], c) for i, c in enumerate(channels)
        )
        dilations = config.context_dilations
        self.context = _conv_block(channels[-1], channels[-1], dilations) if dilations else nn.Identity()
        self.decoders = nn.ModuleDict(
            {
                name: _Decoder(channels, int(math.log2(branch.grid)), config.n_rays, branch.dist_scale)
                for name, branch in config.branches.items()
            }
        )

    def forward(self, images: torch.Tensor) -> dict[str, tuple[torch.Tensor, torch.Tensor]]:
        multiple = self.config.size_multiple
        if images.shape[-2] % multiple or images.shape[-1] % multiple:
            raise ValueError(f"input height and width must be multiples of {multiple}, got {tuple(images.shape[-2:])}")
        skips = []
        x = images
        for i, block in enumerate(self.encoder):
            if i:
                x = F.max_pool2d(x, 2)
            x = block(x)
            skips.append(x)
        skips[-1] = self.context(skips[-1])
        return {name: decoder(skips) for name, decoder in self.decoders.items()}


def is_complete(config: ModelConfig, model_dir: str | Path) -> bool:
    """Whether the model in ``model_dir`` (with its ``config``) is complete: ``config.complete`` where it is set;
    for models written before that field, unless a training directory's ``config.json`` lacks the ``training``
    description that the end of a training writes."""
    if config.complete is not None:
        return config.complete
    return bool(config.training) or not (Path(model_dir) / TRAIN_CONFIG_NAME).is_file()


def save_model(model: StarDistTwoBranch, model_dir: str | Path) -> None:
    """Write ``weights.pt`` and ``config.json`` into ``model_dir`` (atomically, weights first).

    ``config.json`` is the model's configuration as it is: a training saves its best weights so far with
    ``complete`` false, and writes ``complete`` true last.
    """
    model_dir = Path(model_dir)
    model_dir.mkdir(parents=True, exist_ok=True)
    with atomic_path(model_dir / WEIGHTS_NAME) as tmp:
        torch.save({k: v.detach().cpu() for k, v in model.state_dict().items()}, tmp)
    write_json(model_dir / CONFIG_NAME, model.config.model_dump(mode="json"))


def read_model_config(model_dir: str | Path) -> ModelConfig:
    """The :class:`ModelConfig` stored in ``model_dir/config.json``.

    Raises
    ------
    DatasetError
        If the file is missing or not a valid model configuration.
    """
    path = Path(model_dir) / CONFIG_NAME
    if not path.is_file():
        if (Path(model_dir) / TRAIN_CONFIG_NAME).is_file():
            raise UnfinishedModelError(unfinished_message(model_dir))
        raise DatasetError(f"{path}: no such file (is {model_dir} a model directory written by 'platesynth train'?)")
    try:
        return ModelConfig.model_validate(json.loads(path.read_bytes().decode("utf-8")))
    except UnicodeDecodeError as exc:
        raise DatasetError(f"{path}: not a valid model configuration (not UTF-8: byte at position {exc.start})") from None
    except (json.JSONDecodeError, ValidationError) as exc:
        first = str(exc).splitlines()[0] if isinstance(exc, json.JSONDecodeError) else exc.errors()[0]["msg"]
        raise DatasetError(f"{path}: not a valid model configuration ({first})") from None


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_bytes().decode("utf-8"))
    except (OSError, ValueError):
        return None


def unfinished_message(model_dir: str | Path) -> str:
    """Where the training in ``model_dir`` stopped (from ``train.json`` and ``history.json``) and how to resume it."""
    model_dir = Path(model_dir)
    settings = _read_json(model_dir / TRAIN_CONFIG_NAME)
    history = _read_json(model_dir / HISTORY_NAME)
    epochs = settings.get("train", {}).get("epochs") if isinstance(settings, dict) else None
    done = len(history) if isinstance(history, list) else 0
    if isinstance(epochs, int) and done >= epochs:
        where = f"stopped after epoch {epochs} of {epochs}, while tuning its thresholds"
    elif isinstance(epochs, int):
        where = f"stopped during epoch {done + 1} of {epochs}"
    else:
        where = "stopped before it finished"
    return (
        f"{model_dir} is an unfinished training ({where}); resume it by running the same "
        f"`platesynth train --out {model_dir} ...` command again, with the options it was started with "
        f"(they are in {model_dir / TRAIN_CONFIG_NAME})"
    )


def load_tensors(path: str | Path, device: str | torch.device = "cpu") -> Any:
    """``torch.load(path, weights_only=True)``: tensors and plain data (dicts, lists, numbers, strings) only.

    A file holding any other pickled object (which unpickling would run) is refused, not loaded.

    Raises
    ------
    DatasetError
        If the file is missing, unreadable, not a torch file, or holds anything but tensors and plain data.
    """
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: no such file")
    try:
        return load_torch_file(path, device)
    except RefusedFileError as exc:
        raise DatasetError(str(exc)) from None
    except Exception as exc:  # torch raises many types (zip, runtime, EOF, unicode) for a broken file
        first = (str(exc).strip().splitlines() or [exc.__class__.__name__])[0]
        raise DatasetError(f"{path}: not a readable torch file ({exc.__class__.__name__}: {first})") from None


def load_model(model_dir: str | Path, device: str | torch.device = "cpu", allow_unfinished: bool = False) -> StarDistTwoBranch:
    """Rebuild the network stored in ``model_dir`` in evaluation mode on ``device``.

    Parameters
    ----------
    model_dir : a model directory written by ``platesynth train``.
    device : where to put the network.
    allow_unfinished : load the best weights so far of a training that has not finished (to inspect it).

    Raises
    ------
    UnfinishedModelError
        If the training that writes ``model_dir`` has not finished (unless ``allow_unfinished``).
    DatasetError
        If ``config.json`` or ``weights.pt`` is missing, invalid, holds more than tensors, or the weights do not
        fit the configuration.
    """
    config = read_model_config(model_dir)
    if not allow_unfinished and not is_complete(config, model_dir):
        raise UnfinishedModelError(unfinished_message(model_dir))
    path = Path(model_dir) / WEIGHTS_NAME
    if not path.is_file():
        raise DatasetError(f"{path}: no such file (model weights missing)")
    model = StarDistTwoBranch(config)
    state = load_tensors(path)
    try:
        model.load_state_dict(state)
    except (RuntimeError, OSError, EOFError, KeyError, TypeError, AttributeError, ValueError) as exc:
        first = (str(exc).strip().splitlines() or [exc.__class__.__name__])[0]
        raise DatasetError(f"{path}: weights do not load into the configured network ({first})") from None
    return model.to(device).eval()


def select_device(device: str = "auto") -> torch.device:
    """``"auto"`` picks CUDA where available, else the CPU; other values are passed to :class:`torch.device`.

    Raises
    ------
    ParameterError
        For an unknown device name, or CUDA where none is available.
    """
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        chosen = torch.device(device)
    except RuntimeError:
        raise ParameterError(f"unknown device {device!r} (use auto, cpu or cuda)") from None
    if chosen.type == "cuda" and not torch.cuda.is_available():
        raise ParameterError(f"device {device!r} asked for, but CUDA is not available here (use auto or cpu)")
    return chosen
