"""The metric-guided loop of platesynth, driven through its MCP tools alone (no language model).

Starts ``platesynth mcp`` over stdio as an MCP client would, then: looks at a preset (``preview``), compares
candidate parameters with a reference photo (``render`` + ``compare_images``), keeps the closest, renders a
dataset with them, measures it against the reference (``dataset_metrics``), trains a model briefly (``train``) and
evaluates it (``evaluate_masks``, ``evaluate_counts``). Every step is a tool call; the script never touches the
workspace itself.

Without ``--photo`` the reference is a stand-in rendered by the server from hidden parameters (a stain of another
hue and density), so the loop should find its way back to them; with ``--photo`` it is a real plate photo, read
from a read-only root.

    python examples/mcp_loop.py --workspace /tmp/loop
    python examples/mcp_loop.py --workspace /tmp/loop --photo ../shared/data/plaque12/plates/Brisbane_plate2.jpg

``tests/test_agent_example.py`` runs it as an end-to-end test.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

import anyio
from mcp import Client, StdioServerParameters

SIZE = [160, 120]
"""Size of every render (small: the loop runs in seconds on a laptop)."""
HIDDEN = {"stain.hue_deg": 300.0, "stain.density": 1.35}
"""The stand-in reference's stain, which the loop does not know."""
CANDIDATES = [
    {"stain.hue_deg": 262.0, "stain.density": 1.0},
    {"stain.hue_deg": 280.0, "stain.density": 1.2},
    {"stain.hue_deg": 300.0, "stain.density": 1.0},
    {"stain.hue_deg": 300.0, "stain.density": 1.35},
]
"""Parameter changes the loop tries over the preset (a real search would use the `optimise` tool)."""
TINY_NETWORK = {"channels": [8, 12, 16], "context_dilations": [2], "input_long_side": 128}


class ToolFailed(RuntimeError):
    """A tool returned an error (its one-line message)."""


async def call(client: Client, name: str, arguments: dict[str, Any], **options: Any) -> dict[str, Any]:
    """Call a tool and return its structured output, or raise :class:`ToolFailed` with the tool's one line."""
    result = await client.call_tool(name, arguments, **options)
    if result.is_error:
        raise ToolFailed(f"{name}: {result.content[0].text}")
    return result.structured_content


async def run_job(client: Client, name: str, arguments: dict[str, Any]) -> dict[str, Any]:
    """Start a job, wait for it with progress printed, and return its result."""
    job = await call(client, name, arguments)
    print(f"  job {job['job_id']} ({name} -> {job['output']}) started")
    last = [""]

    async def progress(done: float, total: float | None, message: str | None) -> None:
        if message and message != last[0]:
            last[0] = message
            print(f"    progress {done:g}/{total:g}: {message}" if total else f"    progress: {message}")

    while True:
        status = await call(client, "job_wait", {"job_id": job["job_id"], "timeout_seconds": 30},
                            progress_callback=progress)
        if status["state"] != "running":
            break
    if status["state"] != "succeeded":
        raise ToolFailed(f"{name} job {status['state']}: {status['error']}")
    print(f"  job {job['job_id']} succeeded in {status['seconds']:.1f} s")
    return status["result"]


