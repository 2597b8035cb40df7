"""The fast CPU raster renderer: a concrete scene to an RGB image and exact instance masks.

Every pixel centre is mapped back to plate coordinates (mm) through the camera's homography; shapes are then
evaluated in plate space, so the masks are exact by construction (a pixel belongs to a well or a plaque when
its centre lies inside it) and the image is anti-aliased from the same signed distances. Light is composed in
linear RGB (light box or desk, plastic, Beer-Lambert absorption by the stained monolayer), then blurred,
gamma-encoded and post-processed. Low-frequency textures are drawn on coarse grids and upsampled; per-object
work (plaques, scratches, specks) runs in numba kernels inside each object's bounding box.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from platesynth.errors import ParameterError
from platesynth.render import _kernels as kernels
from platesynth.render import postprocess
from platesynth.render.result import RenderResult, WellInfo
from platesynth.scene.params import Scene
from platesynth.scene.sample import color_temperature_rgb, stain_rgb

REFERENCE_WIDTH = 1024
"""Pixel-valued scene parameters (blur, noise lengths) are given for an image this wide."""


@dataclass(frozen=True)
class View:
    """The camera's mapping between plate millimetres and image pixels (pixel centres at ``i + 0.5``)."""

    width: int
    height: int
    plate_to_px: np.ndarray
    px_to_plate: np.ndarray
    px_per_mm: float
    principal_mm: tuple[float, float]
    mirror: float

    def project(self, points_mm: np.ndarray) -> np.ndarray:
        """Pixel positions ``(..., 2)`` of plate points ``(..., 2)`` in mm."""
        points = np.asarray(points_mm, dtype=np.float64)
        h = self.plate_to_px
        w = h[2, 0] * points[..., 0] + h[2, 1] * points[..., 1] + h[2, 2]
        x = (h[0, 0] * points[..., 0] + h[0, 1] * points[..., 1] + h[0, 2]) / w
        y = (h[1, 0] * points[..., 0] + h[1, 1] * points[..., 1] + h[1, 2]) / w
        return np.stack([x, y], axis=-1)

    def plate_coordinates(self) -> tuple[np.ndarray, np.ndarray]:
        """Plate coordinates ``u, v`` (mm, float32, ``(H, W)``) of every pixel centre."""
        h = self.px_to_plate
        xs = np.arange(self.width, dtype=np.float64)[None, :] + 0.5
        ys = np.arange(self.height, dtype=np.float64)[:, None] + 0.5
        w = h[2, 0] * xs + h[2, 1] * ys + h[2, 2]
        u = (h[0, 0] * xs + h[0, 1] * ys + h[0, 2]) / w
        v = (h[1, 0] * xs + h[1, 1] * ys + h[1, 2]) / w
        return u.astype(np.float32), v.astype(np.float32)


def camera_view(scene: Scene, width: int, height: int) -> View:
    """The homography of ``scene.camera`` for an image of ``width`` x ``height`` pixels."""
    cam, plate = scene.camera, scene.plate
    scale = cam.plate_fill * width / plate.length_mm
    mirror = -1.0 if cam.from_below else 1.0
    centre_x, centre_y = plate.length_mm / 2, plate.width_mm / 2
    to_view = np.array([[mirror, 0.0, -mirror * centre_x], [0.0, 1.0, -centre_y], [0.0, 0.0, 1.0]])
    rz, rx, ry = (math.radians(a) for a in (cam.rotation_deg, cam.tilt_x_deg, cam.tilt_y_deg))
    rot_z = np.array([[math.cos(rz), -math.sin(rz), 0], [math.sin(rz), math.cos(rz), 0], [0, 0, 1]])
    rot_x = np.array([[1, 0, 0], [0, math.cos(rx), -math.sin(rx)], [0, math.sin(rx), math.cos(rx)]])
    rot_y = np.array([[math.cos(ry), 0, math.sin(ry)], [0, 1, 0], [-math.sin(ry), 0, math.cos(ry)]])
    r = rot_z @ rot_x @ rot_y
    distance = cam.distance_mm
    focal = scale * distance
    ox = width / 2 + cam.offset[0] * width
    oy = height / 2 + cam.offset[1] * height
    projection = np.array(
        [
            [focal * r[0, 0] + ox * r[2, 0], focal * r[0, 1] + ox * r[2, 1], ox * distance],
            [focal * r[1, 0] + oy * r[2, 0], focal * r[1, 1] + oy * r[2, 1], oy * distance],
            [r[2, 0], r[2, 1], distance],
        ]
    )
    plate_to_px = projection @ to_view
    px_to_plate = np.linalg.inv(plate_to_px)
    principal = px_to_plate @ np.array([ox, oy, 1.0])
    return View(
        width=width,
        height=height,
        plate_to_px=plate_to_px,
        px_to_plate=px_to_plate,
        px_per_mm=scale,
        principal_mm=(float(principal[0] / principal[2]), float(principal[1] / principal[2])),
        mirror=mirror,
    )


