"""The scene's noise textures, drawn once from its seed and read by both renderers.

The raster renderer samples these arrays in its kernels; the Blender backend turns them into image textures
that its shaders look up at the same plate positions. So a scene has one stain unevenness, one drying texture,
one plaque fray and one pattern of lysed remnants and foam, whichever renderer draws it.

Every random stream a renderer draws from a scene's seed is one of
:data:`~platesynth.scene.streams.STREAMS`, spawned from ``numpy.random.SeedSequence(scene.seed)``: adding a stream
never changes the others.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from platesynth.scene.concrete import PlateGeometry, Scene
from platesynth.scene.streams import scene_rng

FINE_CELL_MM = 0.05
"""Cell of the drying texture on the monolayer (the fine tile)."""
FUZZ_CELL_MM = 0.15
"""Cell of a plaque's frayed edge along its radius (the fine tile again; around the plaque its 256 columns)."""
RESIDUAL_CELL_MM = 0.1
"""Cell of the stain left inside plaques (the residual tile)."""
FIBRE_CELL_MM = 0.25
"""Cell of the strands left in lysed wells (the fibre grid)."""
FOAM_TILE = 512
"""Side of the foam tile (texels)..."""
FOAM_HOLE_TEXELS = 12.0
"""...whose holes have this median radius: the tile is read at ``stain.lysed_foam_mm / FOAM_HOLE_TEXELS`` mm per
texel, so its period is about 43 median radii, wider than a 12-well plate's well for radii from 0.5 mm..."""
FOAM_RADIUS_SPREAD = 0.5
"""...spread by this sd of their log radius..."""
FOAM_COVERAGE = 2.0
"""...up to as many as would add up to this share of the tile's area..."""
FOAM_SEPARATION = 0.6
"""...thrown at random, one after the other, each kept only if no two holes' centres lie nearer than this share of
the sum of their radii (a hole whose centre lay inside another drew a ring within it): about 96 % are kept, the
larger ones less often, their discs adding up to about the tile's area, so that thin walls and islands of stain are
left between the merged holes..."""
FOAM_EDGE = 0.3
"""...each hole's clearing falling from full to none across this share of its radius at its outline..."""
FOAM_WALL, FOAM_WALL_TEXELS = 0.4, 0.8
"""...and where two holes meet, a thin wall keeps this share of the stain: along the line where a texel lies as far
inside both holes' outlines, fading over this sd (texels) of the difference of the two distances, as the photos'
merged clearings keep a fine line of cells between them."""
WELL_OFFSET_RANGE_MM = 100.0
"""Each well reads the periodic tiles shifted by its own offset, uniform in [0, this)."""
WALL_GLINT_HARMONICS = 3
"""The uneven brightness around a well's wall is a Fourier series of this many angular harmonics (1, 2, 3); the
raster renderer's ``shading.band_sheen`` and Blender's rim material sum exactly three."""


def plate_grid_index(plate: PlateGeometry, center_mm: tuple[float, float]) -> int:
    """Row-major index in the plate's own grid (row letter, then column number) of the well centred at
    ``center_mm``; may lie outside ``range(rows * cols)`` for a point off the grid."""
    col = round((center_mm[0] - plate.a1_x_mm) / plate.pitch_mm)
    row = round((center_mm[1] - plate.a1_y_mm) / plate.pitch_mm)
    return row * plate.cols + col if 0 <= row < plate.rows and 0 <= col < plate.cols else -1


def noise_grid(rng: np.random.Generator, shape: tuple[int, int], smooth: float, periodic: bool = False) -> np.ndarray:
    """Zero-mean, unit-sd Gaussian-smoothed noise of ``shape`` (float32); ``periodic`` wraps at the edges."""
    grid = rng.standard_normal(shape).astype(np.float32)
    grid = ndimage.gaussian_filter(grid, smooth, mode="wrap" if periodic else "nearest")
    return ((grid - grid.mean()) / (grid.std() + 1e-6)).astype(np.float32)


