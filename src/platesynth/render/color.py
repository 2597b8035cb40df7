"""Colour shared by the renderers: the light's colour, sRGB to linear light and back (lookup tables for the kernels)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from platesynth.scene.sample import color_temperature_rgb


def light_colour(kelvin: float) -> np.ndarray:
    """Linear RGB gains (largest 1) of light of colour temperature ``kelvin`` as the camera's white balance left it;
    the renderers multiply the scene's light by them (the raster renderer with the exposure, Blender's compositor)."""
    white = np.asarray(color_temperature_rgb(kelvin))
    return srgb_to_linear(white / white.max())


def srgb_to_linear(rgb: np.ndarray) -> np.ndarray:
    """sRGB-encoded values (0..1) to linear light."""
    rgb = np.asarray(rgb, dtype=np.float64)
    return np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)


@lru_cache(maxsize=1)
def gamma_lut(size: int = 4096) -> np.ndarray:
    """Display encoding indexed by ``sqrt(linear) * size``."""
    linear = np.linspace(0.0, 1.0, size + 1) ** 2
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055).astype(np.float32)


@lru_cache(maxsize=1)
def linear_lut() -> np.ndarray:
    """Linear light of each 8-bit sRGB level."""
    return srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
