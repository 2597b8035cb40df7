"""Numba kernels of the raster renderer.

Every kernel maps pixel centres ``(x + 0.5, y + 0.5)`` to plate millimetres ``(u, v)`` with the inverse
homography ``hinv``, so shapes are evaluated exactly in plate space whatever the camera. Per-object kernels
(plaques, capsules) work inside each object's pixel box ``(y0, y1, x0, x1)`` (end exclusive).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

# indices into the per-well parameter rows of ``shade``
W_ID, W_CX, W_CY, W_TOP_CX, W_TOP_CY, W_DENSITY, W_GRADIENT, W_COS, W_SIN, W_OFF_X, W_OFF_Y, W_DRYING, W_LYSED, \
    W_EMPTIED, W_NOISE_X, W_NOISE_Y = range(16)
N_WELL_PARAMS = 16
FLOOR_TRANSMITTANCE = 0.96
"""Share of the light a well's thin bottom passes (the thick plastic between the wells passes ``plate_look.transmittance``)."""
WALL_BAND_GAIN = 0.04
"""How much brighter the plate looks over a well's wall, seen end-on, than over the deck around it."""
EDGE_SPAN = 1.5
"""A plaque's clearing falls from full to none over this many edge widths, centred on its outline."""
FRAY_AMPLITUDE = 0.2
"""How far the fray noise (unit sd) shifts the edge's clearing ramp, as a share of the ramp."""
FRAY_ROWS_PER_PLAQUE = 7.37
"""Each plaque reads the fray tile this many rows further along, so that neighbours fray differently."""
RESIDUAL_MEAN, RESIDUAL_SPREAD, RESIDUAL_MAX = 0.03, 0.03, 0.2
"""Share of the stain left inside a cleared plaque: mean, noise amplitude (unit-sd residual tile) and cap."""


@njit(cache=True, nogil=True, inline="always")
def _to_plate(hinv, px, py):
    w = hinv[2, 0] * px + hinv[2, 1] * py + hinv[2, 2]
    u = (hinv[0, 0] * px + hinv[0, 1] * py + hinv[0, 2]) / w
    v = (hinv[1, 0] * px + hinv[1, 1] * py + hinv[1, 2]) / w
    return u, v


@njit(cache=True, nogil=True, inline="always")
def _clip01(x):
    return min(max(x, 0.0), 1.0)


@njit(cache=True, nogil=True)
def _grid(grid, s, t):
    """Bilinear sample of ``grid`` at fractional index (s = column, t = row), clamped at the border."""
    h, w = grid.shape
    s = min(max(s, 0.0), w - 1.001)
    t = min(max(t, 0.0), h - 1.001)
    i = int(t)
    j = int(s)
    fs = s - j
    ft = t - i
    top = grid[i, j] * (1.0 - fs) + grid[i, j + 1] * fs
    bottom = grid[i + 1, j] * (1.0 - fs) + grid[i + 1, j + 1] * fs
    return top * (1.0 - ft) + bottom * ft


@njit(cache=True, nogil=True)
def _tile(tile, s, t):
    """Bilinear sample of a periodic ``tile`` (power-of-two sides) at fractional index (s = column, t = row)."""
    h, w = tile.shape
    fj = math.floor(s)
    fi = math.floor(t)
    fs = s - fj
    ft = t - fi
    j = int(fj) & (w - 1)
    i = int(fi) & (h - 1)
    j1 = (j + 1) & (w - 1)
    i1 = (i + 1) & (h - 1)
    top = tile[i, j] * (1.0 - fs) + tile[i, j1] * fs
    bottom = tile[i1, j] * (1.0 - fs) + tile[i1, j1] * fs
    return top * (1.0 - ft) + bottom * ft


@njit(cache=True, nogil=True)
def _ring(dist, radius, half_width, pixel_mm):
    """Coverage of a thin anti-aliased ring."""
    return _clip01((half_width - abs(dist - radius)) / pixel_mm + 0.5)