def _check_size(size: tuple[int, int]) -> tuple[int, int]:
    try:
        width, height = (int(s) for s in size)
    except (TypeError, ValueError):
        raise ParameterError(f"size must be (width, height), got {size!r}") from None
    if not (16 <= width <= 16384 and 16 <= height <= 16384):
        raise ParameterError(f"size {width}x{height} is out of range: each side must be in [16, 16384] pixels")
    return width, height


def srgb_to_linear(rgb: np.ndarray) -> np.ndarray:
    """sRGB-encoded values (0..1) to linear light."""
    rgb = np.asarray(rgb, dtype=np.float64)
    return np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)


def _smooth_noise(rng: np.random.Generator, height: int, width: int, cell_px: float) -> np.ndarray:
    """Zero-mean, unit-sd smooth noise ``(H, W)`` float32 with blotches about ``cell_px`` pixels across."""
    cell_px = max(cell_px, 1.0)
    gh, gw = int(math.ceil(height / cell_px)) + 3, int(math.ceil(width / cell_px)) + 3
    grid = rng.standard_normal((gh, gw)).astype(np.float32)
    grid = postprocess.gaussian_blur(grid, 0.7)
    grid = (grid - grid.mean()) / (grid.std() + 1e-6)
    # resample so that grid cell centres map to multiples of cell_px (same pattern at any resolution)
    image = Image.fromarray(grid, mode="F")
    box = (1.0, 1.0, 1.0 + width / cell_px, 1.0 + height / cell_px)
    return np.asarray(image.resize((width, height), Image.Resampling.BICUBIC, box=box), dtype=np.float32)


def _disc_coverage(dist: np.ndarray, radius: float, pixel_mm: float) -> np.ndarray:
    return np.clip((radius - dist) / pixel_mm + 0.5, 0.0, 1.0)


def _ring(dist: np.ndarray, radius: float | np.ndarray, width_mm: float, pixel_mm: float) -> np.ndarray:
    """Anti-aliased thin ring: coverage of a line of ``width_mm`` at ``radius``."""
    half = 0.5 * max(width_mm, pixel_mm)
    strength = min(1.0, width_mm / pixel_mm)
    return np.clip((half - np.abs(dist - radius)) / pixel_mm + 0.5, 0.0, 1.0) * strength