async def loop(workspace: Path, photo: Path | None) -> dict[str, Any]:
    """The loop; returns what it found (also printed)."""
    args = ["-c", "from platesynth.cli import main; main()", "mcp", "--workspace", str(workspace),
            "--max-images", "50", "--max-image-side", "2048", "--max-job-seconds", "600"]
    if photo is not None:
        args += ["--read-only-root", str(photo.parent.resolve())]
    # the server gets this environment (PLATESYNTH_WEIGHTS_DIR, PLATESYNTH_MEMORY_LIMIT, ...); by default an MCP
    # client passes only a few variables such as PATH and HOME
    server = StdioServerParameters(command=sys.executable, args=args, env=dict(os.environ))
    async with Client(server) as client:
        tools = await client.list_tools()
        print(f"server: {len(tools.tools)} tools: {', '.join(t.name for t in tools.tools)}")
        presets = await call(client, "presets", {})
        print(f"presets: {', '.join(p['name'] for p in presets['presets'])}")

        print("1. preview the starting preset")
        sheet = await call(client, "preview", {"preset": "high", "count": 4, "columns": 2, "size": SIZE, "seed": 1,
                                               "save_as": "preview-high.png"})
        print(f"  {sheet['count']} scenes of '{sheet['config_name']}', seed {sheet['seed']} -> {sheet['saved_as']} "
              f"({sheet['png_bytes']} bytes of PNG)")

        print("2. the reference photo")
        if photo is None:
            await run_job(client, "render", {"out": "reference", "count": 1, "seed": 7, "preset": "high",
                                             "overrides": HIDDEN, "size": SIZE})
            reference, reference_folder = "reference/images/000000.png", "reference/images"
            print(f"  stand-in reference rendered from hidden parameters -> {reference}")
        else:
            reference, reference_folder = str(photo.resolve()), str(photo.parent.resolve())
            print(f"  {reference} (read-only root)")

        print("3. compare candidate parameters with the reference")
        scores = []
        for number, overrides in enumerate(CANDIDATES):
            out = f"candidates/{number}"
            await run_job(client, "render", {"out": out, "count": 1, "seed": 7, "preset": "high",
                                             "overrides": overrides, "size": SIZE})
            pair = await call(client, "compare_images", {"real": reference, "synthetic": f"{out}/images/000000.png",
                                                         "resize": True, "save_as": f"reports/candidate-{number}.json"})
            score = (1 - pair["ssim"]) + pair["dnf"] + pair["nrmse"]
            scores.append((score, number))
            print(f"  candidate {number} {json.dumps(overrides)}: ssim {pair['ssim']:.3f}, nrmse {pair['nrmse']:.3f}, "
                  f"dnf {pair['dnf']:.3f} -> score {score:.3f}")
        best_score, best = min(scores)
        chosen = CANDIDATES[best]
        print(f"  closest: candidate {best} {json.dumps(chosen)} (score {best_score:.3f})")

        print("4. render a dataset with the chosen parameters and measure it")
        await run_job(client, "render", {"out": "datasets/train", "count": 6, "seed": 11, "preset": "high",
                                         "overrides": chosen, "size": SIZE, "coco": True})
        await run_job(client, "render", {"out": "datasets/test", "count": 2, "seed": 12, "preset": "high",
                                         "overrides": chosen, "size": SIZE})
        metrics = await call(client, "dataset_metrics", {"directory": "datasets/train", "reference": reference_folder,
                                                         "save_as": "reports/train-metrics.json"})
        print(f"  {metrics['n_images']} images: entropy {metrics['entropy']:.3f} bits, brightness variability "
              f"{metrics['brightness_variability']:.4f}, Nf {metrics['nf_mean']:.3f}; reference Nf "
              f"{metrics['nf_mean_reference']:.3f}, dNf {metrics['dnf']:.3f}")

        print("5. train briefly and evaluate")
        trained = await run_job(client, "train", {
            "data": ["datasets/train"], "out": "models/tiny", "epochs": 1, "steps_per_epoch": 3, "batch_size": 2,
            "patch": [64, 64], "val_fraction": 0.2, "tune_thresholds": False, "device": "cpu", "seed": 0,
            "network": TINY_NETWORK,
        })
        print(f"  model {trained['model_dir']}: {trained['epochs']} epoch(s), best validation loss "
              f"{trained['best_val_loss']:.4f}")
        masks = await call(client, "evaluate_masks", {"model": trained["model_dir"], "data": "datasets/test",
                                                      "tau": [0.5], "device": "cpu"})
        for name in ("wells", "plaques"):
            row = masks[name]["0.5"]
            ap = "n/a" if row["ap_mean"] is None else f"{row['ap_mean']:.3f}"
            print(f"  {name}: AP@0.5 {ap} ({row['n_true']} true, {row['n_pred']} predicted)")
        counts = await call(client, "evaluate_counts", {"model": trained["model_dir"], "images": "datasets/test/images",
                                                        "counts": "datasets/test/counts.csv", "device": "cpu"})
        mae = "n/a" if counts["mae"] is None else f"{counts['mae']:.2f}"
        print(f"  plaques per well: MAE {mae} over {counts['n_wells']} wells of {counts['n_images']} images "
              "(a model this small and brief counts nothing yet; train longer for real use)")

        resources = await client.list_resources()
        print("resources: " + ", ".join(str(r.uri) for r in resources.resources))
        return {"chosen": chosen, "candidate": best, "train_metrics": metrics, "model": trained["model_dir"]}


def main(argv: list[str] | None = None) -> int:
    """Run the loop; exit code 0 when every tool call succeeded."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workspace", type=Path, help="the server's workspace (default: a temporary folder)")
    parser.add_argument("--photo", type=Path, help="a real plate photo to match (default: a rendered stand-in)")
    options = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as temporary:
        workspace = options.workspace or Path(temporary) / "workspace"
        try:
            found = anyio.run(loop, workspace, options.photo)
        except ToolFailed as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 1
    if options.photo is None:
        recovered = found["chosen"] == HIDDEN
        print(f"the loop {'recovered' if recovered else 'did not recover'} the hidden stain {json.dumps(HIDDEN)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
