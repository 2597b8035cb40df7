"""Naturalness Nf: parity with granatpy 0.1.3 on real and generated images, conventions, undefined cases."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from platesynth.errors import MetricUndefinedError, ParameterError
from platesynth.io import read_image, to_rgb_uint8
from platesynth.metrics.naturalness import (
    NaturalnessResult,
    naturalize,
    naturalness,
    naturalness_factor,
    naturalness_map,
)

PARITY_TOLERANCE = 1e-6
SMALL = (192, 256)


def synthetic_image(seed: int, shape: tuple[int, int] = SMALL, noise: float = 6.0, discs: int = 8) -> np.ndarray:
    """RGB uint8: per-channel smooth gradients, dark and light discs, Gaussian noise."""
    rng = np.random.default_rng(seed)
    height, width = shape
    yy, xx = np.mgrid[0:height, 0:width] / max(shape)
    channels = [
        rng.uniform(60, 190)
        + rng.uniform(-60, 60) * xx
        + rng.uniform(-60, 60) * yy
        + 15 * np.sin(6 * xx * rng.uniform(1, 3))
        for _ in range(3)
    ]
    image = np.stack(channels, axis=-1)
    for _ in range(discs):
        cy, cx, radius = rng.uniform(0, height), rng.uniform(0, width), rng.uniform(4, 30)
        inside = (np.arange(height)[:, None] - cy) ** 2 + (np.arange(width)[None, :] - cx) ** 2 < radius**2
        image[inside] += rng.uniform(-70, 70, size=3)
    image += rng.normal(0, noise, size=image.shape)
    return np.clip(np.round(image), 0, 255).astype(np.uint8)


def assert_parity(image: np.ndarray) -> None:
    """Our Nf, T1, T2 and naturalized image against granatpy's ``naturalize_rgb_image`` on the same array."""
    granatpy_core = pytest.importorskip("granatpy.core", reason="granatpy 0.1.3 (the reference) is not installed")
    expected_image, expected_nf, expected_t1, expected_t2, _ = granatpy_core.naturalize_rgb_image(image)
    result = naturalness(image)
    np.testing.assert_allclose(result.nf, expected_nf, rtol=0, atol=PARITY_TOLERANCE)
    np.testing.assert_allclose(result.t1, expected_t1, rtol=0, atol=PARITY_TOLERANCE)
    np.testing.assert_allclose(result.t2, expected_t2, rtol=0, atol=PARITY_TOLERANCE)
    assert result.nf_mean == pytest.approx(float(np.mean(expected_nf)), abs=PARITY_TOLERANCE)
    naturalized = naturalize(image)
    assert naturalized.dtype == expected_image.dtype == np.uint8
    np.testing.assert_array_equal(naturalized, expected_image)


@pytest.mark.parametrize(
    "image",
    [
        pytest.param(synthetic_image(1), id="gradients-discs-noise"),
        pytest.param(synthetic_image(2, noise=1.0, discs=3), id="smooth"),
        pytest.param(synthetic_image(3, noise=25.0, discs=20), id="noisy"),
        pytest.param(synthetic_image(4, shape=(61, 47)), id="odd-size"),
    ],
)
def test_parity_with_granatpy_on_generated_rgb_images(image):
    assert_parity(image)


def test_parity_with_granatpy_on_grayscale():
    image = synthetic_image(5)[..., 1]
    assert_parity(image)
    assert naturalness(image).nf.shape == (1,)


def test_parity_with_granatpy_on_rgba_ignores_alpha():
    rgb = synthetic_image(6)
    alpha = np.random.default_rng(6).integers(0, 256, size=rgb.shape[:2], dtype=np.uint8)
    rgba = np.dstack([rgb, alpha])
    assert_parity(rgba)
    assert naturalize(rgba).shape == rgb.shape
    np.testing.assert_array_equal(naturalness(rgba).nf, naturalness(rgb).nf)


def test_parity_with_granatpy_on_a_channel_of_zeros_and_ones():
    # granatpy takes a channel with max <= 1 for a 0..1 image and multiplies it by 255 before measuring.
    image = synthetic_image(7)
    image[..., 2] = np.random.default_rng(7).integers(0, 2, size=SMALL, dtype=np.uint8)
    assert_parity(image)


@pytest.mark.parametrize("name", ["Brisbane_plate2.jpg", "IBV_plate6.jpg", "PR8_plate3.jpg"])
def test_parity_with_granatpy_on_downscaled_real_plates(shared, name):
    plate = read_image(shared("data", "plaque12", "plates", name))
    small = np.asarray(Image.fromarray(plate).resize(SMALL[::-1], Image.BILINEAR))
    assert_parity(small)


def test_parity_with_granatpy_on_a_crop_of_a_light_box_photo(shared):
    photo = read_image(shared("data", "plaque12", "photos", "PR8_plate10.jpg"))
    top, left = photo.shape[0] // 2, photo.shape[1] // 2
    assert_parity(photo[top : top + SMALL[0], left : left + SMALL[1]])