@lru_cache(maxsize=8)
def _font(size_px: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    return ImageFont.load_default(size=max(size_px, 4))


def _plate_texture(scene: Scene, texels_per_mm: float) -> np.ndarray:
    """Plate-space texture ``(h, w, 4)``: RGB multiplier (marker ink, blots) and embossed relief (-1..1)."""
    plate, k = scene.plate, texels_per_mm
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
                x = plate.a1_x_mm + col * pitch - 0.5 * pitch + 0.08 * pitch
                y = plate.a1_y_mm + row * pitch - 0.5 * pitch + 0.05 * pitch
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
    strength = scene.plate_look.label_strength
    relief_value = strength * (0.35 * raw - 0.65 * emboss)

    ink = Image.new("RGB", size, (255, 255, 255))
    for blot in scene.artifacts.blots:
        layer = Image.new("RGB", size, tuple(int(255 * c) for c in blot.color_rgb))
        mask = Image.new("L", size, 0)
        cx, cy, r = blot.center_mm[0] * k, blot.center_mm[1] * k, blot.radius_mm * k
        ImageDraw.Draw(mask).ellipse([cx - r, cy - r, cx + r, cy + r], fill=int(255 * blot.opacity))
        ink = Image.composite(layer, ink, mask)
    ink_draw = ImageDraw.Draw(ink)
    for stroke in scene.artifacts.marker:
        points = [(x * k, y * k) for x, y in stroke.points_mm]
        ink_draw.line(points, fill=tuple(int(255 * c) for c in stroke.color_rgb), width=max(1, round(stroke.width_mm * k)),
                      joint="curve")
    texture = np.empty((size[1], size[0], 4), dtype=np.float32)
    texture[..., :3] = srgb_to_linear(np.asarray(ink, dtype=np.float32) / 255.0)
    texture[..., 3] = relief_value
    return texture


def _rounded_rect_distance(u: np.ndarray, v: np.ndarray, scene: Scene) -> np.ndarray:
    """Signed distance (mm, negative inside) to the plate's footprint with rounded corners and the A1 chamfer."""
    plate = scene.plate
    half_l, half_w, r = plate.length_mm / 2, plate.width_mm / 2, plate.corner_radius_mm
    qx = np.abs(u - half_l) - (half_l - r)
    qy = np.abs(v - half_w) - (half_w - r)
    outside = np.sqrt(np.maximum(qx, 0) ** 2 + np.maximum(qy, 0) ** 2)
    dist = outside + np.minimum(np.maximum(qx, qy), 0) - r
    chamfer = (plate.chamfer_mm - u - v) / math.sqrt(2.0)
    return np.maximum(dist, chamfer)


def _backdrop(scene: Scene, view: View, u: np.ndarray, v: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Linear light reaching the camera from behind the plate: the light panel, its frame, a ruler, a desk."""
    bg = scene.background
    height, width = u.shape
    pixel_mm = 1.0 / view.px_per_mm
    desk = np.asarray(srgb_to_linear(bg.color_rgb), dtype=np.float32)
    texture = 1.0 + bg.texture * _smooth_noise(rng, height, width, 8.0 * view.px_per_mm)
    if bg.kind == "desk":
        return desk[None, None, :] * (bg.brightness * texture)[..., None]
    # image-aligned coordinates (mm) relative to the plate's centre
    x = view.mirror * (u - scene.plate.length_mm / 2)
    y = v - scene.plate.width_mm / 2
    left, top, right, bottom = bg.panel_mm
    inside_x = np.minimum(x - left, right - x)
    inside_y = np.minimum(y - top, bottom - y)
    to_edge = np.minimum(inside_x, inside_y)  # > 0 on the panel
    panel = np.clip(to_edge / pixel_mm + 0.5, 0.0, 1.0)
    glow = bg.brightness * (1.0 - 0.06 * np.exp(-np.maximum(to_edge, 0) / 6.0))
    frame = np.clip((to_edge + bg.frame_mm) / pixel_mm + 0.5, 0.0, 1.0) - panel
    frame_gray = np.float32(0.55)
    out = desk[None, None, :] * (texture * (1.0 - panel - frame))[..., None]
    out += (panel * glow + frame * frame_gray)[..., None]
    if bg.ruler:
        ruler_width = 22.0
        along_left = (x < left) & (x > left - ruler_width) & (y > top) & (y < bottom + ruler_width)
        along_bottom = (y > bottom) & (y < bottom + ruler_width) & (x > left - ruler_width) & (x < right)
        ticks = _ruler_ticks(y - bottom, left - x) * along_left + _ruler_ticks(x - left, y - bottom) * along_bottom
        ruler = (along_left | along_bottom).astype(np.float32)
        out = out * (1.0 - ruler)[..., None] + (0.02 + 0.6 * ticks * ruler)[..., None]
    return out


def _ruler_ticks(along: np.ndarray, across: np.ndarray) -> np.ndarray:
    """Tick marks every mm (longer every 5 and 10 mm) of a ruler, ``across`` measured from its inner edge."""
    position = np.abs(along)
    nearest = np.round(position)
    tick_length = np.where(nearest % 10 == 0, 7.0, np.where(nearest % 5 == 0, 5.0, 3.0))
    return ((np.abs(position - nearest) < 0.12) & (across < tick_length)).astype(np.float32)


def render_raster(scene: Scene, size: tuple[int, int] = (1024, 768)) -> RenderResult:
    """Draw ``scene`` with the raster renderer.

    Parameters
    ----------
    scene : a concrete scene (:func:`platesynth.scene.sample_scene`).
    size : (width, height) in pixels.

    Returns
    -------
    RenderResult
        RGB uint8 image, uint8 well mask (ids as in ``scene.wells``), uint16 plaque mask (visible plaques
        numbered 1..m in the scene's drawing order). The same scene and size give byte-identical arrays.
    """
    width, height = _check_size(size)
    view = camera_view(scene, width, height)
    u, v = view.plate_coordinates()
    pixel_mm = 1.0 / view.px_per_mm
    texture_rng = np.random.default_rng([scene.seed, 0])
    plate, look = scene.plate, scene.plate_look

    backdrop = _backdrop(scene, view, u, v, texture_rng)

    # wells: the nearest well of the grid for every pixel, and the distance to its centre
    well_col = np.clip(np.rint((u - plate.a1_x_mm) / plate.pitch_mm), 0, plate.cols - 1).astype(np.intp)
    well_row = np.clip(np.rint((v - plate.a1_y_mm) / plate.pitch_mm), 0, plate.rows - 1).astype(np.intp)
    grid_index = well_row * plate.cols + well_col
    du = u - (plate.a1_x_mm + well_col * plate.pitch_mm).astype(np.float32)
    dv = v - (plate.a1_y_mm + well_row * plate.pitch_mm).astype(np.float32)
    dist = np.sqrt(du * du + dv * dv)

    wells_by_grid = [None] * (plate.rows * plate.cols)
    for well in scene.wells:
        c = round((well.center_mm[0] - plate.a1_x_mm) / plate.pitch_mm)
        r = round((well.center_mm[1] - plate.a1_y_mm) / plate.pitch_mm)
        wells_by_grid[r * plate.cols + c] = well
    if any(w is None for w in wells_by_grid):
        raise ParameterError("scene.wells must hold one well per position of the plate's grid")

    # the wall's top edge, seen with parallax about the camera's axis
    depth = plate.well_depth_mm if scene.camera.from_below else -plate.well_depth_mm
    parallax = scene.camera.distance_mm / (scene.camera.distance_mm + depth)
    centres = np.array([w.center_mm for w in wells_by_grid], dtype=np.float64)
    principal = np.array(view.principal_mm)
    top_centres = (principal + (centres - principal) * parallax).astype(np.float32)
    top_radius = (plate.well_radius_mm + 0.3) * parallax
    tu = u - top_centres[grid_index, 0]
    tv = v - top_centres[grid_index, 1]
    top_dist = np.sqrt(tu * tu + tv * tv)

    radius = plate.well_radius_mm
    inside = dist < radius
    if not scene.camera.from_below:
        inside &= top_dist < top_radius
    well_ids = np.array([w.id for w in wells_by_grid], dtype=np.uint8)
    wells_mask = np.where(inside, well_ids[grid_index], 0).astype(np.uint8)

    # plastic between the wells: transmittance, wall outlines, embossing, marker ink and blots
    texels_per_mm = float(np.clip(view.px_per_mm, 2.0, 12.0))
    texture = _plate_texture(scene, texels_per_mm)
    sampled = np.zeros((height, width, 4), dtype=np.float32)
    kernels.sample_bilinear(texture, u, v, np.float32(texels_per_mm), sampled)
    ink = np.where(sampled[..., :3] > 0, sampled[..., :3], 1.0)

    line_mm = 0.18
    rim = look.rim_darkness
    outlines = (
        _ring(dist, radius, line_mm, pixel_mm)
        + 0.6 * _ring(dist, radius + plate.wall_mm, line_mm, pixel_mm)
        + 0.8 * _ring(top_dist, top_radius, line_mm, pixel_mm)
        + 0.5 * _ring(top_dist, top_radius + plate.wall_mm, line_mm, pixel_mm)
    )
    wall_band = ((dist > radius) & (dist < radius + plate.wall_mm)).astype(np.float32)
    plastic = look.transmittance * (1.0 - 0.25 * rim * wall_band - rim * np.minimum(outlines, 1.0)) * (
        1.0 - sampled[..., 3]
    )
    plate_signed = _rounded_rect_distance(u, v, scene)
    plate_alpha = np.clip(0.5 - plate_signed / pixel_mm, 0.0, 1.0)
    skirt = np.clip((plate_signed + plate.skirt_mm) / plate.skirt_mm, 0.0, 1.0)
    plastic = plastic * (1.0 - 0.25 * skirt)
    tint = np.asarray(look.tint_rgb, dtype=np.float32)

    # the stained monolayer
    density = _stain_density(scene, view, wells_by_grid, grid_index, du, dv, dist, texture_rng)
    clear, plaque_ids = _draw_plaques(scene, view, u, v, wells_mask)
    scratched, specks = _draw_artifacts(scene, view, u, v)
    stain_linear = srgb_to_linear(stain_rgb(scene.stain))
    absorbance = (-np.log(np.clip(stain_linear, 1e-3, 1.0))).astype(np.float32)
    residual = np.clip(0.12 + 0.25 * _smooth_noise(texture_rng, height, width, 0.12 * view.px_per_mm), 0.0, 0.6)
    density = density * (1.0 - clear * (1.0 - residual)) * (1.0 - scratched) + specks
    translucency = np.float32(scene.stain.translucency)
    transmission = np.exp(-density[..., None] * absorbance[None, None, :])
    transmission = translucency + (1.0 - translucency) * transmission
    disc = _disc_coverage(dist, radius, pixel_mm)[..., None]
    well_layer = transmission * disc + (1.0 - disc)

    if scene.background.kind == "desk":
        behind = 0.3 * backdrop + 0.55 * scene.background.brightness
        sheen = 0.12 * scene.background.brightness
    else:
        behind, sheen = backdrop, 0.0
    on_plate = (behind * plastic[..., None] + sheen) * tint * ink * well_layer
    alpha = plate_alpha[..., None]
    linear = on_plate * alpha + backdrop * (1.0 - alpha)

    linear = _apply_lighting(scene, linear)
    sigma = scene.camera.defocus_px * width / REFERENCE_WIDTH
    if sigma > 0.05:
        linear = postprocess.gaussian_blur(linear, sigma)
    image = np.power(np.clip(linear, 0.0, 1.0), 1.0 / 2.2, dtype=np.float32)
    image = postprocess.apply_post(image, scene.post, np.random.default_rng([scene.seed, 1]), width / REFERENCE_WIDTH)
    image_u8 = postprocess.to_uint8(image)
    if scene.post.jpeg.enabled:
        image_u8 = postprocess.jpeg_roundtrip(image_u8, scene.post.jpeg.strength)

    well_info = [WellInfo(id=w.id, row=w.row, col=w.col, label=w.label) for w in scene.wells]
    return RenderResult(image=image_u8, wells=wells_mask, plaques=plaque_ids, well_info=well_info)


def _stain_density(
    scene: Scene,
    view: View,
    wells_by_grid: list,
    grid_index: np.ndarray,
    du: np.ndarray,
    dv: np.ndarray,
    dist: np.ndarray,
    rng: np.random.Generator,
) -> np.ndarray:
    """Stain density (1 = the plate's nominal colour) of every pixel's nearest well."""
    height, width = du.shape
    radius = scene.plate.well_radius_mm
    stain = scene.stain
    per_well = np.array(
        [
            [
                0.0 if w.emptied else w.stain.density,
                w.stain.centre_gradient,
                math.cos(math.radians(w.stain.centre_angle_deg)),
                math.sin(math.radians(w.stain.centre_angle_deg)),
                w.stain.centre_offset_mm[0],
                w.stain.centre_offset_mm[1],
                w.stain.drying_detail,
                float(w.lysed),
            ]
            for w in wells_by_grid
        ],
        dtype=np.float32,
    )
    p = per_well[grid_index]
    low = _smooth_noise(rng, height, width, stain.unevenness_scale_mm * view.px_per_mm)
    high = _smooth_noise(rng, height, width, max(0.06 * view.px_per_mm, 1.0))
    density = p[..., 0] * (1.0 + stain.unevenness * low)
    # the elongated darker centre
    cu, cv = du - p[..., 4], dv - p[..., 5]
    along = cu * p[..., 2] + cv * p[..., 3]
    across = -cu * p[..., 3] + cv * p[..., 2]
    elongation = math.sqrt(stain.centre_elongation)
    spread = 0.55 * radius
    gradient = np.exp(-((along / (spread * elongation)) ** 2 + (across * elongation / spread) ** 2))
    density = density * (1.0 + p[..., 1] * gradient)
    # thinner layer along the rim
    if stain.rim_clearing_mm > 0:
        density = density * (1.0 - 0.5 * np.exp(-np.maximum(radius - dist, 0.0) / stain.rim_clearing_mm))
    density = density * np.maximum(1.0 + p[..., 6] * 2.0 * high, 0.0)
    lysed = p[..., 7] > 0
    if lysed.any():
        fibres = _smooth_noise(rng, height, width, 0.5 * view.px_per_mm)
        remnant = np.clip(0.15 + 0.5 * gradient + 0.35 * fibres + 0.3 * high, 0.0, 1.0) * 0.45
        density = np.where(lysed, density * remnant, density)
    return density.astype(np.float32)


def _draw_plaques(scene: Scene, view: View, u: np.ndarray, v: np.ndarray, wells_mask: np.ndarray):
    """Clearing (0..1) of all plaques, and the plaque instance mask (visible plaques renumbered 1..m)."""
    height, width = u.shape
    clear = np.zeros((height, width), dtype=np.float32)
    ids = np.zeros((height, width), dtype=np.uint16)
    plaques = scene.plaques
    if not plaques:
        return clear, ids
    pixel_mm = 1.0 / view.px_per_mm
    params = np.array(
        [[p.center_mm[0], p.center_mm[1], p.radius_mm, p.softness * p.radius_mm, p.clearness] for p in plaques],
        dtype=np.float64,
    )
    n_harmonics = max(len(p.fourier) for p in plaques)
    fourier = np.zeros((len(plaques), max(n_harmonics, 1), 2), dtype=np.float64)
    for i, p in enumerate(plaques):
        if p.fourier:
            fourier[i, : len(p.fourier)] = p.fourier
    reach = params[:, 2] * (1.0 + np.abs(fourier).sum(axis=(1, 2))) + 2.0 * params[:, 3] + pixel_mm
    boxes = _boxes(view, params[:, :2], reach)
    plaque_well = np.array([p.well for p in plaques], dtype=np.int64)
    kernels.draw_plaques(u, v, wells_mask, plaque_well, params, fourier, boxes, pixel_mm, clear, ids)
    return clear, _renumber(ids)


def _renumber(ids: np.ndarray) -> np.ndarray:
    """Renumber the ids present to 1..m, keeping their order."""
    present = np.flatnonzero(np.bincount(ids.ravel(), minlength=1))
    present = present[present > 0]
    lookup = np.zeros(int(ids.max()) + 1, dtype=np.uint16)
    lookup[present] = np.arange(1, len(present) + 1, dtype=np.uint16)
    return lookup[ids]


def _boxes(view: View, centres_mm: np.ndarray, reach_mm: np.ndarray) -> np.ndarray:
    signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=np.float64)
    corners = centres_mm[:, None, :] + signs[None] * reach_mm[:, None, None]
    return kernels.boxes_from_extents(view.project(corners), view.height, view.width)


def _draw_artifacts(scene: Scene, view: View, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coverage of scratches (0..1, stain scraped off) and density added by dark specks."""
    height, width = u.shape
    pixel_mm = 1.0 / view.px_per_mm
    scratched = np.zeros((height, width), dtype=np.float32)
    specks = np.zeros((height, width), dtype=np.float32)
    art = scene.artifacts
    segments = [
        (*a, *b, 0.5 * s.width_mm) for s in art.scratches for a, b in zip(s.points_mm[:-1], s.points_mm[1:])
    ]
    if segments:
        _capsules(view, np.array(segments), np.full(len(segments), 0.95), u, v, pixel_mm, scratched)
    if art.debris:
        rows, values = [], []
        for d in art.debris:
            half = 0.5 * max(d.length_mm - d.width_mm, 0.0)
            ca, sa = math.cos(math.radians(d.angle_deg)), math.sin(math.radians(d.angle_deg))
            cx, cy = d.center_mm
            rows.append((cx - half * ca, cy - half * sa, cx + half * ca, cy + half * sa, 0.5 * d.width_mm))
            values.append(d.darkness)
        _capsules(view, np.array(rows), np.array(values), u, v, pixel_mm, specks)
    return scratched, specks


def _capsules(view, segments, values, u, v, pixel_mm, out) -> None:
    ends = segments[:, :4].reshape(-1, 2, 2)
    reach = segments[:, 4] + pixel_mm
    lo = ends.min(axis=1) - reach[:, None]
    hi = ends.max(axis=1) + reach[:, None]
    corners = np.stack([lo, np.stack([hi[:, 0], lo[:, 1]], 1), hi, np.stack([lo[:, 0], hi[:, 1]], 1)], axis=1)
    boxes = kernels.boxes_from_extents(view.project(corners), view.height, view.width)
    kernels.draw_capsules(u, v, segments.astype(np.float64), values.astype(np.float32), boxes, pixel_mm, out)


def _apply_lighting(scene: Scene, linear: np.ndarray) -> np.ndarray:
    """Exposure, colour temperature, vignetting and glare (linear light)."""
    light = scene.lighting
    height, width = linear.shape[:2]
    gains = np.asarray(color_temperature_rgb(light.color_temperature_k), dtype=np.float32)
    gains = gains / gains.max() * np.float32(2.0**light.exposure_ev)
    linear = linear * gains
    if light.vignetting > 0 or light.glare_strength > 0:
        ys = (np.arange(height, dtype=np.float32)[:, None] + 0.5) / height - 0.5
        xs = (np.arange(width, dtype=np.float32)[None, :] + 0.5) / width - 0.5
        aspect = width / height
        r2 = (xs * aspect) ** 2 + ys**2
        factor = 1.0 - light.vignetting * r2 / (0.25 * (aspect**2 + 1))
        linear = linear * factor[..., None]
        if light.glare_strength > 0:
            gx, gy = light.glare_center
            diagonal = math.hypot(aspect, 1.0)
            g2 = ((xs + 0.5 - gx) * aspect) ** 2 + (ys + 0.5 - gy) ** 2
            glare = light.glare_strength * np.exp(-g2 / (light.glare_radius * diagonal) ** 2)
            linear = linear + glare[..., None]
    return linear
