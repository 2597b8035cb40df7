"""The grain statistics of saturated wells (benchmarks/well_grain.py), on tiles whose grain is known."""

from __future__ import annotations

import numpy as np
import pytest

from _benchmarks import benchmark_module


@pytest.fixture(scope="module")
def grain():
    yield from benchmark_module("well_grain")


def tile(rgb, shared_sd: float, own_sd: float, seed: int = 0) -> np.ndarray:
    """A 200x200 well crop of one colour with Gaussian noise, ``shared_sd`` the same in every channel and ``own_sd``
    each channel's own (8-bit levels), rounded and clipped as an image is stored."""
    rng = np.random.default_rng(seed)
    shared = rng.normal(0.0, shared_sd, (200, 200, 1))
    own = rng.normal(0.0, own_sd, (200, 200, 3))
    return np.clip(np.round(np.array(rgb, float) + shared + own), 0, 255).astype(np.uint8)


def test_grey_grain_is_the_same_in_every_channel_and_colour_noise_is_not(grain):
    grey = grain.grain_statistics(tile((90, 30, 200), shared_sd=3.0, own_sd=0.0))
    # white noise less its 2-D blur of sd 1 px, whose centre weight is 1 / (2 pi) and squared weights sum to 1 / (4 pi):
    # a variance of 1 - 2 / (2 pi) + 1 / (4 pi) of the noise's
    assert grey["fine_sd"] == pytest.approx(3.0 * np.sqrt(1 - 1 / np.pi + 1 / (4 * np.pi)), rel=0.03)
    assert grey["rb_corr"] > 0.99 and grey["chroma_over_luma"] < 0.05
    colour = grain.grain_statistics(tile((90, 30, 200), shared_sd=0.0, own_sd=3.0))
    # independent channels: red minus blue has twice a channel's variance, the mean of three a third of it
    assert colour["rb_corr"] == pytest.approx(0.0, abs=0.03)
    assert colour["chroma_over_luma"] == pytest.approx(np.sqrt(2 * 3), rel=0.05)
    assert grey["green_clipped"] == 0.0 and grey["green_mean"] == pytest.approx(30.0, abs=0.1)


def test_a_clipped_green_is_counted_and_pale_wells_are_left_out(grain):
    crushed = grain.grain_statistics(tile((90, 0, 200), shared_sd=0.0, own_sd=1.0))
    # levels 0 and 1 count as clipped: noise of sd 1 about 0 stays under 1.5 with the normal's chance 0.933
    assert crushed["green_clipped"] == pytest.approx(0.933, abs=0.02)
    assert grain.grain_statistics(tile((150, 120, 230), shared_sd=1.0, own_sd=0.0)) is None  # green over 60


def test_blotches_are_the_blue_left_after_the_trend(grain):
    """A smooth gradient of blue is trend (no blotch); a blue wave a few millimetres long is blotch, its sd that of a
    sine of its amplitude (blurred by BLOTCH_SIGMA pixels: exp(-(k sigma)^2 / 2) of it)."""
    y, x = np.mgrid[:200, :200].astype(float)
    gradient = np.zeros((200, 200, 3))
    gradient[...] = (90.0, 0.0, 200.0)
    gradient[..., 2] += 0.1 * (y - 100) + 0.05 * (x - 100)
    smooth = grain.blotch_statistics(gradient)
    assert smooth["blue_blotch_sd"] < 0.05 and smooth["blue_spread_sd"] > 3.0
    wavelength = 40.0  # pixels: about 4.4 mm of a 22 mm well
    waves = gradient.copy()
    waves[..., 2] = 200.0 + 4.0 * np.sin(2 * np.pi * x / wavelength) * np.sin(2 * np.pi * y / wavelength)
    k = 2 * np.pi / wavelength
    expected = 4.0 * 0.5 * np.exp(-(k * grain.BLOTCH_SIGMA) ** 2)  # both factors blurred; sd of sin * sin is 1/2
    assert grain.blotch_statistics(waves)["blue_blotch_sd"] == pytest.approx(expected, rel=0.15)
