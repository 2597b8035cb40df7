"""The raster renderer's per-pixel shading: one row-parallel numba kernel composed of small inlined parts.

For every pixel, in linear light: what lies behind the plate (:func:`backdrop`: a light box with its frame and
ruler, or a desk), the plate's plastic over it (:func:`plastic`, :func:`relief_and_ink`, :func:`blot_filter`), the
well's monolayer (:mod:`platesynth.render.appearance`, the model shared with the Blender backend), then the
lighting and the display encoding (:func:`expose`). The plate's fixed coefficients are in
:mod:`platesynth.render.look`; the per-image scalars travel in one :data:`FRAME_DTYPE` record.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from platesynth.render import appearance
from platesynth.render.look import (
    BLOT_DISTORTION,
    BLOT_REACH,
    CRESCENT_LIGHT,
    DESK_AMBIENT,
    DESK_THROUGH,
    FLOOR_TRANSMITTANCE,
    FRAME_BRIGHTNESS,
    GLOW_DIP,
    GLOW_FALLOFF_MM,
    GLOW_REACH_MM,
    OUTLINE_WEIGHTS,
    OUTLINE_WIDTH_MM,
    RULER_DARK,
    RULER_TICK,
    RULER_TICK_HALF_WIDTH_MM,
    RULER_TICKS_MM,
    RULER_WIDTH_MM,
    SKIRT_DARKENING,
    WALL_HIGHLIGHT_PLACES,
    WALL_LINE_PLACES,
    WALL_LINE_WOBBLE_MM,
    wall_line_phase,
)
from platesynth.render.sampling import clip01, grid_sample, ring, smeared_ring, to_plate

FRAME_DTYPE = np.dtype(
    [
        ("pixel_mm", np.float64),
        ("mirror", np.float64),  # -1 seen from below (the image is mirrored), else 1
        ("length", np.float64),  # the plate's outline (mm)
        ("plate_width", np.float64),
        ("corner", np.float64),
        ("chamfer", np.float64),
        ("skirt", np.float64),
        ("a1x", np.float64),  # the well grid
        ("a1y", np.float64),
        ("pitch", np.float64),
        ("rows", np.int64),
        ("cols", np.int64),
        ("radius", np.float64),
        ("wall", np.float64),
        ("top_radius", np.float64),  # the walls' top edge, seen with parallax
        ("foot_scale", np.float64),  # lengths at the walls' foot, seen with parallax, over those at the floor
        ("from_below", np.bool_),
        ("top_edge_through_floor", np.float64),  # share of the top edge's outlines seen through a floor
        ("top_edge_blur", np.float64),  # width over which the top edge's outlines are smeared (mm)
        ("crescent_veil", np.float64),  # share of the light passing around the stain past the top edge
        ("wall_lines", np.float64),  # darkness of the lines a wall refracts across its band
        ("wall_highlights", np.float64),  # brightness of the highlights between them
        ("transmittance", np.float64),  # the plastic between the wells
        ("rim_darkness", np.float64),
        ("wall_band", np.float64),  # relative brightness over the walls' thickness
        ("label_strength", np.float64),
        ("tint_r", np.float64),
        ("tint_g", np.float64),
        ("tint_b", np.float64),
        ("is_desk", np.bool_),  # the background: a desk, else a light box
        ("brightness", np.float64),
        ("desk_texture", np.float64),
        ("frame_mm", np.float64),
        ("ruler", np.bool_),
        ("sheen", np.float64),
        ("vignetting", np.float64),
        ("glare", np.float64),
        ("glare_x", np.float64),
        ("glare_y", np.float64),
        ("glare_radius", np.float64),
    ]
)
"""The per-image scalars of :func:`shade` (a one-row array)."""


@njit(cache=True, nogil=True, inline="always")
def backdrop(x, y, u, v, f, desk_rgb, panel, desk_grid, desk_cell_px):
    """Linear RGB of what lies behind the plate at pixel ``(x, y)``, plate point ``(u, v)``."""
    if f.is_desk:
        tex = 1.0 + f.desk_texture * grid_sample(desk_grid, (x + 0.5) / desk_cell_px, (y + 0.5) / desk_cell_px)
        return desk_rgb[0] * tex * f.brightness, desk_rgb[1] * tex * f.brightness, desk_rgb[2] * tex * f.brightness
    left, top, right, bottom = panel[0], panel[1], panel[2], panel[3]
    bx = f.mirror * (u - 0.5 * f.length)
    by = v - 0.5 * f.plate_width
    to_edge = min(min(bx - left, right - bx), min(by - top, bottom - by))
    lit = clip01(to_edge / f.pixel_mm + 0.5)
    glow = f.brightness
    if to_edge < GLOW_REACH_MM:
        glow *= 1.0 - GLOW_DIP * math.exp(-max(to_edge, 0.0) / GLOW_FALLOFF_MM)
    r = g = b = glow
    if lit < 1.0:
        frame = clip01((to_edge + f.frame_mm) / f.pixel_mm + 0.5) - lit
        tex = 1.0 + f.desk_texture * grid_sample(desk_grid, (x + 0.5) / desk_cell_px, (y + 0.5) / desk_cell_px)
        dark = 1.0 - lit - frame
        r = desk_rgb[0] * tex * dark + lit * glow + frame * FRAME_BRIGHTNESS
        g = desk_rgb[1] * tex * dark + lit * glow + frame * FRAME_BRIGHTNESS
        b = desk_rgb[2] * tex * dark + lit * glow + frame * FRAME_BRIGHTNESS
    if f.ruler:
        along = -1.0
        across = 0.0
        if bx < left and bx > left - RULER_WIDTH_MM and by > top and by < bottom + RULER_WIDTH_MM:
            along = abs(by - bottom)
            across = left - bx
        elif by > bottom and by < bottom + RULER_WIDTH_MM and bx > left - RULER_WIDTH_MM and bx < right:
            along = abs(bx - left)
            across = by - bottom
        if along >= 0.0:
            nearest = math.floor(along + 0.5)
            tick = RULER_TICKS_MM[2] if nearest % 10 == 0 else (RULER_TICKS_MM[1] if nearest % 5 == 0 else RULER_TICKS_MM[0])
            mark = RULER_TICK if abs(along - nearest) < RULER_TICK_HALF_WIDTH_MM and across < tick else 0.0
            r = g = b = RULER_DARK + mark
    return r, g, b


@njit(cache=True, nogil=True, inline="always")
def plate_signed_distance(u, v, f):
    """Signed distance (mm, negative inside) to the plate's outline: a rounded rectangle, A1 corner chamfered."""
    half_l = 0.5 * f.length
    half_w = 0.5 * f.plate_width
    qx = abs(u - half_l) - (half_l - f.corner)
    qy = abs(v - half_w) - (half_w - f.corner)
    signed = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2) + min(max(qx, qy), 0.0) - f.corner
    return max(signed, (f.chamfer - u - v) * 0.7071067811865476)


