"""Streaming pixel entropy and brightness variability: hand-computed cases, granatpy parity, streaming == batch."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats
from PIL import Image

from platesynth.errors import EmptyDatasetError, ImageReadError, ParameterError
from platesynth.io import read_image
from platesynth.metrics import BrightnessVariability, PixelEntropy, grayscale, size_matched_entropy


@pytest.fixture(scope="module")
def granatpy_metrics():
    """granatpy 0.1.3's metrics module, the reference implementation (installed by ``make env-test``)."""
    return pytest.importorskip("granatpy.metrics", reason="granatpy 0.1.3 (the reference) is not installed")


PARITY = 1e-9


def plate_like(rng: np.random.Generator, height: int, width: int, channels: int | None = 3) -> np.ndarray:
    """A smooth random background with a dark disc and noise, uint8."""
    rows, cols = np.mgrid[0:height, 0:width]
    background = 150 + 60 * np.sin(cols / width * rng.uniform(2, 6) + rng.uniform(0, 6)) * np.cos(rows / height * 3)
    disc = (rows - height / 2) ** 2 + (cols - width / 2) ** 2 < (min(height, width) * rng.uniform(0.2, 0.4)) ** 2
    gray = background - 90 * disc + rng.normal(0, 12, (height, width))
    if channels is None:
        return np.clip(gray, 0, 255).astype(np.uint8)
    tint = rng.uniform(0.7, 1.0, channels)
    return np.clip(gray[..., None] * tint, 0, 255).astype(np.uint8)


def write_images(directory, images) -> list[str]:
    paths = []
    for index, image in enumerate(images):
        path = directory / f"img_{index:03d}.png"
        Image.fromarray(image).save(path)
        paths.append(str(path))
    return paths


def streamed(metric, paths):
    for path in paths:
        metric.update(read_image(path))
    return metric.compute()


def test_two_images_hand_computed():
    first = np.zeros((2, 3), np.uint8)
    second = np.array([[0, 0, 0], [255, 255, 7]], np.uint8)
    entropy, variability = PixelEntropy(), BrightnessVariability()
    for image in (first, second):
        entropy.update(image)
        variability.update(image)
    # 1 bit where the two images differ, 0 where they agree
    np.testing.assert_array_equal(entropy.entropy_map(), [[0, 0, 0], [1, 1, 1]])
    assert entropy.compute() == pytest.approx(0.5, abs=1e-15)
    # population variance of {0, v} is (v / 2) ** 2
    expected_variance = [[0, 0, 0], [127.5**2, 127.5**2, 3.5**2]]
    np.testing.assert_allclose(variability.variance_map(), expected_variance, rtol=0, atol=1e-12)
    assert entropy.n_images == variability.n_images == 2


def test_four_distinct_values_give_two_bits_and_bins_merge_them():
    images = [np.full((4, 4), value, np.uint8) for value in (10, 70, 130, 250)]
    fine, coarse = PixelEntropy(), PixelEntropy(bins=2)  # bins=2: [0, 128) and [128, 256)
    for image in images:
        fine.update(image)
        coarse.update(image)
    assert fine.compute() == pytest.approx(2.0, abs=1e-14)
    assert coarse.compute() == pytest.approx(1.0, abs=1e-14)
    assert fine.histograms().shape == (256, 4, 4)
    assert coarse.histograms()[:, 0, 0].tolist() == [2, 2]


@pytest.mark.parametrize("bins", [256, 10])
def test_parity_with_granatpy_rgb_rgba_gray(tmp_path, bins, granatpy_metrics):
    rng = np.random.default_rng(1)
    images = [plate_like(rng, 30, 40) for _ in range(8)]
    images += [plate_like(rng, 30, 40, channels=4) for _ in range(3)]  # RGBA: alpha ignored
    images += [plate_like(rng, 30, 40, channels=None) for _ in range(3)]  # mode L
    paths = write_images(tmp_path, images)

    ours = streamed(PixelEntropy(bins=bins), paths)
    reference = granatpy_metrics.dataset_entropy(paths, None, bins=bins)
    assert abs(ours - reference) <= PARITY
    assert 1.0 < ours < np.log2(len(paths))  # not a degenerate dataset
    ours_var = streamed(BrightnessVariability(), paths)
    assert abs(ours_var - granatpy_metrics.brightness_var(paths, None)) <= PARITY