@njit(cache=True, nogil=True)
def draw_plaques(hinv, params, fourier, boxes, pixel_mm, from_below, top_radius, fuzz_tile, fuzz_cell_mm, clear, ids):
    """Draw plaques in order (later ones on top).

    ``params[p] = (cx, cy, radius, edge_width, clearness, well_id, well_cx, well_cy, well_radius, top_cx, top_cy)``
    (mm); ``fourier[p, k] = (a, b)`` for harmonic ``k + 2``. ``clear`` (float32) receives the union of the
    plaques' clearing (0..1): a fuzzy edge centred on the outline, frayed by ``fuzz_tile`` noise, and a slightly
    less cleared centre. ``ids`` (uint16) receives ``p + 1`` where the pixel centre lies inside plaque ``p``'s
    outline and inside the visible interior of its well.
    """
    n_harmonics = fourier.shape[1]
    for p in range(params.shape[0]):
        cx, cy, radius, edge, clearness = params[p, 0], params[p, 1], params[p, 2], params[p, 3], params[p, 4]
        well_cx, well_cy, well_radius = params[p, 6], params[p, 7], params[p, 8]
        top_cx, top_cy = params[p, 9], params[p, 10]
        amplitude = 0.0
        for k in range(n_harmonics):
            amplitude += abs(fourier[p, k, 0]) + abs(fourier[p, k, 1])
        width = max(edge, pixel_mm)
        reach = radius * (1.0 + amplitude) + EDGE_SPAN * width
        noise_dx = FRAY_ROWS_PER_PLAQUE * p
        y0, y1, x0, x1 = boxes[p, 0], boxes[p, 1], boxes[p, 2], boxes[p, 3]
        for y in range(y0, y1):
            for x in range(x0, x1):
                u, v = _to_plate(hinv, x + 0.5, y + 0.5)
                du = u - cx
                dv = v - cy
                dist = math.sqrt(du * du + dv * dv)
                if dist > reach:
                    continue
                outline = 1.0
                if dist > 0.0:
                    cos1 = du / dist
                    sin1 = dv / dist
                    cos_k = cos1 * cos1 - sin1 * sin1  # harmonic 2
                    sin_k = 2.0 * sin1 * cos1
                    for k in range(n_harmonics):
                        outline += fourier[p, k, 0] * cos_k + fourier[p, k, 1] * sin_k
                        cos_k, sin_k = cos_k * cos1 - sin_k * sin1, sin_k * cos1 + cos_k * sin1
                signed = dist - radius * outline
                if signed < 0.0:
                    wu = u - well_cx
                    wv = v - well_cy
                    in_well = wu * wu + wv * wv < well_radius * well_radius
                    if in_well and not from_below:
                        tu = u - top_cx
                        tv = v - top_cy
                        in_well = tu * tu + tv * tv < top_radius * top_radius
                    if in_well:
                        ids[y, x] = p + 1
                # radial fibres: noise that varies quickly around the plaque and slowly along its radius
                around = math.atan2(dv, du) * (fuzz_tile.shape[1] / (2.0 * math.pi))
                fray = _tile(fuzz_tile, around, dist / fuzz_cell_mm + noise_dx)
                t = 0.5 - signed / (EDGE_SPAN * width) + FRAY_AMPLITUDE * fray
                if t <= 0.0:
                    continue
                if t > 1.0:
                    t = 1.0
                inner = dist / (radius * outline)
                c = clearness * t * t * (3.0 - 2.0 * t) * (1.0 - 0.02 * math.exp(-3.0 * inner * inner))
                clear[y, x] = 1.0 - (1.0 - clear[y, x]) * (1.0 - c)


