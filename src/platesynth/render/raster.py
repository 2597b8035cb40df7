"""The fast CPU raster renderer: a concrete scene to an RGB image and exact instance masks.

Every pixel centre is mapped back to plate coordinates (mm) through the camera's homography; shapes are then
evaluated in plate space, so the masks are exact by construction (a pixel belongs to a well or a plaque when
its centre lies inside it) and the image is anti-aliased from the same signed distances. Light is composed in
linear RGB (light box or desk, plastic, Beer-Lambert absorption by the stained monolayer), then blurred,
gamma-encoded and post-processed. Noise comes from the scene's coarse grids and small periodic tiles
(:mod:`platesynth.render.textures`, shared with the Blender backend) sampled in plate space;
per-object work (plaques, scratches, specks) runs in numba kernels inside each object's bounding box, and the
per-pixel shading is one fused, row-parallel numba kernel (:func:`platesynth.render._kernels.shade`).
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
from platesynth.render.result import RenderResult, WellInfo, check_size
from platesynth.render.textures import FIBRE_CELL_MM, FINE_CELL_MM, FUZZ_CELL_MM, RESIDUAL_CELL_MM, noise_grid, plate_grid_index, scene_rng, scene_textures
from platesynth.scene.params import PlateGeometry, Scene, Well
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


def srgb_to_linear(rgb: np.ndarray) -> np.ndarray:
    """sRGB-encoded values (0..1) to linear light."""
    rgb = np.asarray(rgb, dtype=np.float64)
    return np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)


@lru_cache(maxsize=1)
def _gamma_lut(size: int = 4096) -> np.ndarray:
    """Display encoding indexed by ``sqrt(linear) * size``."""
    linear = np.linspace(0.0, 1.0, size + 1) ** 2
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055).astype(np.float32)


@lru_cache(maxsize=1)
def _linear_lut() -> np.ndarray:
    """Linear light of each 8-bit sRGB level."""
    return srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


@lru_cache(maxsize=8)
def _font(size_px: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    return ImageFont.load_default(size=max(size_px, 4))


def texels_per_mm(px_per_mm: float) -> float:
    """Resolution of the plate-space textures: about the image's, in steps of a quarter octave (cacheable)."""
    return float(2.0 ** (round(4.0 * math.log2(min(max(px_per_mm, 2.0), 12.0))) / 4.0))


@lru_cache(maxsize=16)
def plate_relief(plate: PlateGeometry, k: float) -> np.ndarray:
    """Darkening (about -0.6..0.4 before scaling by the label strength) by the plate's embossed labels, label
    rings and frame, in plate space at ``k`` texels per mm (texel (0, 0) covers [0, 1/k) mm)."""
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
    relief_value = 0.35 * raw - 0.65 * emboss
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
    return _linear_lut()[np.asarray(ink)]


