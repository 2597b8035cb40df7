"""Reproducibility: the renderer's settings (backend, version; Blender's engine, samples, device) are recorded in
the manifest and every params file, set by option or environment variable, and a resume with others is refused."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from platesynth import __version__
from platesynth.cli import app
from platesynth.data.batch import build_manifest, render_dataset, render_item, rerender
from platesynth.data.layout import Manifest, read_manifest
from platesynth.data.writer import check_directory, prepare_directory
from platesynth.errors import DatasetError, ParameterError, RenderError
from platesynth.render import render_options, renderer_settings
from platesynth.render.blender import blender_settings, bpy_available

SMALL = {"preset": "high", "size": (160, 120), "seed": 5}
BLENDER = {"backend": "blender", "version": "5.0.1", "engine": "CYCLES", "samples": 3, "device": "auto", "denoise": False}
needs_bpy = pytest.mark.skipif(not bpy_available(), reason="bpy (Blender 5.0.1 as a Python module) is not installed here")


def blender_manifest(**renderer) -> Manifest:
    """A Blender dataset's manifest as build_manifest writes it, without needing bpy."""
    raster = build_manifest(count=2, **SMALL)
    return raster.model_copy(update={"backend": "blender", "renderer": BLENDER | renderer})


def test_raster_records_its_backend_and_version(tmp_path):
    manifest = build_manifest(count=1, **SMALL)
    assert manifest.renderer == renderer_settings("raster") == {"backend": "raster", "version": __version__}
    render_dataset(tmp_path, manifest)
    assert read_manifest(tmp_path).renderer == manifest.renderer
    params = json.loads((tmp_path / "params" / "000000.json").read_text())
    assert (params["backend"], params["renderer"]) == ("raster", manifest.renderer)
    assert "device_used" not in params
    with pytest.raises(ParameterError, match="samples: Blender settings"):
        build_manifest(count=1, samples=4, **SMALL)
    with pytest.raises(ParameterError, match="device, engine: Blender settings"):
        renderer_settings("raster", engine="CYCLES", device="CPU")


def test_a_manifest_written_before_the_renderer_was_recorded_still_resumes(tmp_path):
    manifest = build_manifest(count=1, **SMALL)
    render_dataset(tmp_path, manifest)
    old = json.loads((tmp_path / "manifest.json").read_text())
    del old["renderer"]
    (tmp_path / "manifest.json").write_text(json.dumps(old))
    assert read_manifest(tmp_path).renderer == manifest.renderer
    assert render_dataset(tmp_path, manifest).skipped == 1
    with pytest.raises(ValueError, match="not the backend"):
        Manifest.model_validate({**old, "renderer": {"backend": "blender"}})


def test_other_renderer_settings_are_another_dataset(tmp_path):
    there = blender_manifest(samples=2, device="CPU")
    prepare_directory(tmp_path, there)
    asked = blender_manifest()
    assert there.differences(asked) == ["renderer.samples", "renderer.device"]
    with pytest.raises(DatasetError) as refused:
        check_directory(tmp_path, asked)
    message = str(refused.value)
    assert "holds a different dataset (renderer.samples, renderer.device differ" in message
    assert "renderer.samples 2 there, 3 asked; renderer.device 'CPU' there, 'auto' asked" in message
    assert "--overwrite" in message
    assert check_directory(tmp_path, blender_manifest(samples=2, device="CPU")) is not None  # the same: resumes
    assert check_directory(tmp_path, asked, overwrite=True) is None
    assert there.differences(build_manifest(count=2, **SMALL)) == ["backend"]  # not every renderer key as well


def test_an_item_is_not_rendered_by_another_renderer_version():
    manifest = build_manifest(count=1, **SMALL)
    other = manifest.model_copy(update={"renderer": {"backend": "raster", "version": "0.0.1"}})
    with pytest.raises(RenderError, match=f"would render with version '{__version__}'"):
        render_item(other, 0)


