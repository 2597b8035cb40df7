"""The statistics that tell tiles apart (benchmarks/tile_tells.py) and the scrape's measures
(benchmarks/scrape_look.py), on drawn tiles whose answers are known."""

from __future__ import annotations

import numpy as np
import pytest

from _benchmarks import benchmark_module
from platesynth.render.look import LUMINANCE

SIDE = 200


@pytest.fixture(scope="module")
def tells():
    yield from benchmark_module("tile_tells")


@pytest.fixture(scope="module")
def scrapes():
    yield from benchmark_module("scrape_look")


def well_tile(stain=(80.0, 0.0, 216.0), wall=(170.0, 175.0, 200.0), wall_sd: float = 0.0, seed: int = 0):
    """A tile with a disc of ``stain`` out to 0.97 of its half-side and ``wall`` around it, plus Gaussian noise of
    ``wall_sd`` levels outside the disc."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:SIDE, :SIDE]
    radius = np.hypot(yy - SIDE / 2 + 0.5, xx - SIDE / 2 + 0.5) / (SIDE / 2)
    tile = np.empty((SIDE, SIDE, 3))
    tile[...] = wall
    tile[radius >= 0.97] += rng.normal(0.0, wall_sd, ((radius >= 0.97).sum(), 1))
    tile[radius < 0.97] = stain
    return np.clip(np.round(tile), 0, 255).astype(np.uint8)


def test_a_flat_tile_has_its_colour_in_the_middle_and_no_detail(tells):
    stats = tells.tile_statistics(well_tile())
    assert (stats["middle R"], stats["middle G"], stats["middle B"]) == (80.0, 0.0, 216.0)
    assert all(stats[f"layer detail {s:g} px"] == pytest.approx(0.0, abs=1e-9) for s in tells.SCALES_PX)
    assert stats["layer unevenness"] == pytest.approx(0.0, abs=1e-9)
    assert stats["bottom - top"] == pytest.approx(0.0, abs=1e-9)
    luminance = np.dot(LUMINANCE, (170.0, 175.0, 200.0))
    assert stats["corners level"] == pytest.approx(luminance, abs=1e-6)
    assert stats["corners red - green"] == pytest.approx(-5.0) and stats["corners blue - green"] == pytest.approx(25.0)
    # the rings past the stain's edge hold the wall, brighter than the middle by the difference of their luminances
    assert stats["ring 1.01-1.04 level"] == pytest.approx(luminance - np.dot(LUMINANCE, (80.0, 0.0, 216.0)))


def test_separation_is_one_where_every_photo_lies_above_every_render_and_a_half_where_they_mix(tells):
    photos = [tells.tile_statistics(well_tile(stain=(80, 0, 210 + i), wall_sd=5.0, seed=i)) for i in range(6)]
    renders = [tells.tile_statistics(well_tile(stain=(80, 0, 190 + i), wall_sd=5.0, seed=10 + i)) for i in range(6)]
    rows = {name: (auc, real, rendered) for name, auc, real, rendered in tells.separation(photos, renders)}
    assert rows["middle B"] == (1.0, 212.5, 192.5)
    assert rows["middle G"][0] == 0.5  # all alike: ties count a half
    # the corners' spread is the same noise drawn with other seeds: no side holds every larger value
    assert 0.1 < rows["corners sd"][0] < 0.9


def scraped_tile(width: int, ragged: bool = False, colour=(190.0, 160.0, 245.0)) -> np.ndarray:
    """A saturated well with a pale vertical strip from the rim at the top down 40 pixels, ``width`` pixels wide
    (every other row one pixel narrower on each side where ``ragged``)."""
    tile = well_tile()
    for row in range(4, 44):
        half = width // 2 - (1 if ragged and row % 2 else 0)
        tile[row, SIDE // 2 - half: SIDE // 2 + half] = colour
    return tile


def test_a_scrape_from_the_rim_is_measured_and_a_spot_in_the_middle_is_not(scrapes):
    assert scrapes.is_saturated(well_tile()) and not scrapes.is_saturated(well_tile(stain=(150, 140, 230)))
    length, width, width_cv, solidity, red, green, blue = scrapes.scrape_measures(scraped_tile(8))
    # a 40 x 8 rectangle of pixels: its longest extent is its diagonal, about 40 pixels
    assert length == pytest.approx(40.0, rel=0.02)
    assert width == pytest.approx(8.0, rel=0.02) and width_cv == 0.0 and solidity == 1.0
    assert (red, green, blue) == (190.0, 160.0, 245.0)
    ragged = scrapes.scrape_measures(scraped_tile(8, ragged=True))
    assert ragged[2] == pytest.approx(1 / 7, rel=1e-6)  # widths 8 and 6 in turn: sd 1 over mean 7
    assert ragged[3] < 1.0
    spot = well_tile()
    spot[90:110, 90:110] = (190, 160, 245)  # a pale plaque in the middle: not a scrape
    assert scrapes.scrape_measures(spot) is None
