"""Drawing a concrete :class:`Scene` from a :class:`SceneConfig` with one seeded generator.

Every range, spread and factor that shapes a scene is a catalogue parameter (:mod:`platesynth.scene.catalogue`).
What stays here is fixed by geometry or by definition: the SBS plate geometry, the light panel's size, orientations
(uniform over all directions: nothing in the setup prefers one), positions spread over their whole domain (a
well, the plate), how close to a well's wall marks may lie, the pen-stroke model and the number of attempts to
place a plaque.
"""

from __future__ import annotations

import colorsys
import math
from typing import NamedTuple

import numpy as np

from platesynth.errors import ParameterError
from platesynth.scene.catalogue import ArtifactsConfig, PlaquesConfig, SceneConfig
from platesynth.scene.concrete import (
    Artifacts,
    Background,
    Blot,
    Camera,
    Debris,
    Effect,
    Lighting,
    MarkerStroke,
    Plaque,
    PlaqueLook,
    PlateGeometry,
    PlateLook,
    PostProcessing,
    Scene,
    Scratch,
    Smear,
    Stain,
    Well,
    WellStain,
)
from platesynth.scene.streams import scene_rng

STAIN_DRAWN_LAST = ("rim_mottle", "rim_mottle_mm", "lysed_density", "lysed_residue", "lysed_strands", "lysed_grain")
"""Stain parameters drawn after all others (added later; drawing them earlier would change every scene)."""
PLAQUE_LOOK_OWN_STREAM = {"lumps": "plaque_lumps", "residual_mottle": "plaque_residual_mottle",
                          "residual_tint": "plaque_residual_tint", "edge_floor_mm": "plaque_edge_floor",
                          "edge_grain": "plaque_edge_grain", "edge_grain_width": "plaque_edge_grain_width"}
"""Fields of the plaque look drawn from a random stream of their own, and its name (added later: every other draw
stays)."""
PANEL_SHADE = ("panel_shade", "panel_shade_reach_mm", "panel_shade_width_mm")
"""The background's shade of the floors near the light panel's edge, drawn from the stream ``panel_shade``."""
SBS_LENGTH_MM, SBS_WIDTH_MM = 127.76, 85.48
"""The SBS footprint of every plate format."""
# rows, cols, pitch, bottom radius, wall thickness, well depth (mm); SBS footprint, wells centred on the plate
_FORMATS: dict[int, tuple[int, int, float, float, float, float]] = {
    6: (2, 3, 39.12, 17.4, 1.5, 17.4),
    12: (3, 4, 26.01, 11.05, 1.3, 17.5),
    24: (4, 6, 19.30, 7.8, 1.1, 17.4),
    96: (8, 12, 9.00, 3.2, 0.8, 10.7),
}
N_HARMONICS = 5
"""Plaque outlines use the Fourier harmonics k = 2 .. N_HARMONICS + 1."""
MIN_PLAQUE_RADIUS_MM = 0.05
"""The smallest plaque (the lower end of ``plaques.radius_mm``)."""
PLACEMENT_ATTEMPTS = 30
"""Tries to place a plaque within ``plaques.max_overlap`` of the others before it is left out."""
LACE_MAX_PLAQUES = 3000
"""The most plaques a lace well (``plaques.lysed_lace``) holds, whatever their size."""
LIGHT_PANEL_MM = (215.0, 300.0)
"""The light box's glowing panel (about A4), upright; it grows where the margins ask for more."""
PIPETTE_ANGLE_SD = 0.08
"""Spread of a pipette scratch's position along the rim, radians from the top of the well."""
RIM_START = 1.02
"""Scratches that start at the rim (the pipette's, the tears) start this many well radii from the centre: just past
the layer's edge, so that they open onto it."""
SCRATCH_REACH, DEBRIS_REACH = 0.95, 0.97
"""Other scratches start, and specks and smears lie, within this fraction of the well's radius."""
SMEAR_POINTS, SMEAR_BEND_RAD = 4, 0.3
"""A dark smear's centre line: this many points, its heading turning by a normal draw of this sd (radians) at each
(the photos' folds of the layer are nearly straight bands, not curls)."""
MARKER_JITTER_MM = 1.0
"""Spread of the marker writing's start around the free corner, mm per axis."""