def test_blender_settings_are_passed_to_the_renderer_and_recorded(monkeypatch):
    import platesynth.data.batch as batch
    from platesynth.render.result import RenderResult

    calls = []
    result, _ = render_item(build_manifest(count=1, **SMALL), 0)

    def fake_render(scene, size, backend, **options):
        calls.append((backend, {k: v for k, v in options.items() if k != "stats"}))
        options.get("stats", {})["device"] = "CPU"  # render_blender reports the device it used
        return RenderResult(result.image, result.wells, result.plaques, result.well_info)

    monkeypatch.setattr(batch, "render", fake_render)
    monkeypatch.setattr(batch, "renderer_settings", lambda backend, **options: {"backend": backend, "version": "5.0.1", **options})
    manifest = blender_manifest(samples=7, engine="BLENDER_EEVEE", device="GPU")
    _, params = render_item(manifest, 0)
    options = {"engine": "BLENDER_EEVEE", "samples": 7, "device": "GPU", "denoise": False}
    assert calls == [("blender", options)]
    assert params["renderer"] == manifest.renderer and params["device_used"] == "CPU"
    assert render_options(params["renderer"]) == options
    rerender(params)
    assert calls[-1] == ("blender", options)


@needs_bpy
def test_blender_settings_from_options_then_environment_then_defaults(monkeypatch):
    for name in ("PLATESYNTH_BLENDER_SAMPLES", "PLATESYNTH_BLENDER_ENGINE", "PLATESYNTH_BLENDER_DEVICE"):
        monkeypatch.delenv(name, raising=False)
    defaults = blender_settings()
    assert defaults == {"version": defaults["version"], "engine": "CYCLES", "samples": 3, "device": "auto", "denoise": False}
    assert defaults["version"].startswith("5.")
    monkeypatch.setenv("PLATESYNTH_BLENDER_SAMPLES", "8")
    monkeypatch.setenv("PLATESYNTH_BLENDER_ENGINE", "blender_eevee")
    monkeypatch.setenv("PLATESYNTH_BLENDER_DEVICE", "cpu")
    assert renderer_settings("blender") == {"backend": "blender", **defaults, "engine": "BLENDER_EEVEE", "samples": 8, "device": "CPU"}
    assert blender_settings(samples=2, engine="CYCLES", device="GPU") | {"version": None} == {
        "version": None, "engine": "CYCLES", "samples": 2, "device": "GPU", "denoise": False
    }
    with pytest.raises(ParameterError, match="device must be one of"):
        blender_settings(device="TPU")
    monkeypatch.setenv("PLATESYNTH_BLENDER_SAMPLES", "0.5")
    with pytest.raises(ParameterError, match="PLATESYNTH_BLENDER_SAMPLES"):
        blender_settings()


@needs_bpy
def test_render_command_records_blender_settings_and_refuses_others_on_resume(tmp_path, monkeypatch):
    """Through the command line, without rendering: the refusal comes before any item."""
    monkeypatch.setenv("PLATESYNTH_BLENDER_SAMPLES", "2")
    out = tmp_path / "ds"
    args = ["render", "--out", str(out), "--count", "1", "--preset", "high", "--size", "160x120", "--backend", "blender"]
    manifest = build_manifest(count=1, backend="blender", engine="cycles", device="cpu", **SMALL)
    assert (manifest.renderer["samples"], manifest.renderer["engine"], manifest.renderer["device"]) == (2, "CYCLES", "CPU")
    prepare_directory(out, manifest)
    refused = CliRunner().invoke(app, [*args, "--seed", "5", "--device", "CPU", "--samples", "4"])
    assert refused.exit_code == 1
    assert "renderer.samples differ: renderer.samples 2 there, 4 asked" in refused.output
    refused = CliRunner().invoke(app, [*args, "--seed", "5"])  # the environment's 2 samples, but device auto
    assert refused.exit_code == 1 and "renderer.device 'CPU' there, 'auto' asked" in refused.output
    bad = CliRunner().invoke(app, [*args, "--seed", "5", "--engine", "POVRAY"])
    assert bad.exit_code == 1 and "engine must be one of" in bad.output
    assert read_manifest(out) == manifest