@njit(cache=True, nogil=True, inline="always")
def top_ring(dist, radius, half_width, f):
    """Coverage of an outline of the walls' top edge, smeared over ``f.top_edge_blur`` mm (out of focus)."""
    if f.top_edge_blur <= 0.0:  # the anti-aliased ring exactly, also where a pixel is wider than the line
        return ring(dist, radius, half_width, f.pixel_mm)
    return smeared_ring(dist, radius, half_width, math.hypot(f.pixel_mm, f.top_edge_blur))


@njit(cache=True, nogil=True, inline="always")
def past_top_edge(top_dist, f):
    """Share of a pixel whose ray, seen from below, meets the walls' top-edge plane outside the opening (it crossed
    the wall, not the open top), the edge smeared over ``f.top_edge_blur`` mm as its outlines are."""
    return clip01((top_dist - f.top_radius) / math.hypot(f.pixel_mm, f.top_edge_blur) + 0.5)


line_phase = njit(cache=True, nogil=True, inline="always")(wall_line_phase)


@njit(cache=True, nogil=True, inline="always")
def refracted_lines(well, du, dv, dist, f):
    """Coverage of the thin lines a wall refracts across its band (:data:`WALL_LINE_PLACES`) and of the highlights
    between them (:data:`WALL_HIGHLIGHT_PLACES`), each wobbling by :data:`WALL_LINE_WOBBLE_MM` in two waves around the well
    (the phase :func:`~platesynth.render.look.wall_line_phase` of the well's noise shifts); drawn at the walls' foot,
    ``(du, dv)`` from its centre at distance ``dist``."""
    foot_radius = f.radius * f.foot_scale
    width = f.wall * f.foot_scale
    reach = WALL_LINE_WOBBLE_MM * f.foot_scale
    if dist <= foot_radius - reach or dist >= foot_radius + width + reach or dist <= 0.0:
        return 0.0, 0.0
    c1 = du / dist
    s1 = dv / dist
    c2 = c1 * c1 - s1 * s1
    s2 = 2.0 * c1 * s1
    half = 0.5 * OUTLINE_WIDTH_MM
    dark = 0.0
    bright = 0.0
    for j in range(len(WALL_LINE_PLACES)):
        phase = line_phase(well.noise_x, well.noise_y, j)
        wobble = reach * (c2 * math.cos(phase) + s2 * math.sin(phase))
        dark += ring(dist, foot_radius + WALL_LINE_PLACES[j] * width + wobble, half, f.pixel_mm)
        bright += ring(dist, foot_radius + WALL_HIGHLIGHT_PLACES[j] * width + wobble, half, f.pixel_mm)
    return dark, bright


