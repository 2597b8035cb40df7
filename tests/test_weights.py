"""Weight resolution: order of the options, hash checks of local files and downloads, the not-found message."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest
import torch

from platesynth import weights
from platesynth.errors import ParameterError, WeightsNotFoundError
from platesynth.metrics.networks import AlexNetFeatures, build_backbone
from platesynth.weights import (
    FID_WEIGHTS_ENV,
    OFFLINE_ENV,
    WEIGHTS_DIR_ENV,
    NetworkWeights,
    WeightsFile,
    content_sha256,
    load_weights,
    resolve_weights,
)

ALEXNET_FEATURES = "alexnet_features-7be5be79.pth"


@pytest.fixture
def clean_env(monkeypatch, tmp_path):
    """No weights anywhere: empty torch hub cache under tmp_path, no platesynth variables set."""
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch"))
    for name in (WEIGHTS_DIR_ENV, FID_WEIGHTS_ENV, OFFLINE_ENV):
        monkeypatch.delenv(name, raising=False)
    return tmp_path / "torch" / "hub" / "checkpoints"


@pytest.fixture
def no_network(monkeypatch):
    """Fail the test if anything tries to download."""

    def refuse(url, destination):
        raise AssertionError(f"unexpected download of {url}")

    monkeypatch.setattr(weights, "_download", refuse)


def test_content_hash_reproduces_the_documented_hashes(shared):
    # Hashes from shared/weights/README.md: sorted keys, each key's bytes then the raw tensor bytes.
    for file_name, expected in (
        (ALEXNET_FEATURES, "44534cd66e37ce9a6258bb5e845ef8cd47c33aa68024441c7e616d63c0c1c41a"),
        ("squeezenet1_1_features-b8a52dc0.pth", "9a3cd24c3da63ec76ec50dabac44e862029b5c84992e5ddd582be22d0f9ef388"),
    ):
        state_dict = torch.load(shared("weights", file_name), map_location="cpu", weights_only=True)
        assert content_sha256(state_dict) == expected


def test_content_hash_by_hand():
    state_dict = {"features.b": torch.tensor([1.0, 2.0]), "features.a": torch.tensor([3], dtype=torch.int32),
                  "classifier.w": torch.tensor([5.0])}
    expected = hashlib.sha256(b"features.a" + (3).to_bytes(4, "little") + b"features.b"
                              + torch.tensor([1.0, 2.0]).numpy().tobytes()).hexdigest()
    assert content_sha256(state_dict) == expected


def test_explicit_path_wins_over_everything(shared, clean_env, monkeypatch, tmp_path, no_network):
    explicit = shared("weights", ALEXNET_FEATURES)
    monkeypatch.setenv(WEIGHTS_DIR_ENV, str(tmp_path / "does-not-exist"))
    assert resolve_weights("alexnet", explicit) == explicit


def test_weights_dir_then_torch_hub_cache(shared, clean_env, monkeypatch, tmp_path, no_network):
    source = shared("weights", ALEXNET_FEATURES)
    clean_env.mkdir(parents=True)
    (clean_env / ALEXNET_FEATURES).symlink_to(source)
    assert resolve_weights("alexnet") == clean_env / ALEXNET_FEATURES
    other_dir = tmp_path / "weights"
    other_dir.mkdir()
    (other_dir / ALEXNET_FEATURES).symlink_to(source)
    monkeypatch.setenv(WEIGHTS_DIR_ENV, str(other_dir))
    assert resolve_weights("alexnet") == other_dir / ALEXNET_FEATURES


def test_load_weights_returns_the_backbone_tensors(shared, clean_env, monkeypatch, no_network):
    monkeypatch.setenv(WEIGHTS_DIR_ENV, str(shared("weights")))
    state_dict = load_weights("alexnet")
    assert sorted(state_dict) == sorted(f"features.{i}.{p}" for i in (0, 3, 6, 8, 10) for p in ("weight", "bias"))
    assert sum(t.numel() for t in state_dict.values()) == 2_469_696


def test_full_torchvision_file_classifier_keys_are_ignored(shared, clean_env, tmp_path, no_network):
    state_dict = torch.load(shared("weights", ALEXNET_FEATURES), map_location="cpu", weights_only=True)
    full = dict(state_dict, **{"classifier.1.weight": torch.zeros(4, 9216), "classifier.1.bias": torch.zeros(4)})
    path = tmp_path / "my-alexnet.pth"
    torch.save(full, path)
    network = build_backbone("alexnet", path)
    assert isinstance(network, AlexNetFeatures)
    assert torch.equal(network.features[10].weight, state_dict["features.10.weight"])
    assert not network.training and not any(p.requires_grad for p in network.parameters())


def test_corrupt_local_file_is_a_clear_error(shared, clean_env, monkeypatch, tmp_path, no_network):
    weights_dir = tmp_path / "weights"
    weights_dir.mkdir()
    monkeypatch.setenv(WEIGHTS_DIR_ENV, str(weights_dir))
    garbage = weights_dir / ALEXNET_FEATURES
    garbage.write_bytes(b"not a checkpoint")
    with pytest.raises(WeightsNotFoundError, match=f"{garbage}: cannot read weights"):
        resolve_weights("alexnet")

    state_dict = torch.load(shared("weights", ALEXNET_FEATURES), map_location="cpu", weights_only=True)
    state_dict["features.0.bias"][0] += 1e-3
    torch.save(state_dict, garbage)
    with pytest.raises(WeightsNotFoundError, match=rf"{garbage}: sha256 \w+\.\.\. is not one of the known AlexNet"):
        resolve_weights("alexnet")


def test_missing_weights_message_lists_every_option(clean_env, monkeypatch, no_network):
    monkeypatch.setenv(OFFLINE_ENV, "1")
    with pytest.raises(WeightsNotFoundError) as info:
        resolve_weights("inception_fid")
    message = str(info.value)
    assert "\n" not in message
    for part in ("pt_inception-2015-12-05-6726825d.pth", "pass the file's path", FID_WEIGHTS_ENV, WEIGHTS_DIR_ENV,
                 str(clean_env), "https://github.com/mseitzer/pytorch-fid/releases/download/fid_weights/",
                 f"{OFFLINE_ENV}=1"):
        assert part in message


def test_env_file_pointing_nowhere_names_the_file(clean_env, monkeypatch, tmp_path, no_network):
    missing = tmp_path / "nowhere.pth"
    monkeypatch.setenv(FID_WEIGHTS_ENV, str(missing))
    with pytest.raises(WeightsNotFoundError, match=f"{missing}: no such weights file"):
        resolve_weights("inception_fid")


def test_download_disabled_by_argument(clean_env, no_network):
    with pytest.raises(WeightsNotFoundError, match="downloads disabled by the caller"):
        resolve_weights("inception_fid", download=False)


def _fake_network(sha256: str) -> NetworkWeights:
    return NetworkWeights(
        name="fake",
        description="fake test weights",
        files=(WeightsFile("fake-weights.pth", "https://weights.invalid/fake-weights.pth", sha256=sha256),),
    )


def test_download_is_hash_checked_and_cached(clean_env, monkeypatch):
    payload = b"pretend this is a checkpoint"
    calls = []

    def fake_download(url, destination: Path):
        calls.append(url)
        destination.write_bytes(payload)

    monkeypatch.setattr(weights, "_download", fake_download)
    network = _fake_network(hashlib.sha256(payload).hexdigest()[:8])
    path = resolve_weights(network)
    assert path == clean_env / "fake-weights.pth"
    assert path.read_bytes() == payload
    assert resolve_weights(network) == path  # now found in the cache
    assert calls == ["https://weights.invalid/fake-weights.pth"]


def test_download_with_wrong_hash_is_discarded(clean_env, monkeypatch):
    monkeypatch.setattr(weights, "_download", lambda url, destination: destination.write_bytes(b"tampered"))
    network = _fake_network("0123abcd")
    with pytest.raises(WeightsNotFoundError) as info:
        resolve_weights(network)
    message = str(info.value)
    tampered_hash = hashlib.sha256(b"tampered").hexdigest()[:16]
    assert f"download of https://weights.invalid/fake-weights.pth has sha256 {tampered_hash}" in message
    assert "expected 0123abcd" in message and "discarded" in message
    assert not clean_env.exists() or list(clean_env.iterdir()) == []


def test_failed_download_reason_is_in_the_message(clean_env, monkeypatch):
    def unreachable(url, destination):
        raise OSError("Temporary failure in name resolution")

    monkeypatch.setattr(weights, "_download", unreachable)
    with pytest.raises(WeightsNotFoundError, match="failed \\(OSError: Temporary failure in name resolution\\)"):
        resolve_weights("inception_fid")
    assert list(clean_env.iterdir()) == []


def test_unknown_network():
    with pytest.raises(ParameterError, match="unknown network 'vgg'"):
        resolve_weights("vgg")