def _wells_by_grid(scene: Scene) -> list[Well]:
    """The scene's wells in plate row-major order (row letter, then column number)."""
    plate = scene.plate
    grid: list[Well | None] = [None] * (plate.rows * plate.cols)
    for well in scene.wells:
        index = plate_grid_index(plate, well.center_mm)
        if index >= 0:
            grid[index] = well
    if any(w is None for w in grid) or len(scene.wells) != len(grid):
        raise ParameterError(f"scene.wells must hold one well per position of the {plate.format}-well grid")
    return grid  # type: ignore[return-value]


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
    width, height = check_size(size)
    view = camera_view(scene, width, height)
    hinv = view.px_to_plate
    pixel_mm = 1.0 / view.px_per_mm
    plate, look, stain, bg, light = scene.plate, scene.plate_look, scene.stain, scene.background, scene.lighting
    textures = scene_textures(scene)

    wells = _wells_by_grid(scene)
    # the top edge of the wells' walls, seen with parallax about the camera's axis
    depth = plate.well_depth_mm if scene.camera.from_below else -plate.well_depth_mm
    parallax = scene.camera.distance_mm / (scene.camera.distance_mm + depth)
    principal = np.array(view.principal_mm)
    centres = np.array([w.center_mm for w in wells], dtype=np.float64)
    top_centres = principal + (centres - principal) * parallax
    top_radius = (plate.well_radius_mm + 0.3) * parallax
    well_rows = np.zeros((len(wells), kernels.N_WELL_PARAMS), dtype=np.float64)
    for i, w in enumerate(wells):
        angle = math.radians(w.stain.centre_angle_deg)
        well_rows[i] = (
            w.id, *w.center_mm, *top_centres[i], w.stain.density, w.stain.centre_gradient, math.cos(angle),
            math.sin(angle), *w.stain.centre_offset_mm, w.stain.drying_detail, float(w.lysed), float(w.emptied),
            *textures.well_offsets[i],
        )

    clear = np.zeros((height, width), dtype=np.float32)
    plaque_ids = np.zeros((height, width), dtype=np.uint16)
    _draw_plaques(scene, view, wells, top_centres, top_radius, textures.fine_tile, FUZZ_CELL_MM, clear, plaque_ids)
    scratched = np.zeros((height, width), dtype=np.float32)
    specks = np.zeros((height, width), dtype=np.float32)
    _draw_artifacts(scene, view, scratched, specks)

    fibre_grid = textures.fibre_grid if textures.fibre_grid is not None else np.zeros((2, 2), dtype=np.float32)
    desk_cell_px = 8.0 * view.px_per_mm
    desk_grid = noise_grid(scene_rng(scene.seed, "desk"), (int(height / desk_cell_px) + 3, int(width / desk_cell_px) + 3), 1.0)
    k = texels_per_mm(view.px_per_mm)
    relief = plate_relief(plate, k)
    ink = marker_ink(scene, k)

    absorbance = (-np.log(np.clip(srgb_to_linear(stain_rgb(stain)), 1e-3, 1.0))).astype(np.float64)
    gains = srgb_to_linear(np.asarray(color_temperature_rgb(light.color_temperature_k)) / max(
        color_temperature_rgb(light.color_temperature_k)))
    gains = gains * 2.0**light.exposure_ev
    blots = np.array(
        [(*b.center_mm, b.radius_mm, *b.color_rgb, b.opacity) for b in scene.artifacts.blots], dtype=np.float64
    ).reshape(-1, 7)
    sheen = 0.12 * bg.brightness if bg.kind == "desk" else 0.0
    scalars = np.array(
        [
            pixel_mm, view.mirror, plate.length_mm, plate.width_mm, plate.corner_radius_mm, plate.chamfer_mm,
            plate.skirt_mm, plate.a1_x_mm, plate.a1_y_mm, plate.pitch_mm, plate.rows, plate.cols,
            plate.well_radius_mm, plate.wall_mm, top_radius, float(scene.camera.from_below), look.transmittance,
            look.rim_darkness, stain.rim_clearing_mm, stain.unevenness, stain.centre_elongation, stain.translucency,
            float(bg.kind == "desk"), bg.brightness, bg.texture, bg.frame_mm, float(bg.ruler), light.vignetting,
            light.glare_strength, *light.glare_center, light.glare_radius, sheen, *look.tint_rgb,
            look.label_strength,
        ],
        dtype=np.float64,
    )
    image = np.empty((height, width, 3), dtype=np.float32)
    wells_mask = np.zeros((height, width), dtype=np.uint8)
    kernels.shade(
        hinv, scalars, np.asarray(srgb_to_linear(bg.color_rgb)), np.asarray(bg.panel_mm, dtype=np.float64),
        blots, well_rows, relief, ink, k, textures.low_grid, textures.low_cell_mm, fibre_grid, FIBRE_CELL_MM, desk_grid,
        desk_cell_px, textures.fine_tile, FINE_CELL_MM, textures.residual_tile, RESIDUAL_CELL_MM, clear, scratched, specks, absorbance, gains, _gamma_lut(),
        image, wells_mask,
    )
    sigma = scene.camera.defocus_px * width / REFERENCE_WIDTH
    if sigma > 0.05:
        image = postprocess.gaussian_blur(image, sigma)
    image = postprocess.apply_post(image, scene.post, scene_rng(scene.seed, "post"), width / REFERENCE_WIDTH)
    image_u8 = postprocess.to_uint8(image)
    if scene.post.jpeg.enabled:
        image_u8 = postprocess.jpeg_roundtrip(image_u8, scene.post.jpeg.strength)
    kernels.renumber(plaque_ids)
    well_info = [WellInfo(id=w.id, row=w.row, col=w.col, label=w.label) for w in scene.wells]
    return RenderResult(image=image_u8, wells=wells_mask, plaques=plaque_ids, well_info=well_info)