def test_parity_with_granatpy_on_a_full_size_real_plate(shared):
    plate = read_image(shared("data", "plaque12", "plates", "PR8_plate10.jpg"))
    assert min(plate.shape[:2]) > 500
    assert_parity(plate)


def test_result_is_immutable_and_nf_is_mean_of_terms():
    result = naturalness(synthetic_image(8))
    assert isinstance(result, NaturalnessResult)
    assert result.nf.shape == result.t1.shape == result.t2.shape == (3,)
    np.testing.assert_allclose(result.nf, (result.t1 + result.t2) / 2, rtol=1e-15)
    assert naturalness_factor(synthetic_image(8)) == result.nf_mean == pytest.approx(result.nf.mean())
    with pytest.raises(ValueError):
        result.nf[0] = 1.0
    with pytest.raises(AttributeError):
        result.nf = np.zeros(3)  # type: ignore[misc]


def test_smoother_image_is_less_natural_than_its_noisy_version():
    # Nf > 1 marks gradients more concentrated than in natural images (too smooth); noise spreads them.
    smooth = synthetic_image(9, noise=0.5, discs=2)
    noisy = synthetic_image(9, noise=20.0, discs=2)
    assert naturalness_factor(smooth) > naturalness_factor(noisy)


def test_uint16_is_measured_as_its_8_bit_conversion():
    image8 = synthetic_image(10)
    below_half_a_step = np.random.default_rng(10).integers(0, 100, image8.shape)
    image16 = np.minimum(image8 * 257 + below_half_a_step, 65535).astype(np.uint16)
    assert to_rgb_uint8(image16).tolist() == image8.tolist()
    np.testing.assert_array_equal(naturalness(image16).nf, naturalness(image8).nf)
    np.testing.assert_array_equal(naturalize(image16), naturalize(image8))
    np.testing.assert_array_equal(naturalness(image16[..., 0]).t2, naturalness(image8[..., 0]).t2)


def test_constant_image_is_undefined():
    for image in (np.full((40, 50, 3), 128, np.uint8), np.zeros((40, 50), np.uint8)):
        with pytest.raises(MetricUndefinedError, match="constant"):
            naturalness(image)
        with pytest.raises(MetricUndefinedError):
            naturalize(image)


def test_one_flat_channel_makes_the_image_undefined():
    image = synthetic_image(11)
    image[..., 1] = 200
    with pytest.raises(MetricUndefinedError, match="green channel"):
        naturalness_factor(image)


def test_too_small_image_is_undefined():
    with pytest.raises(MetricUndefinedError, match="3x3"):
        naturalness(synthetic_image(12)[:2, :10])


@pytest.mark.parametrize(
    "image",
    [
        np.zeros((20, 20, 3), np.float32),
        np.zeros((20, 20, 3), np.int16),
        np.zeros((20, 20, 2), np.uint8),
        np.zeros((2, 20, 20, 3), np.uint8),
    ],
    ids=["float32", "int16", "two-channels", "4d"],
)
def test_unsupported_images_are_refused(image):
    with pytest.raises(ParameterError, match="naturalness needs"):
        naturalness(image)


def test_naturalness_map_cells_and_undefined_regions():
    tile = synthetic_image(13, shape=(30, 40))
    image = np.zeros((2 * 30 + 1, 3 * 40 + 2, 3), np.uint8)  # the last row and the last 2 columns are left out
    image[:30, :40] = tile
    image[30:60, 80:120] = tile[::-1]
    image[:30, 40:80] = 90
    image[60:, :] = synthetic_image(14, shape=(1, image.shape[1]))
    image[:, 120:] = 255
    values = naturalness_map(image, grid=(2, 3))
    assert values.shape == (2, 3)
    np.testing.assert_array_equal(np.isnan(values), [[False, True, True], [True, True, False]])
    assert values[0, 0] == naturalness_factor(tile)
    assert values[1, 2] == naturalness_factor(tile[::-1])


def test_naturalness_map_matches_whole_image_nf_on_a_one_cell_grid_and_handles_gray():
    image = synthetic_image(15, shape=(33, 45), discs=0)
    assert naturalness_map(image, grid=(1, 1))[0, 0] == naturalness_factor(image)
    gray_map = naturalness_map(image[..., 0], grid=(3, 3))
    assert gray_map[2, 2] == naturalness_factor(image[22:33, 30:45, 0])
    assert np.isnan(naturalness_map(image, grid=(20, 3))).all()  # 1-pixel-high cells


@pytest.mark.parametrize("grid", [(0, 3), (2,), (2.5, 3)])
def test_naturalness_map_refuses_bad_grid(grid):
    with pytest.raises(ParameterError, match="grid"):
        naturalness_map(synthetic_image(16, shape=(30, 30)), grid=grid)
