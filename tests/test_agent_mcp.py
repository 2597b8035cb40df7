"""The MCP server (``platesynth mcp``) through an in-process client session, and once over stdio in a subprocess.

Tools and their schemas; preview, render, metrics and a tiny train/evaluate checked on values against the library;
a job's progress, timeout and cancel; every path escape refused; the limits enforced; errors as one-line tool errors.
"""

from __future__ import annotations

import base64
import io
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import anyio
import numpy as np
import pytest
from PIL import Image

pytest.importorskip("mcp")

from mcp import Client  # noqa: E402

from platesynth.agent.jobs import JobStatus  # noqa: E402
from platesynth.agent.server import build_server  # noqa: E402
from platesynth.agent.workspace import Limits, Workspace  # noqa: E402
from platesynth.schemas import Catalogue, DatasetMetrics, PairMetrics, Presets  # noqa: E402

TOOLS = {
    "presets", "catalogue", "scene_config", "sample_scene", "preview", "render", "compare_images", "dataset_metrics",
    "train", "predict", "evaluate_masks", "evaluate_counts", "job_status", "job_wait", "job_cancel", "jobs",
    "list_files", "read_result", "optimise",
}
TINY_NETWORK = {"channels": [8, 12, 16], "context_dilations": [2], "input_long_side": 128}
SMALL = {"preset": "high", "size": [128, 96]}


def make_server(tmp_path: Path, limits: Limits | None = None, read_only: tuple[Path, ...] = ()) -> tuple[Any, Workspace]:
    workspace = Workspace.create(tmp_path / "ws", read_only)
    return build_server(workspace, limits or Limits(max_images=120, max_image_side=512)), workspace


def call_sync(tmp_path: Path, steps: Any, **options: Any) -> Any:
    """Run ``await steps(client, workspace)`` in a fresh in-process client session."""
    server, workspace = make_server(tmp_path, **options)

    async def main() -> Any:
        async with Client(server) as client:
            return await steps(client, workspace)

    try:
        return anyio.run(main)
    finally:
        server.jobs.shutdown()


def ok(result: Any) -> dict[str, Any]:
    assert not result.is_error, result.content[0].text
    return result.structured_content


def refused(result: Any, *words: str) -> str:
    assert result.is_error, result.structured_content
    text = result.content[0].text
    assert len(text.splitlines()) == 1 and "Traceback" not in text, text
    for word in words:
        assert word in text, text
    return text


async def wait(client: Client, job: dict[str, Any], timeout: float = 120.0) -> dict[str, Any]:
    status = ok(await client.call_tool("job_wait", {"job_id": job["job_id"], "timeout_seconds": timeout}))
    assert status["state"] == "succeeded", status
    return status


# ------------------------------------------------------------------------------------------ tools and schemas


def test_tools_are_listed_with_the_models_schemas(tmp_path):
    async def steps(client, _):
        listed = {tool.name: tool for tool in (await client.list_tools()).tools}
        assert set(listed) == TOOLS
        for tool in listed.values():
            assert tool.description and tool.input_schema["type"] == "object"
            assert tool.output_schema is not None, tool.name
        assert listed["catalogue"].output_schema == Catalogue.model_json_schema()
        assert listed["presets"].output_schema == Presets.model_json_schema()
        assert listed["compare_images"].output_schema == PairMetrics.model_json_schema()
        assert listed["dataset_metrics"].output_schema == DatasetMetrics.model_json_schema()
        assert listed["render"].output_schema == JobStatus.model_json_schema()
        assert listed["train"].output_schema == JobStatus.model_json_schema()
        assert listed["optimise"].output_schema == JobStatus.model_json_schema()
        assert "network" in listed["train"].input_schema["properties"]  # the library's ModelConfig
        assert listed["render"].input_schema["required"] == ["out", "count"]
        assert listed["presets"].annotations.read_only_hint is True

        catalogue = ok(await client.call_tool("catalogue", {"section": "plaques"}))
        from platesynth.scene import parameter_table

        expected = [row for row in parameter_table() if row["name"].startswith("plaques.")]
        assert catalogue["parameters"] == json.loads(json.dumps(expected))
        names = [p["name"] for p in ok(await client.call_tool("presets", {}))["presets"]]
        assert {"high", "low", "diverse"} <= set(names)
        refused(await client.call_tool("catalogue", {"section": "nope"}), "unknown section 'nope'")

    call_sync(tmp_path, steps)


