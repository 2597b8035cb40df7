"""Pair metrics: granatpy ``compute_all_metrics`` parity, hand-checked values, compare_pair's refusals and extras."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from PIL import Image

from platesynth.errors import ImageReadError, MetricUndefinedError, ShapeMismatchError
from platesynth.metrics import (
    MetricSkippedWarning,
    compare_pair,
    mean_squared_error,
    naturalness_factor,
    normalized_root_mse,
    peak_signal_noise_ratio,
    structural_similarity,
)


@pytest.fixture(scope="module")
def granatpy_metrics():
    """granatpy 0.1.3's metrics module, the reference implementation (installed by ``make env-test``)."""
    return pytest.importorskip("granatpy.metrics", reason="granatpy 0.1.3 (the reference) is not installed")


CLASSICAL = {"mse": "MSE", "nrmse": "NRMSE", "ssim": "SSIM", "psnr": "PSNR"}


def textured(seed: int, height: int = 48, width: int = 64) -> np.ndarray:
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0:height, 0:width]
    base = 140 + 50 * np.sin(cols / 7 + seed) + 30 * np.cos(rows / 5)
    return np.clip(base[..., None] * [1.0, 0.8, 0.9] + rng.normal(0, 10, (height, width, 3)), 0, 255).astype(np.uint8)


def real_crops(shared, height: int = 48, width: int = 64) -> tuple[np.ndarray, np.ndarray]:
    plate = np.asarray(Image.open(shared("data", "plaque12", "plates", "Brisbane_plate2.jpg")).convert("RGB"))
    return plate[200 : 200 + height, 150 : 150 + width], plate[420 : 420 + height, 610 : 610 + width]


def assert_matches_granatpy(granatpy_metrics, real: np.ndarray, synthetic: np.ndarray) -> None:
    reference = granatpy_metrics.compute_all_metrics(real, synthetic)
    ours = {
        "mse": mean_squared_error(real, synthetic),
        "nrmse": normalized_root_mse(real, synthetic),
        "ssim": structural_similarity(real, synthetic),
        "psnr": peak_signal_noise_ratio(real, synthetic),
    }
    for name, granatpy_name in CLASSICAL.items():
        assert abs(ours[name] - reference[granatpy_name]) <= 1e-12, name
    pair = compare_pair(real, synthetic, lpips=False, frechet=False)
    assert {name: pair[name] for name in CLASSICAL} == ours
    assert abs(pair["nf_real"] - reference["Nf_real"]) <= 1e-9
    assert abs(pair["nf_synthetic"] - reference["Nf_synthetic"]) <= 1e-9
    assert abs(pair["dnf"] - abs(reference["dNf"])) <= 1e-9  # granatpy's dNf is signed, synthetic - real


def test_parity_with_granatpy_on_real_crops(shared, granatpy_metrics):
    real, other = real_crops(shared)
    assert_matches_granatpy(granatpy_metrics, real, other)


def test_parity_with_granatpy_on_generated_images(granatpy_metrics):
    real = textured(1)
    noisy = np.clip(real + np.random.default_rng(9).normal(0, 6, real.shape), 0, 255).astype(np.uint8)
    assert_matches_granatpy(granatpy_metrics, real, noisy)


def test_hand_checked_values():
    black, grey51 = np.zeros((8, 8, 3), np.uint8), np.full((8, 8, 3), 51, np.uint8)
    assert mean_squared_error(black, grey51) == pytest.approx((51 / 255) ** 2, rel=1e-15)
    assert peak_signal_noise_ratio(black, grey51) == pytest.approx(20 * math.log10(5), rel=1e-14)
    hundred, hundred_ten = np.full((8, 8), 100, np.uint8), np.full((8, 8), 110, np.uint8)
    assert normalized_root_mse(hundred, hundred_ten) == pytest.approx(0.1, rel=1e-14)
    assert structural_similarity(hundred, hundred) == 1.0
    assert peak_signal_noise_ratio(hundred, hundred) == math.inf
    # uint16: the data range is 65535, so the 0..1-scale MSE is the same as for the 8-bit image
    assert mean_squared_error(black.astype(np.uint16), grey51.astype(np.uint16) * 257) == pytest.approx((51 / 255) ** 2)
    # float images are taken to lie in 0..1
    assert mean_squared_error(np.zeros((8, 8)), np.full((8, 8), 0.5)) == 0.25


