"""Fréchet distance, kernel (MMD) distance and nearest-neighbour accuracy between sets of deep image features.

Metric names follow the feature space: ``fd_alexnet`` / ``kid_alexnet`` (AlexNet features), ``fid_inception`` /
``kid_inception`` (pytorch-fid's InceptionV3 pool3, the usual FID and KID), and for one real/synthetic image pair the
patch versions ``fd_patches_alexnet`` / ``fid_patches_inception``.

Public API
----------
frechet_distance_from_stats(mu1, sigma1, mu2, sigma2, eps=1e-6) -> float
    ``|mu1 - mu2|^2 + tr(sigma1 + sigma2 - 2 sqrtm(sigma1 sigma2))`` with ``scipy.linalg.sqrtm``, handled as in
    pytorch-fid: if the square root is not finite, ``eps`` is added to both diagonals; an imaginary part larger
    than 1e-3 on the diagonal is an error, a smaller one is dropped.
frechet_distance(features_a, features_b) -> float
    The same distance from two ``(N, D)`` feature arrays (Gaussians fitted with ``np.mean`` / ``np.cov``).
kernel_distance(features_a, features_b, n_subsets=100, subset_size=1000, seed=0) -> (mean, std)
    KID: unbiased MMD^2 with the polynomial kernel ``(x.y / D + 1)^3``, averaged over random subsets.
nearest_neighbour_accuracy(features_a, features_b, groups_a=None, groups_b=None, seed=0) -> float
    Leave-one-out accuracy of the 1-nearest-neighbour classifier telling the two sets apart (equal sizes): 0.5 when
    they cannot be told apart, 1 when every sample's nearest neighbour is of its own set.
split_into_patches(image, grid=None, overlap=0.15) -> list of arrays
    Overlapping grid of patches (2 rows x 3 columns for landscape images), to fit a Gaussian to one image.
patch_frechet_distance(real, synthetic, extractor, grid=None, overlap=0.15) -> float
    Fréchet distance between the patch features of two images.
get_feature_extractor(name, weights=None) -> FeatureExtractor
    ``"alexnet"`` (1152-d) or ``"inception"`` (2048-d) features of uint8 images; ``extractor(images) -> (N, D)``.
FeatureStatistics(extractor)
    Streaming mean/covariance (``update(images)``, ``compute() -> (mean, cov)``), keeping the features for KID.
"""

from __future__ import annotations

import functools
import os
import warnings
from collections.abc import Iterable, Sequence
from typing import NamedTuple

import numpy as np
import scipy.linalg
import torch
from torch import nn

from platesynth.errors import MetricUndefinedError, ParameterError, ShapeMismatchError
from platesynth.io import to_rgb_uint8
from platesynth.metrics.networks import AlexNetFeatures, FIDInceptionV3, ImageNetScaling, build_backbone
from platesynth.weights import resolve_weights

_IMAGINARY_TOLERANCE = 1e-3


def _check_features(features: np.ndarray, what: str) -> np.ndarray:
    features = np.asarray(features, dtype=np.float64)
    if features.ndim != 2:
        raise ShapeMismatchError(f"{what}: expected an (N, D) feature array, got shape {features.shape}")
    if features.shape[0] < 2:
        raise MetricUndefinedError(f"{what}: {features.shape[0]} sample(s); a covariance needs at least 2")
    if not np.isfinite(features).all():
        raise MetricUndefinedError(f"{what}: features contain NaN or infinity")
    return features


def _check_same_dimension(a: np.ndarray, b: np.ndarray) -> None:
    if a.shape[1] != b.shape[1]:
        raise ShapeMismatchError(f"feature dimensions differ: {a.shape[1]} vs {b.shape[1]}")


