"""Photographic post-processing as plain functions on float images.

Images are ``(H, W, 3)`` float32, display-encoded (sRGB-like), nominally in [0, 1]; each function returns a
new array and leaves clipping to :func:`to_uint8`. Lengths in pixels are for the image as given (the renderer
scales the scene's values, which are for 1024-pixel-wide images). :func:`apply_post` applies a scene's
:class:`~platesynth.scene.concrete.PostProcessing` in order.
"""

from __future__ import annotations

import io
import math

import numpy as np
from PIL import Image

from platesynth.render import post_kernels as kernels
from platesynth.render.look import BLOOM_RADIUS, BLOOM_THRESHOLD, CLARITY_RADIUS, LUMINANCE, noise_grain_gain
from platesynth.scene.concrete import PostProcessing


def gaussian_taps(sigma: float) -> np.ndarray:
    """Half of a normalised Gaussian kernel, centre first."""
    radius = max(1, int(math.ceil(3.0 * sigma)))
    taps = np.exp(-0.5 * (np.arange(radius + 1) / max(sigma, 1e-3)) ** 2)
    return (taps / (taps[0] + 2.0 * taps[1:].sum())).astype(np.float32)


def gaussian_blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur over the first two axes; sigmas above 6 px are done on block means and upsampled.

    Parameters
    ----------
    image : (H, W) or (H, W, C) float array.
    sigma : standard deviation in pixels.
    """
    image = np.asarray(image, dtype=np.float32)
    if sigma <= 0:
        return image.copy()
    planar = np.ascontiguousarray(image[..., None] if image.ndim == 2 else image)
    factor = int(sigma // 3)
    if factor < 2:
        out = np.empty_like(planar)
        kernels.blur_separable(planar, gaussian_taps(sigma), out)
    else:
        small = kernels.downsample_mean(planar, factor)
        blurred = np.empty_like(small)
        # block means already carry a blur of about factor/sqrt(12)
        kernels.blur_separable(small, gaussian_taps(math.sqrt(max(sigma**2 - factor**2 / 12.0, 0.25)) / factor), blurred)
        out = np.empty_like(planar)
        kernels.upsample_bilinear(blurred, factor, out)
    return out[..., 0] if image.ndim == 2 else out


def _luminance(image: np.ndarray) -> np.ndarray:
    return image @ np.array(LUMINANCE, dtype=np.float32)


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
    sigma = CLARITY_RADIUS * image.shape[1]
    base = gaussian_blur(image, sigma)
    midtones = 1.0 - (2.0 * _luminance(image) - 1.0) ** 2
    return image + strength * midtones[..., None] * (image - base)


def motion_blur(image: np.ndarray, length_px: float, angle_deg: float) -> np.ndarray:
    """Average along a line of ``length_px`` pixels at ``angle_deg`` (camera shake)."""
    if length_px <= 0.5:
        return image.copy()
    planar = np.ascontiguousarray(image, dtype=np.float32)
    out = np.empty_like(planar)
    dx, dy = length_px * math.cos(math.radians(angle_deg)), length_px * math.sin(math.radians(angle_deg))
    kernels.line_blur(planar, dx, dy, int(math.ceil(length_px)) + 1, out)
    return out


def shadows(image: np.ndarray, strength: float, rng: np.random.Generator) -> np.ndarray:
    """Darken by soft, low-frequency shadows (depth ``strength``) drawn from ``rng``."""
    height, width = image.shape[:2]
    factor = max(1, int(math.ceil(max(height / 3, width / 4))))
    grid = rng.random((int(math.ceil(height / factor)), int(math.ceil(width / factor)), 1)).astype(np.float32)
    field = np.empty((height, width, 1), dtype=np.float32)
    kernels.upsample_bilinear(grid, factor, field)
    return image * (1.0 - strength * field)


def chromatic_aberration(image: np.ndarray, shift_px: float) -> np.ndarray:
    """Lateral colour: red scaled outward and blue inward about the centre by ``shift_px`` at the corners."""
    height, width = image.shape[:2]
    half_diagonal = 0.5 * math.hypot(width, height)
    scales = np.array([1.0 + shift_px / half_diagonal, 1.0, 1.0 - shift_px / half_diagonal])
    out = np.empty_like(image)
    kernels.scale_channels(np.ascontiguousarray(image, dtype=np.float32), scales, out)
    return out


def bloom(image: np.ndarray, strength: float, threshold: float = BLOOM_THRESHOLD) -> np.ndarray:
    """Glow around areas brighter than ``threshold``."""
    bright = np.clip(image - threshold, 0.0, None) / (1.0 - threshold)
    glow = gaussian_blur(bright, BLOOM_RADIUS * image.shape[1])
    return image + strength * glow


def sharpen(image: np.ndarray, amount: float, sigma: float = 1.0, luma: float = 0.0,
            threshold: float = 0.0) -> np.ndarray:
    """Unsharp masking; a share ``luma`` (0..1) of it adds the luminance's detail to every channel, as a phone
    sharpens, so that a coloured edge gets no coloured halo; detail within ``threshold`` (display units, 0..1) of 0
    is left alone and only the rest is sharpened (coring: edges are sharpened, the flat stain's grain is not)."""
    detail = image - gaussian_blur(image, sigma)
    if luma > 0.0:
        detail = (1.0 - luma) * detail + luma * _luminance(detail)[..., None]
    if threshold > 0.0:
        detail = detail - np.clip(detail, -threshold, threshold)
    return image + amount * detail


def sensor_noise(image: np.ndarray, sd_levels: float, rng: np.random.Generator, grain_px: float = 0.0) -> np.ndarray:
    """Signal-dependent, nearly Gaussian noise with sd ``sd_levels`` (8-bit levels) at mid grey, partly shared
    by the channels like a demosaiced sensor's; ``grain_px`` > 0 clumps it into grains (blurred by that sd in
    pixels, its sd kept), as a phone's demosaicing and denoising leave it."""
    out = np.array(image, dtype=np.float32, copy=True)
    kernels.add_sensor_noise(out, np.float32(sd_levels / 255.0), int(rng.integers(0, 2**62)))
    if grain_px > 0.0:
        out = image + gaussian_blur(out - image, grain_px) * np.float32(noise_grain_gain(grain_px))
    return out


def black_level(image: np.ndarray, level: float) -> np.ndarray:
    """A tone curve's black point: ``level`` maps to 0 and 1 stays 1, linearly between (darker levels go below 0 and
    clip when the image is stored)."""
    return (image - np.float32(level)) / np.float32(1.0 - level)


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
        image = sharpen(image, post.sharpen.strength, sigma=max(0.5, px_scale), luma=post.sharpen_luma,
                        threshold=post.sharpen_threshold / 255.0)
    if post.noise.enabled:
        image = sensor_noise(image, post.noise.strength, rng, grain_px=post.noise_grain_px * px_scale)
    if post.black_level > 0.0:
        image = black_level(image, post.black_level)
    return image
