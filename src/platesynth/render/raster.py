"""The fast CPU raster renderer: a concrete scene to an RGB image and exact instance masks.

Every pixel centre is mapped back to plate coordinates (mm) through the camera's homography; shapes are then
evaluated in plate space, so the masks are exact by construction (a pixel belongs to a well or a plaque when
its centre lies inside it) and the image is anti-aliased from the same signed distances. Light is composed in
linear RGB (light box or desk, plastic, Beer-Lambert absorption by the stained monolayer), then blurred,
gamma-encoded and post-processed. Noise comes from the scene's coarse grids and small periodic tiles
(:mod:`platesynth.render.textures`, shared with the Blender backend) sampled in plate space;
per-object work (plaques, scratches, specks) runs in numba kernels inside each object's bounding box, and the
per-pixel shading is one fused, row-parallel numba kernel (:func:`platesynth.render.shading.shade`); the well content is the appearance model shared with the Blender backend (:mod:`platesynth.render.appearance`).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from platesynth.render import appearance, postprocess, shading
from platesynth.render.camera import REFERENCE_WIDTH, View, camera_view
from platesynth.render.color import gamma_lut, light_colour, linear_lut, srgb_to_linear
from platesynth.render.look import DESK_CELL_MM, DESK_SHEEN, RELIEF_EMBOSS, RELIEF_RAISED, TOP_EDGE_OFFSET_MM
from platesynth.render.masks import renumber
from platesynth.render.result import RenderResult, WellInfo, check_size
from platesynth.render.textures import noise_grid, scene_textures
from platesynth.scene.concrete import PlateGeometry, Scene, Well
from platesynth.scene.streams import scene_rng

__all__ = ["REFERENCE_WIDTH", "View", "camera_view", "render_raster", "scratch_map", "srgb_to_linear", "texels_per_mm"]


@lru_cache(maxsize=8)
def _font(size_px: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    return ImageFont.load_default(size=max(size_px, 4))


def texels_per_mm(px_per_mm: float) -> float:
    """Resolution of the plate-space textures: about the image's, in steps of a quarter octave (cacheable)."""
    return float(2.0 ** (round(4.0 * math.log2(min(max(px_per_mm, 2.0), 12.0))) / 4.0))


@lru_cache(maxsize=16)
def plate_relief(plate: PlateGeometry, k: float, labels_at_junction: bool = False) -> np.ndarray:
    """Darkening (about -0.6..0.4 before scaling by the label strength) by the plate's embossed labels, label
    rings and frame, in plate space at ``k`` texels per mm (texel (0, 0) covers [0, 1/k) mm). Each well's label
    circle lies a little off the junction of four wells toward its well, or, ``labels_at_junction``, on it with a
    rib to its well's wall (``plate_look.labels_at_junction``)."""
    size = (int(math.ceil(plate.length_mm * k)) + 2, int(math.ceil(plate.width_mm * k)) + 2)
    relief = Image.new("L", size, 0)
    draw = ImageDraw.Draw(relief)
    line = max(1, round(0.25 * k))

    def circle(x: float, y: float, r: float) -> None:
        draw.ellipse([(x - r) * k, (y - r) * k, (x + r) * k, (y + r) * k], outline=255, width=line)

    def text(x: float, y: float, label: str, height_mm: float) -> None:
        draw.text((x * k, y * k), label, fill=255, font=_font(round(height_mm * k)), anchor="mm")

    pitch, radius = plate.pitch_mm, plate.well_radius_mm
    label_mm = min(3.5, 0.4 * pitch)
    for row in range(plate.rows):
        y = plate.a1_y_mm + row * pitch
        text(plate.a1_x_mm - 0.5 * pitch - 0.1 * radius if plate.format <= 24 else 3.5, y - 0.1 * pitch,
             chr(ord("A") + row), label_mm)
    for col in range(plate.cols):
        x = plate.a1_x_mm + col * pitch
        text(x - 0.42 * pitch if plate.format <= 24 else x, max(plate.a1_y_mm - radius - 3.0, 3.5), str(col + 1),
             label_mm)
        if plate.format <= 12:
            circle(x - 0.42 * pitch + 3.6, max(plate.a1_y_mm - radius - 3.0, 3.5), 1.6)
    if plate.format in (6, 12, 24):
        for row in range(1, plate.rows):
            for col in range(plate.cols):
                x = plate.a1_x_mm + col * pitch - 0.5 * pitch
                y = plate.a1_y_mm + row * pitch - 0.5 * pitch
                if labels_at_junction:  # a rib from the circle to the wall, toward the well's centre
                    start, end = 0.11 * pitch / math.sqrt(2.0), 0.5 * pitch - (radius + plate.wall_mm) / math.sqrt(2.0)
                    draw.line([((x + start) * k, (y + start) * k), ((x + end) * k, (y + end) * k)], fill=255, width=line)
                else:
                    x, y = x + 0.08 * pitch, y + 0.05 * pitch
                circle(x, y, 0.11 * pitch)
                text(x, y, f"{chr(ord('A') + row)}{col + 1}", 0.1 * pitch)
    # the plate's frame: a raised rim and ribs at every column
    inset = (1.5, 3.0)
    for d in inset:
        draw.rounded_rectangle([d * k, d * k, (plate.length_mm - d) * k, (plate.width_mm - d) * k],
                               radius=plate.corner_radius_mm * k, outline=255, width=line)
    for col in range(plate.cols):
        x = (plate.a1_x_mm + col * pitch) * k
        for y0, y1 in ((0.0, inset[1]), (plate.width_mm - inset[1], plate.width_mm)):
            draw.line([(x, y0 * k), (x, y1 * k)], fill=255, width=line)
    raw = np.asarray(relief, dtype=np.float32) / 255.0
    shift = max(1, round(0.2 * k))
    emboss = raw - np.pad(raw, ((shift, 0), (shift, 0)))[: raw.shape[0], : raw.shape[1]]
    relief_value = RELIEF_RAISED * raw - RELIEF_EMBOSS * emboss
    relief_value.flags.writeable = False
    return relief_value


