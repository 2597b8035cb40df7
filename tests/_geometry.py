"""Where image pixels lie on the plate, for tests that compare renders region by region (tests/test_raster.py,
tests/test_blender.py)."""

from __future__ import annotations

import numpy as np

from platesynth.render.camera import View
from platesynth.render.raster import camera_view, wells_in_view
from platesynth.scene import Scene


def pixel_centres_mm(view: View) -> tuple[np.ndarray, np.ndarray]:
    """Plate millimetres ``(u, v)`` of every pixel centre of ``view``, each ``(height, width)``."""
    ys, xs = np.mgrid[0 : view.height, 0 : view.width] + 0.5
    mapped = np.einsum("ij,jhw->ihw", view.px_to_plate, np.stack([xs, ys, np.ones_like(xs)]))
    return mapped[0] / mapped[2], mapped[1] / mapped[2]


def distance_to_top_edges(scene: Scene, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, float]:
    """Per pixel: the distance (mm) to the nearest outline of the wells' top edge as the camera sees it, whether
    the pixel lies on a floor (1 px inside it), and the pixel size (mm)."""
    view = camera_view(scene, *size)
    wells, top_centres, top_radius = wells_in_view(scene, view)
    u, v = pixel_centres_mm(view)
    pixel_mm = 1.0 / view.px_per_mm
    to_edge = np.full(u.shape, np.inf)
    on_floor = np.zeros(u.shape, dtype=bool)
    for well, (tx, ty) in zip(wells, top_centres, strict=True):
        off_centre = np.hypot(u - tx, v - ty)
        for edge in (top_radius, top_radius + scene.plate.wall_mm):  # the edge's inner and outer outline
            to_edge = np.minimum(to_edge, np.abs(off_centre - edge))
        on_floor |= np.hypot(u - well.center_mm[0], v - well.center_mm[1]) < scene.plate.well_radius_mm - pixel_mm
    return to_edge, on_floor, pixel_mm


def past_top_edge(scene: Scene, size: tuple[int, int]) -> tuple[np.ndarray, float]:
    """Per pixel on a floor (1 px inside it): how far (mm) it lies past its well's top edge as the camera sees it,
    the edge's opening seen with parallax (negative: within the opening; NaN off the floors), and the pixel size
    (mm)."""
    view = camera_view(scene, *size)
    wells, top_centres, top_radius = wells_in_view(scene, view)
    u, v = pixel_centres_mm(view)
    pixel_mm = 1.0 / view.px_per_mm
    past = np.full(u.shape, np.nan)
    for well, (tx, ty) in zip(wells, top_centres, strict=True):
        on_floor = np.hypot(u - well.center_mm[0], v - well.center_mm[1]) < scene.plate.well_radius_mm - pixel_mm
        past[on_floor] = np.hypot(u - tx, v - ty)[on_floor] - top_radius
    return past, pixel_mm


def wall_band(scene: Scene, size: tuple[int, int], margin_px: float = 2.0) -> np.ndarray:
    """Per pixel: whether it lies over a well's wall (between the floor's edge and the wall's outer foot), at least
    ``margin_px`` pixels from both, where the walls' outlines and their blur do not reach (a negative margin widens
    the band by as much)."""
    view = camera_view(scene, *size)
    wells, _, _ = wells_in_view(scene, view)
    u, v = pixel_centres_mm(view)
    margin = margin_px / view.px_per_mm
    radius, wall = scene.plate.well_radius_mm, scene.plate.wall_mm
    inside = np.zeros(u.shape, dtype=bool)
    for well in wells:
        off_centre = np.hypot(u - well.center_mm[0], v - well.center_mm[1])
        inside |= (off_centre > radius + margin) & (off_centre < radius + wall - margin)
    return inside
