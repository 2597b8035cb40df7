"""``platesynth render``, ``preview`` and ``demo`` through the command line (typer's CliRunner)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from platesynth.cli import app
from platesynth.data.batch import build_manifest, render_item
from platesynth.data.layout import list_items, read_counts_csv, read_manifest
from platesynth.data.preview import draw_outlines

SMALL = ["--preset", "high", "--size", "160x120", "--seed", "5"]


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def test_render_writes_dataset_and_resumes(tmp_path):
    out = tmp_path / "ds"
    result = invoke("render", "--out", out, "--count", 2, *SMALL, "--coco", "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout) | {"seconds": 0} == {
        "directory": str(out),
        "count": 2,
        "rendered": 2,
        "skipped": 0,
        "failed": {},
        "seconds": 0,
    }
    assert [item.name for item in list_items(out)] == ["000000", "000001"]
    assert len(read_counts_csv(out / "counts.csv")) == 2 * 12
    assert len(json.loads((out / "annotations.coco.json").read_text())["images"]) == 2
    manifest = read_manifest(out)
    assert (manifest.preset, manifest.seed, manifest.size, manifest.backend, manifest.coco) == (
        "high", 5, (160, 120), "raster", True
    )
    before = {p: p.read_bytes() for p in out.rglob("*.png")}
    again = invoke("render", "--out", out, "--count", 2, *SMALL, "--coco")
    assert again.exit_code == 0, again.output
    assert "0 rendered, 2 already there, 0 failed" in again.output
    assert {p: p.read_bytes() for p in out.rglob("*.png")} == before


def test_refuses_a_different_dataset_unless_overwrite(tmp_path):
    assert invoke("render", "--out", tmp_path, "--count", 1, *SMALL).exit_code == 0
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    refused = invoke("render", "--out", tmp_path, "--count", 1, *SMALL, "--size", "128x96")
    assert refused.exit_code == 1
    assert "holds a different dataset (size differ)" in refused.output and "--overwrite" in refused.output
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before
    replaced = invoke("render", "--out", tmp_path, "--count", 1, *SMALL, "--size", "128x96", "--overwrite")
    assert replaced.exit_code == 0, replaced.output
    assert read_manifest(tmp_path).size == (128, 96)
    assert Image.open(tmp_path / "images" / "000000.png").size == (128, 96)


@pytest.fixture
def bad_configs(tmp_path):
    (tmp_path / "bad_yaml.yaml").write_text("plaques: [1, 2\n")
    (tmp_path / "bad_value.yaml").write_text("plaques:\n  radius_mm: [-5, 1]\n")
    (tmp_path / "a_file").write_text("x")
    return tmp_path


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--preset", "nope"], "unknown preset 'nope'"),
        (["--size", "1024by768"], "size '1024by768': expected WIDTHxHEIGHT"),
        (["--size", "0x768"], "expected WIDTHxHEIGHT"),
        (["--size", "8x8"], "size 8x8 is out of range: each side must be in [16, 16384] pixels"),
        (["--count", "0"], "count must be > 0, got 0"),
        (["--count", "-3"], "count must be > 0, got -3"),
        (["--config", "{dir}/missing.yaml"], "missing.yaml: no such configuration file"),
        (["--config", "{dir}/bad_yaml.yaml"], "bad_yaml.yaml: cannot read YAML"),
        (["--config", "{dir}/bad_value.yaml"], "bad_value.yaml: plaques.radius_mm: -5 is out of range"),
        (["--plate", "7"], "plate.format: 7 is not allowed"),
        (["--set", "plate.format"], "expected NAME=VALUE"),
        (["--backend", "povray"], "unknown backend 'povray'"),
        (["--workers", "0"], "workers must be >= 1"),
        (["--executor", "mpi"], "unknown executor 'mpi'"),
        (["--scheduler", "tcp://127.0.0.1:1", "--connect-timeout", "1"], "cannot connect to Dask scheduler"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(bad_configs, args, message):
    out = bad_configs / "out"
    args = [a.format(dir=bad_configs) for a in args]
    result = invoke("render", "--out", out, "--count", 2, "--size", "160x120", *args)
    assert result.exit_code == 1
    assert result.output.startswith("error: ") and message in result.output, result.output
    assert len(result.output.strip().splitlines()) == 1 and "Traceback" not in result.output
    assert not out.exists()


def test_out_is_a_file(bad_configs):
    result = invoke("render", "--out", bad_configs / "a_file", "--count", 1, "--size", "160x120")
    assert result.exit_code == 1
    assert "a_file: exists and is not a directory" in result.output
    assert (bad_configs / "a_file").read_text() == "x"


def test_preview_contact_sheet(tmp_path):
    sheet_path = tmp_path / "sheet.png"
    result = invoke("preview", "--out", sheet_path, "--count", 3, "--columns", 2, "--preset", "high", "--size", "64x48")
    assert result.exit_code == 0, result.output
    sheet = np.asarray(Image.open(sheet_path))
    assert sheet.shape == (4 + 2 * (48 + 4), 4 + 2 * (64 + 4), 3)
    manifest = build_manifest(preset="high", count=3, size=(64, 48))
    second, _ = render_item(manifest, 1)  # the same scenes as `render --seed 0`
    assert np.array_equal(sheet[4:52, 72:136], draw_outlines(second.image, second.wells, second.plaques))
    plain = invoke("preview", "--out", sheet_path, "--count", 1, "--preset", "high", "--size", "64x48", "--no-outlines")
    assert plain.exit_code == 0, plain.output
    first, _ = render_item(manifest, 0)
    assert np.array_equal(np.asarray(Image.open(sheet_path))[4:52, 4:68], first.image)


def test_preview_needs_a_png_name(tmp_path):
    result = invoke("preview", "--out", tmp_path / "sheet.jpg", "--count", 1)
    assert result.exit_code == 1 and "ending in .png" in result.output
    assert not (tmp_path / "sheet.jpg").exists()


def test_demo(tmp_path):
    out = tmp_path / "demo"
    result = invoke("demo", "--out", out, "--count", 2, "--size", "160x120")
    assert result.exit_code == 0, result.output
    assert len(list_items(out)) == 2 and (out / "preview.png").is_file()
    assert (out / "annotations.coco.json").is_file() and len(read_counts_csv(out / "counts.csv")) == 24
    assert "nf_mean" in result.stdout and "brightness_variability" in result.stdout
    assert read_manifest(out).config["plate"]["format"] == 12


def test_demo_counts_plaques_with_the_shipped_model(tmp_path):
    model = Path(__file__).resolve().parents[1] / "models" / "plaque12"
    out = tmp_path / "demo"
    result = invoke("demo", "--out", out, "--count", 2, "--size", "320x240", "--model", model)
    assert result.exit_code == 0, result.output
    assert "plaques per well" in result.stdout
    assert re.search(r"n_wells\s+│\s+24\s", result.stdout)  # 2 images x 12 wells, all scored
    assert re.search(r"n_wells_not_detected\s+│\s+0\s", result.stdout)