def test_scene_tools_match_the_library(tmp_path):
    from platesynth.scene import load_config, sample_scene

    async def steps(client, _):
        overrides = {"plate.format": 24, "plaques.radius_mm": [0.4, 0.6]}
        scene = ok(await client.call_tool("sample_scene", {"seed": 7, "preset": "high", "overrides": overrides}))
        assert scene == sample_scene(load_config("high", None, overrides), 7).model_dump(mode="json")
        config = ok(await client.call_tool("scene_config", {"preset": "low", "overrides": {"plate.format": 6}}))
        assert config["plate"]["format"] == 6 and config["name"] == "low"
        refused(await client.call_tool("scene_config", {"overrides": {"plaques.radius_mm": 99}}), "plaques.radius_mm")
        refused(await client.call_tool("scene_config", {"overrides": {"plaques.radius": 1}}), "did you mean plaques.radius_mm")
        refused(await client.call_tool("sample_scene", {"preset": "../high"}), "preset: Input should be 'diverse'")

    call_sync(tmp_path, steps)


def test_preview_returns_a_png_and_saves_it(tmp_path):
    async def steps(client, workspace):
        result = await client.call_tool("preview", {"count": 3, "columns": 2, "seed": 5, "save_as": "sheets/a.png",
                                                    **SMALL})
        summary = ok(result)
        image = next(c for c in result.content if c.type == "image")
        assert image.mime_type == "image/png"
        sheet = np.asarray(Image.open(io.BytesIO(base64.b64decode(image.data))))
        assert sheet.shape[1] >= 2 * 128 and sheet.shape[0] >= 2 * 96 and sheet.std() > 5
        assert summary["count"] == 3 and summary["seed"] == 5 and summary["saved_as"] == "sheets/a.png"
        assert len(summary["item_seeds"]) == 3 and summary["png_bytes"] == len(base64.b64decode(image.data))
        saved = np.asarray(Image.open(workspace.root / "sheets" / "a.png"))
        np.testing.assert_array_equal(saved, sheet)
        again = await client.call_tool("preview", {"count": 3, "columns": 2, "seed": 5, **SMALL})
        assert next(c for c in again.content if c.type == "image").data == image.data  # same seed, same pixels

    call_sync(tmp_path, steps)


# ------------------------------------------------------------------ render, metrics, train, evaluate, resources


