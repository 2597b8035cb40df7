"""Fréchet distance, KID, patches, feature extractors and streaming statistics."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import torch
from torch import nn

from platesynth.errors import MetricUndefinedError, ParameterError, ShapeMismatchError, WeightsNotFoundError
from platesynth.io import read_image
from platesynth.metrics import frechet
from platesynth.metrics.frechet import (
    FeatureExtractor,
    FeatureStatistics,
    frechet_distance,
    frechet_distance_from_stats,
    get_feature_extractor,
    kernel_distance,
    nearest_neighbour_accuracy,
    patch_frechet_distance,
    split_into_patches,
)
from platesynth.metrics.networks import AlexNetFeatures, FIDInceptionV3, ImageNetScaling, load_backbone_state

# ---------------------------------------------------------------- references written out plainly

def reference_frechet(a: np.ndarray, b: np.ndarray) -> float:
    """FD with tr sqrt(S1 S2) from the eigenvalues of the symmetric S1^1/2 S2 S1^1/2.

    Eigenvalues below 1e-12 of the largest are rounding noise of a rank-deficient matrix and are set to 0.
    """

    def clean(eigenvalues):
        return np.where(eigenvalues > 1e-12 * eigenvalues.max(), eigenvalues, 0.0)

    mu_a, mu_b = a.mean(axis=0), b.mean(axis=0)
    s_a, s_b = np.atleast_2d(np.cov(a, rowvar=False)), np.atleast_2d(np.cov(b, rowvar=False))
    w, v = np.linalg.eigh(s_a)
    root_a = (v * np.sqrt(clean(w))) @ v.T
    eigenvalues = clean(np.linalg.eigvalsh(root_a @ s_b @ root_a))
    return float(np.sum((mu_a - mu_b) ** 2) + np.trace(s_a) + np.trace(s_b) - 2 * np.sum(np.sqrt(eigenvalues)))


def reference_mmd(x: np.ndarray, y: np.ndarray) -> float:
    """Unbiased MMD^2 with k(u, v) = (u.v / d + 1)^3, by explicit loops."""
    m, n, d = len(x), len(y), x.shape[1]

    def k(u, v):
        return (sum(u[i] * v[i] for i in range(d)) / d + 1) ** 3

    xx = sum(k(x[i], x[j]) for i in range(m) for j in range(m) if i != j) / (m * (m - 1))
    yy = sum(k(y[i], y[j]) for i in range(n) for j in range(n) if i != j) / (n * (n - 1))
    xy = sum(k(x[i], y[j]) for i in range(m) for j in range(n)) / (m * n)
    return xx + yy - 2 * xy


# ---------------------------------------------------------------- Fréchet distance

@pytest.mark.parametrize(("n_a", "n_b", "dim"), [(300, 250, 6), (5, 7, 40), (30, 30, 30)])
def test_frechet_matches_eigen_reference(n_a, n_b, dim):
    rng = np.random.default_rng(n_a + dim)
    mixing = np.linalg.qr(rng.normal(size=(dim, dim)))[0] * rng.uniform(0.5, 2.0, size=dim)  # condition number <= 4
    a = rng.normal(size=(n_a, dim)) @ mixing
    b = rng.normal(size=(n_b, dim)) @ mixing * 1.3 + 0.5
    expected = reference_frechet(a, b)
    # FD is a difference of traces: rounding errors scale with them, not with the (smaller) result
    tolerance = 1e-10 * (np.trace(np.cov(a, rowvar=False)) + np.trace(np.cov(b, rowvar=False)))
    assert frechet_distance(a, b) == pytest.approx(expected, abs=tolerance)
    if n_a > dim and n_b > dim:  # sqrtm is only accurate for non-singular covariances
        stats = (a.mean(0), np.cov(a, rowvar=False), b.mean(0), np.cov(b, rowvar=False))
        assert frechet_distance_from_stats(*stats) == pytest.approx(expected, abs=tolerance)


def test_frechet_of_identical_sets_is_zero():
    a = np.random.default_rng(1).normal(size=(50, 8))
    assert frechet_distance(a, a) == pytest.approx(0, abs=1e-9)
    few = a[:4]  # singular covariances, sample-space route
    assert frechet_distance(few, few) == pytest.approx(0, abs=1e-9)


def test_frechet_closed_forms():
    # 1-D Gaussians: (m1 - m2)^2 + (s1 - s2)^2
    assert frechet_distance_from_stats([1.0], [[4.0]], [3.0], [[9.0]]) == pytest.approx(4 + 1, rel=1e-12)
    # diagonal covariances: sum over dimensions
    mu1, mu2 = np.array([0.0, 1.0, -2.0]), np.array([1.0, 1.0, 0.0])
    sd1, sd2 = np.array([1.0, 2.0, 0.5]), np.array([3.0, 2.0, 1.5])
    expected = np.sum((mu1 - mu2) ** 2) + np.sum((sd1 - sd2) ** 2)
    assert frechet_distance_from_stats(mu1, np.diag(sd1**2), mu2, np.diag(sd2**2)) == pytest.approx(expected)
    # a shifted copy has the same covariance: FD is the squared shift, by either route
    a = np.random.default_rng(2).normal(size=(40, 3))
    shift = np.array([0.5, -1.0, 2.0])
    assert frechet_distance(a, a + shift) == pytest.approx(shift @ shift, rel=1e-9)
    assert frechet_distance(a[:3], a[:3] + shift) == pytest.approx(shift @ shift, rel=1e-9)


def test_singular_product_gets_the_eps_offset(monkeypatch):
    calls = []
    real_sqrtm = scipy.linalg.sqrtm

    def sqrtm_failing_once(matrix):
        calls.append(matrix.copy())
        return np.full_like(matrix, np.inf) if len(calls) == 1 else real_sqrtm(matrix)

    monkeypatch.setattr(frechet.scipy.linalg, "sqrtm", sqrtm_failing_once)
    sigma = np.diag([1.0, 4.0])
    value = frechet_distance_from_stats(np.zeros(2), sigma, np.zeros(2), sigma, eps=1e-3)
    np.testing.assert_allclose(calls[1], (sigma + 1e-3 * np.eye(2)) @ (sigma + 1e-3 * np.eye(2)))
    # tr(S) + tr(S) - 2 tr(S + eps I): the offset shows as -4 eps
    assert value == pytest.approx(0.0, abs=1e-12)  # clipped at zero


def test_large_imaginary_part_is_an_error(monkeypatch):
    monkeypatch.setattr(frechet.scipy.linalg, "sqrtm", lambda matrix: matrix + 0.1j * np.eye(len(matrix)))
    with pytest.raises(MetricUndefinedError, match="imaginary component of 0.1"):
        frechet_distance_from_stats(np.zeros(2), np.eye(2), np.zeros(2), np.eye(2))


def test_small_imaginary_part_is_dropped(monkeypatch):
    monkeypatch.setattr(frechet.scipy.linalg, "sqrtm", lambda matrix: matrix + 1e-5j * np.eye(len(matrix)))
    assert frechet_distance_from_stats(np.ones(2), np.eye(2), np.zeros(2), np.eye(2)) == pytest.approx(2.0)


def test_frechet_bad_input():
    a = np.zeros((5, 3))
    with pytest.raises(ShapeMismatchError, match="feature dimensions differ: 3 vs 4"):
        frechet_distance(a, np.zeros((5, 4)))
    with pytest.raises(MetricUndefinedError, match="1 sample"):
        frechet_distance(a[:1], a)
    with pytest.raises(ShapeMismatchError, match="do not fit"):
        frechet_distance_from_stats(np.zeros(3), np.eye(3), np.zeros(2), np.eye(2))


# ---------------------------------------------------------------- KID

def test_kid_matches_loops_when_subsets_are_whole_sets():
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=(7, 4)), rng.normal(size=(7, 4)) + 0.3
    mean, std = kernel_distance(x, y, n_subsets=4, subset_size=1000)  # clipped to 7: every subset is the whole set
    assert mean == pytest.approx(reference_mmd(x, y), rel=1e-10)
    assert std == pytest.approx(0, abs=1e-12)


def test_kid_subsets_average_to_the_full_estimate():
    # The unbiased estimate on random subsets has the full-set estimate as its expectation.
    rng = np.random.default_rng(4)
    x, y = rng.normal(size=(12, 3)), rng.normal(size=(15, 3)) * 1.5
    mean, std = kernel_distance(x, y, n_subsets=3000, subset_size=6, seed=1)
    assert std > 0
    assert mean == pytest.approx(reference_mmd(x, y), abs=4 * std / np.sqrt(3000))


def test_kid_seeded_and_sensitive():
    rng = np.random.default_rng(5)
    a, b = rng.normal(size=(60, 5)), rng.normal(size=(60, 5))
    assert kernel_distance(a, b, n_subsets=10, subset_size=20, seed=7) == kernel_distance(
        a, b, n_subsets=10, subset_size=20, seed=7)
    same, _ = kernel_distance(a, b, n_subsets=10, subset_size=20)
    shifted, _ = kernel_distance(a, b + 2.0, n_subsets=10, subset_size=20)
    assert abs(same) < 0.2 * shifted
    with pytest.raises(MetricUndefinedError):
        kernel_distance(a[:1], b)


# ---------------------------------------------------------------- 1-NN two-sample accuracy

def test_nearest_neighbour_accuracy_by_hand():
    # a: 0, 1.2, 10; b: 2, 11, 12.5 (1-d). Nearest other point: 0->1.2 (a, right), 1.2->2 (b, wrong),
    # 10->11 (b, wrong), 2->1.2 (a, wrong), 11->10 (a, wrong), 12.5->11 (b, right): 2 of 6
    a, b = np.array([[0.0], [1.2], [10.0]]), np.array([[2.0], [11.0], [12.5]])
    assert nearest_neighbour_accuracy(a, b) == pytest.approx(2 / 6)


def test_nearest_neighbour_accuracy_separated_mixed_and_balanced():
    rng = np.random.default_rng(6)
    a, b = rng.normal(size=(200, 8)), rng.normal(size=(300, 8))
    assert nearest_neighbour_accuracy(a, b + 20.0) == 1.0  # two far clusters: every neighbour is of its own set
    same = nearest_neighbour_accuracy(a, b)  # one distribution: about chance (the larger set subsampled to 200)
    assert 0.4 < same < 0.6
    assert nearest_neighbour_accuracy(a, b, seed=1) == nearest_neighbour_accuracy(a, b, seed=1)
    assert nearest_neighbour_accuracy(a, a.copy()) == 0.0  # copies: each sample's nearest is its twin, of the other set
    with pytest.raises(MetricUndefinedError):
        nearest_neighbour_accuracy(a[:1], b)


def test_nearest_neighbour_accuracy_looks_outside_a_samples_group():
    # both sets: 12 groups (plates) of 6 samples (wells) sharing their group's offset, from one distribution
    rng = np.random.default_rng(7)

    def plates() -> np.ndarray:
        return (rng.normal(0, 3, size=(12, 1, 4)) + rng.normal(0, 0.1, size=(12, 6, 4))).reshape(72, 4)

    a, b, groups = plates(), plates(), np.repeat(np.arange(12), 6)
    assert nearest_neighbour_accuracy(a, b) == 1.0  # every nearest neighbour is a well of the same plate
    assert 0.3 < nearest_neighbour_accuracy(a, b, groups, groups) < 0.7  # other plates: about chance
    with pytest.raises(ShapeMismatchError):
        nearest_neighbour_accuracy(a, b, groups[:5], groups)
    # one group per set: every neighbour is of the other set
    assert nearest_neighbour_accuracy(a[:6], b[:6], groups[:6], groups[:6]) == 0.0



# ---------------------------------------------------------------- patches

def test_patches_landscape_grid_by_hand():
    image = np.arange(100 * 200 * 3).reshape(100, 200, 3)
    patches = split_into_patches(image)
    # rows: 100 / (2 - 0.15) = 54.05 -> 54 px at 0, 46; columns: 200 / (3 - 0.3) = 74.07 -> 74 px at 0, 63, 126
    assert len(patches) == 6
    expected = [image[r:r + 54, c:c + 74] for r in (0, 46) for c in (0, 63, 126)]
    for patch, want in zip(patches, expected, strict=True):
        np.testing.assert_array_equal(patch, want)
    assert (54 - 46) / 54 == pytest.approx(0.15, abs=0.01) and (74 - 63) / 74 == pytest.approx(0.15, abs=0.01)


def test_patches_portrait_and_explicit_grid():
    image = np.zeros((300, 100), dtype=np.uint8)
    assert [p.shape for p in split_into_patches(image)] == [(int(round(300 / 2.7)), 54)] * 6
    patches = split_into_patches(np.arange(300 * 100).reshape(300, 100), grid=(4, 1), overlap=0.0)
    assert [p.shape for p in patches] == [(75, 100)] * 4
    np.testing.assert_array_equal(np.concatenate(patches), np.arange(300 * 100).reshape(300, 100))
    with pytest.raises(ParameterError):
        split_into_patches(image, overlap=1.0)


# ---------------------------------------------------------------- streaming statistics

def test_streaming_statistics_equal_batch():
    rng = np.random.default_rng(6)
    features = rng.normal(size=(103, 7)) * 5 + 100
    stats = FeatureStatistics()
    for start, stop in ((0, 1), (1, 40), (40, 41), (41, 103)):
        stats.update_features(features[start:stop])
    mean, cov = stats.compute()
    np.testing.assert_allclose(mean, features.mean(axis=0), rtol=1e-13)
    np.testing.assert_allclose(cov, np.cov(features, rowvar=False), rtol=1e-11)
    np.testing.assert_array_equal(stats.features, features)
    assert stats.count == 103
    stats.reset()
    with pytest.raises(MetricUndefinedError, match="0 image"):
        stats.compute()


# ---------------------------------------------------------------- networks and extractors

INCEPTION_BLOCKS = {
    "Conv2d_1a_3x3": [""], "Conv2d_2a_3x3": [""], "Conv2d_2b_3x3": [""], "Conv2d_3b_1x1": [""], "Conv2d_4a_3x3": [""],
    **{f"Mixed_5{s}": ["branch1x1", "branch5x5_1", "branch5x5_2", "branch3x3dbl_1", "branch3x3dbl_2",
                       "branch3x3dbl_3", "branch_pool"] for s in "bcd"},
    "Mixed_6a": ["branch3x3", "branch3x3dbl_1", "branch3x3dbl_2", "branch3x3dbl_3"],
    **{f"Mixed_6{s}": ["branch1x1", "branch7x7_1", "branch7x7_2", "branch7x7_3", "branch7x7dbl_1", "branch7x7dbl_2",
                       "branch7x7dbl_3", "branch7x7dbl_4", "branch7x7dbl_5", "branch_pool"] for s in "bcde"},
    "Mixed_7a": ["branch3x3_1", "branch3x3_2", "branch7x7x3_1", "branch7x7x3_2", "branch7x7x3_3", "branch7x7x3_4"],
    **{f"Mixed_7{s}": ["branch1x1", "branch3x3_1", "branch3x3_2a", "branch3x3_2b", "branch3x3dbl_1", "branch3x3dbl_2",
                       "branch3x3dbl_3a", "branch3x3dbl_3b", "branch_pool"] for s in "bc"},
}


def expected_inception_keys() -> list[str]:
    """pytorch-fid's key names: every BasicConv2d has conv.weight and bn.{weight,bias,running_mean,running_var,...}."""
    keys = []
    for block, units in INCEPTION_BLOCKS.items():
        for unit in units:
            prefix = f"{block}.{unit}." if unit else f"{block}."
            batch_norm = ("weight", "bias", "running_mean", "running_var", "num_batches_tracked")
            keys += [prefix + "conv.weight"] + [prefix + f"bn.{p}" for p in batch_norm]
    return sorted(keys)


