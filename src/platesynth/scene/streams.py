"""Named random streams of a scene's seed, beside the sampler's own generator.

:func:`~platesynth.scene.sample.sample_scene` draws a scene's parameters in a fixed order from
``numpy.random.default_rng(seed)``. Everything else drawn from the seed (the renderers' noise textures, a parameter
added after the others) comes from one of :data:`STREAMS`, spawned from ``numpy.random.SeedSequence(seed)``: adding
a stream never changes the others, nor the sampler's order, so scenes drawn before stay as they were.
"""

from __future__ import annotations

import numpy as np

STREAMS = ("well_offsets", "unevenness", "fibres", "desk", "fine", "residual", "post", "mottle", "stain_palette",
           "lysed_palette", "scratch_edges", "lysed_disc",
           "plate_walls", "lysed_clumps", "rim_band", "plate_floor", "wall_stain", "pipette_pose",
           "plaque_lumps", "lysed_speckle", "sharpen_luma",
           "top_edge_blur", "noise_grain", "wall_slant", "wall_glints", "wall_glint_harmonics",
           "scratch_clearing", "scratch_softness", "scratch_haze",
           "rim_patches", "label_place", "crescent_veil",
           "wall_lines", "wall_highlights", "plaque_residual_mottle", "plaque_residual_tint",
           "lysed_lace", "black_level", "rim_tears", "scratch_heaps",
           "scratch_ridge", "scratch_ridge_sides", "stain_pooling", "rim_mottle_grain",
           "plaque_edge_floor", "panel_shade", "crowd_thinning", "lysed_foam", "foam", "unevenness_light",
           "lysed_rim_loss", "lysed_haze", "plaque_edge_grain", "plaque_edge_grain_width",
           "sharpen_threshold", "smears")
"""The random streams of a scene's seed, in the order they are spawned (append new ones at the end)."""


def scene_rng(seed: int, stream: str) -> np.random.Generator:
    """The generator of one of :data:`STREAMS` for a scene's ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(int(seed)).spawn(len(STREAMS))[STREAMS.index(stream)])