@njit(cache=True, nogil=True)
def draw_capsules(hinv, segments, values, boxes, pixel_mm, out):
    """Max-combine anti-aliased capsules (thick line segments) into ``out``.

    ``segments[s] = (x0, y0, x1, y1, half_width)`` in mm; ``values[s]`` the value at full coverage.
    """
    for s in range(segments.shape[0]):
        ax, ay, bx, by, half = segments[s, 0], segments[s, 1], segments[s, 2], segments[s, 3], segments[s, 4]
        ex = bx - ax
        ey = by - ay
        length2 = ex * ex + ey * ey
        value = values[s]
        y0, y1, x0, x1 = boxes[s, 0], boxes[s, 1], boxes[s, 2], boxes[s, 3]
        for y in range(y0, y1):
            for x in range(x0, x1):
                u, v = _to_plate(hinv, x + 0.5, y + 0.5)
                px = u - ax
                py = v - ay
                t = 0.0
                if length2 > 0.0:
                    t = min(max((px * ex + py * ey) / length2, 0.0), 1.0)
                dx = px - t * ex
                dy = py - t * ey
                thin = min(1.0, 2.0 * half / pixel_mm)  # lines thinner than a pixel fade instead of vanishing
                coverage = 0.5 - (math.sqrt(dx * dx + dy * dy) - max(half, 0.5 * pixel_mm)) / pixel_mm
                if coverage <= 0.0:
                    continue
                coverage = min(coverage, 1.0) * thin * value
                if coverage > out[y, x]:
                    out[y, x] = coverage


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def shade(
    hinv, scalars, desk_rgb, panel, blots, wells, relief_map, ink, texels_per_mm, low_grid, low_cell_mm,
    fibre_grid, fibre_cell_mm, desk_grid, desk_cell_px, fine_tile, fine_cell_mm, residual_tile, residual_cell_mm,
    clear, scratched, specks, absorbance, gains, gamma_lut, out, wells_mask,
):
    """Shade every pixel (linear light, then display-encoded through ``gamma_lut``) and fill the well mask.

    ``scalars`` holds, in order: pixel_mm, mirror, plate length, plate width, corner radius, chamfer, skirt,
    a1_x, a1_y, pitch, rows, cols, well radius, wall, top radius, from_below, transmittance, rim darkness,
    rim clearing, unevenness, elongation, translucency, desk?, brightness, texture, frame_mm, ruler?,
    vignetting, glare strength, glare x, glare y, glare radius, sheen, tint r, tint g, tint b, label strength.
    ``relief_map`` (h, w) and ``ink`` (h, w, 3), or (1, 1, 3) for no ink, are plate-space textures.
    """
    height, width = out.shape[0], out.shape[1]
    pixel_mm, mirror, length, plate_w, corner, chamfer, skirt = (
        scalars[0], scalars[1], scalars[2], scalars[3], scalars[4], scalars[5], scalars[6])
    a1x, a1y, pitch, rows, cols, radius, wall, top_radius = (
        scalars[7], scalars[8], scalars[9], int(scalars[10]), int(scalars[11]), scalars[12], scalars[13], scalars[14])
    from_below, transmittance, rim_dark, rim_clearing, unevenness, elongation, translucency = (
        scalars[15] > 0.5, scalars[16], scalars[17], scalars[18], scalars[19], scalars[20], scalars[21])
    is_desk, brightness, desk_texture, frame_mm, ruler = (
        scalars[22] > 0.5, scalars[23], scalars[24], scalars[25], scalars[26] > 0.5)
    vignetting, glare, glare_x, glare_y, glare_r, sheen = (
        scalars[27], scalars[28], scalars[29], scalars[30], scalars[31], scalars[32])
    tint_r, tint_g, tint_b, label_strength = scalars[33], scalars[34], scalars[35], scalars[36]
    has_ink = ink.shape[0] > 1
    half_l = 0.5 * length
    half_w = 0.5 * plate_w
    spread = 0.55 * radius
    sqrt_el = math.sqrt(elongation)
    line_half = 0.09
    aspect = width / height
    corner_r2 = 0.25 * (aspect * aspect + 1.0)
    glare_r2 = (glare_r * math.sqrt(aspect * aspect + 1.0)) ** 2
    n_lut = gamma_lut.shape[0] - 1
    left, top, right, bottom = panel[0], panel[1], panel[2], panel[3]
    for y in prange(height):
        rgb = np.empty(3, dtype=np.float64)
        for x in range(width):
            u, v = _to_plate(hinv, x + 0.5, y + 0.5)
            # ---- what lies behind the plate
            if is_desk:
                tex = 1.0 + desk_texture * _grid(desk_grid, (x + 0.5) / desk_cell_px, (y + 0.5) / desk_cell_px)
                for c in range(3):
                    rgb[c] = desk_rgb[c] * tex * brightness
            else:
                bx = mirror * (u - half_l)
                by = v - half_w
                to_edge = min(min(bx - left, right - bx), min(by - top, bottom - by))
                lit = _clip01(to_edge / pixel_mm + 0.5)
                glow = brightness
                if to_edge < 40.0:
                    glow *= 1.0 - 0.06 * math.exp(-max(to_edge, 0.0) / 6.0)
                if lit < 1.0:
                    frame = _clip01((to_edge + frame_mm) / pixel_mm + 0.5) - lit
                    tex = 1.0 + desk_texture * _grid(desk_grid, (x + 0.5) / desk_cell_px, (y + 0.5) / desk_cell_px)
                    for c in range(3):
                        rgb[c] = desk_rgb[c] * tex * (1.0 - lit - frame) + lit * glow + frame * 0.55
                else:
                    for c in range(3):
                        rgb[c] = glow
                if ruler:
                    rw = 22.0
                    along = -1.0
                    across = 0.0
                    if bx < left and bx > left - rw and by > top and by < bottom + rw:
                        along = abs(by - bottom)
                        across = left - bx
                    elif by > bottom and by < bottom + rw and bx > left - rw and bx < right:
                        along = abs(bx - left)
                        across = by - bottom
                    if along >= 0.0:
                        nearest = math.floor(along + 0.5)
                        tick = 7.0 if nearest % 10 == 0 else (5.0 if nearest % 5 == 0 else 3.0)
                        mark = 0.6 if abs(along - nearest) < 0.12 and across < tick else 0.0
                        for c in range(3):
                            rgb[c] = 0.02 + mark
            # ---- the plate
            qx = abs(u - half_l) - (half_l - corner)
            qy = abs(v - half_w) - (half_w - corner)
            signed = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2) + min(max(qx, qy), 0.0) - corner
            signed = max(signed, (chamfer - u - v) * 0.7071067811865476)
            plate_alpha = _clip01(0.5 - signed / pixel_mm)
            if plate_alpha > 0.0:
                col = min(max(math.floor((u - a1x) / pitch + 0.5), 0.0), cols - 1.0)
                row = min(max(math.floor((v - a1y) / pitch + 0.5), 0.0), rows - 1.0)
                k = int(row) * cols + int(col)
                du = u - wells[k, W_CX]
                dv = v - wells[k, W_CY]
                dist = math.sqrt(du * du + dv * dv)
                tu = u - wells[k, W_TOP_CX]
                tv = v - wells[k, W_TOP_CY]
                top_dist = math.sqrt(tu * tu + tv * tv)
                if dist < radius and (from_below or top_dist < top_radius):
                    wells_mask[y, x] = np.uint8(wells[k, W_ID])
                # plastic: outlines of the wall's bottom and (with parallax) top edges, embossing, skirt
                disc = _clip01((radius - dist) / pixel_mm + 0.5)
                behind_layer = 1.0 - disc if from_below else 1.0
                outlines = (
                    0.5 * _ring(dist, radius, line_half, pixel_mm)
                    + _ring(dist, radius + wall, line_half, pixel_mm)
                    + behind_layer * (0.35 * _ring(top_dist, top_radius, line_half, pixel_mm)
                                      + 0.5 * _ring(top_dist, top_radius + wall, line_half, pixel_mm))
                )
                band = 1.0 if radius < dist < radius + wall else 0.0
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
                    if has_ink:
                        ink_r = w00 * ink[i, j, 0] + w01 * ink[i, j + 1, 0] + w10 * ink[i + 1, j, 0] + w11 * ink[i + 1, j + 1, 0]
                        ink_g = w00 * ink[i, j, 1] + w01 * ink[i, j + 1, 1] + w10 * ink[i + 1, j, 1] + w11 * ink[i + 1, j + 1, 1]
                        ink_b = w00 * ink[i, j, 2] + w01 * ink[i, j + 1, 2] + w10 * ink[i + 1, j, 2] + w11 * ink[i + 1, j + 1, 2]
                skirt_shade = 1.0 - 0.25 * _clip01((signed + skirt) / skirt)
                # the thick plastic between the wells passes less light than a well's thin bottom
                plastic = (transmittance * (1.0 - disc) + FLOOR_TRANSMITTANCE * disc) * (1.0 + WALL_BAND_GAIN * band - rim_dark * min(outlines, 1.0))
                plastic *= (1.0 - relief) * skirt_shade
                # blots: soft smudges on the plate
                blot_r = 1.0
                blot_g = 1.0
                blot_b = 1.0
                for b in range(blots.shape[0]):
                    bu = u - blots[b, 0]
                    bv = v - blots[b, 1]
                    d2 = (bu * bu + bv * bv) / (blots[b, 2] * blots[b, 2])
                    if d2 < 4.0:
                        a = blots[b, 6] * math.exp(-d2 * (1.0 + 0.3 * _grid(low_grid, u / low_cell_mm, v / low_cell_mm)))
                        blot_r *= 1.0 - a * (1.0 - blots[b, 3])
                        blot_g *= 1.0 - a * (1.0 - blots[b, 4])
                        blot_b *= 1.0 - a * (1.0 - blots[b, 5])
                # the stained monolayer, Beer-Lambert through its local density
                layer_r = 1.0
                layer_g = 1.0
                layer_b = 1.0
                if disc > 0.0 and wells[k, W_EMPTIED] < 0.5:
                    density = wells[k, W_DENSITY] * (1.0 + unevenness * _grid(low_grid, u / low_cell_mm, v / low_cell_mm))
                    cu = du - wells[k, W_OFF_X]
                    cv = dv - wells[k, W_OFF_Y]
                    along = (cu * wells[k, W_COS] + cv * wells[k, W_SIN]) / (spread * sqrt_el)
                    across = (-cu * wells[k, W_SIN] + cv * wells[k, W_COS]) * sqrt_el / spread
                    gradient = math.exp(-(along * along + across * across))
                    density *= 1.0 + wells[k, W_GRADIENT] * gradient
                    if rim_clearing > 0.0 and radius - dist < 8.0 * rim_clearing:
                        density *= 1.0 - 0.5 * math.exp(-max(radius - dist, 0.0) / rim_clearing)
                    fine = _tile(fine_tile, (u + wells[k, W_NOISE_X]) / fine_cell_mm, (v + wells[k, W_NOISE_Y]) / fine_cell_mm)
                    density *= max(1.0 + 2.0 * wells[k, W_DRYING] * fine, 0.0)
                    if wells[k, W_LYSED] > 0.5:
                        # what is left of a lysed layer: a cloud around the centre and a network of strands
                        fibre = _grid(fibre_grid, u / fibre_cell_mm, v / fibre_cell_mm)
                        strands = (1.0 - min(abs(fibre), 1.0)) ** 2 * (0.6 + 0.4 * fine)
                        cloud = 0.55 * gradient + 0.25 * _grid(low_grid, u / low_cell_mm + 17.0, v / low_cell_mm)
                        remnant = _clip01(0.04 + cloud * (0.4 + 0.6 * strands) + 0.15 * strands)
                        density *= 0.6 * remnant * (1.0 - 0.7 * math.exp(-max(radius - dist, 0.0) / 1.5))
                    c_plaque = clear[y, x]
                    if c_plaque > 0.0:
                        residual = _tile(residual_tile, (u + wells[k, W_NOISE_Y]) / residual_cell_mm, (v + wells[k, W_NOISE_X]) / residual_cell_mm)
                        residual = min(max(RESIDUAL_MEAN + RESIDUAL_SPREAD * residual, 0.0), RESIDUAL_MAX)
                        density *= 1.0 - c_plaque * (1.0 - residual)
                    density = density * (1.0 - scratched[y, x]) + specks[y, x]
                    layer_r = translucency + (1.0 - translucency) * math.exp(-density * absorbance[0])
                    layer_g = translucency + (1.0 - translucency) * math.exp(-density * absorbance[1])
                    layer_b = translucency + (1.0 - translucency) * math.exp(-density * absorbance[2])
                    layer_r = layer_r * disc + 1.0 - disc
                    layer_g = layer_g * disc + 1.0 - disc
                    layer_b = layer_b * disc + 1.0 - disc
                if is_desk:
                    behind_r = 0.3 * rgb[0] + 0.55 * brightness
                    behind_g = 0.3 * rgb[1] + 0.55 * brightness
                    behind_b = 0.3 * rgb[2] + 0.55 * brightness
                else:
                    behind_r = rgb[0]
                    behind_g = rgb[1]
                    behind_b = rgb[2]
                on_r = (behind_r * plastic + sheen) * tint_r * ink_r * blot_r * layer_r
                on_g = (behind_g * plastic + sheen) * tint_g * ink_g * blot_g * layer_g
                on_b = (behind_b * plastic + sheen) * tint_b * ink_b * blot_b * layer_b
                rgb[0] = on_r * plate_alpha + rgb[0] * (1.0 - plate_alpha)
                rgb[1] = on_g * plate_alpha + rgb[1] * (1.0 - plate_alpha)
                rgb[2] = on_b * plate_alpha + rgb[2] * (1.0 - plate_alpha)
            # ---- lighting and exposure
            fx = ((x + 0.5) / width - 0.5) * aspect
            fy = (y + 0.5) / height - 0.5
            vignette = 1.0 - vignetting * (fx * fx + fy * fy) / corner_r2
            flare = 0.0
            if glare > 0.0:
                gx = fx - (glare_x - 0.5) * aspect
                gy = fy - (glare_y - 0.5)
                flare = glare * math.exp(-(gx * gx + gy * gy) / glare_r2)
            for c in range(3):
                value = rgb[c] * gains[c] * vignette + flare
                value = min(max(value, 0.0), 1.0)
                out[y, x, c] = gamma_lut[int(math.sqrt(value) * n_lut + 0.5)]


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def blur_separable(image, taps, out):
    """Convolve ``image`` (H, W, C) with the symmetric 1-D kernel ``taps`` (centre first) along both axes,
    repeating the border pixels."""
    height, width, channels = image.shape
    radius = taps.shape[0] - 1
    row_len = width * channels
    tmp = np.empty((height, row_len), dtype=np.float32)
    for y in prange(height):
        line = np.empty(row_len + 2 * radius * channels, dtype=np.float32)
        src = image[y].reshape(row_len)
        line[radius * channels : radius * channels + row_len] = src
        for r in range(radius):
            for c in range(channels):
                line[r * channels + c] = src[c]
                line[radius * channels + row_len + r * channels + c] = src[row_len - channels + c]
        for i in range(row_len):
            centre = i + radius * channels
            acc = taps[0] * line[centre]
            for r in range(1, radius + 1):
                acc += taps[r] * (line[centre - r * channels] + line[centre + r * channels])
            tmp[y, i] = acc
    for y in prange(height):
        dst = out[y].reshape(row_len)
        for i in range(row_len):
            dst[i] = taps[0] * tmp[y, i]
        for r in range(1, radius + 1):
            above = tmp[max(y - r, 0)]
            below = tmp[min(y + r, height - 1)]
            weight = taps[r]
            for i in range(row_len):
                dst[i] += weight * (above[i] + below[i])