def seeded_inception() -> FIDInceptionV3:
    """A stand-in for the real FID network: the same architecture, seeded variance-preserving random weights."""
    torch.manual_seed(0)
    network = FIDInceptionV3()
    for module in network.modules():
        if isinstance(module, nn.Conv2d):
            nn.init.kaiming_normal_(module.weight, nonlinearity="relu")
    return network.eval()


def test_inception_keys_and_size_match_pytorch_fid():
    network = FIDInceptionV3()
    assert sorted(network.state_dict()) == expected_inception_keys()
    # torchvision documents 27,161,264 parameters for inception_v3 (1000 classes, with AuxLogits); without AuxLogits
    # (3,326,696) and fc (2,049,000), the convolutional part has 21,785,568.
    assert sum(p.numel() for p in network.parameters()) == 27_161_264 - 3_326_696 - 2_049_000


def test_inception_loads_a_pytorch_fid_shaped_state_dict():
    # The released file holds these keys plus fc.* (1008 classes); num_batches_tracked may be absent.
    source = seeded_inception().state_dict()
    state_dict = {k: v.clone() for k, v in source.items() if not k.endswith("num_batches_tracked")}
    state_dict["fc.weight"], state_dict["fc.bias"] = torch.zeros(1008, 2048), torch.zeros(1008)
    target = FIDInceptionV3()
    load_backbone_state(target, state_dict, ("fc.",))
    for key, value in target.state_dict().items():
        if not key.endswith("num_batches_tracked"):
            assert torch.equal(value, source[key]), key
    del state_dict["Mixed_7c.branch_pool.conv.weight"]
    with pytest.raises(WeightsNotFoundError, match="missing \\['Mixed_7c.branch_pool.conv.weight'\\]"):
        load_backbone_state(FIDInceptionV3(), state_dict, ("fc.",))