@njit(cache=True, nogil=True, inline="always")
def band_sheen(well, du, dv, dist):
    """The relative brightness change of the band over ``well``'s wall at ``(du, dv)`` from the well's centre, at
    distance ``dist``: the Fourier series of :func:`~platesynth.render.appearance.wall_sheen`, its three harmonics."""
    if dist <= 0.0:
        return 0.0
    c1 = du / dist
    s1 = dv / dist
    c2 = c1 * c1 - s1 * s1
    s2 = 2.0 * c1 * s1
    c3 = c1 * c2 - s1 * s2
    s3 = s1 * c2 + c1 * s2
    return (well.sheen_a1 * c1 + well.sheen_b1 * s1 + well.sheen_a2 * c2 + well.sheen_b2 * s2
            + well.sheen_a3 * c3 + well.sheen_b3 * s3)


@njit(cache=True, nogil=True, inline="always")
def plastic(foot_dist, top_dist, disc, signed, relief, sheen, lines, highlights, f):
    """Share of the light the plastic passes: the floor or the deck, the walls' band and outlines, the embossing
    (``relief``) and the skirt; ``disc`` is the pixel's coverage by the well's floor, ``foot_dist`` its distance from
    the centre of the walls' foot as the camera sees it. Where the foot's opening shows no floor, the camera sees
    the inside of the wall below the floor: it takes the band's brightness, changed by ``sheen`` (relative) where
    the pixel lies (:func:`band_sheen`). Seen from below, the walls' top edge lies behind the floor: only
    ``top_edge_through_floor`` of its outlines shows through it. ``lines`` and ``highlights`` are the pixel's
    coverage by the lines the wall refracts and by their highlights (:func:`refracted_lines`), darkened and brightened
    by ``wall_lines`` and ``wall_highlights``. Returns the share passed and the pixel's coverage by the band (0..1)."""
    behind_layer = 1.0 - disc * (1.0 - f.top_edge_through_floor) if f.from_below else 1.0
    line_half = 0.5 * OUTLINE_WIDTH_MM
    foot_radius = f.radius * f.foot_scale
    foot_outer = (f.radius + f.wall) * f.foot_scale
    outlines = (
        OUTLINE_WEIGHTS[0] * ring(foot_dist, foot_radius, line_half, f.pixel_mm)
        + OUTLINE_WEIGHTS[1] * ring(foot_dist, foot_outer, line_half, f.pixel_mm)
        + behind_layer * (OUTLINE_WEIGHTS[2] * top_ring(top_dist, f.top_radius, line_half, f)
                          + OUTLINE_WEIGHTS[3] * top_ring(top_dist, f.top_radius + f.wall, line_half, f))
    ) + f.wall_lines * lines
    band = 1.0 if foot_radius < foot_dist < foot_outer else 0.0
    # the foot's opening minus the floor: none where the foot lies at the floor's height
    band = min(band + max(clip01((foot_radius - foot_dist) / f.pixel_mm + 0.5) - disc, 0.0), 1.0)
    skirt_shade = 1.0 - SKIRT_DARKENING * clip01((signed + f.skirt) / f.skirt)
    # the thick plastic between the wells passes less light than a well's thin bottom
    passing = (f.transmittance * (1.0 - disc) + FLOOR_TRANSMITTANCE * disc) * (
        1.0 + (f.wall_band + sheen) * band + f.wall_highlights * highlights - f.rim_darkness * min(outlines, 1.0))
    return passing * ((1.0 - relief) * skirt_shade), band


