"""Renderers: a concrete :class:`~platesynth.scene.Scene` to an image and exact instance masks."""

from __future__ import annotations

import importlib
from typing import Any

from platesynth import __version__
from platesynth.errors import ParameterError
from platesynth.limits import check_render
from platesynth.render.kernel_cache import drop_stale_kernels
from platesynth.render.result import RenderResult, WellInfo, check_size, plaque_counts
from platesynth.scene.concrete import Scene

drop_stale_kernels()  # before any kernel runs: numba's cache does not see edits of the modules a kernel inlines

BACKENDS: dict[str, str] = {
    "raster": "platesynth.render.raster:render_raster",
    "blender": "platesynth.render.blender:render_blender",
}
"""Backend name -> ``module:function`` taking ``(scene, size)`` and returning a :class:`RenderResult`."""


def _check_backend(backend: str) -> None:
    if backend not in BACKENDS:
        raise ParameterError(f"unknown backend {backend!r}: choose from {', '.join(BACKENDS)}")


def render(scene: Scene, size: tuple[int, int] = (1024, 768), backend: str = "raster", **options: Any) -> RenderResult:
    """Draw ``scene`` at ``size`` = (width, height) pixels with the named backend.

    Parameters
    ----------
    scene : a concrete scene.
    size : (width, height) in pixels.
    backend : ``"raster"`` (fast CPU renderer) or ``"blender"``.
    **options : the backend's own settings: none for the raster renderer; for Blender ``samples``, ``engine``,
        ``device`` and ``denoise`` (see :func:`renderer_settings`), and the keywords of
        :func:`platesynth.render.blender.render_blender`.

    Raises
    ------
    ParameterError
        For an unknown backend, a bad size, or options the backend does not take.
    ResourceLimitError
        If the render would need more memory than the limit (:mod:`platesynth.limits`).
    """
    _check_backend(backend)
    if backend == "raster" and options:
        raise ParameterError(f"{', '.join(sorted(options))}: Blender settings, which the raster backend does not take")
    check_render(check_size(size), backend)
    module_name, function_name = BACKENDS[backend].split(":")
    function = getattr(importlib.import_module(module_name), function_name)
    return function(scene, size, **options)


def renderer_settings(backend: str, **options: Any) -> dict[str, Any]:
    """Everything besides the scene and the size that decides a backend's images, as a dataset records it.

    Parameters
    ----------
    backend : ``"raster"`` or ``"blender"``.
    **options : Blender's ``samples``, ``engine``, ``device``, ``denoise``; where not given, their environment
        variables or defaults (:func:`platesynth.render.blender.blender_settings`). The raster renderer has none.

    Returns
    -------
    dict
        ``{"backend": "raster", "version": <platesynth's version>}`` or ``{"backend": "blender", "version":
        <Blender's (bpy's) version>, "engine": ..., "samples": ..., "device": ..., "denoise": ...}``; the keys
        other than ``backend`` and ``version`` are the options that :func:`render` takes to render it again.

    Raises
    ------
    ParameterError
        For an unknown backend, or options it does not take or that are invalid.
    RenderError
        For the Blender backend where bpy is not installed.
    """
    _check_backend(backend)
    if backend == "raster":
        if options:
            names = ", ".join(sorted(options))
            raise ParameterError(f"{names}: Blender settings, which the raster backend does not take")
        return {"backend": "raster", "version": __version__}
    from platesynth.render.blender import blender_settings

    return {"backend": backend, **blender_settings(**options)}


def render_options(settings: dict[str, Any]) -> dict[str, Any]:
    """The options of :func:`render` in the ``settings`` of :func:`renderer_settings` (all but backend and version)."""
    return {key: value for key, value in settings.items() if key not in ("backend", "version")}


__all__ = ["BACKENDS", "RenderResult", "WellInfo", "plaque_counts", "render", "render_options", "renderer_settings"]