@pytest.mark.parametrize(("block_name", "expected_at_corner"), [("Mixed_7b", 1 / 4), ("Mixed_7c", 1.0)])
def test_fid_pool_branches(block_name, expected_at_corner):
    # The TensorFlow quirks: Mixed_7b averages without counting the zero padding (a corner sees 4 pixels, not 9);
    # Mixed_7c max-pools. Route input channel 0 unchanged through the pool branch and put a spike in the corner.
    block = getattr(FIDInceptionV3(), block_name).eval()
    with torch.no_grad():
        block.branch_pool.conv.weight.zero_()
        block.branch_pool.conv.weight[0, 0] = 1.0
    x = torch.zeros(1, block.branch1x1.conv.in_channels, 5, 5)
    x[0, 0, 0, 0] = 1.0
    with torch.no_grad():
        pool_branch = block(x)[:, -192:]
    batch_norm_scale = (1 + 1e-3) ** -0.5  # fresh running statistics, eps 0.001
    assert pool_branch[0, 0, 0, 0].item() == pytest.approx(expected_at_corner * batch_norm_scale, rel=1e-6)


def smooth_image(seed: int, height: int, width: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width] / max(height, width)
    channels = [np.sin(2 * np.pi * (rng.uniform(1, 4) * x + rng.uniform(1, 4) * y) + rng.uniform(0, 6))
                for _ in range(3)]
    noise = rng.normal(scale=0.1, size=(height, width, 3))
    return np.clip((np.stack(channels, axis=-1) + noise + 1) * 127.5, 0, 255).astype(np.uint8)