def test_pair_functions_refuse_mismatches_and_tiny_images():
    with pytest.raises(ShapeMismatchError, match=r"\(8, 8\).*\(8, 9\)"):
        mean_squared_error(np.zeros((8, 8), np.uint8), np.zeros((8, 9), np.uint8))
    with pytest.raises(ShapeMismatchError, match="uint16"):
        peak_signal_noise_ratio(np.zeros((8, 8), np.uint8), np.zeros((8, 8), np.uint16))
    with pytest.raises(ImageReadError, match="int32"):
        normalized_root_mse(np.ones((8, 8), np.int32), np.ones((8, 8), np.int32))
    with pytest.raises(MetricUndefinedError, match="7x7"):
        structural_similarity(np.zeros((6, 20), np.uint8), np.zeros((6, 20), np.uint8))


def test_compare_pair_refuses_other_sizes_unless_resize(tmp_path):
    real, synthetic = textured(2), textured(3, 60, 80)
    real_path, synthetic_path = tmp_path / "real.png", tmp_path / "synthetic.png"
    Image.fromarray(real).save(real_path)
    Image.fromarray(synthetic).save(synthetic_path)
    with pytest.raises(ShapeMismatchError) as error:
        compare_pair(real_path, synthetic_path, lpips=False, frechet=False)
    message = str(error.value)
    assert "synthetic.png is 80x60" in message and "real.png is 64x48" in message and "resize" in message

    resized = compare_pair(real_path, synthetic_path, lpips=False, frechet=False, resize=True)
    from skimage.transform import resize

    expected = resize(synthetic, real.shape, order=1, anti_aliasing=True, preserve_range=True)
    expected = np.round(expected).astype(np.uint8)
    assert resized["mse"] == mean_squared_error(real, expected)
    assert resized["ssim"] == structural_similarity(real, expected)
    assert resized["nf_synthetic"] == naturalness_factor(expected)


def test_compare_pair_converts_gray_rgba_and_16_bit():
    rgb = textured(4)
    gray = rgb[..., 1]
    rgba = np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 255, np.uint8)], axis=-1)
    assert compare_pair(rgb, rgba, lpips=False, frechet=False)["mse"] == 0.0
    assert compare_pair(rgb.astype(np.uint16) * 257, rgb, lpips=False, frechet=False)["psnr"] == math.inf
    from_gray = compare_pair(gray, rgb, lpips=False, frechet=False)
    assert from_gray["mse"] == mean_squared_error(np.repeat(gray[..., None], 3, axis=-1), rgb)


def test_compare_pair_names_the_constant_image(tmp_path):
    constant = tmp_path / "flat.png"
    Image.fromarray(np.full((48, 64, 3), 128, np.uint8)).save(constant)
    with pytest.raises(MetricUndefinedError, match="flat.png"):
        compare_pair(textured(5), constant, lpips=False, frechet=False)
    with pytest.raises(ImageReadError, match="nothing.png"):
        compare_pair(tmp_path / "nothing.png", constant, lpips=False, frechet=False)



def test_compare_pair_with_deep_metrics(offline_weights, shared):
    from platesynth.metrics import get_feature_extractor, lpips_distance, patch_frechet_distance

    real, other = real_crops(shared, 96, 128)  # patches of at least 31 px for AlexNet
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = compare_pair(real, other)
    assert result["lpips"] == lpips_distance(real, other)
    assert result["fd_patches_alexnet"] == patch_frechet_distance(real, other, get_feature_extractor("alexnet"))
    assert result["lpips"] > 0.05 and result["fd_patches_alexnet"] > 0
    assert "fid_patches_inception" not in result
    assert any(issubclass(w.category, MetricSkippedWarning) and "Inception" in str(w.message) for w in caught)

    with pytest.warns(MetricSkippedWarning, match="fid_patches_inception left out"):
        same = compare_pair(real, real)
    assert same["lpips"] == pytest.approx(0.0, abs=1e-7)
    assert same["fd_patches_alexnet"] == pytest.approx(0.0, abs=1e-6)
    assert same["psnr"] == math.inf and same["dnf"] == 0.0 and same["ssim"] == 1.0