def plate_geometry(fmt: int) -> PlateGeometry:
    """SBS geometry of a plate with ``fmt`` wells (6, 12, 24 or 96)."""
    if fmt not in _FORMATS:
        raise ParameterError(f"plate.format: {fmt} is not a plate format: valid formats are 6, 12, 24, 96")
    rows, cols, pitch, radius, wall, depth = _FORMATS[fmt]
    length, width = SBS_LENGTH_MM, SBS_WIDTH_MM
    return PlateGeometry(
        format=fmt,
        rows=rows,
        cols=cols,
        length_mm=length,
        width_mm=width,
        a1_x_mm=round((length - (cols - 1) * pitch) / 2, 3),
        a1_y_mm=round((width - (rows - 1) * pitch) / 2, 3),
        pitch_mm=pitch,
        well_radius_mm=radius,
        wall_mm=wall,
        well_depth_mm=depth,
    )


def color_temperature_rgb(kelvin: float) -> tuple[float, float, float]:
    """Approximate sRGB-encoded colour of a black body at ``kelvin`` (Tanner Helland's fit), scaled so that
    green = 1 (6500 K is about neutral)."""
    t = kelvin / 100.0
    red = 255.0 if t <= 66 else 329.698727446 * (t - 60) ** -0.1332047592
    green = 99.4708025861 * math.log(t) - 161.1195681661 if t <= 66 else 288.1221695283 * (t - 60) ** -0.0755148492
    blue = 255.0 if t >= 66 else (0.0 if t <= 19 else 138.5177312231 * math.log(t - 10) - 305.0447927307)
    rgb = np.clip([red, green, blue], 1.0, 255.0)
    return tuple(float(v) for v in rgb / rgb[1])  # type: ignore[return-value]


def stain_rgb(stain: Stain) -> tuple[float, float, float]:
    """RGB (0..1) of the monolayer at nominal density."""
    return colorsys.hsv_to_rgb((stain.hue_deg % 360.0) / 360.0, stain.saturation, stain.value)


def _smooth_stroke(rng: np.random.Generator, start: np.ndarray, size: float, n_points: int = 9) -> np.ndarray:
    """A hand-written-looking curve: a random walk with momentum, ``size`` mm across."""
    heading = rng.uniform(0, 2 * np.pi)
    turn = rng.normal(0, 0.6)
    points = [start]
    step = size / (n_points - 1)
    for _ in range(n_points - 1):
        turn = 0.7 * turn + rng.normal(0, 0.5)
        heading += turn
        points.append(points[-1] + step * np.array([math.cos(heading), math.sin(heading)]))
    return np.asarray(points)


def _tuple2(a: np.ndarray) -> tuple[float, float]:
    return (round(float(a[0]), 4), round(float(a[1]), 4))