@pytest.mark.slow
def test_inception_pipeline_with_a_seeded_stand_in():
    network = seeded_inception()
    # the FID convention: any input size is resized to 299x299, giving 2048 pool3 features
    default = FeatureExtractor("inception", network, dim=2048, device="cpu")([smooth_image(9, 40, 50)])
    assert default.shape == (1, 2048) and np.isfinite(default).all() and default.std() > 0

    # the rest at native size (patches of about 90x90 px) to keep the test fast on a CPU
    network.resize_input = False
    extractor = FeatureExtractor("inception", network, dim=2048, batch_size=4, device="cpu")
    real, synthetic = smooth_image(0, 160, 240), smooth_image(1, 170, 220)
    patches = split_into_patches(real)
    features = extractor(patches)
    assert features.shape == (6, 2048) and features.dtype == np.float64 and np.isfinite(features).all()
    with torch.no_grad():  # the same numbers straight from the network
        direct = network(torch.from_numpy(patches[4].transpose(2, 0, 1).copy())[None].float() / 255).numpy()
    np.testing.assert_allclose(features[4], direct[0], rtol=1e-4, atol=1e-6 * np.abs(direct).max())

    value = patch_frechet_distance(real, synthetic, extractor)
    assert value == pytest.approx(frechet_distance(features, extractor(split_into_patches(synthetic))), rel=1e-9)
    assert value > 0


