"""LPIPS v0.1 (Zhang et al., 2018), the learned perceptual image patch similarity, without the lpips package.

Computation, as in the original ``lpips.LPIPS(net=..., version="0.1")``:

1. images in [-1, 1] go through the ImageNet scaling layer and the backbone (AlexNet: 5 ReLU taps; SqueezeNet 1.1:
   7 taps; see :mod:`platesynth.metrics.networks`),
2. each tap is unit-normalised over channels, ``f / (sqrt(sum_c f^2) + 1e-10)``,
3. the squared difference of the two images' normalised taps is weighted per channel by a learned 1x1 convolution
   (no bias), averaged over space, and the layers' values are summed.

The learned linear weights (BSD-2-Clause, Zhang et al.; see ``lpips_weights/LICENSE``) ship with this package and
are hash-checked on load; the ImageNet backbone is resolved by :mod:`platesynth.weights`.
On the upstream example images the AlexNet variant gives 0.722 for (ex_ref, ex_p0) and 0.138 for (ex_ref, ex_p1).

Public API: :class:`LPIPS` (a ``torch.nn.Module``, differentiable in its inputs) and
:func:`lpips_distance` for two uint8 ``(H, W, 3)`` numpy images (the model is cached per network and weights file).
"""

from __future__ import annotations

import functools
import hashlib
import os
from importlib import resources

import numpy as np
import torch
from torch import nn

from platesynth.errors import ParameterError, ShapeMismatchError, WeightsNotFoundError
from platesynth.io import to_rgb_uint8
from platesynth.limits import load_torch_file
from platesynth.metrics.networks import ImageNetScaling, build_backbone
from platesynth.weights import resolve_weights

# net name: (backbone name, linear-weights file shipped in lpips_weights/, its sha256)
LPIPS_NETS = {
    "alex": ("alexnet", "alex.pth", "df73285e35b22355a2df87cdb6b70b343713b667eddbda73e1977e0c860835c0"),
    "squeeze": ("squeezenet1_1", "squeeze.pth", "4a5350f23600cb79923ce65bb07cbf57dca461329894153e05a1346bd531cf76"),
}
_EPS = 1e-10


def _load_linear_weights(net: str) -> list[torch.Tensor]:
    """The per-layer 1x1 weights ``(1, C, 1, 1)`` of LPIPS v0.1, hash-checked."""
    _, file_name, expected_sha256 = LPIPS_NETS[net]
    resource = resources.files("platesynth.metrics").joinpath("lpips_weights", file_name)
    data = resource.read_bytes()
    if hashlib.sha256(data).hexdigest() != expected_sha256:
        raise WeightsNotFoundError(
            f"{resource}: sha256 does not match the LPIPS v0.1 {net} weights; reinstall platesynth"
        )
    with resources.as_file(resource) as path:
        state_dict = load_torch_file(path)  # tensors only (and hash-checked above)
    return [state_dict[f"lin{i}.model.1.weight"] for i in range(len(state_dict))]


def _unit_normalize(features: torch.Tensor) -> torch.Tensor:
    norm = torch.sqrt(torch.sum(features**2, dim=1, keepdim=True))
    return features / (norm + _EPS)


class LPIPS(nn.Module):
    """LPIPS v0.1 distance between batches of images.

    Parameters
    ----------
    net : {"alex", "squeeze"}
        Backbone: AlexNet (the default, and the variant recommended by the authors as a metric) or SqueezeNet 1.1.
    backbone_weights : str or path-like, optional
        ImageNet weight file of the backbone; otherwise resolved by :func:`platesynth.weights.resolve_weights`.

    Notes
    -----
    ``forward(image0, image1)`` takes two ``(N, 3, H, W)`` float tensors in [-1, 1] of the same shape and returns
    ``(N,)`` distances. Parameters are frozen and the module is in eval mode.
    """

    def __init__(self, net: str = "alex", backbone_weights: str | os.PathLike | None = None) -> None:
        super().__init__()
        if net not in LPIPS_NETS:
            raise ParameterError(f"unknown LPIPS network {net!r}; choose one of {', '.join(LPIPS_NETS)}")
        self.net = net
        self.scaling = ImageNetScaling()
        self.backbone = build_backbone(LPIPS_NETS[net][0], backbone_weights)
        self.linear = nn.ParameterList(nn.Parameter(w, requires_grad=False) for w in _load_linear_weights(net))
        self.eval()

    def forward(self, image0: torch.Tensor, image1: torch.Tensor) -> torch.Tensor:
        taps0 = self.backbone(self.scaling(image0))
        taps1 = self.backbone(self.scaling(image1))
        total = 0
        for f0, f1, weight in zip(taps0, taps1, self.linear, strict=True):
            squared_difference = (_unit_normalize(f0) - _unit_normalize(f1)) ** 2
            weighted = torch.nn.functional.conv2d(squared_difference, weight)
            total = total + weighted.mean(dim=(2, 3))
        return total[:, 0]


def _device() -> torch.device:
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


@functools.lru_cache(maxsize=4)
def _cached_model(net: str, backbone_file: str, device: str) -> LPIPS:
    return LPIPS(net, backbone_file).to(device)


def _to_tensor(image: np.ndarray) -> torch.Tensor:
    """uint8 (H, W, 3) -> (1, 3, H, W) float32 in [-1, 1], as ``lpips.im2tensor``."""
    array = to_rgb_uint8(np.asarray(image)).astype(np.float32) / 127.5 - 1.0
    return torch.from_numpy(array.transpose(2, 0, 1).copy())[None]


def lpips_distance(
    image0: np.ndarray, image1: np.ndarray, net: str = "alex", backbone_weights: str | os.PathLike | None = None
) -> float:
    """LPIPS v0.1 distance between two images.

    Parameters
    ----------
    image0, image1 : numpy.ndarray
        ``(H, W, 3)`` uint8 images of the same shape (grayscale, RGBA and uint16 are converted like
        :func:`platesynth.io.to_rgb_uint8`).
    net : {"alex", "squeeze"}
        Backbone network.
    backbone_weights : str or path-like, optional
        ImageNet weight file of the backbone (see :class:`LPIPS`).

    Returns
    -------
    float
        0 for identical images; larger is more different (typically below 1).

    Raises
    ------
    ShapeMismatchError
        If the images' shapes differ.
    WeightsNotFoundError
        If the backbone weights cannot be found.
    """
    if net not in LPIPS_NETS:
        raise ParameterError(f"unknown LPIPS network {net!r}; choose one of {', '.join(LPIPS_NETS)}")
    tensor0, tensor1 = _to_tensor(image0), _to_tensor(image1)
    if tensor0.shape != tensor1.shape:
        raise ShapeMismatchError(
            f"LPIPS needs images of the same size: {tuple(tensor0.shape[2:])} vs {tuple(tensor1.shape[2:])} (H, W)"
        )
    backbone_file = str(resolve_weights(LPIPS_NETS[net][0], backbone_weights).resolve())
    device = _device()
    model = _cached_model(net, backbone_file, str(device))
    with torch.no_grad():
        return float(model(tensor0.to(device), tensor1.to(device))[0])