def foam_tile(rng: np.random.Generator) -> np.ndarray:
    """A periodic :data:`FOAM_TILE`-square tile of merged round holes: each texel's clearing, 0 (stain left) to 1
    (inside a hole): the soft disc of the hole it lies deepest in, less a thin wall where it lies as deep in a second
    one (float32)."""
    mean_area = np.pi * FOAM_HOLE_TEXELS**2 * np.exp(2.0 * FOAM_RADIUS_SPREAD**2)
    wanted = int(round(FOAM_COVERAGE * FOAM_TILE**2 / mean_area))
    candidates = rng.uniform(0.0, FOAM_TILE, (4 * wanted, 2))
    candidate_radii = FOAM_HOLE_TEXELS * np.exp(FOAM_RADIUS_SPREAD * rng.standard_normal(4 * wanted))
    centres, radii, kept = np.empty((wanted, 2)), np.empty(wanted), 0
    for centre, radius in zip(candidates, candidate_radii):
        apart = np.abs(centres[:kept] - centre)
        apart = np.minimum(apart, FOAM_TILE - apart)  # periodic
        if np.all(np.hypot(apart[:, 0], apart[:, 1]) > FOAM_SEPARATION * (radii[:kept] + radius)):
            centres[kept], radii[kept] = centre, radius
            kept += 1
            if kept == wanted:
                break
    centres, radii = centres[:kept], radii[:kept]
    deepest = np.full((FOAM_TILE, FOAM_TILE), -FOAM_TILE, dtype=np.float64)
    second = deepest.copy()
    for (cx, cy), radius in zip(centres, radii):
        reach = int(np.ceil(radius * (1.0 + FOAM_EDGE))) + 2
        cols = np.arange(int(cx) - reach, int(cx) + reach + 1)
        rows = np.arange(int(cy) - reach, int(cy) + reach + 1)
        depth = radius - np.hypot(cols[None, :] + 0.5 - cx, rows[:, None] + 0.5 - cy)  # texels inside its outline
        index = np.ix_(rows % FOAM_TILE, cols % FOAM_TILE)
        second[index] = np.maximum(second[index], np.minimum(deepest[index], depth))
        deepest[index] = np.maximum(deepest[index], depth)
    edge = FOAM_EDGE * FOAM_HOLE_TEXELS
    hole = np.clip(deepest / edge + 0.5, 0.0, 1.0)
    meeting = np.clip(second / edge + 0.5, 0.0, 1.0)
    wall = FOAM_WALL * meeting * np.exp(-0.5 * ((deepest - second) / FOAM_WALL_TEXELS) ** 2)
    return (hole * (1.0 - wall)).astype(np.float32)


@dataclass(frozen=True)
class SceneTextures:
    """A scene's noise textures (all zero mean, unit standard deviation).

    Grids cover the plate from its corner (plate millimetres ``(u, v)`` are read at column ``u / cell`` and row
    ``v / cell``, clamped at the border); tiles are periodic and read at ``(u + offset) / cell``.

    Attributes
    ----------
    well_offsets : (n_wells, 2) array
        Each well's shift into the tiles (mm), row ``i`` for the well at :func:`plate_grid_index` ``i``.
    low_grid, low_cell_mm : the stain's low-frequency unevenness (cells half the unevenness scale).
    fibre_grid : the lysed wells' strands (cells :data:`FIBRE_CELL_MM`); ``None`` when no well is lysed.
    fine_tile : 256 x 256 tile of the drying texture and of the plaques' fray.
    residual_tile : 128 x 128 tile of the stain left inside plaques.
    mottle_tile : 256 x 256 tile of the patchy cells along the rims.
    foam_tile : :data:`FOAM_TILE`-square tile of the holes of a lysed well's foam (:func:`foam_tile`, 0 to 1); a 2 x 2
        zero tile when no lysed well has a foam.
    wall_glints : (n_wells, 2 * WALL_GLINT_HARMONICS) array
        Each well's unit-sd Fourier coefficients ``(a1, b1, a2, b2, ...)`` of its wall's uneven brightness, rows as
        in ``well_offsets``.
    """

    well_offsets: np.ndarray
    low_grid: np.ndarray
    low_cell_mm: float
    fibre_grid: np.ndarray | None
    fine_tile: np.ndarray
    residual_tile: np.ndarray
    mottle_tile: np.ndarray
    foam_tile: np.ndarray
    wall_glints: np.ndarray


def scene_textures(scene: Scene) -> SceneTextures:
    """Draw the noise textures of ``scene`` from its seed (the same arrays on every call)."""
    plate, seed = scene.plate, scene.seed
    low_cell = scene.stain.unevenness_scale_mm / 2.0

    def plate_grid(cell_mm: float) -> tuple[int, int]:
        return int(plate.width_mm / cell_mm) + 3, int(plate.length_mm / cell_mm) + 3

    lysed_film = any(w.lysed_film for w in scene.wells)
    fibre_grid = None
    if lysed_film:
        fibre_grid = noise_grid(scene_rng(seed, "fibres"), plate_grid(FIBRE_CELL_MM), 2.0)
    foamed = lysed_film and scene.stain.lysed_foam > 0.0
    return SceneTextures(
        well_offsets=scene_rng(seed, "well_offsets").uniform(0.0, WELL_OFFSET_RANGE_MM, (len(scene.wells), 2)),
        low_grid=noise_grid(scene_rng(seed, "unevenness"), plate_grid(low_cell), 1.5),
        low_cell_mm=low_cell,
        fibre_grid=fibre_grid,
        fine_tile=noise_grid(scene_rng(seed, "fine"), (256, 256), 0.8, periodic=True),
        residual_tile=noise_grid(scene_rng(seed, "residual"), (128, 128), 1.2, periodic=True),
        mottle_tile=noise_grid(scene_rng(seed, "mottle"), (256, 256), 1.5, periodic=True),
        foam_tile=foam_tile(scene_rng(seed, "foam")) if foamed else np.zeros((2, 2), dtype=np.float32),
        wall_glints=scene_rng(seed, "wall_glint_harmonics").standard_normal((len(scene.wells), 2 * WALL_GLINT_HARMONICS)),
    )
