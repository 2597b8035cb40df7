"""The Blender backend: the same concrete scenes drawn by Blender 5.0 (``bpy``) with Cycles, in worker processes.

Host side (this package's top level, no ``bpy`` needed): :func:`render_blender`, :func:`export_blend`, the worker
pool (:mod:`.pool`) and the scene description (:mod:`.describe`). Blender side (:mod:`.inside`, imported only in
the worker process ``python -m platesynth.render.blender.worker``): building the bpy scene and rendering it.

Examples
--------
>>> from platesynth.scene import load_config, sample_scene             # doctest: +SKIP
>>> scene = sample_scene(load_config("high"), seed=1)                  # doctest: +SKIP
>>> result = render_blender(scene, (1024, 768), samples=8)            # doctest: +SKIP
>>> result.plaque_counts()                                            # doctest: +SKIP
"""

from __future__ import annotations

import functools
import importlib.metadata
import importlib.util
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from platesynth.errors import ImageReadError, ParameterError, RenderError
from platesynth.io import read_image, read_mask
from platesynth.render.blender.describe import describe_scene
from platesynth.render.blender.pool import (
    BlenderScriptError,
    BlenderWorkerError,
    BlenderWorkerPool,
    blender_home,
    close_default_pool,
    default_pool,
    setting_from_env,
)
from platesynth.render.masks import renumber
from platesynth.render.result import RenderResult, WellInfo, check_size
from platesynth.scene.concrete import Scene

ENGINES = ("CYCLES", "BLENDER_EEVEE")
DEVICES = ("auto", "CPU", "GPU")
DEFAULT_SAMPLES = 3
SAMPLES_VARIABLE, ENGINE_VARIABLE, DEVICE_VARIABLE = (
    "PLATESYNTH_BLENDER_SAMPLES",
    "PLATESYNTH_BLENDER_ENGINE",
    "PLATESYNTH_BLENDER_DEVICE",
)
"""The environment variables that give the image pass's samples, engine and device where the caller does not."""


def bpy_available() -> bool:
    """Whether the ``bpy`` module (Blender as a Python module) is installed, without importing it."""
    return importlib.util.find_spec("bpy") is not None


@functools.lru_cache(maxsize=1)
def blender_version() -> str | None:
    """The installed ``bpy``'s version (e.g. ``"5.0.1"``) from its package metadata, without importing it; ``None``
    where it is not installed."""
    try:
        return importlib.metadata.version("bpy")
    except importlib.metadata.PackageNotFoundError:
        return None


def blender_settings(
    samples: int | None = None, engine: str | None = None, device: str | None = None, denoise: bool = False
) -> dict[str, Any]:
    """Everything besides the scene and the size that decides a Blender image, checked, defaults filled in.

    ``samples``, ``engine`` and ``device`` default to :data:`SAMPLES_VARIABLE`, :data:`ENGINE_VARIABLE` and
    :data:`DEVICE_VARIABLE`, then to :data:`DEFAULT_SAMPLES`, ``"CYCLES"`` and ``"auto"``; engine and device names
    are case-insensitive.

    Returns
    -------
    dict
        ``{"version": bpy's version, "engine": ..., "samples": ..., "device": ..., "denoise": ...}``, as a dataset
        records it.

    Raises
    ------
    ParameterError
        For a bad sample count, engine or device.
    RenderError
        Where bpy is not installed.
    """
    if samples is None:
        samples = int(setting_from_env(SAMPLES_VARIABLE, DEFAULT_SAMPLES))
    engine = str(engine or os.environ.get(ENGINE_VARIABLE) or "CYCLES").upper()
    device = str(device or os.environ.get(DEVICE_VARIABLE) or "auto")
    device = {d.lower(): d for d in DEVICES}.get(device.lower(), device)
    _check_settings(samples, engine, device)
    version = blender_version()
    return {"version": version, "engine": engine, "samples": int(samples), "device": device, "denoise": bool(denoise)}


def _check(size: tuple[int, int], samples: int, engine: str, device: str) -> tuple[int, int]:
    width, height = check_size(size)
    _check_settings(samples, engine, device)
    return width, height


def _check_settings(samples: int, engine: str, device: str) -> None:
    if not 1 <= int(samples) <= 4096:
        raise ParameterError(f"samples must be in [1, 4096], got {samples}")
    if engine not in ENGINES:
        raise ParameterError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if device not in DEVICES:
        raise ParameterError(f"device must be one of {', '.join(DEVICES)}, got {device!r}")
    if not bpy_available():
        raise RenderError("the Blender backend needs bpy: pip install 'platesynth[blender]' (bpy 5.0.1, Python 3.11)")