def test_parity_with_granatpy_mixed_sizes(tmp_path, granatpy_metrics):
    rng = np.random.default_rng(2)
    shapes = [(30, 40), (60, 80), (15, 20), (33, 41), (30, 40), (90, 70)]
    paths = write_images(tmp_path, [plate_like(rng, h, w) for h, w in shapes])
    # default size: the first image's (30 x 40); granatpy needs it explicitly, as (width, height)
    entropy, variability = PixelEntropy(), BrightnessVariability()
    assert abs(streamed(entropy, paths) - granatpy_metrics.dataset_entropy(paths, (40, 30))) <= PARITY
    assert abs(streamed(variability, paths) - granatpy_metrics.brightness_var(paths, (40, 30))) <= PARITY
    assert entropy.size == variability.size == (30, 40)
    # an explicit (height, width)
    sized = PixelEntropy(size=(25, 35))
    assert abs(streamed(sized, paths) - granatpy_metrics.dataset_entropy(paths, (35, 25))) <= PARITY
    assert sized.entropy_map().shape == (25, 35)


def test_parity_with_granatpy_on_real_plates(shared, granatpy_metrics):
    plates = sorted(shared("data", "plaque12", "plates").glob("*.jpg"))[:3]
    paths = [str(p) for p in plates]
    size = (40, 50)  # (height, width); the plates are ~950 x 1200 and of several sizes
    ours = streamed(PixelEntropy(size=size), paths)
    assert abs(ours - granatpy_metrics.dataset_entropy(paths, size[::-1])) <= PARITY
    ours_var = streamed(BrightnessVariability(size=size), paths)
    assert abs(ours_var - granatpy_metrics.brightness_var(paths, size[::-1])) <= PARITY


def test_counts_promote_past_255_images_and_match_granatpy(tmp_path, granatpy_metrics):
    rng = np.random.default_rng(3)
    images = [rng.integers(0, 6, (3, 4), dtype=np.uint8) * 40 for _ in range(300)]
    entropy = PixelEntropy()
    for image in images:
        entropy.update(image)
    assert entropy.histograms().dtype == np.uint16
    assert int(entropy.histograms()[:, 0, 0].sum()) == 300
    # batch: histogram of the stacked images at every position, scipy's entropy
    stack = np.stack(images)
    counts = np.stack([(stack == v).sum(axis=0) for v in range(256)])
    np.testing.assert_allclose(entropy.entropy_map(), scipy.stats.entropy(counts, base=2, axis=0), rtol=0, atol=1e-12)
    paths = write_images(tmp_path, images)
    assert abs(entropy.compute() - granatpy_metrics.dataset_entropy(paths, None)) <= PARITY


def test_streaming_equals_batch_in_any_order():
    rng = np.random.default_rng(4)
    images = [plate_like(rng, 20, 24, channels=None) for _ in range(9)]
    stack = np.stack(images).astype(np.float64)
    forward, backward = BrightnessVariability(), BrightnessVariability()
    entropy_forward, entropy_backward = PixelEntropy(), PixelEntropy()
    for image in images:
        forward.update(image)
        entropy_forward.update(image)
    for image in images[::-1]:
        backward.update(image)
        entropy_backward.update(image)
    np.testing.assert_allclose(forward.variance_map(), stack.var(axis=0), rtol=1e-13)
    assert forward.compute() == backward.compute()
    np.testing.assert_array_equal(entropy_forward.histograms(), entropy_backward.histograms())
    assert entropy_forward.compute() == entropy_backward.compute()


def test_reset_forgets_images_but_keeps_requested_size():
    metric = PixelEntropy(size=(4, 5))
    metric.update(np.zeros((8, 10), np.uint8))
    metric.update(np.full((8, 10), 200, np.uint8))
    assert metric.compute() > 0.9
    metric.reset()
    assert metric.n_images == 0 and metric.size == (4, 5)
    metric.update(np.zeros((8, 10), np.uint8))
    assert metric.compute() == 0.0
    free = BrightnessVariability()
    free.update(np.zeros((3, 3), np.uint8))
    free.reset()
    free.update(np.zeros((5, 6), np.uint8))  # a new first image sets a new size
    assert free.size == (5, 6)