def test_render_metrics_train_evaluate_and_resources(tmp_path, one_torch_thread):
    from typer.testing import CliRunner

    from platesynth.cli import app
    from platesynth.data.layout import read_manifest
    from platesynth.metrics import compare_pair
    from platesynth.metrics import dataset_metrics as library_dataset_metrics

    async def steps(client, workspace):
        root = workspace.root
        job = ok(await client.call_tool("render", {"out": "train", "count": 4, "seed": 3, "coco": True, **SMALL}))
        assert job["state"] in ("running", "succeeded") and job["output"] == "train" and job["arguments"]["seed"] == 3
        status = await wait(client, job)
        assert status["result"] == {**status["result"], "directory": "train", "count": 4, "rendered": 4, "failed": {}}
        assert status["done"] == status["total"] == 4
        manifest = read_manifest(root / "train")
        assert manifest.seed == 3 and manifest.size == (128, 96) and manifest.count == 4
        assert len(list((root / "train" / "images").glob("*.png"))) == 4 and (root / "train" / "annotations.coco.json").is_file()
        await wait(client, ok(await client.call_tool("render", {"out": "test", "count": 2, "seed": 9, **SMALL})))

        # metrics: the library's values, in the CLI's --json shape
        pair = ok(await client.call_tool("compare_images", {"real": "train/images/000000.png",
                                                            "synthetic": "train/images/000001.png",
                                                            "save_as": "reports/pair.json"}))
        expected = compare_pair(root / "train/images/000000.png", root / "train/images/000001.png", lpips=False,
                                frechet=False)
        assert pair == pytest.approx(expected)
        assert PairMetrics.model_validate(pair).model_extra == {}
        cli = CliRunner().invoke(app, ["metrics", "pair", str(root / "train/images/000000.png"),
                                       str(root / "train/images/000001.png"), "--json", "--no-lpips", "--no-frechet"])
        assert cli.exit_code == 0 and json.loads(cli.stdout) == pair
        report = json.loads((root / "reports" / "pair.json").read_text())
        assert report["platesynth_report"] == "compare_images" and report["result"] == pair
        assert report["arguments"]["real"] == "train/images/000000.png"

        metrics = ok(await client.call_tool("dataset_metrics", {"directory": "train", "reference": "test/images"}))
        expected = library_dataset_metrics(root / "train/images", root / "test/images", frechet=False)
        assert DatasetMetrics.model_validate(metrics).model_extra == {}
        assert metrics.pop("size") == list(expected.pop("size")) == [96, 128]
        assert metrics == pytest.approx(expected)
        assert metrics["n_images"] == 4 and metrics["n_images_reference"] == 2 and metrics["dnf"] >= 0
        wells = ok(await client.call_tool("dataset_metrics", {"directory": "train", "reference": "test",
                                                             "wells": True, "well_size": 32}))
        assert wells["n_wells"] > 0 and wells["n_wells_reference"] > 0 and wells["dnf_wells"] >= 0
        assert DatasetMetrics.model_validate(wells).model_extra == {}

        # a tiny training, then the model evaluated and applied
        job = ok(await client.call_tool("train", {
            "data": ["train"], "out": "models/tiny", "epochs": 1, "steps_per_epoch": 2, "batch_size": 2,
            "patch": [64, 64], "val_fraction": 0.25, "tune_thresholds": False, "device": "cpu",
            "network": TINY_NETWORK,
        }))
        status = await wait(client, job)
        assert status["result"]["model_dir"] == "models/tiny" and status["result"]["epochs"] == 1
        assert status["total"] == 2 and status["done"] == 2
        assert json.loads((root / "models/tiny/config.json").read_text())["complete"] is True

        masks = ok(await client.call_tool("evaluate_masks", {"model": "models/tiny", "data": "test", "tau": [0.5],
                                                            "device": "cpu", "save_as": "reports/masks.json"}))
        assert masks["n_images"] == 2 and set(masks["wells"]) == {"0.5"}
        assert masks["wells"]["0.5"]["n_true"] > 0 and 0 <= (masks["wells"]["0.5"]["ap_mean"] or 0) <= 1
        counts = ok(await client.call_tool("evaluate_counts", {"model": "models/tiny", "images": "test/images",
                                                              "counts": "test/counts.csv", "device": "cpu"}))
        n_wells = sum(1 for _ in open(root / "test/counts.csv")) - 1
        assert len(counts["wells"]) == n_wells and counts["n_images"] == 2
        predicted = ok(await client.call_tool("predict", {"images": ["test/images/000000.png"], "model": "models/tiny",
                                                         "out": "pred", "device": "cpu"}))
        assert predicted["output"] == "pred" and predicted["counts_csv"] == "pred/counts.csv" and predicted["n_images"] == 1
        rows = (root / "pred/counts.csv").read_text().splitlines()
        assert rows[0] == "image,row,col,well,count" and len(predicted["wells"]) == len(rows) - 1  # untrained: few

        # resources: the workspace's datasets, models and reports
        uris = {str(r.uri) for r in (await client.list_resources()).resources}
        assert {"platesynth://datasets", "platesynth://models", "platesynth://reports", "platesynth://dataset/train",
                "platesynth://model/models/tiny", "platesynth://report/reports/pair.json"} <= uris
        dataset = json.loads((await client.read_resource("platesynth://dataset/train")).contents[0].text)
        assert dataset["n_items"] == 4 and dataset["manifest"]["seed"] == 3
        model = json.loads((await client.read_resource("platesynth://model/models/tiny")).contents[0].text)
        assert model["config"]["complete"] is True and model["train"]["train"]["epochs"] == 1
        index = json.loads((await client.read_resource("platesynth://reports")).contents[0].text)
        assert {r["path"] for r in index["reports"]} == {"reports/pair.json", "reports/masks.json"}

        files = ok(await client.call_tool("list_files", {}))
        kinds = {e["path"]: e["kind"] for e in files["entries"]}
        assert kinds["train"] == "dataset" and kinds["pred"] == "prediction" and kinds["models"] is None
        text = await client.call_tool("read_result", {"path": "test/counts.csv"})
        assert ok(text)["media_type"] == "text/csv" and text.content[0].text.startswith("image,row,col,well,count")
        image = await client.call_tool("read_result", {"path": "test/images/000001.png"})
        assert ok(image)["media_type"] == "image/png" and image.content[0].type == "image"

    call_sync(tmp_path, steps)