def marker_ink(scene: Scene, k: float) -> np.ndarray:
    """Linear RGB transmission ``(h, w, 3)`` of the marker writing in plate space (``(1, 1, 3)`` ones if none)."""
    if not scene.artifacts.marker:
        return np.ones((1, 1, 3), dtype=np.float32)
    plate = scene.plate
    size = (int(math.ceil(plate.length_mm * k)) + 2, int(math.ceil(plate.width_mm * k)) + 2)
    ink = Image.new("RGB", size, (255, 255, 255))
    draw = ImageDraw.Draw(ink)
    for stroke in scene.artifacts.marker:
        points = [(x * k, y * k) for x, y in stroke.points_mm]
        color = tuple(int(255 * c) for c in stroke.color_rgb)
        draw.line(points, fill=color, width=max(1, round(stroke.width_mm * k)), joint="curve")
    return linear_lut()[np.asarray(ink)]


def parallax(scene: Scene, view: View, height_mm: float, points_mm: np.ndarray) -> tuple[np.ndarray, float]:
    """Where the camera sees plate points lifted ``height_mm`` above the wells' floors (negative: below them), in
    the floor's plate coordinates, and the scale of lengths there (about the camera's axis)."""
    towards = height_mm if scene.camera.from_below else -height_mm  # further from a camera below the plate
    scale = scene.camera.distance_mm / (scene.camera.distance_mm + towards)
    principal = np.array(view.principal_mm)
    return points_mm + (points_mm - principal) * (scale - 1.0), scale


def wells_in_view(scene: Scene, view: View) -> tuple[list[Well], np.ndarray, float]:
    """The scene's wells in plate row-major order, the centres of their walls' top edges as the camera sees them
    (with parallax about its axis) and the top edges' radius."""
    plate = scene.plate
    wells = appearance.wells_by_grid(scene)
    centres = np.array([w.center_mm for w in wells], dtype=np.float64)
    top_centres, scale = parallax(scene, view, plate.well_depth_mm, centres)
    return wells, top_centres, (plate.well_radius_mm + TOP_EDGE_OFFSET_MM) * scale


def _frame(scene: Scene, view: View, top_radius: float, foot_scale: float) -> np.ndarray:
    """The per-image scalars of :func:`platesynth.render.shading.shade`."""
    plate, look, bg, light = scene.plate, scene.plate_look, scene.background, scene.lighting
    frame = np.zeros(1, dtype=shading.FRAME_DTYPE)
    values = dict(
        pixel_mm=1.0 / view.px_per_mm, mirror=view.mirror, length=plate.length_mm, plate_width=plate.width_mm,
        corner=plate.corner_radius_mm, chamfer=plate.chamfer_mm, skirt=plate.skirt_mm, a1x=plate.a1_x_mm,
        a1y=plate.a1_y_mm, pitch=plate.pitch_mm, rows=plate.rows, cols=plate.cols, radius=plate.well_radius_mm,
        wall=plate.wall_mm, top_radius=top_radius, foot_scale=foot_scale, from_below=scene.camera.from_below,
        transmittance=look.transmittance, rim_darkness=look.rim_darkness, label_strength=look.label_strength,
        top_edge_through_floor=look.top_edge_through_floor, top_edge_blur=look.top_edge_blur_mm, wall_band=look.wall_band,
        crescent_veil=look.crescent_veil, wall_lines=look.wall_lines, wall_highlights=look.wall_highlights,
        tint_r=look.tint_rgb[0], tint_g=look.tint_rgb[1], tint_b=look.tint_rgb[2], is_desk=bg.kind == "desk",
        brightness=bg.brightness, desk_texture=bg.texture, frame_mm=bg.frame_mm, ruler=bg.ruler,
        sheen=DESK_SHEEN * bg.brightness if bg.kind == "desk" else 0.0, vignetting=light.vignetting,
        glare=light.glare_strength, glare_x=light.glare_center[0], glare_y=light.glare_center[1],
        glare_radius=light.glare_radius,
    )
    for name, value in values.items():
        frame[name] = value
    return frame