def test_16_bit_images_are_scaled_to_8_bits(tmp_path):
    rng = np.random.default_rng(5)
    images8 = [plate_like(rng, 16, 20) for _ in range(5)]
    images16 = [image.astype(np.uint16) * 257 for image in images8]  # round(v * 257 * 255 / 65535) == v
    for metric_type in (PixelEntropy, BrightnessVariability):
        eight, sixteen = metric_type(), metric_type()
        for image8, image16 in zip(images8, images16):
            eight.update(image8)
            sixteen.update(image16)
        assert eight.compute() == sixteen.compute()
    # a 16-bit grayscale PNG read from disk goes the same way
    gray16 = (plate_like(rng, 16, 20, channels=None).astype(np.uint16) * 257)
    path = tmp_path / "gray16.png"
    Image.fromarray(gray16).save(path)
    assert read_image(path).dtype == np.uint16
    np.testing.assert_array_equal(grayscale(read_image(path)), (gray16 // 257).astype(np.uint8))


def test_grayscale_is_pillow_luma():
    rng = np.random.default_rng(6)
    rgb = rng.integers(0, 256, (7, 9, 3), dtype=np.uint8)
    r, g, b = np.moveaxis(rgb.astype(np.uint32), -1, 0)
    expected = (r * 19595 + g * 38470 + b * 7471 + 0x8000) >> 16
    np.testing.assert_array_equal(grayscale(rgb), expected)
    rgba = np.concatenate([rgb, rng.integers(0, 256, (7, 9, 1), dtype=np.uint8)], axis=-1)
    np.testing.assert_array_equal(grayscale(rgba), expected)
    assert grayscale(rgb, size=(3, 4)).shape == (3, 4)


@pytest.mark.parametrize(
    ("image", "message"),
    [
        (np.zeros((4, 4), np.float32), "float32"),
        (np.zeros((4, 4, 2), np.uint8), "shape"),
        (np.zeros((4, 4), np.int16), "int16"),
        (np.zeros((0, 4), np.uint8), "shape"),
    ],
)
def test_unsupported_arrays_are_refused(image, message):
    with pytest.raises(ImageReadError, match=message):
        PixelEntropy().update(image)
    with pytest.raises(ImageReadError, match=message):
        BrightnessVariability().update(image)


def test_bad_parameters_and_empty_state():
    with pytest.raises(EmptyDatasetError):
        PixelEntropy().compute()
    with pytest.raises(EmptyDatasetError):
        BrightnessVariability().compute()
    with pytest.raises(ParameterError, match="bins"):
        PixelEntropy(bins=0)
    with pytest.raises(ParameterError, match="size"):
        PixelEntropy(size=(0, 5))
    with pytest.raises(ParameterError, match="size"):
        BrightnessVariability(size=(2.5, 5))


def test_size_matched_entropy(tmp_path):
    rng = np.random.default_rng(7)
    images = [plate_like(rng, 12, 16) for _ in range(10)]
    everything = PixelEntropy()
    for image in images:
        everything.update(image)
    # one subset holding every image is the whole dataset
    assert size_matched_entropy(images, subset_size=10, n_subsets=1) == pytest.approx(everything.compute(), abs=1e-12)
    assert size_matched_entropy(images, subset_size=1, n_subsets=3) == 0.0
    small = size_matched_entropy(images, subset_size=4, n_subsets=5, seed=1)
    assert 0 < small <= 2.0  # at most log2(4)
    assert small < everything.compute()
    # paths give the same value as arrays, and the seed fixes the subsets
    paths = write_images(tmp_path, images)
    assert size_matched_entropy(paths, subset_size=4, n_subsets=5, seed=1) == small
    with pytest.raises(ParameterError, match="subset_size"):
        size_matched_entropy(images, subset_size=11)
    with pytest.raises(EmptyDatasetError):
        size_matched_entropy([], subset_size=1)
    with pytest.raises(ImageReadError, match="missing.png"):
        size_matched_entropy([tmp_path / "missing.png"], subset_size=1)