def _check_feature_sets(features_a: np.ndarray, features_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both sets as float64 ``(N, D)`` arrays of one dimension, each of at least 2 finite samples."""
    a = _check_features(features_a, "first feature set")
    b = _check_features(features_b, "second feature set")
    _check_same_dimension(a, b)
    return a, b


def frechet_distance_from_stats(
    mu1: np.ndarray, sigma1: np.ndarray, mu2: np.ndarray, sigma2: np.ndarray, eps: float = 1e-6
) -> float:
    """Fréchet distance between two Gaussians, computed as pytorch-fid does.

    Parameters
    ----------
    mu1, mu2 : numpy.ndarray
        ``(D,)`` means.
    sigma1, sigma2 : numpy.ndarray
        ``(D, D)`` covariances.
    eps : float
        Added to both diagonals when ``sqrtm(sigma1 @ sigma2)`` is not finite (a singular product).

    Returns
    -------
    float
        ``|mu1 - mu2|^2 + tr(sigma1) + tr(sigma2) - 2 tr(sqrtm(sigma1 @ sigma2))``, at least 0.

    Raises
    ------
    ShapeMismatchError
        If the shapes do not fit together.
    MetricUndefinedError
        If the matrix square root has a significant imaginary part (more than 1e-3 on its diagonal).
    """
    mu1, mu2 = np.atleast_1d(np.asarray(mu1, dtype=np.float64)), np.atleast_1d(np.asarray(mu2, dtype=np.float64))
    sigma1, sigma2 = np.atleast_2d(np.asarray(sigma1, dtype=np.float64)), np.atleast_2d(np.asarray(sigma2, np.float64))
    dim = mu1.shape[0]
    if mu1.shape != (dim,) or mu2.shape != (dim,) or sigma1.shape != (dim, dim) or sigma2.shape != (dim, dim):
        raise ShapeMismatchError(
            f"Gaussian statistics do not fit: mu1 {mu1.shape}, sigma1 {sigma1.shape}, mu2 {mu2.shape}, "
            f"sigma2 {sigma2.shape}"
        )
    with warnings.catch_warnings():  # a singular product is handled below, as pytorch-fid does with disp=False
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        covmean = scipy.linalg.sqrtm(sigma1 @ sigma2)
        if not np.isfinite(covmean).all():
            offset = np.eye(dim) * eps
            covmean = scipy.linalg.sqrtm((sigma1 + offset) @ (sigma2 + offset))
    if np.iscomplexobj(covmean):
        if not np.allclose(np.diagonal(covmean).imag, 0, atol=_IMAGINARY_TOLERANCE):
            raise MetricUndefinedError(
                f"Fréchet distance: sqrtm(sigma1 sigma2) has an imaginary component of "
                f"{np.max(np.abs(covmean.imag)):.3g}; the covariances are ill-conditioned (too few samples?)"
            )
        covmean = covmean.real
    diff = mu1 - mu2
    value = diff @ diff + np.trace(sigma1) + np.trace(sigma2) - 2 * np.trace(covmean)
    return float(max(value, 0.0))  # a squared distance; only rounding makes it negative


def frechet_distance(features_a: np.ndarray, features_b: np.ndarray) -> float:
    """Fréchet distance between Gaussians fitted to two feature sets.

    Parameters
    ----------
    features_a, features_b : numpy.ndarray
        ``(N_a, D)`` and ``(N_b, D)`` features, N at least 2.

    Returns
    -------
    float
        The Fréchet distance of ``(mean, np.cov)`` of each set.

    Notes
    -----
    When ``N_a * N_b <= D^2`` (few samples, e.g. image patches) the covariance product is singular: ``sqrtm`` is
    then slow (tens of seconds at D = 2048) and inexact. There the trace of its square root is computed exactly in
    sample space: with centred features ``A`` and ``B``, ``tr sqrtm(cov_a cov_b)`` is the sum of the singular values
    of ``A B^T`` divided by ``sqrt((N_a - 1)(N_b - 1))``. Otherwise :func:`frechet_distance_from_stats` is used.
    """
    a, b = _check_feature_sets(features_a, features_b)
    n_a, n_b, dim = a.shape[0], b.shape[0], a.shape[1]
    if n_a * n_b > dim * dim:
        return frechet_distance_from_stats(a.mean(axis=0), np.cov(a, rowvar=False), b.mean(axis=0),
                                           np.cov(b, rowvar=False))
    centred_a, centred_b = a - a.mean(axis=0), b - b.mean(axis=0)
    trace_sqrt = np.linalg.svd(centred_a @ centred_b.T, compute_uv=False).sum() / np.sqrt((n_a - 1) * (n_b - 1))
    diff = a.mean(axis=0) - b.mean(axis=0)
    trace_a = np.sum(centred_a**2) / (n_a - 1)
    trace_b = np.sum(centred_b**2) / (n_b - 1)
    return float(max(diff @ diff + trace_a + trace_b - 2 * trace_sqrt, 0.0))


def _polynomial_kernel(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return (x @ y.T / x.shape[1] + 1.0) ** 3


def kernel_distance(
    features_a: np.ndarray, features_b: np.ndarray, n_subsets: int = 100, subset_size: int = 1000, seed: int = 0
) -> tuple[float, float]:
    """Kernel distance (KID, Bińkowski et al. 2018) between two feature sets.

    The unbiased estimate of the squared MMD with the polynomial kernel ``k(x, y) = (x.y / D + 1)^3`` is computed on
    ``n_subsets`` pairs of random subsets (drawn without replacement from each set), as torch-fidelity does.

    Parameters
    ----------
    features_a, features_b : numpy.ndarray
        ``(N_a, D)`` and ``(N_b, D)`` features.
    n_subsets : int
        Number of subset pairs.
    subset_size : int
        Samples per subset, clipped to ``min(N_a, N_b)``.
    seed : int
        Seed of the subset draws (``numpy.random.default_rng``).

    Returns
    -------
    (float, float)
        Mean and standard deviation (ddof 0) of the per-subset MMD^2 values. Often reported multiplied by 1000.

    Raises
    ------
    MetricUndefinedError
        If a set has fewer than 2 samples.
    """
    a, b = _check_feature_sets(features_a, features_b)
    if n_subsets < 1 or subset_size < 2:
        raise ParameterError(
            f"kernel distance needs n_subsets >= 1 and subset_size >= 2, got {n_subsets} and {subset_size}"
        )
    m = min(subset_size, a.shape[0], b.shape[0])
    rng = np.random.default_rng(seed)
    values = np.empty(n_subsets)
    for i in range(n_subsets):
        x = a[rng.choice(a.shape[0], m, replace=False)]
        y = b[rng.choice(b.shape[0], m, replace=False)]
        k_xx, k_yy, k_xy = _polynomial_kernel(x, x), _polynomial_kernel(y, y), _polynomial_kernel(x, y)
        within = (k_xx.sum() - np.trace(k_xx) + k_yy.sum() - np.trace(k_yy)) / (m * (m - 1))
        values[i] = within - 2.0 * k_xy.mean()
    return float(values.mean()), float(values.std())


def nearest_neighbour_accuracy(
    features_a: np.ndarray,
    features_b: np.ndarray,
    groups_a: Sequence[int] | np.ndarray | None = None,
    groups_b: Sequence[int] | np.ndarray | None = None,
    seed: int = 0,
) -> float:
    """How well the two feature sets can be told apart: the 1-NN two-sample test (Lopez-Paz and Oquab 2017).

    The larger set is subsampled (without replacement, seeded) to the size ``n`` of the smaller, so that both sets
    weigh the same. Every one of the ``2 n`` samples is labelled by its nearest neighbour (Euclidean) among the other
    ``2 n - 1``; the accuracy is the share labelled with its own set. As a realism metric (Xu et al. 2018, "An
    empirical study on evaluation metrics of generative adversarial networks"): 0.5 means the sets cannot be told
    apart, 1.0 that they are fully separated; clearly below 0.5, that one set copies the other. Samples that are not
    independent (the wells of one plate share its light and stain) find each other first; with ``groups`` a sample's
    neighbour is sought outside its own group of its own set.

    Parameters
    ----------
    features_a, features_b : numpy.ndarray
        ``(N_a, D)`` and ``(N_b, D)`` features.
    groups_a, groups_b : sequence of int, optional
        A group label per sample (e.g. the plate image a well crop came from); ``None``: every sample its own group.
    seed : int
        Seed of the subsample of the larger set (``numpy.random.default_rng``).

    Returns
    -------
    float
        The leave-one-out accuracy, in [0, 1].

    Raises
    ------
    MetricUndefinedError
        If a set has fewer than 2 samples.
    """
    a, b = _check_feature_sets(features_a, features_b)
    labels = []
    for features, groups, what in ((a, groups_a, "first"), (b, groups_b, "second")):
        groups = np.arange(features.shape[0]) if groups is None else np.asarray(groups)
        if groups.shape != (features.shape[0],):
            raise ShapeMismatchError(f"the {what} set has {features.shape[0]} samples and {groups.size} group labels")
        labels.append(groups)
    n = min(a.shape[0], b.shape[0])
    rng = np.random.default_rng(seed)
    kept = [np.sort(rng.choice(len(x), n, replace=False)) if len(x) > n else np.arange(n) for x in (a, b)]
    both = np.concatenate([a[kept[0]], b[kept[1]]])
    from_a = np.arange(2 * n) < n
    group = np.concatenate([labels[0][kept[0]], labels[1][kept[1]]])
    squared = np.sum(both * both, axis=1)
    distance = squared[:, None] + squared[None, :] - 2.0 * both @ both.T
    distance[(from_a[:, None] == from_a[None, :]) & (group[:, None] == group[None, :])] = np.inf  # self included
    return float(np.mean(from_a[np.argmin(distance, axis=1)] == from_a))  # the other set is never excluded


def split_into_patches(
    image: np.ndarray, grid: tuple[int, int] | None = None, overlap: float = 0.15
) -> list[np.ndarray]:
    """Cut an image into an overlapping grid of equal-sized patches.

    Parameters
    ----------
    image : numpy.ndarray
        ``(H, W)`` or ``(H, W, C)`` image.
    grid : (int, int), optional
        ``(rows, columns)``. By default 2 rows x 3 columns for landscape (or square) images and 3 x 2 for portrait
        ones, so that patches stay close to square: 6 patches per image, as in the paper's single-image FID.
    overlap : float
        Fraction of a patch's height (width) shared with its neighbour below (to the right), in [0, 1).

    Returns
    -------
    list of numpy.ndarray
        ``rows * columns`` views into ``image``, row by row. Along an axis of length L with n patches, patches are
        ``round(L / (n - (n - 1) * overlap))`` long and start at ``round(linspace(0, L - length, n))``, so together
        they cover the whole image.
    """
    image = np.asarray(image)
    if image.ndim not in (2, 3):
        raise ShapeMismatchError(f"expected an (H, W) or (H, W, C) image, got shape {image.shape}")
    height, width = image.shape[:2]
    if grid is None:
        grid = (2, 3) if width >= height else (3, 2)
    rows, columns = grid
    if rows < 1 or columns < 1 or not 0.0 <= overlap < 1.0:
        raise ParameterError(f"patch grid must be at least 1x1 and overlap in [0, 1): got {grid}, {overlap}")

    def spans(length: int, count: int) -> list[slice]:
        size = min(length, int(round(length / (count - (count - 1) * overlap))))
        if size < 1:
            raise MetricUndefinedError(f"image of {height}x{width} px is too small for a {rows}x{columns} patch grid")
        starts = np.round(np.linspace(0, length - size, count)).astype(int)
        return [slice(start, start + size) for start in starts]

    return [image[r, c] for r in spans(height, rows) for c in spans(width, columns)]


class SpatialMeanFeatures(nn.Module):
    """Images in [0, 1] -> ImageNet scaling -> tapped backbone -> each tap averaged over space -> concatenated."""

    def __init__(self, backbone: nn.Module) -> None:
        super().__init__()
        self.scaling = ImageNetScaling()
        self.backbone = backbone

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        taps = self.backbone(self.scaling(2 * x - 1))
        return torch.cat([tap.mean(dim=(2, 3)) for tap in taps], dim=1)


class FeatureExtractor:
    """Deep features of uint8 images, batched, without gradients, on CUDA when available.

    Parameters
    ----------
    name : str
        Feature space, used in metric names (``"alexnet"``, ``"inception"``).
    network : torch.nn.Module
        Maps ``(N, 3, H, W)`` float32 images in [0, 1] to ``(N, dim)`` features.
    dim : int
        Feature dimension.
    min_size : int
        Smallest image side the network accepts.
    batch_size : int
        Images per forward pass (images of different shapes go in different batches).
    device : str or torch.device, optional
        Defaults to ``"cuda"`` when available, else ``"cpu"``.

    Notes
    -----
    ``extractor(images)`` takes a sequence of ``(H, W, 3)`` uint8 images (or an ``(N, H, W, 3)`` array; grayscale,
    RGBA and uint16 images are converted like :func:`platesynth.io.to_rgb_uint8`) and returns an ``(N, dim)``
    float64 array in the input order.
    """

    def __init__(
        self,
        name: str,
        network: nn.Module,
        dim: int,
        min_size: int = 1,
        batch_size: int = 16,
        device: str | torch.device | None = None,
    ) -> None:
        self.name = name
        self.dim = dim
        self.min_size = min_size
        self.batch_size = batch_size
        self.device = torch.device(device or ("cuda" if torch.cuda.is_available() else "cpu"))
        self.network = network.to(self.device).eval()

    def __call__(self, images: Sequence[np.ndarray] | np.ndarray) -> np.ndarray:
        images = [to_rgb_uint8(np.asarray(image)) for image in images]
        features = np.empty((len(images), self.dim), dtype=np.float64)
        by_shape: dict[tuple[int, ...], list[int]] = {}
        for index, image in enumerate(images):
            if min(image.shape[:2]) < self.min_size:
                raise MetricUndefinedError(
                    f"{self.name} features need images of at least {self.min_size}x{self.min_size} px, "
                    f"got {image.shape[0]}x{image.shape[1]}"
                )
            by_shape.setdefault(image.shape, []).append(index)
        with torch.no_grad():
            for indices in by_shape.values():
                for start in range(0, len(indices), self.batch_size):
                    chunk = indices[start : start + self.batch_size]
                    batch = torch.from_numpy(np.stack([images[i] for i in chunk]).transpose(0, 3, 1, 2).copy())
                    batch = batch.to(self.device, dtype=torch.float32) / 255.0
                    features[chunk] = self.network(batch).double().cpu().numpy()
        return features


def _alexnet_extractor(weights: str | os.PathLike | None) -> FeatureExtractor:
    return FeatureExtractor("alexnet", SpatialMeanFeatures(build_backbone("alexnet", weights)),
                            dim=sum(AlexNetFeatures.channels), min_size=31)


def _inception_extractor(weights: str | os.PathLike | None) -> FeatureExtractor:
    return FeatureExtractor("inception", build_backbone("inception_fid", weights), dim=FIDInceptionV3.dim)


# extractor name: (builder, weights registry key)
_EXTRACTORS = {"alexnet": (_alexnet_extractor, "alexnet"), "inception": (_inception_extractor, "inception_fid")}


@functools.lru_cache(maxsize=4)
def _cached_extractor(name: str, weights_file: str) -> FeatureExtractor:
    return _EXTRACTORS[name][0](weights_file)


def get_feature_extractor(name: str, weights: str | os.PathLike | None = None) -> FeatureExtractor:
    """The feature extractor of a named feature space (cached per weights file).

    Parameters
    ----------
    name : {"alexnet", "inception"}
        ``"alexnet"``: the five ReLU outputs of torchvision AlexNet's convolutional part (the LPIPS taps, 64 + 192 +
        384 + 256 + 256 = 1152 channels), each averaged over space, concatenated; images at their own resolution
        (at least 31 px), ImageNet-normalised. ``"inception"``: pytorch-fid's InceptionV3 pool3 features (2048-d),
        images resized to 299x299.
    weights : str or path-like, optional
        Weight file; otherwise resolved as described in :mod:`platesynth.weights`.

    Raises
    ------
    WeightsNotFoundError
        If the weights cannot be found (the message lists where they were looked for).
    """
    if name not in _EXTRACTORS:
        raise ParameterError(f"unknown feature space {name!r}; choose one of {', '.join(_EXTRACTORS)}")
    weights_file = resolve_weights(_EXTRACTORS[name][1], weights)
    return _cached_extractor(name, str(weights_file.resolve()))


def patch_frechet_distance(
    real: np.ndarray,
    synthetic: np.ndarray,
    extractor: FeatureExtractor,
    grid: tuple[int, int] | None = None,
    overlap: float = 0.15,
) -> float:
    """Fréchet distance between the patch features of two images (single-image FD).

    Each image is cut by :func:`split_into_patches` (6 overlapping patches by default), the patches' features are
    extracted and :func:`frechet_distance` compares the two sets. The images may differ in size.
    """
    real_features = extractor(split_into_patches(real, grid, overlap))
    synthetic_features = extractor(split_into_patches(synthetic, grid, overlap))
    return frechet_distance(real_features, synthetic_features)


class GaussianMoments(NamedTuple):
    """Mean ``(D,)`` and covariance ``(D, D)`` of a feature set."""

    mean: np.ndarray
    cov: np.ndarray


class FeatureStatistics:
    """Streaming mean and covariance of the features of many images.

    Parameters
    ----------
    extractor : FeatureExtractor, optional
        Used by :meth:`update`; may be None when only :meth:`update_features` is used.
    keep_features : bool
        Keep every feature vector (needed for :func:`kernel_distance`; N x D float64).

    Examples
    --------
    >>> stats_real, stats_synth = FeatureStatistics(extractor), FeatureStatistics(extractor)  # doctest: +SKIP
    >>> for image in real_images: stats_real.update([image])  # doctest: +SKIP
    >>> fid = frechet_distance_from_stats(*stats_real.compute(), *stats_synth.compute())  # doctest: +SKIP
    >>> kid_mean, kid_std = kernel_distance(stats_real.features, stats_synth.features)  # doctest: +SKIP
    """

    def __init__(self, extractor: FeatureExtractor | None = None, keep_features: bool = True) -> None:
        self.extractor = extractor
        self.keep_features = keep_features
        self.reset()

    def reset(self) -> None:
        """Forget everything seen."""
        self.count = 0
        self._mean: np.ndarray | None = None
        self._scatter: np.ndarray | None = None  # sum of outer products of deviations from the mean
        self._kept: list[np.ndarray] = []

    def update(self, images: Iterable[np.ndarray] | np.ndarray) -> None:
        """Extract the features of a batch of uint8 ``(H, W, 3)`` images and add them."""
        if self.extractor is None:
            raise ParameterError("FeatureStatistics.update needs an extractor; use update_features for raw features")
        self.update_features(self.extractor(list(images)))

    def update_features(self, features: np.ndarray) -> None:
        """Add an ``(N, D)`` batch of feature vectors (merged with Chan et al.'s pairwise update)."""
        features = np.asarray(features, dtype=np.float64)
        if features.ndim != 2 or (self._mean is not None and features.shape[1] != self._mean.shape[0]):
            raise ShapeMismatchError(f"expected an (N, D) feature batch matching earlier ones, got {features.shape}")
        n_new = features.shape[0]
        if n_new == 0:
            return
        batch_mean = features.mean(axis=0)
        centred = features - batch_mean
        batch_scatter = centred.T @ centred
        if self._mean is None:
            self._mean, self._scatter = batch_mean, batch_scatter
        else:
            total = self.count + n_new
            delta = batch_mean - self._mean
            self._mean = self._mean + delta * (n_new / total)
            self._scatter = self._scatter + batch_scatter + np.outer(delta, delta) * (self.count * n_new / total)
        self.count += n_new
        if self.keep_features:
            self._kept.append(features)

    def compute(self) -> GaussianMoments:
        """Mean and unbiased covariance (``np.cov`` convention) of everything added.

        Raises
        ------
        MetricUndefinedError
            If fewer than 2 feature vectors were added.
        """
        if self.count < 2:
            raise MetricUndefinedError(f"{self.count} image(s) seen; a covariance needs at least 2")
        return GaussianMoments(self._mean.copy(), self._scatter / (self.count - 1))

    @property
    def features(self) -> np.ndarray:
        """All feature vectors added, ``(N, D)`` (requires ``keep_features=True``)."""
        if not self.keep_features:
            raise ParameterError("features were not kept (keep_features=False)")
        if not self._kept:
            return np.empty((0, 0))
        if len(self._kept) > 1:
            self._kept = [np.concatenate(self._kept, axis=0)]
        return self._kept[0]