# ------------------------------------------------------------------------------------------------------- jobs


def test_job_progress_timeout_cancel_and_resume(tmp_path):
    big = {"count": 100, "seed": 1, "preset": "high", "size": [256, 192]}

    async def steps(client, workspace):
        job = ok(await client.call_tool("render", {"out": "big", **big}))
        progress: list[tuple[float, float | None, str | None]] = []

        async def on_progress(done: float, total: float | None, message: str | None) -> None:
            progress.append((done, total, message))

        started = time.monotonic()
        status = ok(await client.call_tool("job_wait", {"job_id": job["job_id"], "timeout_seconds": 0.8},
                                           progress_callback=on_progress))
        assert status["state"] == "running" and 0.7 < time.monotonic() - started < 15
        assert progress and progress[-1][1] == 100 and all(p[2] for p in progress)
        # a second job into the same folder, or over the concurrency limit, is refused while this one runs
        refused(await client.call_tool("render", {"out": "other", **big}), "limit is 1", "--max-jobs")
        for _ in range(600):  # a slow machine (or numba compiling) may not have finished an image yet
            polled = ok(await client.call_tool("job_status", {"job_id": job["job_id"]}))
            if polled["done"]:
                break
            await anyio.sleep(0.1)
        assert polled["state"] == "running" and 0 < polled["done"] < 100

        cancelled = ok(await client.call_tool("job_cancel", {"job_id": job["job_id"]}))
        assert cancelled["state"] == "cancelled" and cancelled["cancel_requested"] and "resumes" in cancelled["error"]
        kept = len(list((workspace.root / "big" / "images").glob("*.png")))
        assert 0 < kept < 100

        timed = ok(await client.call_tool("render", {"out": "big", "time_limit_seconds": 0.5, **big}))
        timed = ok(await client.call_tool("job_wait", {"job_id": timed["job_id"], "timeout_seconds": 30}))
        assert timed["state"] == "timed_out" and "time limit of 0.5 s" in timed["error"]
        resumed = len(list((workspace.root / "big" / "images").glob("*.png")))
        assert kept <= resumed < 100  # resumed where the cancelled run stopped

        listed = ok(await client.call_tool("jobs", {}))["jobs"]
        assert [j["state"] for j in listed] == ["cancelled", "timed_out"]
        refused(await client.call_tool("job_status", {"job_id": "nope"}), "no job 'nope'")

    call_sync(tmp_path, steps, limits=Limits(max_images=100, max_image_side=512, max_jobs=1))


def test_job_time_limit_of_the_server(tmp_path):
    async def steps(client, _):
        job = ok(await client.call_tool("render", {"out": "d", "count": 60, "size": [256, 192]}))
        assert job["time_limit_seconds"] == 0.3
        status = ok(await client.call_tool("job_wait", {"job_id": job["job_id"], "timeout_seconds": 30}))
        assert status["state"] == "timed_out" and "--max-job-seconds" in status["error"]

    call_sync(tmp_path, steps, limits=Limits(max_job_seconds=0.3))