def _draw_plaques(
    scene: Scene,
    view: View,
    wells: list[Well],
    top_centres: np.ndarray,
    top_radius: float,
    fuzz_tile: np.ndarray,
    fuzz_cell_mm: float,
    clear: np.ndarray,
    ids: np.ndarray,
) -> None:
    """Clearing (0..1) of all plaques into ``clear`` and their ids (scene order, 1-based) into ``ids``."""
    plaques = scene.plaques
    if not plaques:
        return
    index_of_well = {w.id: i for i, w in enumerate(wells)}
    radius = scene.plate.well_radius_mm
    params = np.empty((len(plaques), 11), dtype=np.float64)
    for i, p in enumerate(plaques):
        k = index_of_well.get(p.well)
        if k is None:
            raise ParameterError(f"plaque {p.id} lies in well {p.well}, which the scene does not have")
        w = wells[k]
        params[i] = (*p.center_mm, p.radius_mm, p.softness * p.radius_mm, p.clearness, w.id, *w.center_mm, radius,
                     *top_centres[k])
    n_harmonics = max(1, max(len(p.fourier) for p in plaques))
    fourier = np.zeros((len(plaques), n_harmonics, 2), dtype=np.float64)
    for i, p in enumerate(plaques):
        if p.fourier:
            fourier[i, : len(p.fourier)] = p.fourier
    pixel_mm = 1.0 / view.px_per_mm
    reach = params[:, 2] * (1.0 + np.abs(fourier).sum(axis=(1, 2))) + kernels.EDGE_SPAN * np.maximum(params[:, 3], pixel_mm) + pixel_mm
    boxes = _boxes(view, params[:, :2], reach)
    kernels.draw_plaques(view.px_to_plate, params, fourier, boxes, pixel_mm, scene.camera.from_below, top_radius,
                         fuzz_tile, fuzz_cell_mm, clear, ids)


def _boxes(view: View, centres_mm: np.ndarray, reach_mm: np.ndarray) -> np.ndarray:
    signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=np.float64)
    corners = centres_mm[:, None, :] + signs[None] * reach_mm[:, None, None]
    return kernels.boxes_from_extents(view.project(corners), view.height, view.width)


def _draw_artifacts(scene: Scene, view: View, scratched: np.ndarray, specks: np.ndarray) -> None:
    """Coverage of scratches (0..1, stain scraped off) and the density added by dark specks."""
    art = scene.artifacts
    segments = [
        (*a, *b, 0.5 * s.width_mm) for s in art.scratches for a, b in zip(s.points_mm[:-1], s.points_mm[1:])
    ]
    if segments:
        _capsules(view, np.array(segments), np.full(len(segments), 0.95), scratched)
    if art.debris:
        rows, values = [], []
        for d in art.debris:
            half = 0.5 * max(d.length_mm - d.width_mm, 0.0)
            ca, sa = math.cos(math.radians(d.angle_deg)), math.sin(math.radians(d.angle_deg))
            cx, cy = d.center_mm
            rows.append((cx - half * ca, cy - half * sa, cx + half * ca, cy + half * sa, 0.5 * d.width_mm))
            values.append(d.darkness)
        _capsules(view, np.array(rows), np.array(values), specks)


def _capsules(view: View, segments: np.ndarray, values: np.ndarray, out: np.ndarray) -> None:
    pixel_mm = 1.0 / view.px_per_mm
    ends = segments[:, :4].reshape(-1, 2, 2)
    reach = segments[:, 4] + pixel_mm
    lo = ends.min(axis=1) - reach[:, None]
    hi = ends.max(axis=1) + reach[:, None]
    corners = np.stack([lo, np.stack([hi[:, 0], lo[:, 1]], 1), hi, np.stack([lo[:, 0], hi[:, 1]], 1)], axis=1)
    boxes = kernels.boxes_from_extents(view.project(corners), view.height, view.width)
    kernels.draw_capsules(view.px_to_plate, segments.astype(np.float64), values.astype(np.float32), boxes, pixel_mm,
                          out)