def render_blender(
    scene: Scene,
    size: tuple[int, int] = (1024, 768),
    *,
    samples: int | None = None,
    engine: str | None = None,
    device: str | None = None,
    denoise: bool = False,
    timeout: float | None = None,
    pool: BlenderWorkerPool | None = None,
    stats: dict | None = None,
) -> RenderResult:
    """Draw ``scene`` with Blender: the image with ``samples`` samples per pixel, then exact masks.

    Parameters
    ----------
    scene : a concrete scene (:func:`platesynth.scene.sample_scene`).
    size : (width, height) in pixels.
    samples : Cycles samples per pixel (EEVEE: TAA samples) of the image pass; default
        ``$PLATESYNTH_BLENDER_SAMPLES`` or :data:`DEFAULT_SAMPLES`.
    engine : ``"CYCLES"`` or ``"BLENDER_EEVEE"`` (the mask pass always uses Cycles); default
        ``$PLATESYNTH_BLENDER_ENGINE`` or ``"CYCLES"``.
    device : ``"auto"`` (a CUDA/OptiX GPU where Cycles finds one, else the CPU), ``"CPU"`` or ``"GPU"``; default
        ``$PLATESYNTH_BLENDER_DEVICE`` or ``"auto"``. See :func:`blender_settings`.
    denoise : denoise the image pass (OpenImageDenoise, fast quality).
    timeout : seconds one image may take (default: the pool's).
    pool : the worker pool to use (default: a process-wide pool started on first use, closed at exit).
    stats : if given, filled with the worker's ``seconds`` and ``cpu_seconds`` (all threads) for this image,
        its ``peak_rss_mb`` and the ``device`` used.

    Returns
    -------
    RenderResult
        RGB uint8 image, uint8 well mask and uint16 plaque mask (visible plaques numbered 1..m in drawing order),
        with the same ids as the raster renderer for the same scene.

    Raises
    ------
    ParameterError
        For a bad size, sample count, engine or device.
    RenderError
        Where bpy is missing, Blender raised (:class:`BlenderScriptError`) or its worker crashed or hung twice
        (:class:`BlenderWorkerError`, with Blender's log in ``log``).
    """
    settings = blender_settings(samples, engine, device, denoise)
    width, height = _check(size, settings["samples"], settings["engine"], settings["device"])
    pool = pool or default_pool()
    out_dir = pool.new_output_dir()
    try:
        reply = pool.request(
            {
                "op": "render",
                "scene": describe_scene(scene, (width, height), out_dir),
                "options": {key: settings[key] for key in ("samples", "engine", "device", "denoise")},
                "out_dir": str(out_dir),
            },
            timeout=timeout,
        )
        files = reply["files"]
        if stats is not None:
            stats.update(
                seconds=reply.get("seconds"), cpu_seconds=reply.get("cpu_seconds"), peak_rss_mb=reply.get("peak_rss_mb"), device=files.get("device")
            )
        try:
            image = read_image(files["image"])
            wells = read_mask(files["well_id"], first_channel=True)
            plaques = read_mask(files["plaque_id"], first_channel=True)
        except ImageReadError as exc:
            raise RenderError(f"Blender's output cannot be read: {exc}") from None
    finally:
        shutil.rmtree(out_dir, ignore_errors=True)
    if image.shape[:2] != (height, width) or wells.shape != (height, width) or plaques.shape != (height, width):
        raise RenderError(f"Blender wrote images of the wrong size: {image.shape}, {wells.shape}, {plaques.shape} for {width}x{height}")
    if image.ndim == 3 and image.shape[2] == 4:
        image = image[..., :3]
    if int(wells.max()) > 255:
        raise RenderError(f"Blender's well mask holds id {int(wells.max())} > 255")
    if scene.post.jpeg.enabled:
        from platesynth.render.postprocess import jpeg_roundtrip

        image = jpeg_roundtrip(image, scene.post.jpeg.strength)
    well_info = [WellInfo(id=w.id, row=w.row, col=w.col, label=w.label, countable=w.countable) for w in scene.wells]
    return RenderResult(image=np.ascontiguousarray(image), wells=wells.astype(np.uint8), plaques=renumber(plaques.astype(np.uint16)), well_info=well_info)


def export_blend(
    scene: Scene,
    path: str | os.PathLike,
    size: tuple[int, int] = (1024, 768),
    *,
    samples: int = DEFAULT_SAMPLES,
    engine: str = "CYCLES",
    device: str = "auto",
    pool: BlenderWorkerPool | None = None,
) -> Path:
    """Save ``scene`` as a .blend file that opens in Blender 5.0, ready to render.

    The plate, wells and plaques are geometry-node modifiers whose inputs (well radius, depth, segments, layer
    step, extra random emptying...) are named; per-well and per-plaque values are point attributes; plate-wide
    material values are named Value/RGB nodes (``Unevenness``, ``Translucency``, ``Stain Colour``...); the
    compositor holds the post-processing with named strength nodes. The file is written atomically.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    width, height = _check(size, samples, engine, device)
    target = Path(path)
    if target.suffix.lower() != ".blend":
        raise ParameterError(f"{target}: the file name must end in .blend")
    pool = pool or default_pool()
    texture_dir = pool.new_output_dir()  # the textures are packed into the .blend
    try:
        pool.request(
            {
                "op": "export",
                "scene": describe_scene(scene, (width, height), texture_dir),
                "options": {"samples": int(samples), "engine": engine, "device": device},
                "path": str(target.resolve()),
            }
        )
    finally:
        shutil.rmtree(texture_dir, ignore_errors=True)
    return target


def warm_up(pool: BlenderWorkerPool | None = None) -> None:
    """Start the worker(s) of ``pool`` (default: the process-wide pool) now, e.g. as an executor's worker setup."""
    (pool or default_pool()).request({"op": "ping"})


__all__ = [
    "BlenderScriptError",
    "BlenderWorkerError",
    "BlenderWorkerPool",
    "DEFAULT_SAMPLES",
    "blender_home",
    "blender_settings",
    "blender_version",
    "bpy_available",
    "close_default_pool",
    "default_pool",
    "describe_scene",
    "export_blend",
    "render_blender",
    "warm_up",
]