def test_extractor_keeps_order_across_shapes():
    torch.manual_seed(1)
    extractor = FeatureExtractor("toy", nn.Sequential(nn.Conv2d(3, 4, 3), nn.AdaptiveAvgPool2d(1), nn.Flatten()),
                                 dim=4, batch_size=2, device="cpu")
    a, b, c = smooth_image(2, 20, 30), smooth_image(3, 25, 25), smooth_image(4, 20, 30)
    together = extractor([a, b, c, a])
    separately = np.concatenate([extractor([image]) for image in (a, b, c, a)])
    np.testing.assert_allclose(together, separately, rtol=1e-6)
    np.testing.assert_allclose(together[0], together[3], rtol=1e-6)
    stats = FeatureStatistics(extractor)
    stats.update([a, b])
    stats.update(np.stack([c, a]))
    np.testing.assert_allclose(stats.compute().cov, np.cov(together, rowvar=False), rtol=1e-6)


def test_missing_inception_weights(monkeypatch, tmp_path):
    monkeypatch.setenv("TORCH_HOME", str(tmp_path))
    monkeypatch.setenv("PLATESYNTH_OFFLINE", "1")
    monkeypatch.delenv("PLATESYNTH_FID_WEIGHTS", raising=False)
    monkeypatch.delenv("PLATESYNTH_WEIGHTS_DIR", raising=False)
    with pytest.raises(WeightsNotFoundError) as info:
        get_feature_extractor("inception")
    for part in ("PLATESYNTH_FID_WEIGHTS", "PLATESYNTH_WEIGHTS_DIR", str(tmp_path / "hub" / "checkpoints"),
                 "pt_inception-2015-12-05-6726825d.pth", "https://github.com/mseitzer/pytorch-fid/releases"):
        assert part in str(info.value)


