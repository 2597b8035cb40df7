"""Shared fixtures. ``../shared`` (real photos, weights) is used by path and skipped clearly where absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

SHARED = Path(os.environ.get("PLATESYNTH_SHARED", Path(__file__).resolve().parents[1].parent / "shared"))


def shared_path(*parts: str) -> Path:
    """Path under ``../shared``; skips the calling test with a clear message where it is absent."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"{path} not found: this test needs the developers' ../shared material (set PLATESYNTH_SHARED)")
    return path


@pytest.fixture
def shared():
    """Callable fixture: ``shared('weights', 'alexnet_features-7be5be79.pth')``."""
    return shared_path


@pytest.fixture
def offline_weights(shared, monkeypatch, tmp_path):
    """The developers' AlexNet weights, no download, an empty torch hub cache (so no Inception weights)."""
    monkeypatch.setenv("PLATESYNTH_WEIGHTS_DIR", str(shared("weights")))
    monkeypatch.setenv("PLATESYNTH_OFFLINE", "1")
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch-home"))
    monkeypatch.delenv("PLATESYNTH_FID_WEIGHTS", raising=False)


@pytest.fixture(scope="module")
def one_torch_thread():
    """Several torch threads on a busy 2-core machine spin-wait each other (tens of times slower); tests use one."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