def test_optimise_job_and_its_best_configuration(tmp_path, monkeypatch, one_torch_thread):
    """A tiny optimisation over two trials against shared photos read from a read-only root (skipped without them)."""
    from conftest import shared_path

    plates = shared_path("data", "plaque12", "plates")
    weights = shared_path("weights", "alexnet_features-7be5be79.pth")
    monkeypatch.setenv("PLATESYNTH_WEIGHTS_DIR", str(weights.parent))
    monkeypatch.setenv("PLATESYNTH_OFFLINE", "1")
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch-home"))
    photos = tmp_path / "photos"
    photos.mkdir()
    for name in ("Brisbane_plate2.jpg", "Brisbane_plate3.jpg", "PR8_plate1.jpg", "PR8_plate2.jpg"):
        with Image.open(plates / name) as image:
            image.convert("RGB").resize((152, 118)).save(photos / f"{name[:-4]}.png")

    async def steps(client, workspace):
        job = ok(await client.call_tool("optimise", {
            "reference": str(photos), "out": "opt", "trials": 2, "preset": "low", "count": 2, "size": [128, 100],
            "eval_count": 2, "seed": 5, "weights": {"fid_inception": 0},
        }))
        assert job["kind"] == "optimise" and job["arguments"]["trials"] == 2
        status = await wait(client, job, timeout=300)
        result = status["result"]
        assert result["out"] == "opt" and result["best_config"] == "opt/best.yaml" and result["n_trials"] == 2
        assert set(result["evaluation"]) == {"fit", "check"} and result["start"] == "low"
        assert {"start", "best"} <= set(result["evaluation"]["check"])
        assert (workspace.root / "opt" / "report.json").is_file()
        # the best configuration feeds the other tools
        ok(await client.call_tool("preview", {"config": result["best_config"], "count": 1, "size": [128, 100]}))
        report = json.loads((await client.read_resource("platesynth://report/opt")).contents[0].text)
        assert report["best_trial"] == result["best_trial"]
        refused(await client.call_tool("optimise", {"reference": "../photos", "out": "o2", "trials": 1}), "'..'")

    call_sync(tmp_path, steps, read_only=(photos,))


# ------------------------------------------------------------------------------------------------ guardrails


def test_every_path_escape_is_refused(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "secret.json").write_text('{"secret": 1}')
    (outside / "photo.png").write_bytes(b"")
    readable = tmp_path / "photos"
    readable.mkdir()
    Image.fromarray(np.random.default_rng(0).integers(0, 255, (96, 128, 3), dtype=np.uint8)).save(readable / "real.png")

    async def steps(client, workspace):
        root = workspace.root
        (root / "link-out").symlink_to(outside, target_is_directory=True)
        (root / "secret-link.json").symlink_to(outside / "secret.json")
        (root / "inside").mkdir()
        (root / "inside" / "ok.json").write_text("{}")
        (root / "link-in").symlink_to(root / "inside", target_is_directory=True)
        attempts = [
            ("render", {"out": "../escaped", "count": 1, **SMALL}, "'..' is not allowed"),
            ("render", {"out": "a/../../escaped", "count": 1, **SMALL}, "'..' is not allowed"),
            ("render", {"out": str(tmp_path / "escaped"), "count": 1, **SMALL}, "absolute paths are not allowed"),
            ("render", {"out": "link-out/escaped", "count": 1, **SMALL}, "leads out of the workspace"),
            ("render", {"out": ".", "count": 1, **SMALL}, "the workspace itself"),
            ("render", {"out": "d", "count": 1, "config": "../outside/c.yaml", **SMALL}, "'..' is not allowed"),
            ("read_result", {"path": "../outside/secret.json"}, "'..' is not allowed"),
            ("read_result", {"path": str(outside / "secret.json")}, "absolute paths are allowed only inside a read-only root"),
            ("read_result", {"path": "secret-link.json"}, "leads out of the workspace"),
            ("read_result", {"path": "link-out/secret.json"}, "leads out of the workspace"),
            ("read_result", {"path": "~/.bashrc"}, "absolute paths"),
            ("read_result", {"path": "a\x00b"}, "NUL"),
            ("list_files", {"folder": ".."}, "'..' is not allowed"),
            ("list_files", {"folder": "/"}, "absolute paths"),
            ("list_files", {"folder": "link-out"}, "leads out of the workspace"),
            ("compare_images", {"real": str(outside / "photo.png"), "synthetic": str(readable / "real.png")}, "read-only root"),
            ("dataset_metrics", {"directory": "..\\outside"}, "'..' is not allowed"),
            ("preview", {"save_as": str(readable / "sheet.png"), **SMALL}, "absolute paths are not allowed for outputs"),
            ("compare_images", {"real": str(readable / "real.png"), "synthetic": str(readable / "real.png"),
                                "save_as": str(readable / "r.json")}, "absolute paths are not allowed for outputs"),
            ("train", {"data": ["link-out"], "out": "m"}, "leads out of the workspace"),
            ("predict", {"images": ["../outside/photo.png"], "model": "m", "out": "p"}, "'..' is not allowed"),
        ]
        for name, arguments, words in attempts:
            refused(await client.call_tool(name, arguments), words)
        with pytest.raises(Exception, match="security|not a dataset|out of the workspace"):
            await client.read_resource("platesynth://dataset/link-out")
        # reading from a read-only root by absolute path, and through a link that stays inside, is allowed
        same = ok(await client.call_tool("compare_images", {"real": str(readable / "real.png"),
                                                           "synthetic": str(readable / "real.png")}))
        assert same["mse"] == 0 and same["psnr"] is None  # identical: infinite PSNR is null in JSON
        assert ok(await client.call_tool("read_result", {"path": "link-in/ok.json"}))["text"] == "{}"
        listing = ok(await client.call_tool("list_files", {}))
        assert "link-out" not in {e["path"] for e in listing["entries"]}

    call_sync(tmp_path, steps, read_only=(readable,))
    assert sorted(p.name for p in (tmp_path / "outside").iterdir()) == ["photo.png", "secret.json"]
    assert not (tmp_path / "escaped").exists() and sorted(p.name for p in readable.iterdir()) == ["real.png"]