def test_alexnet_features_on_real_plates(shared):
    extractor = get_feature_extractor("alexnet", shared("weights", "alexnet_features-7be5be79.pth"))
    assert extractor.dim == 1152
    plates = sorted(shared("data", "plaque12", "plates").glob("*.jpg"))
    real, other = read_image(plates[0])[::2, ::2], read_image(plates[1])[::2, ::2]

    features = extractor([real])
    # the definition: spatial means of AlexNet's five ReLU outputs on the ImageNet-normalised image, concatenated
    backbone = extractor.network.backbone
    with torch.no_grad():
        x = torch.from_numpy(real.transpose(2, 0, 1).copy())[None].float() / 127.5 - 1
        taps = backbone(ImageNetScaling()(x))
    assert isinstance(backbone, AlexNetFeatures) and [t.shape[1] for t in taps] == [64, 192, 384, 256, 256]
    np.testing.assert_allclose(features[0], torch.cat([t.mean(dim=(2, 3))[0] for t in taps]).numpy(), rtol=1e-5)

    assert patch_frechet_distance(real, real, extractor) == pytest.approx(0, abs=1e-9)
    assert patch_frechet_distance(real, other, extractor) > 1.0
    with pytest.raises(MetricUndefinedError, match="at least 31x31"):
        extractor([real[:20, :20]])
