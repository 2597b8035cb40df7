"""The fixed coefficients of the plate, the light box, the desk and the post-processing, named once.

Both renderers read these: the raster renderer's numba kernels (:mod:`platesynth.render.shading`,
:mod:`platesynth.render.postprocess`) and the Blender side's node trees (:mod:`platesynth.render.blender.inside`).
This module is plain Python importing only :mod:`math`, so the Blender side can import it without numba or the raster
renderer. The look of a well's content (stain, plaques, lysis) is not here: :mod:`platesynth.render.appearance`
computes it once, and Blender receives it as textures. Scene parameters that vary between images are in the
parameter catalogue (:mod:`platesynth.scene`), not here.
"""

import math

# ---- the plate's plastic
FLOOR_TRANSMITTANCE = 0.96
"""Share of the light a well's thin bottom passes (the thick plastic between the wells passes ``plate_look.transmittance``)."""
OUTLINE_WIDTH_MM = 0.18
"""Width of the thin dark outlines of the walls' foot and top edges."""
TOP_EDGE_OFFSET_MM = 0.3
"""The wall's top edge lies this much further out than its foot (the well widens towards the top)."""
CRESCENT_LIGHT = 0.6
"""The light that reaches a floor past the walls' top edge through the wall (``plate_look.crescent_veil``), relative
to the light through the open top: on IBV's wells the crescent's red and green rise while its blue falls a little, a
mix of about 0.1 toward 0.5-0.6 of the unstained light (two wells of IBV_plate1 fitted, in linear light)."""
OUTLINE_WEIGHTS = (0.5, 1.0, 0.35, 0.5)
"""Darkness of the outlines (times ``plate_look.rim_darkness``): foot inner, foot outer, top inner, top outer."""
WALL_LINE_PLACES = (0.12, 0.3, 0.55)
"""Where the thin lines refracted by a wall (``plate_look.wall_lines``) lie across its band, as shares of its width
from the floor's edge..."""
WALL_HIGHLIGHT_PLACES = tuple(0.5 * (place + after) for place, after in zip(WALL_LINE_PLACES, WALL_LINE_PLACES[1:] + (1.0,)))
"""...and its highlights (``plate_look.wall_highlights``): halfway between each line and the next (or the band's
outer edge)."""
WALL_LINE_WOBBLE_MM = 0.12
"""How far each refracted line wanders in and out around the well (two waves around it, a phase per well and line)."""
SKIRT_DARKENING = 0.25
"""The skirt along the plate's outline passes this much less light at the outline itself."""
RELIEF_RAISED, RELIEF_EMBOSS = 0.35, 0.65
"""The embossed labels and ribs: darkening of a raised line, and of its shadowed edge (before ``label_strength``)."""
BLOT_REACH = 2.0
"""A blot's smudge ends at this many radii."""
BLOT_DISTORTION = 0.3
"""How much the stain's unevenness grid distorts a blot's Gaussian falloff."""

# ---- the light box and what lies around it
GLOW_DIP = 0.06
"""The light box's panel is this much dimmer at its edge than in its middle..."""
GLOW_FALLOFF_MM = 6.0
"""...falling off exponentially over this distance from the edge."""
GLOW_REACH_MM = 40.0
"""Beyond this distance from the panel's edge the falloff is not computed (it is below 0.06 * exp(-40 / 6))."""
FRAME_BRIGHTNESS = 0.55
"""The light box's frame, around the panel (linear light)."""
RULER_WIDTH_MM = 22.0
"""The ruler along the panel's left and bottom edges."""
RULER_TICKS_MM = (3.0, 5.0, 7.0)
"""Tick lengths: every mm, every 5 mm, every 10 mm."""
RULER_TICK_HALF_WIDTH_MM = 0.12
RULER_DARK, RULER_TICK = 0.02, 0.6
"""The ruler's body and the extra brightness of its ticks (linear light)."""

# ---- the desk
DESK_CELL_MM = 8.0
"""Blotches of the desk's texture."""
DESK_SHEEN = 0.12
"""Light reflected by the plate's top on a desk (times the background's brightness)."""
DESK_THROUGH, DESK_AMBIENT = 0.3, 0.55
"""On a desk the plate is lit from above: the desk seen through it (share) plus ambient light (times brightness)."""

# ---- post-processing
BLOOM_THRESHOLD = 0.75
"""Levels above this glow (bloom); the excess is scaled to [0, 1] by ``1 / (1 - threshold)``."""
BLOOM_RADIUS = 0.015
"""The bloom's Gaussian sigma as a share of the image width."""
CLARITY_RADIUS = 0.02
"""The local-contrast (clarity) base blur as a share of the image width."""
NOISE_SHARED, NOISE_OWN = 0.5, 0.85
"""Sensor noise: weights of the part shared by the three channels and of each channel's own part."""
NOISE_FLOOR, NOISE_MID_GREY = 0.02, 0.5
"""Sensor noise grows as the square root of the level (floored) relative to mid grey."""
LUMINANCE = (0.2126, 0.7152, 0.0722)
"""Rec. 709 luminance weights."""


def noise_grain_gain(sigma_px: float) -> float:
    """The factor that gives white noise blurred by a Gaussian of ``sigma_px`` (sampled out to 3 sigma, as the
    post-processing samples it) its standard deviation back: ``1 / sum(w**2)`` over the normalised 1-D weights ``w``
    (in 2-D the sd falls by that sum)."""
    radius = max(1, math.ceil(3.0 * sigma_px))
    weights = [math.exp(-0.5 * (i / sigma_px) ** 2) for i in range(-radius, radius + 1)]
    total = sum(weights)
    return 1.0 / sum((w / total) ** 2 for w in weights)


def wall_line_phase(noise_x: float, noise_y: float, line: int) -> float:
    """The phase (radians) of refracted line ``line``'s wobble in the well whose noise shifts are ``(noise_x,
    noise_y)`` mm: an arithmetic hash, the same in both renderers."""
    return 2.0 * math.pi * ((noise_x * 0.1373 * (line + 1) + noise_y * 0.0711 + 0.29 * line) % 1.0)