def test_a_read_only_root_cannot_hold_the_workspace(tmp_path):
    from platesynth.agent.workspace import GuardrailError

    with pytest.raises(GuardrailError, match="may not contain or lie inside"):
        Workspace.create(tmp_path / "ws", (tmp_path,))


def test_limits_are_enforced(tmp_path):
    limits = Limits(max_images=3, max_image_side=200, max_train_steps=5, max_read_bytes=100)

    async def steps(client, workspace):
        refused(await client.call_tool("render", {"out": "d", "count": 4, **SMALL}), "4 images", "limit of 3", "--max-images")
        refused(await client.call_tool("preview", {"count": 4, **SMALL}), "--max-images")
        refused(await client.call_tool("render", {"out": "d", "count": 1, "size": [256, 96]}), "256x96", "--max-image-side")
        refused(await client.call_tool("preview", {"count": 1, "size": [96, 201]}), "--max-image-side")
        await wait(client, ok(await client.call_tool("render", {"out": "d", "count": 3, **SMALL})))
        refused(await client.call_tool("train", {"data": ["d"], "out": "m", "epochs": 2, "steps_per_epoch": 3}),
                "6 optimiser steps", "--max-train-steps")
        refused(await client.call_tool("read_result", {"path": "d/manifest.json"}), "--max-read-bytes")
        (workspace.root / "more").mkdir()
        for i in range(4):
            (workspace.root / "more" / f"{i}.png").write_bytes((workspace.root / "d/images/000000.png").read_bytes())
        refused(await client.call_tool("dataset_metrics", {"directory": "more"}), "--max-images")
        refused(await client.call_tool("predict", {"images": ["more"], "model": "m", "out": "p"}), "--max-images")
        refused(await client.call_tool("job_wait", {"job_id": "x", "timeout_seconds": 601}), "timeout_seconds")

    call_sync(tmp_path, steps, limits=limits)


