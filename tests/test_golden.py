"""Golden renders: a small raster render of every preset is pinned, so that a change of look is deliberate.

A change that alters how an image looks fails here; if the change is meant, update the hashes in the same commit
(``python tests/test_golden.py`` prints the current ones) and say in the commit message what changed and why.
"""

from __future__ import annotations

import hashlib

import pytest

from platesynth.render.raster import render_raster
from platesynth.scene import list_presets, load_config, sample_scene

GOLDEN_SIZE = (320, 240)
GOLDEN_SEED = 3
GOLDEN = {
    # preset: sha256[:16] of (image, well mask, plaque mask) bytes
    "diverse": ("481d941fcd0f3c0e", "844f673d905e5611", "9d6d1664aeb1e953"),
    "high": ("befc9515dff00a80", "b8d69b0a3053cc3c", "eecb9a922f44a7aa"),
    "lightbox12": ("e7ec8c032f5eff51", "628d50b8fa623f9f", "823fd4f4b0b7dc7f"),
    "low": ("4cd9717deefdb4db", "746052f88d9526dc", "1d78f3ec8ecc4589"),
    "medium": ("88c6059e7c06d422", "6d3d02473c2a6619", "428d11b17a0a7657"),
}


def golden_hashes(preset: str) -> tuple[str, str, str]:
    """Hashes of the image and both masks of ``preset`` at :data:`GOLDEN_SEED` and :data:`GOLDEN_SIZE`."""
    result = render_raster(sample_scene(load_config(preset), GOLDEN_SEED), GOLDEN_SIZE)
    return tuple(hashlib.sha256(a.tobytes()).hexdigest()[:16] for a in (result.image, result.wells, result.plaques))


def test_every_preset_is_pinned():
    assert sorted(GOLDEN) == sorted(list_presets())


@pytest.mark.parametrize("preset", sorted(GOLDEN))
def test_preset_renders_as_pinned(preset):
    assert golden_hashes(preset) == GOLDEN[preset]


if __name__ == "__main__":
    for name in list_presets():
        print(f'    "{name}": {golden_hashes(name)},')