def light_gains(scene: Scene) -> np.ndarray:
    """Linear RGB gains of the light's colour temperature and exposure."""
    return light_colour(scene.lighting.color_temperature_k) * 2.0**scene.lighting.exposure_ev


def render_raster(scene: Scene, size: tuple[int, int] = (1024, 768)) -> RenderResult:
    """Draw ``scene`` with the raster renderer.

    Parameters
    ----------
    scene : Scene
        A concrete scene (:func:`platesynth.scene.sample_scene`).
    size : tuple of int
        (width, height) in pixels.

    Returns
    -------
    RenderResult
        RGB uint8 image, uint8 well mask (ids as in ``scene.wells``), uint16 plaque mask (visible plaques
        numbered 1..m in the scene's drawing order). The same scene and size give byte-identical arrays.
    """
    width, height = check_size(size)
    view = camera_view(scene, width, height)
    bg = scene.background
    textures = scene_textures(scene)
    wells, top_centres, top_radius = wells_in_view(scene, view)
    centres = np.array([w.center_mm for w in wells], dtype=np.float64)
    foot_centres, foot_scale = parallax(scene, view, -scene.plate_look.floor_height_mm, centres)
    stain = appearance.stain_table(scene, textures)
    content = appearance.draw_well_content(scene, view, wells, top_centres, top_radius, textures)

    desk_cell_px = DESK_CELL_MM * view.px_per_mm
    desk_grid = noise_grid(scene_rng(scene.seed, "desk"), (int(height / desk_cell_px) + 3, int(width / desk_cell_px) + 3), 1.0)
    k = texels_per_mm(view.px_per_mm)
    blots = np.array(
        [(*b.center_mm, b.radius_mm, *b.color_rgb, b.opacity) for b in scene.artifacts.blots], dtype=np.float64
    ).reshape(-1, 7)
    image = np.empty((height, width, 3), dtype=np.float32)
    wells_mask = np.zeros((height, width), dtype=np.uint8)
    shading.shade(
        view.px_to_plate, _frame(scene, view, top_radius, foot_scale), np.asarray(srgb_to_linear(bg.color_rgb)),
        np.asarray(bg.panel_mm, dtype=np.float64), blots,
        appearance.well_table(wells, top_centres, foot_centres, appearance.wall_tints(scene, wells, stain[0]),
                              appearance.wall_sheen(scene, wells, view.principal_mm, textures.wall_glints),
                              textures.well_offsets, appearance.panel_shades(scene, wells),
                              appearance.layer_densities(scene, wells)), stain,
        plate_relief(scene.plate, k, scene.plate_look.labels_at_junction), marker_ink(scene, k), k, textures.low_grid,
        appearance.fibre_grid_or_empty(textures), desk_grid, desk_cell_px, textures.fine_tile,
        textures.mottle_tile, textures.foam_tile, textures.residual_tile, content.clearing, content.rim, content.scratched, content.heaped, content.specks, light_gains(scene),
        gamma_lut(), image, wells_mask,
    )
    sigma = scene.camera.defocus_px * width / REFERENCE_WIDTH
    if sigma > 0.05:
        image = postprocess.gaussian_blur(image, sigma)
    image = postprocess.apply_post(image, scene.post, scene_rng(scene.seed, "post"), width / REFERENCE_WIDTH)
    image_u8 = postprocess.to_uint8(image)
    if scene.post.jpeg.enabled:
        image_u8 = postprocess.jpeg_roundtrip(image_u8, scene.post.jpeg.strength)
    plaque_ids = content.plaque_ids
    renumber(plaque_ids)
    well_info = [WellInfo(id=w.id, row=w.row, col=w.col, label=w.label, countable=w.countable) for w in scene.wells]
    return RenderResult(image=image_u8, wells=wells_mask, plaques=plaque_ids, well_info=well_info)


def scratch_map(scene: Scene, size: tuple[int, int]) -> np.ndarray:
    """Where the scene's scratches (the scrapes, stray scratches and tears at the rim) took the stain off, in the
    pixels of an image of ``size`` = (width, height): the share of the stain scraped off, 0..1.

    The same drawing :func:`render_raster` shades, so it lies where any renderer's image of the scene shows the
    scratches (the renderers share the camera and the plate geometry, as their masks do). Training weighs these
    pixels, pale lesions that are not plaques, with ``scratch_weight`` (:class:`platesynth.segment.train.TrainConfig`).
    """
    width, height = check_size(size)
    scraped = np.zeros((height, width), np.float32)
    appearance.draw_scratches(scene, camera_view(scene, width, height), scraped)
    return scraped
