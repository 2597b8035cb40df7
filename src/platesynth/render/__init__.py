"""Renderers: a concrete :class:`~platesynth.scene.Scene` to an image and exact instance masks."""

from __future__ import annotations

import importlib

from platesynth.errors import ParameterError
from platesynth.render.result import RenderResult, WellInfo, plaque_counts
from platesynth.scene.concrete import Scene

BACKENDS: dict[str, str] = {
    "raster": "platesynth.render.raster:render_raster",
    "blender": "platesynth.render.blender:render_blender",
}
"""Backend name -> ``module:function`` taking ``(scene, size)`` and returning a :class:`RenderResult`."""


def render(scene: Scene, size: tuple[int, int] = (1024, 768), backend: str = "raster") -> RenderResult:
    """Draw ``scene`` at ``size`` = (width, height) pixels with the named backend.

    Parameters
    ----------
    scene : a concrete scene.
    size : (width, height) in pixels.
    backend : ``"raster"`` (fast CPU renderer) or ``"blender"``.

    Raises
    ------
    ParameterError
        For an unknown backend or a bad size.
    """
    if backend not in BACKENDS:
        raise ParameterError(f"unknown backend {backend!r}: choose from {', '.join(BACKENDS)}")
    module_name, function_name = BACKENDS[backend].split(":")
    function = getattr(importlib.import_module(module_name), function_name)
    return function(scene, size)


__all__ = ["BACKENDS", "RenderResult", "WellInfo", "plaque_counts", "render"]
