"""Option types and parsers that several commands share (``render``, ``preview``, ``demo``, ``scene ...``)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Any

import typer
import yaml

from platesynth.errors import ParameterError
from platesynth.limits import load_yaml

_SIZE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")

Out = Annotated[Path, typer.Option("--out", "-o", help="Output directory of the dataset.")]
Seed = Annotated[int, typer.Option("--seed", help="Dataset seed: image i gets a seed derived from (seed, i).")]


def preset_name(value: str | None) -> str | None:
    """``--preset``'s check (:func:`platesynth.scene.loading.check_preset_name`); ``None`` passes."""
    from platesynth.scene.loading import check_preset_name

    return None if value is None else check_preset_name(value)


Preset = Annotated[
    str | None,
    typer.Option("--preset", callback=preset_name, help="Scene preset (see `platesynth scene presets`)."),
]
Plate = Annotated[
    int | None, typer.Option("--plate", help="Plate format: 6, 12, 24 or 96 wells (overrides the preset).")
]
ConfigFile = Annotated[
    Path | None, typer.Option("--config", help="YAML scene configuration (applied over the preset).")
]
Overrides = Annotated[
    list[str] | None,
    typer.Option("--set", help="Override one parameter, e.g. --set plaques.radius_mm=[0.5,1.0]; repeatable."),
]


def _executors_help() -> str:
    from platesynth.data.executor import EXECUTORS

    return f"Where the work runs: {' or '.join(EXECUTORS)}."


ExecutorKind = Annotated[str, typer.Option("--executor", help=_executors_help())]
Scheduler = Annotated[
    str | None, typer.Option("--scheduler", help="Address of a running Dask scheduler (implies --executor dask).")
]
ConnectTimeout = Annotated[float, typer.Option("--connect-timeout", help="Seconds to wait for the Dask scheduler.")]


def open_executor(executor: str, workers: int, scheduler: str | None, connect_timeout: float) -> Any:
    """The executor that ``--executor``, ``--workers``, ``--scheduler`` and ``--connect-timeout`` ask for (a
    scheduler's address implies Dask)."""
    from platesynth.data.executor import make_executor

    kind = "dask" if scheduler is not None else executor
    return make_executor(kind, workers=workers, scheduler=scheduler, timeout=connect_timeout)


Backend = Annotated[str, typer.Option("--backend", help="Renderer: raster (fast, numpy) or blender.")]
Samples = Annotated[
    int | None,
    typer.Option(
        "--samples", help="Blender: samples per pixel of the image (default: $PLATESYNTH_BLENDER_SAMPLES, else 3)."
    ),
]
Engine = Annotated[
    str | None,
    typer.Option(
        "--engine", help="Blender: CYCLES or BLENDER_EEVEE (default: $PLATESYNTH_BLENDER_ENGINE, else CYCLES)."
    ),
]
BlenderDevice = Annotated[
    str | None,
    typer.Option(
        "--device",
        help="Blender: auto (a GPU where there is one), CPU or GPU (default: $PLATESYNTH_BLENDER_DEVICE, else auto).",
    ),
]


def parse_size(text: str) -> tuple[int, int]:
    """``"1024x768"`` -> ``(1024, 768)`` (width, height).

    Raises
    ------
    ParameterError
        If the text is not ``WIDTHxHEIGHT`` with positive integers.
    """
    match = _SIZE.match(text)
    if not match or min(int(match[1]), int(match[2])) <= 0:
        raise ParameterError(f"size {text!r}: expected WIDTHxHEIGHT in pixels, e.g. 1024x768")
    return int(match[1]), int(match[2])


def parse_overrides(items: list[str] | None, plate: int | None = None) -> dict[str, Any]:
    """``["plaques.radius_mm=[0.5, 1]"]`` -> ``{"plaques.radius_mm": [0.5, 1]}`` (values read as YAML).

    ``plate``, if given, becomes ``plate.format``.
    """
    overrides: dict[str, Any] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ParameterError(f"--set {item!r}: expected NAME=VALUE, e.g. plate.format=24")
        try:
            overrides[name.strip()] = load_yaml(value, f"--set {item!r}")  # no aliases (platesynth.limits)
        except yaml.YAMLError:
            raise ParameterError(f"--set {item!r}: the value is not valid YAML") from None
    if plate is not None:
        overrides["plate.format"] = plate
    return overrides