@njit(cache=True, nogil=True, inline="always")
def _hash64(x):
    """SplitMix64 finaliser: a well-mixed 64-bit hash of ``x``."""
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def add_sensor_noise(image, sd, seed):
    """Add signal-dependent, approximately Gaussian noise (sd ``sd`` at mid grey) in place; each pixel's noise
    is a hash of its index and ``seed``, so it is the same on every run and for any thread count."""
    height, width, channels = image.shape
    scale = np.float32(1.0 / 65535.0)
    base = np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15)
    for y in prange(height):
        for x in range(width):
            index = np.uint64(y * width + x) * np.uint64(4)
            common_bits = _hash64(base + index)
            # a sum of four 16-bit uniforms is close to Gaussian (Irwin-Hall): mean 2, variance 1/3
            common = (
                np.float32(common_bits & np.uint64(0xFFFF)) + np.float32((common_bits >> np.uint64(16)) & np.uint64(0xFFFF))
                + np.float32((common_bits >> np.uint64(32)) & np.uint64(0xFFFF)) + np.float32(common_bits >> np.uint64(48))
            ) * scale - np.float32(2.0)
            for c in range(channels):
                bits = _hash64(base + index + np.uint64(c + 1))
                own = (
                    np.float32(bits & np.uint64(0xFFFF)) + np.float32((bits >> np.uint64(16)) & np.uint64(0xFFFF))
                    + np.float32((bits >> np.uint64(32)) & np.uint64(0xFFFF)) + np.float32(bits >> np.uint64(48))
                ) * scale - np.float32(2.0)
                value = image[y, x, c]
                level = math.sqrt(min(max(value, np.float32(0.02)), np.float32(1.0)) / np.float32(0.5))
                image[y, x, c] = value + sd * level * np.float32(1.7320508) * (np.float32(0.5) * common + np.float32(0.85) * own)


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def scale_channels(image, scales, out):
    """Resample each channel scaled by ``scales[c]`` about the image centre (bilinear, clamped at borders)."""
    height, width, channels = image.shape
    cx = width / 2.0
    cy = height / 2.0
    for y in prange(height):
        for x in range(width):
            for c in range(channels):
                s = scales[c]
                if s == 1.0:
                    out[y, x, c] = image[y, x, c]
                    continue
                sx = min(max((x + 0.5 - cx) / s + cx - 0.5, 0.0), width - 1.001)
                sy = min(max((y + 0.5 - cy) / s + cy - 0.5, 0.0), height - 1.001)
                j = int(sx)
                i = int(sy)
                fx = sx - j
                fy = sy - i
                top = image[i, j, c] * (1.0 - fx) + image[i, j + 1, c] * fx
                bottom = image[i + 1, j, c] * (1.0 - fx) + image[i + 1, j + 1, c] * fx
                out[y, x, c] = top * (1.0 - fy) + bottom * fy


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def line_blur(image, dx, dy, samples, out):
    """Average ``samples`` bilinear samples along the segment from ``-(dx, dy)/2`` to ``+(dx, dy)/2`` (pixels)."""
    height, width, channels = image.shape
    for y in prange(height):
        for x in range(width):
            for c in range(channels):
                out[y, x, c] = 0.0
            for k in range(samples):
                t = (k / (samples - 1) - 0.5) if samples > 1 else 0.0
                sx = min(max(x + t * dx, 0.0), width - 1.001)
                sy = min(max(y + t * dy, 0.0), height - 1.001)
                j = int(sx)
                i = int(sy)
                fx = sx - j
                fy = sy - i
                for c in range(channels):
                    top = image[i, j, c] * (1.0 - fx) + image[i, j + 1, c] * fx
                    bottom = image[i + 1, j, c] * (1.0 - fx) + image[i + 1, j + 1, c] * fx
                    out[y, x, c] += (top * (1.0 - fy) + bottom * fy) / samples


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def downsample_mean(image, factor):
    """Mean over ``factor`` x ``factor`` blocks (the last partial blocks average what they hold)."""
    height, width, channels = image.shape
    small_h = (height + factor - 1) // factor
    small_w = (width + factor - 1) // factor
    small = np.zeros((small_h, small_w, channels), dtype=np.float32)
    for i in prange(small_h):
        for y in range(i * factor, min((i + 1) * factor, height)):
            for x in range(width):
                for c in range(channels):
                    small[i, x // factor, c] += image[y, x, c]
        for j in range(small_w):
            count = (min((i + 1) * factor, height) - i * factor) * (min((j + 1) * factor, width) - j * factor)
            for c in range(channels):
                small[i, j, c] /= count
    return small


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def upsample_bilinear(small, factor, out):
    """Bilinear upsampling of block means made by :func:`downsample_mean` back to ``out``'s size."""
    height, width, channels = out.shape
    small_h, small_w = small.shape[0], small.shape[1]
    for y in prange(height):
        sy = min(max((y + 0.5) / factor - 0.5, 0.0), small_h - 1.0)
        i = min(int(sy), small_h - 2) if small_h > 1 else 0
        fy = sy - i if small_h > 1 else 0.0
        i1 = i + 1 if small_h > 1 else 0
        for x in range(width):
            sx = min(max((x + 0.5) / factor - 0.5, 0.0), small_w - 1.0)
            j = min(int(sx), small_w - 2) if small_w > 1 else 0
            fx = sx - j if small_w > 1 else 0.0
            j1 = j + 1 if small_w > 1 else 0
            for c in range(channels):
                top = small[i, j, c] * (1.0 - fx) + small[i, j1, c] * fx
                bottom = small[i1, j, c] * (1.0 - fx) + small[i1, j1, c] * fx
                out[y, x, c] = top * (1.0 - fy) + bottom * fy


@njit(cache=True, nogil=True)
def renumber(ids):
    """Renumber the non-zero ids present in ``ids`` to 1..m in increasing order (in place)."""
    top = 0
    for value in ids.ravel():
        if value > top:
            top = value
    lookup = np.zeros(top + 1, dtype=ids.dtype)
    flat = ids.ravel()
    for value in flat:
        lookup[value] = 1
    lookup[0] = 0
    next_id = 0
    for value in range(1, top + 1):
        if lookup[value]:
            next_id += 1
            lookup[value] = next_id
    for i in range(flat.shape[0]):
        flat[i] = lookup[flat[i]]


def boxes_from_extents(corners_px: np.ndarray, height: int, width: int) -> np.ndarray:
    """Pixel boxes ``(y0, y1, x0, x1)`` (clipped, int64) from the projected corners ``(n, 4, 2)`` of each object."""
    lo = np.floor(corners_px.min(axis=1)) - 1
    hi = np.ceil(corners_px.max(axis=1)) + 2
    boxes = np.stack([lo[:, 1], hi[:, 1], lo[:, 0], hi[:, 0]], axis=1)
    boxes[:, :2] = np.clip(boxes[:, :2], 0, height)
    boxes[:, 2:] = np.clip(boxes[:, 2:], 0, width)
    return boxes.astype(np.int64)
