"""Contact sheets: many images tiled into one, optionally with the mask outlines drawn on them."""

from __future__ import annotations

import numpy as np
from PIL import Image
from skimage.segmentation import find_boundaries

WELL_OUTLINE_RGB = (255, 210, 0)
PLAQUE_OUTLINE_RGB = (0, 230, 255)


def draw_outlines(image: np.ndarray, wells: np.ndarray, plaques: np.ndarray) -> np.ndarray:
    """A copy of an RGB uint8 image with well outlines in yellow and plaque outlines in cyan."""
    out = image.copy()
    out[find_boundaries(wells, mode="inner")] = WELL_OUTLINE_RGB
    out[find_boundaries(plaques, mode="inner")] = PLAQUE_OUTLINE_RGB
    return out


def contact_sheet(
    images: list[np.ndarray], columns: int = 4, tile_width: int = 256, gap: int = 4, background: int = 255
) -> np.ndarray:
    """Tile RGB uint8 images into one sheet, row by row.

    Parameters
    ----------
    images : list of (H, W, 3) uint8
        Images of any sizes; each is scaled to ``tile_width`` keeping its aspect ratio.
    columns : int
        Tiles per row.
    tile_width : int
        Width of each tile in pixels.
    gap : int
        Pixels between tiles and around the sheet.
    background : int
        Gray level of the gaps.

    Returns
    -------
    (H, W, 3) uint8
    """
    if not images:
        raise ValueError("no images to tile")
    tiles = []
    for image in images:
        height = max(1, round(image.shape[0] * tile_width / image.shape[1]))
        tiles.append(np.asarray(Image.fromarray(image).resize((tile_width, height), Image.Resampling.LANCZOS)))
    columns = max(1, min(columns, len(tiles)))
    rows = -(-len(tiles) // columns)
    tile_height = max(t.shape[0] for t in tiles)
    sheet = np.full(
        (gap + rows * (tile_height + gap), gap + columns * (tile_width + gap), 3), background, dtype=np.uint8
    )
    for index, tile in enumerate(tiles):
        row, col = divmod(index, columns)
        top, left = gap + row * (tile_height + gap), gap + col * (tile_width + gap)
        sheet[top : top + tile.shape[0], left : left + tile_width] = tile
    return sheet
