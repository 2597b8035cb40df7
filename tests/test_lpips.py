"""LPIPS v0.1: the published values on the upstream example images, and the module's behaviour."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from platesynth.errors import ParameterError, ShapeMismatchError, WeightsNotFoundError
from platesynth.io import read_image
from platesynth.metrics import lpips as lpips_module
from platesynth.metrics.lpips import LPIPS, lpips_distance


@pytest.fixture
def examples(shared):
    return {name: read_image(shared("data", "lpips_examples", f"{name}.png")) for name in ("ex_ref", "ex_p0", "ex_p1")}


@pytest.fixture
def alexnet_weights(shared):
    return shared("weights", "alexnet_features-7be5be79.pth")


def test_published_lpips_alex_values(examples, alexnet_weights):
    # Published LPIPS v0.1 (alex) values of the original repository's example images.
    d0 = lpips_distance(examples["ex_ref"], examples["ex_p0"], backbone_weights=alexnet_weights)
    d1 = lpips_distance(examples["ex_ref"], examples["ex_p1"], backbone_weights=alexnet_weights)
    assert d0 == pytest.approx(0.722, abs=1e-3)
    assert d1 == pytest.approx(0.138, abs=1e-3)


def test_weights_from_environment(examples, shared, monkeypatch):
    monkeypatch.setenv("PLATESYNTH_WEIGHTS_DIR", str(shared("weights")))
    monkeypatch.setenv("PLATESYNTH_OFFLINE", "1")
    assert lpips_distance(examples["ex_ref"], examples["ex_p1"]) == pytest.approx(0.138, abs=1e-3)


def test_identity_symmetry_and_ordering(examples, alexnet_weights, shared):
    ref, p0, p1 = examples["ex_ref"], examples["ex_p0"], examples["ex_p1"]
    assert lpips_distance(ref, ref, backbone_weights=alexnet_weights) == 0.0
    assert lpips_distance(p0, ref, backbone_weights=alexnet_weights) == pytest.approx(
        lpips_distance(ref, p0, backbone_weights=alexnet_weights), abs=1e-6)
    squeeze_weights = shared("weights", "squeezenet1_1_features-b8a52dc0.pth")
    s0 = lpips_distance(ref, p0, net="squeeze", backbone_weights=squeeze_weights)
    s1 = lpips_distance(ref, p1, net="squeeze", backbone_weights=squeeze_weights)
    assert 0 < s1 < s0 < 1  # both networks judge p1 closer to the reference, as people did


def test_module_batches_and_gradients(examples, alexnet_weights):
    model = LPIPS("alex", alexnet_weights)

    def to_tensor(image):
        return torch.from_numpy(image.astype(np.float32) / 127.5 - 1).permute(2, 0, 1)

    ref = torch.stack([to_tensor(examples["ex_ref"])] * 2)
    others = torch.stack([to_tensor(examples["ex_p0"]), to_tensor(examples["ex_p1"])]).requires_grad_(True)
    distances = model(ref, others)
    expected = [lpips_distance(examples["ex_ref"], examples[n], backbone_weights=alexnet_weights)
                for n in ("ex_p0", "ex_p1")]
    np.testing.assert_allclose(distances.detach().numpy(), expected, atol=1e-6)
    distances.sum().backward()
    assert others.grad is not None and others.grad.abs().sum() > 0
    assert not any(p.requires_grad for p in model.parameters())


def test_grayscale_input_equals_repeated_rgb(examples, alexnet_weights):
    gray = examples["ex_ref"][..., 1]
    rgb = np.repeat(gray[..., None], 3, axis=-1)
    assert lpips_distance(gray, examples["ex_p0"], backbone_weights=alexnet_weights) == pytest.approx(
        lpips_distance(rgb, examples["ex_p0"], backbone_weights=alexnet_weights), abs=1e-7)


def test_shape_mismatch(examples, alexnet_weights):
    with pytest.raises(ShapeMismatchError, match=r"\(64, 64\) vs \(32, 64\)"):
        lpips_distance(examples["ex_ref"], examples["ex_p0"][:32], backbone_weights=alexnet_weights)


def test_unknown_network(examples):
    with pytest.raises(ParameterError, match="unknown LPIPS network 'vgg'"):
        lpips_distance(examples["ex_ref"], examples["ex_p0"], net="vgg")


def test_linear_weights_are_hash_checked(monkeypatch, alexnet_weights):
    backbone, file_name, _ = lpips_module.LPIPS_NETS["alex"]
    monkeypatch.setitem(lpips_module.LPIPS_NETS, "alex", (backbone, file_name, "0" * 64))
    with pytest.raises(WeightsNotFoundError, match="alex.pth: sha256 does not match"):
        LPIPS("alex", alexnet_weights)