class _Payload:
    """Unpickling this would create the file ``path``: what a crafted weights file could do instead."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)

    def __reduce__(self):
        return open, (self.path, "w")


def test_errors_are_one_line_tool_errors(tmp_path):
    async def steps(client, workspace):
        refused(await client.call_tool("render", {"out": "d", "count": "many"}), "invalid arguments for render", "count")
        refused(await client.call_tool("render", {"out": "d"}), "count: Field required")
        refused(await client.call_tool("render", {"out": "d", "count": 1, "size": [0, 10]}), "size")
        refused(await client.call_tool("dataset_metrics", {"directory": "nothing"}), "nothing")
        refused(await client.call_tool("dataset_metrics", {"directory": "d", "model": "m"}), "model is used by wells only")
        refused(await client.call_tool("dataset_metrics", {"directory": "d", "wells": True}), "wells needs a reference")
        refused(await client.call_tool("evaluate_masks", {"model": "nowhere", "data": "nothing"}))
        # a model whose weights would run code when unpickled: refused, the payload never runs
        import shutil

        import torch

        shutil.copytree(Path(__file__).resolve().parents[1] / "models" / "plaque12", workspace.root / "m")
        torch.save(_Payload(workspace.root / "PWNED"), workspace.root / "m" / "weights.pt")
        refused(await client.call_tool("evaluate_masks", {"model": "m", "data": "d"}))  # no such dataset yet
        await wait(client, ok(await client.call_tool("render", {"out": "d", "count": 1, **SMALL})))
        for name, arguments in (("evaluate_masks", {"model": "m", "data": "d"}),
                                ("predict", {"images": ["d/images"], "model": "m", "out": "p"})):
            refused(await client.call_tool(name, arguments), "m/weights.pt: refused, not a file of tensors and plain data only")
        assert not (workspace.root / "PWNED").exists() and not (workspace.root / "p").exists()
        (workspace.root / "junk").mkdir()
        (workspace.root / "junk" / "mine.txt").write_text("not platesynth's")
        refused(await client.call_tool("render", {"out": "junk", "count": 1, **SMALL}), "choose another output")
        assert (workspace.root / "junk" / "mine.txt").read_text() == "not platesynth's"
        refused(await client.call_tool("preview", {"save_as": "x.jpg", **SMALL}), "ending in .png")
        refused(await client.call_tool("no_such_tool", {}))

    call_sync(tmp_path, steps)


# ------------------------------------------------------------------------------------------------------ stdio


def test_stdio_subprocess_speaks_only_protocol_on_stdout(tmp_path):
    """The real command over stdio: every line on stdout is a JSON-RPC message, and a render job runs."""
    messages = [
        {"jsonrpc": "2.0", "id": 1, "method": "initialize", "params": {
            "protocolVersion": "2025-06-18", "capabilities": {}, "clientInfo": {"name": "test", "version": "0"}}},
        {"jsonrpc": "2.0", "method": "notifications/initialized"},
        {"jsonrpc": "2.0", "id": 2, "method": "tools/list"},
        {"jsonrpc": "2.0", "id": 3, "method": "tools/call", "params": {"name": "render", "arguments": {
            "out": "d", "count": 2, "size": [96, 72], "preset": "high"}}},
        {"jsonrpc": "2.0", "id": 4, "method": "tools/call", "params": {"name": "render", "arguments": {
            "out": "../x", "count": 1}}},
        {"jsonrpc": "2.0", "id": 5, "method": "tools/call", "params": {"name": "jobs", "arguments": {}}},
    ]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(
        [sys.executable, "-c", "from platesynth.cli import main; main()", "mcp", "--workspace", str(tmp_path / "ws")],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
    )
    replies: dict[int, dict[str, Any]] = {}
    lines: list[bytes] = []
    try:
        for message in messages:
            process.stdin.write((json.dumps(message) + "\n").encode())
            process.stdin.flush()
            if "id" not in message:
                continue
            while message["id"] not in replies:  # one request at a time, as a client would
                line = process.stdout.readline()
                assert line, process.stderr.read().decode()
                lines.append(line)
                data = json.loads(line)
                assert data["jsonrpc"] == "2.0"
                if "id" in data:
                    replies[data["id"]] = data
        job_id = replies[3]["result"]["structuredContent"]["job_id"]
        request = {"jsonrpc": "2.0", "id": 6, "method": "tools/call", "params": {
            "name": "job_wait", "arguments": {"job_id": job_id, "timeout_seconds": 60}}}
        process.stdin.write((json.dumps(request) + "\n").encode())
        process.stdin.flush()
        while 6 not in replies:
            line = process.stdout.readline()
            assert line, process.stderr.read().decode()
            lines.append(line)
            data = json.loads(line)
            if "id" in data:
                replies[data["id"]] = data
        process.stdin.close()
        rest, errors = process.stdout.read(), process.stderr.read()
        assert process.wait(timeout=30) == 0, errors.decode()
    finally:
        if process.poll() is None:
            process.kill()
    assert rest.strip() == b"", rest  # nothing after the last reply
    assert all(json.loads(line)["jsonrpc"] == "2.0" for line in lines)
    assert {tool["name"] for tool in replies[2]["result"]["tools"]} == TOOLS
    assert replies[4]["result"]["isError"] is True and "'..' is not allowed" in replies[4]["result"]["content"][0]["text"]
    assert replies[6]["result"]["structuredContent"]["state"] == "succeeded"
    assert len(list((tmp_path / "ws" / "d" / "images").glob("*.png"))) == 2
    assert b"platesynth MCP server over stdio" in errors  # people's messages go to stderr


def test_job_manager_failures_and_overlapping_outputs(tmp_path):
    import threading

    from platesynth.agent.jobs import JobManager
    from platesynth.agent.workspace import GuardrailError
    from platesynth.cli._common import error_message
    from platesynth.errors import DatasetError

    manager = JobManager(Limits(max_jobs=2), error_message, tmp_path)
    release = threading.Event()

    def slow(report):
        while not release.wait(0.01):
            report(0, 1, "waiting")
        raise DatasetError(f"{tmp_path}/data: broken\nsecond line")

    first = manager.start("render", tmp_path / "a", "a", {}, slow)
    for clash in (tmp_path / "a", tmp_path / "a" / "inner", tmp_path):
        with pytest.raises(GuardrailError, match=f"job {first.job_id} is writing there"):
            manager.start("render", clash, "x", {}, slow)
    second = manager.start("train", tmp_path / "b", "b", {}, slow)
    with pytest.raises(GuardrailError, match="2 job"):
        manager.start("render", tmp_path / "c", "c", {}, slow)
    release.set()
    for job_id in (first.job_id, second.job_id):
        job = manager.get(job_id)
        assert job.finished.wait(10)
        assert job.status().state == "failed" and job.status().error == "data: broken second line"


def test_a_render_with_a_failed_image_is_a_failed_job(tmp_path, monkeypatch):
    import platesynth.data.batch as batch
    from platesynth.errors import RenderError

    original = batch.render_item

    def flaky(manifest, index):
        if index == 1:
            raise RenderError("Blender said: out of GPU memory\nsecond line of the log")
        return original(manifest, index)

    monkeypatch.setattr(batch, "render_item", flaky)

    async def steps(client, workspace):
        job = ok(await client.call_tool("render", {"out": "d", "count": 3, **SMALL}))
        status = ok(await client.call_tool("job_wait", {"job_id": job["job_id"], "timeout_seconds": 60}))
        assert status["state"] == "failed" and status["result"] is None
        assert status["error"].startswith("1 of 3 images failed to render (first: 000001: RenderError: Blender said")
        assert "\n" not in status["error"] and "retries the failed ones" in status["error"]
        assert len(list((workspace.root / "d" / "images").glob("*.png"))) == 2
        monkeypatch.setattr(batch, "render_item", original)
        again = await wait(client, ok(await client.call_tool("render", {"out": "d", "count": 3, **SMALL})))
        assert again["result"]["rendered"] == 1 and again["result"]["skipped"] == 2

    call_sync(tmp_path, steps)


def test_the_mcp_command_refuses_bad_options_in_one_line(tmp_path):
    from typer.testing import CliRunner

    from platesynth.cli import app

    runner = CliRunner()
    for options, words in (
        (["--transport", "tcp"], "--transport 'tcp': choose stdio or http"),
        (["--read-only-root", str(tmp_path / "missing")], "a read-only root must be an existing folder"),
        (["--read-only-root", str(tmp_path)], "may not contain or lie inside the workspace"),
        (["--max-jobs", "0"], "limit max_jobs must be >= 1"),
        (["--max-job-seconds", "0"], "limit max_job_seconds must be > 0"),
    ):
        result = runner.invoke(app, ["mcp", "--workspace", str(tmp_path / "ws"), *options])
        assert result.exit_code == 1 and result.stdout == "", (options, result.output)
        assert len(result.stderr.strip().splitlines()) == 1 and words in result.stderr, result.stderr
        assert not (tmp_path / "ws").exists()  # nothing created by a refused command