@njit(cache=True, nogil=True, inline="always")
def relief_and_ink(u, v, texels_per_mm, relief_map, ink, label_strength):
    """The embossing's darkening and the marker ink's RGB transmission at ``(u, v)`` (bilinear, plate textures)."""
    relief = 0.0
    ink_r = 1.0
    ink_g = 1.0
    ink_b = 1.0
    ts = u * texels_per_mm - 0.5
    tt = v * texels_per_mm - 0.5
    if ts >= 0.0 and tt >= 0.0 and ts < relief_map.shape[1] - 1 and tt < relief_map.shape[0] - 1:
        i = int(tt)
        j = int(ts)
        fs = ts - j
        ft = tt - i
        w00 = (1.0 - fs) * (1.0 - ft)
        w01 = fs * (1.0 - ft)
        w10 = (1.0 - fs) * ft
        w11 = fs * ft
        relief = label_strength * (w00 * relief_map[i, j] + w01 * relief_map[i, j + 1]
                                   + w10 * relief_map[i + 1, j] + w11 * relief_map[i + 1, j + 1])
        if ink.shape[0] > 1:
            ink_r = w00 * ink[i, j, 0] + w01 * ink[i, j + 1, 0] + w10 * ink[i + 1, j, 0] + w11 * ink[i + 1, j + 1, 0]
            ink_g = w00 * ink[i, j, 1] + w01 * ink[i, j + 1, 1] + w10 * ink[i + 1, j, 1] + w11 * ink[i + 1, j + 1, 1]
            ink_b = w00 * ink[i, j, 2] + w01 * ink[i, j + 1, 2] + w10 * ink[i + 1, j, 2] + w11 * ink[i + 1, j + 1, 2]
    return relief, ink_r, ink_g, ink_b


@njit(cache=True, nogil=True, inline="always")
def blot_filter(u, v, blots, low_grid, low_cell_mm):
    """RGB transmission of the soft smudges on the plate; ``blots[b] = (cx, cy, radius, r, g, b, opacity)``."""
    blot_r = 1.0
    blot_g = 1.0
    blot_b = 1.0
    for b in range(blots.shape[0]):
        bu = u - blots[b, 0]
        bv = v - blots[b, 1]
        d2 = (bu * bu + bv * bv) / (blots[b, 2] * blots[b, 2])
        if d2 < BLOT_REACH * BLOT_REACH:
            a = blots[b, 6] * math.exp(-d2 * (1.0 + BLOT_DISTORTION * grid_sample(low_grid, u / low_cell_mm, v / low_cell_mm)))
            blot_r *= 1.0 - a * (1.0 - blots[b, 3])
            blot_g *= 1.0 - a * (1.0 - blots[b, 4])
            blot_b *= 1.0 - a * (1.0 - blots[b, 5])
    return blot_r, blot_g, blot_b


