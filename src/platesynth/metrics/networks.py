"""Pretrained image networks written out by hand, so that no torchvision is needed.

Layer layouts and attribute names follow torchvision (AlexNet, SqueezeNet 1.1) and pytorch-fid (FID InceptionV3),
so their published state dicts load unchanged:

* :class:`AlexNetFeatures`: torchvision ``alexnet().features``; keys ``features.{0,3,6,8,10}.{weight,bias}``.
  :meth:`AlexNetFeatures.forward` returns the five ReLU outputs (64, 192, 384, 256, 256 channels) used by LPIPS.
* :class:`SqueezeNetFeatures`: torchvision ``squeezenet1_1().features``; :meth:`SqueezeNetFeatures.forward`
  returns the seven LPIPS taps (64, 128, 256, 384, 384, 512, 512 channels).
* :class:`FIDInceptionV3`: the InceptionV3 of pytorch-fid (TensorFlow's 2015-12-05 graph ported to PyTorch)
  returning the 2048-d pool3 features. It differs from torchvision's InceptionV3 in its pooling: the average
  pools inside the Mixed blocks exclude the zero padding (``count_include_pad=False``, TensorFlow's behaviour), and
  the last block (``Mixed_7c``) max-pools its pool branch. Inputs are ``(N, 3, H, W)`` in [0, 1]; they are resized
  to 299x299 (bilinear, ``align_corners=False``, no antialiasing) and scaled to [-1, 1], as pytorch-fid does.
  Its ``fc.*`` (1008 classes) weights are not used; :func:`load_backbone_state` drops them.

:class:`ImageNetScaling` is the input normalisation shared by AlexNet and SqueezeNet: it takes images in [-1, 1]
(LPIPS's convention) and applies the ImageNet mean/std, which LPIPS writes as shift ``(-.030, -.088, -.188)`` and
scale ``(.458, .448, .450)``.

Use :func:`build_backbone` to get a network with verified pretrained weights (see :mod:`platesynth.weights`).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping

import torch
import torch.nn.functional as F
from torch import nn

from platesynth.errors import ParameterError, WeightsNotFoundError
from platesynth.weights import load_weights


class ImageNetScaling(nn.Module):
    """LPIPS's ScalingLayer: ``(x - shift) / scale`` for inputs in [-1, 1] (the ImageNet mean/std normalisation)."""

    def __init__(self) -> None:
        super().__init__()
        self.register_buffer("shift", torch.tensor([-0.030, -0.088, -0.188]).view(1, 3, 1, 1))
        self.register_buffer("scale", torch.tensor([0.458, 0.448, 0.450]).view(1, 3, 1, 1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.shift) / self.scale


class _TappedFeatures(nn.Module):
    """A ``features`` Sequential whose outputs are collected at the end of given stages."""

    features: nn.Sequential
    tap_ends: tuple[int, ...]
    channels: tuple[int, ...]

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        """Run the layers and return the activations after layers ``tap_ends[i] - 1`` (ReLU outputs)."""
        outputs = []
        start = 0
        for end in self.tap_ends:
            for layer in self.features[start:end]:
                x = layer(x)
            outputs.append(x)
            start = end
        return outputs


class AlexNetFeatures(_TappedFeatures):
    """torchvision AlexNet's convolutional part; ``forward`` returns the 5 ReLU outputs."""

    tap_ends = (2, 5, 8, 10, 12)
    channels = (64, 192, 384, 256, 256)

    def __init__(self) -> None:
        super().__init__()
        self.features = nn.Sequential(
            nn.Conv2d(3, 64, kernel_size=11, stride=4, padding=2),
            nn.ReLU(),
            nn.MaxPool2d(kernel_size=3, stride=2),
            nn.Conv2d(64, 192, kernel_size=5, padding=2),
            nn.ReLU(),
            nn.MaxPool2d(kernel_size=3, stride=2),
            nn.Conv2d(192, 384, kernel_size=3, padding=1),
            nn.ReLU(),
            nn.Conv2d(384, 256, kernel_size=3, padding=1),
            nn.ReLU(),
            nn.Conv2d(256, 256, kernel_size=3, padding=1),
            nn.ReLU(),
            nn.MaxPool2d(kernel_size=3, stride=2),
        )


class Fire(nn.Module):
    """SqueezeNet's Fire module: a 1x1 squeeze, then 1x1 and 3x3 expands concatenated (all followed by ReLU)."""

    def __init__(self, in_channels: int, squeeze_channels: int, expand1x1_channels: int, expand3x3_channels: int):
        super().__init__()
        self.squeeze = nn.Conv2d(in_channels, squeeze_channels, kernel_size=1)
        self.expand1x1 = nn.Conv2d(squeeze_channels, expand1x1_channels, kernel_size=1)
        self.expand3x3 = nn.Conv2d(squeeze_channels, expand3x3_channels, kernel_size=3, padding=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = F.relu(self.squeeze(x))
        return torch.cat([F.relu(self.expand1x1(x)), F.relu(self.expand3x3(x))], dim=1)


class SqueezeNetFeatures(_TappedFeatures):
    """torchvision SqueezeNet 1.1's convolutional part; ``forward`` returns the 7 LPIPS taps."""

    tap_ends = (2, 5, 8, 10, 11, 12, 13)
    channels = (64, 128, 256, 384, 384, 512, 512)

    def __init__(self) -> None:
        super().__init__()
        self.features = nn.Sequential(
            nn.Conv2d(3, 64, kernel_size=3, stride=2),
            nn.ReLU(),
            nn.MaxPool2d(kernel_size=3, stride=2, ceil_mode=True),
            Fire(64, 16, 64, 64),
            Fire(128, 16, 64, 64),
            nn.MaxPool2d(kernel_size=3, stride=2, ceil_mode=True),
            Fire(128, 32, 128, 128),
            Fire(256, 32, 128, 128),
            nn.MaxPool2d(kernel_size=3, stride=2, ceil_mode=True),
            Fire(256, 48, 192, 192),
            Fire(384, 48, 192, 192),
            Fire(384, 64, 256, 256),
            Fire(512, 64, 256, 256),
        )


class BasicConv2d(nn.Module):
    """Convolution without bias, batch norm (eps 0.001), ReLU: Inception's unit (keys ``conv.*``, ``bn.*``)."""

    def __init__(self, in_channels: int, out_channels: int, **conv_kwargs) -> None:
        super().__init__()
        self.conv = nn.Conv2d(in_channels, out_channels, bias=False, **conv_kwargs)
        self.bn = nn.BatchNorm2d(out_channels, eps=0.001)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.relu(self.bn(self.conv(x)))


def _pool_3x3_same(x: torch.Tensor) -> torch.Tensor:
    """TensorFlow's 3x3 stride-1 'SAME' average pool: padded zeros are not counted."""
    return F.avg_pool2d(x, kernel_size=3, stride=1, padding=1, count_include_pad=False)


class InceptionA(nn.Module):
    """Mixed_5b/c/d (FID variant: pool branch averages without the padding)."""

    def __init__(self, in_channels: int, pool_features: int) -> None:
        super().__init__()
        self.branch1x1 = BasicConv2d(in_channels, 64, kernel_size=1)
        self.branch5x5_1 = BasicConv2d(in_channels, 48, kernel_size=1)
        self.branch5x5_2 = BasicConv2d(48, 64, kernel_size=5, padding=2)
        self.branch3x3dbl_1 = BasicConv2d(in_channels, 64, kernel_size=1)
        self.branch3x3dbl_2 = BasicConv2d(64, 96, kernel_size=3, padding=1)
        self.branch3x3dbl_3 = BasicConv2d(96, 96, kernel_size=3, padding=1)
        self.branch_pool = BasicConv2d(in_channels, pool_features, kernel_size=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        branch5x5 = self.branch5x5_2(self.branch5x5_1(x))
        branch3x3dbl = self.branch3x3dbl_3(self.branch3x3dbl_2(self.branch3x3dbl_1(x)))
        branch_pool = self.branch_pool(_pool_3x3_same(x))
        return torch.cat([self.branch1x1(x), branch5x5, branch3x3dbl, branch_pool], dim=1)


class InceptionB(nn.Module):
    """Mixed_6a: grid reduction 35 -> 17."""

    def __init__(self, in_channels: int) -> None:
        super().__init__()
        self.branch3x3 = BasicConv2d(in_channels, 384, kernel_size=3, stride=2)
        self.branch3x3dbl_1 = BasicConv2d(in_channels, 64, kernel_size=1)
        self.branch3x3dbl_2 = BasicConv2d(64, 96, kernel_size=3, padding=1)
        self.branch3x3dbl_3 = BasicConv2d(96, 96, kernel_size=3, stride=2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        branch3x3dbl = self.branch3x3dbl_3(self.branch3x3dbl_2(self.branch3x3dbl_1(x)))
        branch_pool = F.max_pool2d(x, kernel_size=3, stride=2)
        return torch.cat([self.branch3x3(x), branch3x3dbl, branch_pool], dim=1)


class InceptionC(nn.Module):
    """Mixed_6b/c/d/e with factorised 7x7 convolutions (FID variant: pool branch averages without the padding)."""

    def __init__(self, in_channels: int, channels_7x7: int) -> None:
        super().__init__()
        c7 = channels_7x7
        self.branch1x1 = BasicConv2d(in_channels, 192, kernel_size=1)
        self.branch7x7_1 = BasicConv2d(in_channels, c7, kernel_size=1)
        self.branch7x7_2 = BasicConv2d(c7, c7, kernel_size=(1, 7), padding=(0, 3))
        self.branch7x7_3 = BasicConv2d(c7, 192, kernel_size=(7, 1), padding=(3, 0))
        self.branch7x7dbl_1 = BasicConv2d(in_channels, c7, kernel_size=1)
        self.branch7x7dbl_2 = BasicConv2d(c7, c7, kernel_size=(7, 1), padding=(3, 0))
        self.branch7x7dbl_3 = BasicConv2d(c7, c7, kernel_size=(1, 7), padding=(0, 3))
        self.branch7x7dbl_4 = BasicConv2d(c7, c7, kernel_size=(7, 1), padding=(3, 0))
        self.branch7x7dbl_5 = BasicConv2d(c7, 192, kernel_size=(1, 7), padding=(0, 3))
        self.branch_pool = BasicConv2d(in_channels, 192, kernel_size=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        branch7x7 = self.branch7x7_3(self.branch7x7_2(self.branch7x7_1(x)))
        branch7x7dbl = x
        for layer in (self.branch7x7dbl_1, self.branch7x7dbl_2, self.branch7x7dbl_3, self.branch7x7dbl_4,
                      self.branch7x7dbl_5):
            branch7x7dbl = layer(branch7x7dbl)
        branch_pool = self.branch_pool(_pool_3x3_same(x))
        return torch.cat([self.branch1x1(x), branch7x7, branch7x7dbl, branch_pool], dim=1)


class InceptionD(nn.Module):
    """Mixed_7a: grid reduction 17 -> 8."""

    def __init__(self, in_channels: int) -> None:
        super().__init__()
        self.branch3x3_1 = BasicConv2d(in_channels, 192, kernel_size=1)
        self.branch3x3_2 = BasicConv2d(192, 320, kernel_size=3, stride=2)
        self.branch7x7x3_1 = BasicConv2d(in_channels, 192, kernel_size=1)
        self.branch7x7x3_2 = BasicConv2d(192, 192, kernel_size=(1, 7), padding=(0, 3))
        self.branch7x7x3_3 = BasicConv2d(192, 192, kernel_size=(7, 1), padding=(3, 0))
        self.branch7x7x3_4 = BasicConv2d(192, 192, kernel_size=3, stride=2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        branch3x3 = self.branch3x3_2(self.branch3x3_1(x))
        branch7x7x3 = self.branch7x7x3_4(self.branch7x7x3_3(self.branch7x7x3_2(self.branch7x7x3_1(x))))
        branch_pool = F.max_pool2d(x, kernel_size=3, stride=2)
        return torch.cat([branch3x3, branch7x7x3, branch_pool], dim=1)


class InceptionE(nn.Module):
    """Mixed_7b/c with expanded filter banks.

    ``max_pool_branch=False`` (Mixed_7b) averages without the padding; ``True`` (Mixed_7c) max-pools, a quirk of the
    TensorFlow graph that FID was defined with.
    """

    def __init__(self, in_channels: int, max_pool_branch: bool) -> None:
        super().__init__()
        self.max_pool_branch = max_pool_branch
        self.branch1x1 = BasicConv2d(in_channels, 320, kernel_size=1)
        self.branch3x3_1 = BasicConv2d(in_channels, 384, kernel_size=1)
        self.branch3x3_2a = BasicConv2d(384, 384, kernel_size=(1, 3), padding=(0, 1))
        self.branch3x3_2b = BasicConv2d(384, 384, kernel_size=(3, 1), padding=(1, 0))
        self.branch3x3dbl_1 = BasicConv2d(in_channels, 448, kernel_size=1)
        self.branch3x3dbl_2 = BasicConv2d(448, 384, kernel_size=3, padding=1)
        self.branch3x3dbl_3a = BasicConv2d(384, 384, kernel_size=(1, 3), padding=(0, 1))
        self.branch3x3dbl_3b = BasicConv2d(384, 384, kernel_size=(3, 1), padding=(1, 0))
        self.branch_pool = BasicConv2d(in_channels, 192, kernel_size=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        branch3x3 = self.branch3x3_1(x)
        branch3x3 = torch.cat([self.branch3x3_2a(branch3x3), self.branch3x3_2b(branch3x3)], dim=1)
        branch3x3dbl = self.branch3x3dbl_2(self.branch3x3dbl_1(x))
        branch3x3dbl = torch.cat([self.branch3x3dbl_3a(branch3x3dbl), self.branch3x3dbl_3b(branch3x3dbl)], dim=1)
        if self.max_pool_branch:
            pooled = F.max_pool2d(x, kernel_size=3, stride=1, padding=1)
        else:
            pooled = _pool_3x3_same(x)
        return torch.cat([self.branch1x1(x), branch3x3, branch3x3dbl, self.branch_pool(pooled)], dim=1)


class FIDInceptionV3(nn.Module):
    """pytorch-fid's InceptionV3 up to pool3: ``(N, 3, H, W)`` in [0, 1] -> ``(N, 2048)``.

    Parameters
    ----------
    resize_input : bool
        Resize inputs to 299x299 bilinearly (``align_corners=False``), as pytorch-fid does by default.
    normalize_input : bool
        Scale inputs from [0, 1] to [-1, 1], the range the network was trained on.
    """

    input_size = (299, 299)
    dim = 2048

    def __init__(self, resize_input: bool = True, normalize_input: bool = True) -> None:
        super().__init__()
        self.resize_input = resize_input
        self.normalize_input = normalize_input
        self.Conv2d_1a_3x3 = BasicConv2d(3, 32, kernel_size=3, stride=2)
        self.Conv2d_2a_3x3 = BasicConv2d(32, 32, kernel_size=3)
        self.Conv2d_2b_3x3 = BasicConv2d(32, 64, kernel_size=3, padding=1)
        self.Conv2d_3b_1x1 = BasicConv2d(64, 80, kernel_size=1)
        self.Conv2d_4a_3x3 = BasicConv2d(80, 192, kernel_size=3)
        self.Mixed_5b = InceptionA(192, pool_features=32)
        self.Mixed_5c = InceptionA(256, pool_features=64)
        self.Mixed_5d = InceptionA(288, pool_features=64)
        self.Mixed_6a = InceptionB(288)
        self.Mixed_6b = InceptionC(768, channels_7x7=128)
        self.Mixed_6c = InceptionC(768, channels_7x7=160)
        self.Mixed_6d = InceptionC(768, channels_7x7=160)
        self.Mixed_6e = InceptionC(768, channels_7x7=192)
        self.Mixed_7a = InceptionD(768)
        self.Mixed_7b = InceptionE(1280, max_pool_branch=False)
        self.Mixed_7c = InceptionE(2048, max_pool_branch=True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.resize_input:
            x = F.interpolate(x, size=self.input_size, mode="bilinear", align_corners=False)
        if self.normalize_input:
            x = 2 * x - 1
        x = self.Conv2d_2b_3x3(self.Conv2d_2a_3x3(self.Conv2d_1a_3x3(x)))
        x = F.max_pool2d(x, kernel_size=3, stride=2)
        x = self.Conv2d_4a_3x3(self.Conv2d_3b_1x1(x))
        x = F.max_pool2d(x, kernel_size=3, stride=2)
        for block in (self.Mixed_5b, self.Mixed_5c, self.Mixed_5d, self.Mixed_6a, self.Mixed_6b, self.Mixed_6c,
                      self.Mixed_6d, self.Mixed_6e, self.Mixed_7a, self.Mixed_7b, self.Mixed_7c):
            x = block(x)
        return torch.flatten(F.adaptive_avg_pool2d(x, 1), 1)


BACKBONES: dict[str, tuple[type[nn.Module], str, tuple[str, ...]]] = {
    # name: (module class, weights registry key, key prefixes of the weight files that the module does not use)
    "alexnet": (AlexNetFeatures, "alexnet", ("classifier.",)),
    "squeezenet1_1": (SqueezeNetFeatures, "squeezenet1_1", ("classifier.",)),
    "inception_fid": (FIDInceptionV3, "inception_fid", ("fc.", "AuxLogits.")),
}


def load_backbone_state(
    module: nn.Module, state_dict: Mapping[str, torch.Tensor], ignored_prefixes: Iterable[str] = ()
) -> None:
    """Load ``state_dict`` into ``module`` strictly, after dropping keys under ``ignored_prefixes``.

    Batch-norm ``num_batches_tracked`` counters may be absent (they are not used in inference).

    Raises
    ------
    WeightsNotFoundError
        If keys are missing or unexpected, or shapes differ: the file does not fit the architecture.
    """
    ignored = tuple(ignored_prefixes)
    kept = {k: v for k, v in state_dict.items() if not k.startswith(ignored)}
    expected = module.state_dict()
    missing = sorted(k for k in expected if k not in kept and not k.endswith("num_batches_tracked"))
    unexpected = sorted(k for k in kept if k not in expected)
    wrong_shape = sorted(k for k in kept if k in expected and kept[k].shape != expected[k].shape)
    if missing or unexpected or wrong_shape:
        raise WeightsNotFoundError(
            f"weights do not fit {type(module).__name__}: missing {missing[:3]}, unexpected {unexpected[:3]}, "
            f"wrong shape {wrong_shape[:3]}"
        )
    for key, value in expected.items():
        if key.endswith("num_batches_tracked") and key not in kept:
            kept[key] = value
    module.load_state_dict(kept, strict=True)


def build_backbone(name: str, weights: str | os.PathLike | None = None) -> nn.Module:
    """A pretrained backbone in eval mode with frozen parameters.

    Parameters
    ----------
    name : {"alexnet", "squeezenet1_1", "inception_fid"}
        Which network.
    weights : str or path-like, optional
        Explicit weight file; otherwise resolved as described in :mod:`platesynth.weights`.

    Raises
    ------
    WeightsNotFoundError
        If the weights cannot be found, are corrupt or do not fit.
    """
    try:
        module_class, registry_key, ignored_prefixes = BACKBONES[name]
    except KeyError:
        raise ParameterError(f"unknown backbone {name!r}; known: {', '.join(BACKBONES)}") from None
    module = module_class()
    load_backbone_state(module, load_weights(registry_key, weights), ignored_prefixes)
    module.eval()
    module.requires_grad_(False)
    return module
