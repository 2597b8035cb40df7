"""The scene's noise textures: drawn once from the seed, the same arrays for both renderers."""

from __future__ import annotations

import numpy as np
import pytest

from platesynth.render.textures import noise_grid, plate_grid_index, scene_textures
from platesynth.scene import load_config, sample_scene
from platesynth.scene.streams import STREAMS, scene_rng


def test_textures_are_fixed_by_the_seed_and_differ_between_seeds():
    scene = sample_scene(load_config("high"), 3)
    first, again = scene_textures(scene), scene_textures(scene)
    other = scene_textures(scene.model_copy(update={"seed": scene.seed + 1}))
    for name in ("well_offsets", "low_grid", "fine_tile", "residual_tile"):
        assert np.array_equal(getattr(first, name), getattr(again, name)), name
        assert not np.allclose(getattr(first, name), getattr(other, name)), name
    assert first.fine_tile.shape == (256, 256) and first.residual_tile.shape == (128, 128)
    for tile in (first.fine_tile, first.residual_tile, first.low_grid):
        assert abs(float(tile.mean())) < 1e-4 and abs(float(tile.std()) - 1.0) < 1e-3
    assert first.well_offsets.shape == (len(scene.wells), 2)
    assert ((first.well_offsets >= 0) & (first.well_offsets < 100.0)).all()


def test_the_unevenness_grid_covers_the_plate_in_cells_of_half_the_scale():
    scene = sample_scene(load_config("high"), 3)
    textures = scene_textures(scene)
    assert textures.low_cell_mm == pytest.approx(scene.stain.unevenness_scale_mm / 2)
    rows, cols = textures.low_grid.shape
    assert rows * textures.low_cell_mm >= scene.plate.width_mm and cols * textures.low_cell_mm >= scene.plate.length_mm


def test_the_fibre_grid_exists_only_when_a_well_is_lysed():
    # a plate with plaques whose every well holding more than one is lysed
    lysed = sample_scene(load_config("high", overrides={"plaques.lysis_count": 1, "plaques.negative_plate": 0.0}), 1000)
    intact = sample_scene(load_config("high", overrides={"plaques.negative_plate": 1.0}), 1000)
    assert any(w.lysed for w in lysed.wells) and not any(w.lysed for w in intact.wells)
    assert scene_textures(lysed).fibre_grid is not None
    assert scene_textures(intact).fibre_grid is None


def test_streams_are_independent_generators_of_the_seed():
    draws = {stream: scene_rng(7, stream).random(4) for stream in STREAMS}
    assert len({tuple(d) for d in draws.values()}) == len(STREAMS)
    assert np.array_equal(scene_rng(7, "fine").random(4), draws["fine"])
    with pytest.raises(ValueError):
        scene_rng(7, "nonexistent")


@pytest.mark.parametrize("plate_format", [6, 12, 24, 96])
def test_every_well_has_its_own_place_in_the_plate_grid(plate_format):
    scene = sample_scene(load_config("high", overrides={"plate.format": plate_format}), 0)
    indices = sorted(plate_grid_index(scene.plate, w.center_mm) for w in scene.wells)
    assert indices == list(range(scene.plate.rows * scene.plate.cols))
    assert plate_grid_index(scene.plate, (-50.0, -50.0)) == -1


def test_noise_grid_wraps_when_periodic():
    tile = noise_grid(np.random.default_rng(0), (64, 64), 3.0, periodic=True)
    edge_step = np.abs(tile[:, 0] - tile[:, -1]).mean()
    inner_step = np.abs(np.diff(tile, axis=1)).mean()
    assert edge_step < 2 * inner_step