@njit(cache=True, nogil=True, inline="always")
def expose(x, y, width, height, value, channel_gain, f):
    """The light's colour and exposure, vignetting and glare applied to one linear channel ``value``."""
    aspect = width / height
    fx = ((x + 0.5) / width - 0.5) * aspect
    fy = (y + 0.5) / height - 0.5
    vignette = 1.0 - f.vignetting * (fx * fx + fy * fy) / (0.25 * (aspect * aspect + 1.0))
    flare = 0.0
    if f.glare > 0.0:
        gx = fx - (f.glare_x - 0.5) * aspect
        gy = fy - (f.glare_y - 0.5)
        flare = f.glare * math.exp(-(gx * gx + gy * gy) / (f.glare_radius * math.sqrt(aspect * aspect + 1.0)) ** 2)
    return min(max(value * channel_gain * vignette + flare, 0.0), 1.0)


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def shade(
    hinv, frame, desk_rgb, panel, blots, wells, stain, relief_map, ink, texels_per_mm, low_grid, fibre_grid,
    desk_grid, desk_cell_px, fine_tile, mottle_tile, foam_tile, residual_tile, clearing, rim, scratched, heaped, specks, gains, gamma_lut, out, wells_mask,
):
    """Shade every pixel (linear light, then display-encoded through ``gamma_lut``) and fill the well mask.

    ``frame`` is a one-row :data:`FRAME_DTYPE` array, ``wells`` and ``stain`` the appearance model's tables
    (:data:`~platesynth.render.appearance.WELL_DTYPE`, :data:`~platesynth.render.appearance.STAIN_DTYPE`);
    ``clearing``, ``rim``, ``scratched``, ``heaped`` and ``specks`` its :class:`~platesynth.render.appearance.WellContent` at the
    pixels. ``relief_map`` (h, w) and ``ink`` (h, w, 3), or (1, 1, 3) for no ink, are plate-space textures.
    """
    height, width = out.shape[0], out.shape[1]
    n_lut = gamma_lut.shape[0] - 1
    for y in prange(height):
        f = frame[0]  # records are read inside the parallel loop (numba cannot pass them into it)
        st = stain[0]
        rgb = np.empty(3, dtype=np.float64)
        for x in range(width):
            u, v = to_plate(hinv, x + 0.5, y + 0.5)
            rgb[0], rgb[1], rgb[2] = backdrop(x, y, u, v, f, desk_rgb, panel, desk_grid, desk_cell_px)
            signed = plate_signed_distance(u, v, f)
            plate_alpha = clip01(0.5 - signed / f.pixel_mm)
            if plate_alpha > 0.0:
                k = appearance.well_at(u, v, f.a1x, f.a1y, f.pitch, f.rows, f.cols)
                well = wells[k]
                du = u - well.cx
                dv = v - well.cy
                dist = math.sqrt(du * du + dv * dv)
                tu = u - well.top_cx
                tv = v - well.top_cy
                top_dist = math.sqrt(tu * tu + tv * tv)
                fu = u - well.foot_cx
                fv = v - well.foot_cy
                foot_dist = math.sqrt(fu * fu + fv * fv)
                if dist < f.radius and (f.from_below or top_dist < f.top_radius):
                    wells_mask[y, x] = np.uint8(well.id)
                disc = clip01((f.radius - dist) / f.pixel_mm + 0.5)
                relief, ink_r, ink_g, ink_b = relief_and_ink(u, v, texels_per_mm, relief_map, ink, f.label_strength)
                sheen = band_sheen(well, fu, fv, foot_dist)
                lines = highlights = 0.0
                if f.wall_lines > 0.0 or f.wall_highlights > 0.0:
                    lines, highlights = refracted_lines(well, fu, fv, foot_dist, f)
                passing, band = plastic(foot_dist, top_dist, disc, signed, relief, sheen, lines, highlights, f)
                # the band takes a share of its well's stain (a factor of 1 where the share is 0)
                wall_r = 1.0 - band * (1.0 - well.wall_r)
                wall_g = 1.0 - band * (1.0 - well.wall_g)
                wall_b = 1.0 - band * (1.0 - well.wall_b)
                blot_r, blot_g, blot_b = blot_filter(u, v, blots, low_grid, st.unevenness_cell_mm)
                # the stained monolayer: the appearance model, over the pixel's coverage by the floor
                layer_r = 1.0
                layer_g = 1.0
                layer_b = 1.0
                if disc > 0.0 and well.emptied < 0.5:
                    layer_r, layer_g, layer_b = appearance.floor_rgb(
                        u, v, du, dv, dist, f.radius, well, st, low_grid, fibre_grid, fine_tile, mottle_tile,
                        foam_tile, residual_tile, clearing[y, x], rim[y, x], scratched[y, x], heaped[y, x],
                        specks[y, x])
                    layer_r = layer_r * disc + 1.0 - disc
                    layer_g = layer_g * disc + 1.0 - disc
                    layer_b = layer_b * disc + 1.0 - disc
                if f.crescent_veil > 0.0 and f.from_below and disc > 0.0:
                    # past the top edge, part of the light came through the wall around the stain: a paler crescent
                    veil = f.crescent_veil * disc * past_top_edge(top_dist, f)
                    layer_r = layer_r * (1.0 - veil) + veil * CRESCENT_LIGHT
                    layer_g = layer_g * (1.0 - veil) + veil * CRESCENT_LIGHT
                    layer_b = layer_b * (1.0 - veil) + veil * CRESCENT_LIGHT
                if f.is_desk:
                    behind_r = DESK_THROUGH * rgb[0] + DESK_AMBIENT * f.brightness
                    behind_g = DESK_THROUGH * rgb[1] + DESK_AMBIENT * f.brightness
                    behind_b = DESK_THROUGH * rgb[2] + DESK_AMBIENT * f.brightness
                else:
                    behind_r = rgb[0]
                    behind_g = rgb[1]
                    behind_b = rgb[2]
                on_r = (behind_r * passing * wall_r + f.sheen) * f.tint_r * ink_r * blot_r * layer_r
                on_g = (behind_g * passing * wall_g + f.sheen) * f.tint_g * ink_g * blot_g * layer_g
                on_b = (behind_b * passing * wall_b + f.sheen) * f.tint_b * ink_b * blot_b * layer_b
                rgb[0] = on_r * plate_alpha + rgb[0] * (1.0 - plate_alpha)
                rgb[1] = on_g * plate_alpha + rgb[1] * (1.0 - plate_alpha)
                rgb[2] = on_b * plate_alpha + rgb[2] * (1.0 - plate_alpha)
            for c in range(3):
                value = expose(x, y, width, height, rgb[c], gains[c], f)
                out[y, x, c] = gamma_lut[int(math.sqrt(value) * n_lut + 0.5)]
