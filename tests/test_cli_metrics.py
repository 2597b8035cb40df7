"""``platesynth metrics pair|dataset``: JSON equals the library, readable tables, every bad input refused cleanly."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from platesynth.cli import app
from platesynth.metrics import compare_pair, dataset_metrics

runner = CliRunner()


def textured(seed: int, height: int = 48, width: int = 64) -> np.ndarray:
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0:height, 0:width]
    base = 130 + 50 * np.sin(cols / (5 + seed % 4) + seed) + 30 * np.cos(rows / 6)
    return np.clip(base[..., None] * [1.0, 0.75, 0.9] + rng.normal(0, 9, (height, width, 3)), 0, 255).astype(np.uint8)


def save(path: Path, image: np.ndarray) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image).save(path)
    return path


def folder(path: Path, seeds, height: int = 48, width: int = 64) -> Path:
    for seed in seeds:
        save(path / f"image_{seed:02d}.png", textured(seed, height, width))
    return path


def invoke(*args: str):
    return runner.invoke(app, ["metrics", *args])


def assert_refused(result, *names: str) -> None:
    """Exit code 1, nothing on stdout, one line on stderr naming every ``names``, no traceback."""
    assert result.exit_code == 1, result.output
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error:")
    for name in names:
        assert name in lines[0]
    assert "Traceback" not in result.output
    assert not isinstance(result.exception, Exception) or isinstance(result.exception, SystemExit)



def test_pair_json_equals_library(tmp_path):
    real = save(tmp_path / "real.png", textured(1))
    synthetic = save(tmp_path / "synthetic.png", textured(2))
    result = invoke("pair", str(real), str(synthetic), "--json", "--no-lpips", "--no-frechet")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout) == compare_pair(real, synthetic, lpips=False, frechet=False)


def test_pair_identical_images_give_valid_json_with_null_psnr(tmp_path):
    real = save(tmp_path / "real.png", textured(3))
    result = invoke("pair", str(real), str(real), "--json", "--no-lpips", "--no-frechet")
    assert result.exit_code == 0, result.output
    values = json.loads(result.stdout)
    assert values["psnr"] is None and values["mse"] == 0.0 and values["ssim"] == 1.0


def test_pair_with_deep_metrics_and_table(tmp_path, offline_weights):
    real = save(tmp_path / "real.png", textured(4, 96, 128))
    synthetic = save(tmp_path / "synthetic.png", textured(5, 96, 128))
    result = invoke("pair", str(real), str(synthetic), "--json")
    assert result.exit_code == 0, result.output
    values = json.loads(result.stdout)
    with pytest.warns(UserWarning, match="fid_patches_inception"):
        assert values == compare_pair(real, synthetic)
    assert {"lpips", "fd_patches_alexnet"} <= values.keys() and "fid_patches_inception" not in values
    assert "note:" in result.stderr and "Inception" in result.stderr

    table = invoke("pair", str(real), str(synthetic), "--no-frechet")
    assert table.exit_code == 0, table.output
    for name in ("mse", "nrmse", "ssim", "psnr", "nf_real", "nf_synthetic", "dnf", "lpips"):
        assert name in table.stdout
    assert f"{values['lpips']:.6g}" in table.stdout


def test_pair_resize(tmp_path):
    real = save(tmp_path / "real.png", textured(6))
    bigger = save(tmp_path / "bigger.png", textured(7, 60, 80))
    refused = invoke("pair", str(real), str(bigger), "--no-lpips", "--no-frechet")
    assert_refused(refused, "bigger.png", "real.png", "--resize")
    result = invoke("pair", str(real), str(bigger), "--json", "--resize", "--no-lpips", "--no-frechet")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout) == compare_pair(real, bigger, lpips=False, frechet=False, resize=True)


def test_pair_images_too_small_for_deep_metrics(tmp_path, offline_weights):
    real = save(tmp_path / "real.png", textured(10, 24, 40))
    synthetic = save(tmp_path / "synthetic.png", textured(11, 24, 40))
    assert_refused(invoke("pair", str(real), str(synthetic), "--no-frechet"), "LPIPS", "31x31", "--no-lpips")
    assert_refused(invoke("pair", str(real), str(synthetic), "--no-lpips"), "fd_patches_alexnet", "--no-frechet")
    assert invoke("pair", str(real), str(synthetic), "--no-lpips", "--no-frechet").exit_code == 0


def test_dataset_json_equals_library(tmp_path):
    images = folder(tmp_path / "synthetic", range(5))
    result = invoke("dataset", str(images), "--json", "--size", "40x30")
    assert result.exit_code == 0, result.output
    values = json.loads(result.stdout)
    assert values == dataset_metrics(images, size=(30, 40))
    assert values["size"] == [30, 40] and values["n_images"] == 5
    assert set(values) == {"n_images", "size", "entropy", "brightness_variability", "nf_mean"}


def test_dataset_with_reference(tmp_path, offline_weights):
    images = folder(tmp_path / "synthetic", range(3))
    reference = folder(tmp_path / "real", range(10, 12), height=56, width=70)
    result = invoke("dataset", str(images), "--reference", str(reference), "--json")
    assert result.exit_code == 0, result.output
    values = json.loads(result.stdout)
    with pytest.warns(UserWarning, match="fid_inception"):
        assert values == dataset_metrics(images, reference)
    assert values["size"] == [48, 64] and values["n_images_reference"] == 2
    assert values["dnf"] == pytest.approx(abs(values["nf_mean_reference"] - values["nf_mean"]), abs=1e-15)
    assert values["fd_alexnet"] > 0 and "kid_alexnet_std" in values and "fid_inception" not in values
    assert "note:" in result.stderr and "Inception" in result.stderr

    table = invoke("dataset", str(images), "--reference", str(reference), "--no-frechet")
    assert table.exit_code == 0, table.output
    assert "64x48" in table.stdout and "entropy_reference" in table.stdout and "fd_alexnet" not in table.stdout


def test_dataset_reference_without_alexnet_weights_is_refused(tmp_path, monkeypatch):
    monkeypatch.setenv("PLATESYNTH_WEIGHTS_DIR", str(tmp_path / "no-weights"))
    monkeypatch.setenv("PLATESYNTH_OFFLINE", "1")
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch-home"))
    images = folder(tmp_path / "synthetic", range(2))
    assert_refused(invoke("dataset", str(images), "--reference", str(images)), "AlexNet", "PLATESYNTH_WEIGHTS_DIR")


def truncated_png(path: Path) -> Path:
    save(path, textured(8))
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def test_pair_bad_inputs(tmp_path):
    good = save(tmp_path / "good.png", textured(9))
    text = tmp_path / "notes.png"
    text.write_text("not an image\n")
    truncated = truncated_png(tmp_path / "truncated.png")
    flat = save(tmp_path / "flat.png", np.full((48, 64, 3), 77, np.uint8))
    fast = ("--no-lpips", "--no-frechet")
    assert_refused(invoke("pair", str(tmp_path / "missing.png"), str(good), *fast), "missing.png")
    assert_refused(invoke("pair", str(good), str(text), *fast), "notes.png")
    assert_refused(invoke("pair", str(truncated), str(good), *fast), "truncated.png")
    assert_refused(invoke("pair", str(good), str(flat), *fast), "flat.png")
    assert_refused(invoke("pair", str(good), str(tmp_path), *fast), str(tmp_path))


def test_dataset_bad_inputs(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "readme.txt").write_text("no images here\n")
    assert_refused(invoke("dataset", str(empty)), "empty", "no images")
    assert_refused(invoke("dataset", str(tmp_path / "absent")), "absent")

    corrupt = folder(tmp_path / "corrupt", range(2))
    (corrupt / "z_text.png").write_text("not an image\n")
    assert_refused(invoke("dataset", str(corrupt)), "z_text.png")

    truncated = folder(tmp_path / "truncated", range(2))
    truncated_png(truncated / "broken.png")
    assert_refused(invoke("dataset", str(truncated)), "broken.png")

    constant = folder(tmp_path / "constant", range(2))
    save(constant / "flat.png", np.full((48, 64, 3), 200, np.uint8))
    assert_refused(invoke("dataset", str(constant)), "flat.png")

    good = folder(tmp_path / "good", range(2))
    assert_refused(invoke("dataset", str(good), "--reference", str(empty)), "empty")
    assert_refused(invoke("dataset", str(good), "--size", "big"), "--size", "WIDTHxHEIGHT")
    assert_refused(invoke("dataset", str(good), "--size", "0x10"), "--size")


def test_console_script_reports_one_line_without_traceback(tmp_path):
    text = tmp_path / "fake.png"
    text.write_text("hello\n")
    script = Path(sys.executable).with_name("platesynth")
    completed = subprocess.run(
        [str(script), "metrics", "pair", str(text), str(text), "--json"], capture_output=True, text=True, timeout=120
    )
    assert completed.returncode == 1
    assert completed.stdout == ""
    assert completed.stderr.strip().count("\n") == 0 and "fake.png" in completed.stderr
    assert "Traceback" not in completed.stderr
