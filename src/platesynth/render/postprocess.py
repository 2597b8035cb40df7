"""Photographic post-processing as plain functions on float images.

Images are ``(H, W, 3)`` float32, display-encoded (sRGB-like), nominally in [0, 1]; each function returns a
new array and leaves clipping to :func:`to_uint8`. Lengths in pixels are for the image as given (the renderer
scales the scene's values, which are for 1024-pixel-wide images). :func:`apply_post` applies a scene's
:class:`~platesynth.scene.params.PostProcessing` in order.
"""

from __future__ import annotations

import io
import math

import numpy as np
from PIL import Image
from scipy import ndimage

from platesynth.scene.params import PostProcessing


def gaussian_blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur over the first two axes; large sigmas are done at reduced resolution.

    Parameters
    ----------
    image : (H, W) or (H, W, C) float array.
    sigma : standard deviation in pixels.
    """
    image = np.asarray(image, dtype=np.float32)
    if sigma <= 0:
        return image.copy()
    sigmas = (sigma, sigma) + (0,) * (image.ndim - 2)
    factor = int(sigma // 3)
    if factor < 2:
        return ndimage.gaussian_filter(image, sigmas, mode="nearest", truncate=3.0)
    height, width = image.shape[:2]
    small_size = (max(1, width // factor), max(1, height // factor))
    channels = [image] if image.ndim == 2 else [image[..., c] for c in range(image.shape[2])]
    out = []
    for channel in channels:
        small = np.asarray(Image.fromarray(channel, mode="F").resize(small_size, Image.Resampling.BOX))
        small = ndimage.gaussian_filter(small, math.sqrt(max(sigma**2 / factor**2 - 0.25, 0.1)), mode="nearest")
        out.append(np.asarray(Image.fromarray(small, mode="F").resize((width, height), Image.Resampling.BILINEAR)))
    return out[0] if image.ndim == 2 else np.stack(out, axis=-1)


def _luminance(image: np.ndarray) -> np.ndarray:
    return image @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)


def brightness(image: np.ndarray, strength: float) -> np.ndarray:
    """Brighten (``strength`` > 0, towards white) or darken (< 0, towards black); ``strength`` in [-1, 1]."""
    if strength >= 0:
        return image + strength * (1.0 - image)
    return image * (1.0 + strength)


def white_balance(image: np.ndarray, gains: tuple[float, float, float]) -> np.ndarray:
    """Multiply the channels by ``gains`` normalised to keep the luminance of grey."""
    gains = np.asarray(gains, dtype=np.float32)
    gains = gains / float(_luminance(gains[None, None, :])[0, 0])
    return image * gains


def clarity(image: np.ndarray, strength: float) -> np.ndarray:
    """Local (mid-tone) contrast: ``strength`` > 0 adds, < 0 removes detail at a scale of ~2% of the width."""
    sigma = 0.02 * image.shape[1]
    base = gaussian_blur(image, sigma)
    midtones = 1.0 - (2.0 * _luminance(image) - 1.0) ** 2
    return image + strength * midtones[..., None] * (image - base)


def motion_blur(image: np.ndarray, length_px: float, angle_deg: float) -> np.ndarray:
    """Average along a line of ``length_px`` pixels at ``angle_deg`` (camera shake)."""
    steps = max(1, int(math.ceil(length_px)))
    if length_px <= 0.5:
        return image.copy()
    dx, dy = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    out = np.zeros_like(image)
    for t in np.linspace(-0.5, 0.5, steps + 1):
        out += ndimage.shift(image, (t * length_px * dy, t * length_px * dx, 0), order=1, mode="nearest")
    return out / (steps + 1)


def shadows(image: np.ndarray, strength: float, rng: np.random.Generator) -> np.ndarray:
    """Darken by soft, low-frequency shadows (depth ``strength``) drawn from ``rng``."""
    height, width = image.shape[:2]
    grid = rng.random((4, 5)).astype(np.float32)
    field = np.asarray(Image.fromarray(grid, mode="F").resize((width, height), Image.Resampling.BICUBIC))
    return image * (1.0 - strength * np.clip(field, 0.0, 1.0))[..., None]


def chromatic_aberration(image: np.ndarray, shift_px: float) -> np.ndarray:
    """Lateral colour: red scaled outward and blue inward about the centre by ``shift_px`` at the corners."""
    height, width = image.shape[:2]
    half_diagonal = 0.5 * math.hypot(width, height)
    out = image.copy()
    for channel, sign in ((0, 1.0), (2, -1.0)):
        scale = 1.0 + sign * shift_px / half_diagonal
        # PIL's affine maps output to input coordinates
        a = 1.0 / scale
        data = (a, 0.0, width / 2 * (1 - a), 0.0, a, height / 2 * (1 - a))
        band = Image.fromarray(np.ascontiguousarray(image[..., channel]), mode="F")
        out[..., channel] = np.asarray(band.transform((width, height), Image.Transform.AFFINE, data,
                                                      Image.Resampling.BILINEAR, fillcolor=None))
    return out


def bloom(image: np.ndarray, strength: float, threshold: float = 0.75) -> np.ndarray:
    """Glow around areas brighter than ``threshold``."""
    bright = np.clip(image - threshold, 0.0, None) / (1.0 - threshold)
    glow = gaussian_blur(bright, 0.015 * image.shape[1])
    return image + strength * glow


def sharpen(image: np.ndarray, amount: float, sigma: float = 1.0) -> np.ndarray:
    """Unsharp masking."""
    return image + amount * (image - gaussian_blur(image, sigma))


def sensor_noise(image: np.ndarray, sd_levels: float, rng: np.random.Generator) -> np.ndarray:
    """Signal-dependent Gaussian noise with sd ``sd_levels`` (8-bit levels) at mid grey; slightly correlated
    across channels like a demosaiced sensor."""
    height, width = image.shape[:2]
    sd = sd_levels / 255.0 * np.sqrt(np.clip(image, 0.02, 1.0) / 0.5)
    common = rng.standard_normal((height, width, 1), dtype=np.float32)
    own = rng.standard_normal((height, width, 3), dtype=np.float32)
    return image + sd * (0.5 * common + 0.85 * own)


def to_uint8(image: np.ndarray) -> np.ndarray:
    """Clip to [0, 1] and quantise to uint8."""
    return (np.clip(image, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def jpeg_roundtrip(image: np.ndarray, strength: float) -> np.ndarray:
    """Compress as JPEG with quality ``100 * (1 - strength)`` and decode (uint8 in, uint8 out)."""
    quality = int(round(100 * (1.0 - strength)))
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="JPEG", quality=max(5, min(quality, 100)))
    buffer.seek(0)
    with Image.open(buffer) as decoded:
        return np.asarray(decoded.convert("RGB"))


def apply_post(image: np.ndarray, post: PostProcessing, rng: np.random.Generator, px_scale: float = 1.0) -> np.ndarray:
    """Apply the enabled effects of ``post`` (except JPEG, which works on the uint8 image) in order.

    Parameters
    ----------
    image : (H, W, 3) float32 display-encoded image.
    post : the scene's post-processing switches and strengths.
    rng : randomness for shadows and noise (derive it from the scene's seed).
    px_scale : image width / 1024, to scale lengths given in pixels.
    """
    if post.brightness.enabled:
        image = brightness(image, post.brightness.strength)
    if post.white_balance.enabled:
        image = white_balance(image, post.white_balance_shift)
    if post.clarity.enabled:
        image = clarity(image, post.clarity.strength)
    if post.motion_blur.enabled:
        image = motion_blur(image, post.motion_blur.strength * px_scale, post.motion_blur_angle_deg)
    if post.shadows.enabled:
        image = shadows(image, post.shadows.strength, rng)
    if post.chromatic_aberration.enabled:
        image = chromatic_aberration(image, post.chromatic_aberration.strength * px_scale)
    if post.bloom.enabled:
        image = bloom(image, post.bloom.strength)
    if post.sharpen.enabled:
        image = sharpen(image, post.sharpen.strength, sigma=max(0.5, px_scale))
    if post.noise.enabled:
        image = sensor_noise(image, post.noise.strength, rng)
    return image
