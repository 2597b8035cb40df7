"""examples/mcp_loop.py end to end: the metric-guided loop through the MCP tools alone, over stdio."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mcp")

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "mcp_loop.py"


def test_the_example_client_runs_the_loop(tmp_path):
    workspace = tmp_path / "workspace"
    result = subprocess.run([sys.executable, str(EXAMPLE), "--workspace", str(workspace)], capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    out = result.stdout
    for step in ("1. preview", "2. the reference photo", "3. compare candidate", "4. render a dataset", "5. train briefly"):
        assert step in out
    assert "the loop recovered the hidden stain" in out
    assert "candidate 3" in out and "ssim 1.000, nrmse 0.000, dnf 0.000" in out  # the hidden parameters, same seed
    assert "platesynth://model/models/tiny" in out and "platesynth://dataset/datasets/train" in out
    # everything it made lies in the workspace, written by the server
    assert (workspace / "preview-high.png").is_file() and (workspace / "models/tiny/config.json").is_file()
    assert len(list((workspace / "datasets/train/images").glob("*.png"))) == 6
    assert "Traceback" not in result.stderr