def sample_scene(config: SceneConfig, seed: int) -> Scene:
    """Draw a concrete scene from ``config``; every random draw comes from ``numpy.random.default_rng(seed)``, or
    for parameters added later from a named stream of the seed (:mod:`platesynth.scene.streams`).

    Parameters
    ----------
    config : the ranges and distributions (see :func:`platesynth.scene.load_config`).
    seed : non-negative integer; the same config and seed give the same scene.

    Returns
    -------
    Scene
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError(f"seed must be a non-negative integer, got {seed!r}")
    rng = np.random.default_rng(int(seed))
    c = config

    plate = plate_geometry(c.plate.draw("format", rng))
    transmittance = c.plate.draw("transmittance", rng)
    tint = c.plate.draw("tint", rng)  # blue plastic passes less red than green
    plate_look = PlateLook(
        transmittance=transmittance,
        tint_rgb=(round(1.0 - 1.5 * tint, 4), round(1.0 - 0.6 * tint, 4), 1.0),
        rim_darkness=c.plate.draw("rim_darkness", rng),
        label_strength=c.plate.draw("label_strength", rng),
        top_edge_through_floor=c.plate.draw("top_edge_through_floor", rng),
        wall_band=c.plate.draw("wall_band", scene_rng(seed, "plate_walls")),  # beside the main order
        floor_height_mm=c.plate.draw("floor_height_mm", scene_rng(seed, "plate_floor")),
        wall_stain=c.plate.draw("wall_stain", scene_rng(seed, "wall_stain")),
        top_edge_blur_mm=c.plate.draw("top_edge_blur_mm", scene_rng(seed, "top_edge_blur")),
        wall_slant=c.plate.draw("wall_slant", scene_rng(seed, "wall_slant")),
        wall_glints=c.plate.draw("wall_glints", scene_rng(seed, "wall_glints")),
        labels_at_junction=c.plate.draw("labels_at_junction", scene_rng(seed, "label_place")),
        crescent_veil=c.plate.draw("crescent_veil", scene_rng(seed, "crescent_veil")),
        wall_lines=c.plate.draw("wall_lines", scene_rng(seed, "wall_lines")),
        wall_highlights=c.plate.draw("wall_highlights", scene_rng(seed, "wall_highlights")),
    )

    tilt = c.camera.draw("tilt_deg", rng)
    tilt_direction = rng.uniform(0, 2 * np.pi)
    camera = Camera(
        from_below=c.camera.draw("from_below", rng),
        plate_fill=c.camera.draw("plate_fill", rng),
        rotation_deg=c.camera.draw("rotation_deg", rng),
        tilt_x_deg=tilt * math.cos(tilt_direction),
        tilt_y_deg=tilt * math.sin(tilt_direction),
        offset=(c.camera.draw("offset", rng), c.camera.draw("offset", rng)),
        distance_mm=c.camera.draw("distance_mm", rng),
        defocus_px=c.camera.draw("defocus_px", rng),
    )

    b = c.background
    kind = b.draw("kind", rng)
    gray = b.draw("desk_gray", rng)
    warmth = b.draw("desk_warmth", rng)
    brightness = b.draw("brightness", rng)
    texture = b.draw("texture", rng)
    ruler = b.draw("ruler", rng)
    margins = [b.draw("panel_margin_x_mm", rng), b.draw("panel_margin_y_mm", rng)]
    below = b.draw("panel_below", rng)
    portrait = b.draw("panel_portrait", rng)
    left = b.draw("panel_left", rng)
    shade_rng = scene_rng(seed, "panel_shade")  # drawn beside the main order: scenes drawn before stay
    background = Background(
        kind=kind,
        brightness=brightness,
        color_rgb=tuple(np.clip(np.round([gray * (1 + warmth), gray, gray * (1 - warmth)], 4), 0, 1)),
        texture=texture,
        ruler=ruler,
        panel_mm=_light_panel(plate, margins, below, portrait, left),
        frame_mm=b.draw("frame_mm", rng),
        **{name: b.draw(name, shade_rng) for name in PANEL_SHADE},
    )

    hue_deg, saturation = c.stain.draw("hue_deg", rng), c.stain.draw("saturation", rng)
    palette = scene_rng(seed, "stain_palette")  # drawn beside the main order: scenes drawn before stay
    if palette.random() < c.stain.draw("pale_plates", palette):
        hue_deg, saturation = c.stain.draw("pale_hue_deg", palette), c.stain.draw("pale_saturation", palette)
    lysed_palette = scene_rng(seed, "lysed_palette")  # the colour of what lysed wells keep, likewise
    lysed_paleness = c.stain.draw("lysed_paleness", lysed_palette)
    lysed_colour = {}
    if lysed_paleness > 0.0:
        lysed_colour = {"lysed_paleness": lysed_paleness, "lysed_hue_deg": c.stain.draw("pale_hue_deg", lysed_palette),
                        "lysed_saturation": c.stain.draw("pale_saturation", lysed_palette)}
    lysed_disc = scene_rng(seed, "lysed_disc")  # the disc of what lysed wells keep, likewise
    lysed_shape = {name: c.stain.draw(name, lysed_disc) for name in ("lysed_disc", "lysed_disc_radius")}
    lysed_shape["lysed_clumps"] = c.stain.draw("lysed_clumps", scene_rng(seed, "lysed_clumps"))  # likewise
    lysed_shape["lysed_speckle"] = c.stain.draw("lysed_speckle", scene_rng(seed, "lysed_speckle"))  # likewise
    foam = scene_rng(seed, "lysed_foam")  # likewise
    lysed_shape.update({name: c.stain.draw(name, foam) for name in ("lysed_foam", "lysed_foam_mm")})
    stain = Stain(
        hue_deg=hue_deg,
        saturation=saturation,
        value=c.stain.draw("value", rng),
        unevenness=c.stain.draw("unevenness", rng),
        unevenness_scale_mm=c.stain.draw("unevenness_scale_mm", rng),
        centre_elongation=c.stain.draw("centre_elongation", rng),
        rim_clearing_mm=c.stain.draw("rim_clearing_mm", rng),
        translucency=c.stain.draw("translucency", rng),
        **lysed_colour,
        **lysed_shape,
    )
    density = c.stain.draw("density", rng)
    jitter = c.stain.draw("well_density_jitter", rng)
    centre_gradient = c.stain.draw("centre_gradient", rng)
    drying = c.stain.draw("drying_detail", rng)
    centre_offset = c.stain.draw("centre_offset", rng)

    negative = c.plaques.draw("negative_plate", rng)
    top_count = c.plaques.draw("top_count", rng)
    factor = c.plaques.draw("dilution_factor", rng)
    reverse = c.plaques.draw("reverse_series", rng)
    lysis_count = c.plaques.draw("lysis_count", rng)
    median_radius = c.plaques.draw("radius_mm", rng)
    radius_spread = c.plaques.draw("radius_spread", rng)
    irregularity = c.plaques.draw("irregularity", rng)
    softness = c.plaques.draw("softness", rng)
    clearness = c.plaques.draw("clearness", rng)
    edge_bias = c.plaques.draw("edge_bias", rng)
    max_overlap = c.plaques.draw("max_overlap", rng)
    count_jitter = c.plaques.draw("count_jitter", rng)
    max_radius = c.plaques.draw("max_radius", rng)
    harmonic_decay = c.plaques.draw("harmonic_decay", rng)
    emptied_p = c.wells.emptied

    wells: list[Well] = []
    plaques: list[Plaque] = []
    scratches: list[Scratch] = []
    pipette_pose = scene_rng(seed, "pipette_pose")
    debris: list[Debris] = []
    scratch_length = c.artifacts.draw("scratch_length_mm", rng)
    scratch_width = c.artifacts.draw("scratch_width_mm", rng)
    extra_scratches = c.artifacts.draw("extra_scratches", rng)
    debris_rate = c.artifacts.draw("debris", rng)
    radius = plate.well_radius_mm
    harmonic_scale = irregularity / np.array([float(k) ** harmonic_decay for k in range(2, N_HARMONICS + 2)])
    shared = _PlaqueDraws(median_radius, radius_spread, max_radius, harmonic_scale, softness, clearness)
    a = c.artifacts

    for plate_row in range(plate.rows):
        for plate_col in range(plate.cols):
            col = plate.cols - 1 - plate_col if camera.from_below else plate_col
            well_id = plate_row * plate.cols + col + 1
            center = np.array([plate.a1_x_mm + plate_col * plate.pitch_mm, plate.a1_y_mm + plate_row * plate.pitch_mm])
            step = plate.cols - 1 - plate_col if reverse else plate_col
            expected = 0.0 if negative else top_count / factor**step
            emptied = bool(rng.random() < emptied_p)
            lysed = (not emptied) and expected > lysis_count
            count = 0 if emptied or lysed else int(rng.poisson(expected * rng.lognormal(0.0, count_jitter)))
            wells.append(
                Well(
                    id=well_id,
                    row=plate_row,
                    col=col,
                    label=f"{chr(ord('A') + plate_row)}{plate_col + 1}",
                    center_mm=_tuple2(center),
                    emptied=emptied,
                    lysed=lysed,
                    expected_plaques=round(expected, 4),
                    stain=WellStain(
                        density=density * math.exp(rng.normal(0.0, jitter)),
                        centre_gradient=centre_gradient * c.stain.draw("centre_gradient_factor", rng),
                        centre_angle_deg=rng.uniform(0, 180),
                        centre_offset_mm=_tuple2(rng.normal(0, centre_offset * radius, 2)),
                        drying_detail=drying * c.stain.draw("drying_detail_factor", rng),
                    ),
                )
            )
            if emptied:
                continue
            plaques.extend(
                _sample_plaques(rng, c.plaques, count, well_id, center, radius, len(plaques), shared, edge_bias, max_overlap)
            )
            if a.draw("pipette_scratch", rng):
                scratches.append(_pipette_scratch(rng, pipette_pose, a, well_id, center, radius, scratch_length,
                                                  scratch_width))
            for _ in range(int(rng.poisson(extra_scratches))):
                start = center + _in_disc(rng, radius * SCRATCH_REACH)
                stroke = _smooth_stroke(rng, start, a.draw("scratch_length_factor", rng) * scratch_length, n_points=4)
                scratches.append(Scratch(well=well_id, points_mm=tuple(map(_tuple2, stroke)),
                                         width_mm=scratch_width * a.draw("scratch_width_factor", rng)))
            for _ in range(int(rng.poisson(debris_rate))):
                length = a.draw("debris_length_mm", rng)
                debris.append(
                    Debris(
                        well=well_id,
                        center_mm=_tuple2(center + _in_disc(rng, radius * DEBRIS_REACH)),
                        length_mm=length,
                        width_mm=length * a.draw("debris_width_factor", rng),
                        angle_deg=rng.uniform(0, 180),
                        darkness=a.draw("debris_darkness", rng),
                    )
                )
    wells.sort(key=lambda w: w.id)

    marker: list[MarkerStroke] = []
    if a.draw("marker", rng):
        marker = _marker_writing(rng, a, plate, camera.from_below)
    blots = [
        Blot(
            center_mm=_tuple2(rng.uniform([0, 0], [plate.length_mm, plate.width_mm])),
            radius_mm=a.draw("blot_radius_mm", rng),
            color_rgb=tuple(np.round(a.draw("blot_rgb", rng), 4)),
            opacity=a.draw("blot_opacity", rng),
        )
        for _ in range(int(rng.poisson(a.draw("blots", rng))))
    ]

    lighting = Lighting(
        exposure_ev=c.lighting.draw("exposure_ev", rng),
        color_temperature_k=c.lighting.draw("color_temperature_k", rng),
        vignetting=c.lighting.draw("vignetting", rng),
        glare_strength=c.lighting.draw("glare", rng),
        glare_center=_tuple2(c.lighting.draw("glare_position", rng)),
        glare_radius=c.lighting.draw("glare_radius", rng),
    )
    post = _sample_post(c, rng)
    post = post.model_copy(update={"sharpen_luma": c.post.draw("sharpen_luma", scene_rng(seed, "sharpen_luma")),
                                   "noise_grain_px": c.post.draw("noise_grain_px", scene_rng(seed, "noise_grain")),
                                   "black_level": c.post.draw("black_level", scene_rng(seed, "black_level")),
                                   "sharpen_threshold": c.post.draw("sharpen_threshold",
                                                                    scene_rng(seed, "sharpen_threshold"))})
    texture_seed = int(rng.integers(0, 2**31 - 1))
    # the look of plaques and of the rim's mottle are drawn last, so that adding them left every earlier draw as it was
    plaque_look = PlaqueLook(**{name: c.plaques.draw(name, rng) for name in PlaqueLook.model_fields
                                if name not in PLAQUE_LOOK_OWN_STREAM},
                             **{name: c.plaques.draw(name, scene_rng(seed, stream))
                                for name, stream in PLAQUE_LOOK_OWN_STREAM.items()})
    stain = stain.model_copy(update={name: c.stain.draw(name, rng) for name in STAIN_DRAWN_LAST})
    rim_band = scene_rng(seed, "rim_band")  # drawn beside the main order: scenes drawn before stay
    side_angle = round(c.stain.draw("rim_mottle_angle_deg", rim_band), 2)  # first: a fixed setting below draws nothing
    stain = stain.model_copy(update={"rim_mottle_angle_deg": side_angle,
                                     "rim_mottle_side": c.stain.draw("rim_mottle_side", rim_band),
                                     "meniscus": c.stain.draw("meniscus", rim_band),
                                     "rim_mottle_patches": c.stain.draw("rim_mottle_patches",
                                                                        scene_rng(seed, "rim_patches")),
                                     "pooling": c.stain.draw("pooling", scene_rng(seed, "stain_pooling")),
                                     "unevenness_light": c.stain.draw("unevenness_light",
                                                                      scene_rng(seed, "unevenness_light")),
                                     "crowd_thinning": c.stain.draw("crowd_thinning", scene_rng(seed, "crowd_thinning")),
                                     "lysed_rim_loss": c.stain.draw("lysed_rim_loss", scene_rng(seed, "lysed_rim_loss")),
                                     "lysed_haze": c.stain.draw("lysed_haze", scene_rng(seed, "lysed_haze")),
                                     "rim_mottle_grain_mm": c.stain.draw("rim_mottle_grain_mm",
                                                                         scene_rng(seed, "rim_mottle_grain"))})
    plaques = _shrink_crowded(plaques, c.plaques.draw("max_coverage", rng), plate.well_radius_mm)
    wells, lace_plaques = _lace_lysed_wells(scene_rng(seed, "lysed_lace"), c.plaques, wells, len(plaques), radius, shared)
    plaques += lace_plaques
    scratches += _rim_tears(scene_rng(seed, "rim_tears"), a, wells, radius)
    ridge_sides = scene_rng(seed, "scratch_ridge_sides")
    scratches = [s.model_copy(update={"ridge_side": int(ridge_sides.choice((-1, 1)))}) for s in scratches]
    return Scene(
        seed=texture_seed,
        plate=plate,
        plate_look=plate_look,
        stain=stain,
        wells=tuple(wells),
        plaques=tuple(plaques),
        plaque_look=plaque_look,
        artifacts=Artifacts(scratches=tuple(scratches), marker=tuple(marker), blots=tuple(blots), debris=tuple(debris),
                            scratch_roughness=c.artifacts.draw("scratch_roughness", scene_rng(seed, "scratch_edges")),
                            scratch_clearing=c.artifacts.draw("scratch_clearing", scene_rng(seed, "scratch_clearing")),
                            scratch_softness_mm=c.artifacts.draw("scratch_softness_mm",
                                                                 scene_rng(seed, "scratch_softness")),
                            scratch_haze=c.artifacts.draw("scratch_haze", scene_rng(seed, "scratch_haze")),
                            scratch_heaps=c.artifacts.draw("scratch_heaps", scene_rng(seed, "scratch_heaps")),
                            scratch_ridge=c.artifacts.draw("scratch_ridge", scene_rng(seed, "scratch_ridge")),
                            smears=tuple(_smears(scene_rng(seed, "smears"), a, wells, radius))),
        background=background,
        lighting=lighting,
        camera=camera,
        post=post,
    )


def _light_panel(
    plate: PlateGeometry, margins: list[float], below: bool, portrait: bool, near_left: bool
) -> tuple[float, ...]:
    """An A4-sized light panel (:data:`LIGHT_PANEL_MM`, upright when ``portrait``) with the plate near one of its
    corners: ``margins`` (mm) from the nearest side edge (the left one when ``near_left``) and from the nearest
    top/bottom edge (below the plate when ``below``); negative: the plate overhangs."""
    panel_w, panel_h = LIGHT_PANEL_MM if portrait else LIGHT_PANEL_MM[::-1]
    panel_w, panel_h = max(panel_w, plate.length_mm + 2 * margins[0]), max(panel_h, plate.width_mm + 2 * margins[1])
    half_l, half_w = plate.length_mm / 2, plate.width_mm / 2
    left = -half_l - margins[0] if near_left else half_l + margins[0] - panel_w
    top = half_w + margins[1] - panel_h if below else -half_w - margins[1]
    return tuple(round(v, 3) for v in (left, top, left + panel_w, top + panel_h))


def _in_disc(rng: np.random.Generator, radius: float, edge_bias: float = 0.0) -> np.ndarray:
    angle = rng.uniform(0, 2 * np.pi)
    rho = radius * rng.random() ** (1.0 / (2.0 + 6.0 * edge_bias))
    return np.array([rho * math.cos(angle), rho * math.sin(angle)])


class _PlaqueDraws(NamedTuple):
    """The plate's draws that all its plaques share: the median radius and the sd of the log radii, the largest radius
    (share of the well's), the outline harmonics' amplitudes, the softness and the clearness."""

    median_radius: float
    radius_spread: float
    max_radius: float
    harmonic_scale: np.ndarray
    softness: float
    clearness: float


def _sample_plaques(
    rng: np.random.Generator,
    section: PlaquesConfig,
    count: int,
    well_id: int,
    center: np.ndarray,
    well_radius: float,
    first_index: int,
    shared: _PlaqueDraws,
    edge_bias: float,
    max_overlap: float,
) -> list[Plaque]:
    radii = np.clip(
        shared.median_radius * np.array([math.exp(z) for z in rng.normal(0, shared.radius_spread, count)]),
        MIN_PLAQUE_RADIUS_MM,
        shared.max_radius * well_radius,
    )
    placed: list[tuple[np.ndarray, float]] = []
    out: list[Plaque] = []
    for radius in radii:
        for _attempt in range(PLACEMENT_ATTEMPTS if max_overlap < 1.0 else 1):
            offset = _in_disc(rng, well_radius, edge_bias)
            if max_overlap >= 1.0 or all(
                (radius + r - math.hypot(*(offset - o))) <= 2 * max_overlap * min(radius, r) for o, r in placed
            ):
                break
        else:
            continue
        placed.append((offset, float(radius)))
        coefficients = rng.normal(0.0, 1.0, (len(shared.harmonic_scale), 2)) * shared.harmonic_scale[:, None]
        out.append(
            Plaque(
                id=first_index + len(out) + 1,
                well=well_id,
                center_mm=_tuple2(center + offset),
                radius_mm=round(float(radius), 4),
                fourier=tuple(_tuple2(pair) for pair in coefficients),
                softness=shared.softness * section.draw("softness_factor", rng),
                clearness=min(1.0, shared.clearness * section.draw("clearness_factor", rng)),
            )
        )
    return out


def _lace_lysed_wells(
    rng: np.random.Generator,
    section: PlaquesConfig,
    wells: list[Well],
    first_index: int,
    well_radius: float,
    shared: _PlaqueDraws,
) -> tuple[list[Well], list[Plaque]]:
    """Turn each lysed well, with chance ``plaques.lysed_lace``, into a lace: as many plaques like the plate's others
    (``shared``), spread evenly, as cover ``plaques.lace_coverage`` of its area (their discs' sum), numbered after all
    others (``first_index``), over a layer the renderers draw damaged (``Well.lace``). Drawn from ``rng``, a stream
    of their own, after every other draw."""
    mean_square_radius = shared.median_radius**2 * math.exp(2.0 * shared.radius_spread**2)  # of the lognormal radii
    laced, plaques = [], []
    for well in wells:
        if well.lysed and section.draw("lysed_lace", rng):
            count = min(LACE_MAX_PLAQUES, round(section.draw("lace_coverage", rng) * well_radius**2 / mean_square_radius))
            plaques += _sample_plaques(rng, section, count, well.id, np.array(well.center_mm), well_radius,
                                       first_index + len(plaques), shared, 0.0, 1.0)
            well = well.model_copy(update={"lace": True})
        laced.append(well)
    return laced, plaques


def _shrink_crowded(plaques: list[Plaque], max_coverage: float, well_radius: float) -> list[Plaque]:
    """Scale the radii of each well's plaques by one factor so that their discs together cover at most
    ``max_coverage`` of the well's area (centres stay where they are)."""
    areas: dict[int, float] = {}
    for plaque in plaques:
        areas[plaque.well] = areas.get(plaque.well, 0.0) + plaque.radius_mm**2
    limit = max_coverage * well_radius**2
    shrunk = []
    for plaque in plaques:
        if areas[plaque.well] > limit:
            radius = max(MIN_PLAQUE_RADIUS_MM, plaque.radius_mm * math.sqrt(limit / areas[plaque.well]))
            plaque = plaque.model_copy(update={"radius_mm": round(radius, 4)})
        shrunk.append(plaque)
    return shrunk


def _pipette_scratch(
    rng: np.random.Generator,
    pose: np.random.Generator,
    section: ArtifactsConfig,
    well_id: int,
    center: np.ndarray,
    radius: float,
    length: float,
    width: float,
) -> Scratch:
    """The short hook-shaped streak where the pipette tip touched the layer, at the top of the well; its tilt off
    the radius and its start's inset from the rim come from ``pose``, a random stream of their own."""
    angle = rng.normal(0.0, PIPETTE_ANGLE_SD)
    tilt = math.radians(section.draw("pipette_tilt_deg", pose))
    inward = np.array([-math.sin(angle), math.cos(angle)])
    start = center - (radius * RIM_START - section.draw("pipette_inset_mm", pose)) * inward
    length *= section.draw("pipette_length_factor", rng)
    bend = section.draw("pipette_bend", rng)
    t = np.linspace(0.0, 1.0, 5)
    along = t * length
    side = bend * length * t**2
    direction = np.array([-math.sin(angle + tilt), math.cos(angle + tilt)])
    normal = np.array([direction[1], -direction[0]])
    points = start + along[:, None] * direction + side[:, None] * normal
    return Scratch(
        well=well_id, points_mm=tuple(map(_tuple2, points)), width_mm=width * section.draw("pipette_width_factor", rng)
    )


def _rim_tears(rng: np.random.Generator, section: ArtifactsConfig, wells: list[Well], radius: float) -> list[Scratch]:
    """The tears where the layer came off at the rim (``artifacts.rim_tears`` per well, Poisson): each a short, wide,
    straight scratch from just outside the rim, anywhere around the well, running inward at ``rim_tear_tilt_deg`` off
    the radius, to either side. Drawn from ``rng``, a stream of their own, after every other draw; an emptied well has
    no layer to tear."""
    rate = section.draw("rim_tears", rng)
    tears = []
    for well in wells:
        if well.emptied:
            continue
        center = np.array(well.center_mm)
        for _ in range(int(rng.poisson(rate))):
            angle = rng.uniform(0.0, 2.0 * math.pi)
            side = 1.0 if rng.random() < 0.5 else -1.0
            heading = angle + math.pi + side * math.radians(section.draw("rim_tear_tilt_deg", rng))
            start = center + radius * RIM_START * np.array([math.cos(angle), math.sin(angle)])
            end = start + section.draw("rim_tear_length_mm", rng) * np.array([math.cos(heading), math.sin(heading)])
            tears.append(Scratch(well=well.id, points_mm=(_tuple2(start), _tuple2(end)),
                                 width_mm=section.draw("rim_tear_width_mm", rng)))
    return tears


def _smears(rng: np.random.Generator, section: ArtifactsConfig, wells: list[Well], radius: float) -> list[Smear]:
    """The dark smears (``artifacts.smears`` per well, Poisson): each a nearly straight band of
    :data:`SMEAR_POINTS` points anywhere in the well, bending by :data:`SMEAR_BEND_RAD` at each, drawn from ``rng``,
    a stream of their own; an emptied or lysed well has no layer to fold."""
    rate = section.draw("smears", rng)
    smears = []
    for well in wells:
        if well.emptied or well.lysed:
            continue
        for _ in range(int(rng.poisson(rate))):
            start = np.array(well.center_mm) + _in_disc(rng, radius * DEBRIS_REACH)
            headings = rng.uniform(0.0, 2.0 * math.pi) + np.cumsum(rng.normal(0.0, SMEAR_BEND_RAD, SMEAR_POINTS - 1))
            step = section.draw("smear_length_mm", rng) / (SMEAR_POINTS - 1)
            steps = step * np.stack([np.cos(headings), np.sin(headings)], axis=1)
            stroke = start + np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
            smears.append(Smear(well=well.id, points_mm=tuple(map(_tuple2, stroke)),
                                width_mm=section.draw("smear_width_mm", rng),
                                darkness=section.draw("smear_darkness", rng)))
    return smears


def _marker_writing(
    rng: np.random.Generator, section: ArtifactsConfig, plate: PlateGeometry, from_below: bool
) -> list[MarkerStroke]:
    """A few pen strokes in a free corner of the plate, in one ink."""
    ink = tuple(np.round(section.draw("marker_ink_rgb", rng), 4))
    margin_x = plate.a1_x_mm - plate.well_radius_mm - plate.wall_mm
    margin_y = plate.a1_y_mm - plate.well_radius_mm - plate.wall_mm
    # the corner that appears top-left in the image: the plate's top-right when seen from below
    corner_x = plate.length_mm - max(margin_x, 4.0) / 2 if from_below else max(margin_x, 4.0) / 2
    start = np.array([corner_x, max(margin_y, 4.0) / 2 + 2.0]) + rng.normal(0, MARKER_JITTER_MM, 2)
    size = section.draw("marker_size_mm", rng)
    width = section.draw("marker_width_mm", rng)
    strokes = []
    for i in range(section.draw("marker_strokes", rng)):
        stroke = _smooth_stroke(rng, start + np.array([i * size * 0.6, 0.0]), size)
        strokes.append(MarkerStroke(points_mm=tuple(map(_tuple2, stroke)), width_mm=width, color_rgb=ink))
    return strokes


def _sample_post(c: SceneConfig, rng: np.random.Generator) -> PostProcessing:
    p = c.post

    def effect(name: str) -> Effect:
        enabled = p.draw(name, rng)
        strength = p.draw(f"{name}_strength", rng)
        return Effect(enabled=enabled, strength=strength)

    brightness = effect("brightness")
    white_balance = effect("white_balance")
    shift = rng.normal(0.0, 1.0, 3)
    clarity = effect("clarity")
    motion_blur = effect("motion_blur")
    angle = rng.uniform(0, 180)
    return PostProcessing(
        brightness=brightness,
        white_balance=white_balance,
        white_balance_shift=tuple(np.round(1.0 + white_balance.strength * shift, 4)),
        clarity=clarity,
        motion_blur=motion_blur,
        motion_blur_angle_deg=angle,
        shadows=effect("shadows"),
        chromatic_aberration=effect("chromatic_aberration"),
        bloom=effect("bloom"),
        sharpen=effect("sharpen"),
        noise=effect("noise"),
        jpeg=effect("jpeg"),
    )
