"""Materials: the well floors, the plate's plastic, the light box, the desk, ink and blots, and the mask pass.

The well floors show the appearance model's texture (``textures.floor`` of the description, computed on the host
by :mod:`platesynth.render.appearance`, the model the raster renderer draws too): the monolayer's linear RGB
transmittance with its plaques, lysis, drying texture and marks, looked up at the shading point's plate position.
So the well content is defined once; Cycles adds what it is there for: light through the plastic and the stain,
the camera and the optics. The plastic multiplies by its tint and transmittance; the plate's fixed coefficients
come from :mod:`platesynth.render.look`. Per-element values come from point attributes; plate-wide values are
named Value/RGB nodes. The mask pass overrides every material with :func:`mask_material`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import bpy

from platesynth.render.blender.inside.nodes import add, feed, link, math, output, vector_math
from platesynth.render.look import (
    BLOT_DISTORTION,
    CRESCENT_LIGHT,
    GLOW_DIP,
    GLOW_FALLOFF_MM,
    RULER_DARK,
    RULER_TICK,
    RULER_TICK_HALF_WIDTH_MM,
    RULER_TICKS_MM,
    SKIRT_DARKENING,
)

MASK_AOVS = ("well_id", "plaque_id")
"""Shader AOVs of the mask pass: each holds the integer id of the well / plaque seen in the pixel (0: none)."""

_NOISE_SD = 0.123
"""Standard deviation of Blender's 3-D Noise Texture factor (detail 0, mean 0.5), measured on a large plane."""


def _new_material(name: str) -> tuple[bpy.types.Material, bpy.types.NodeTree, bpy.types.Node]:
    material = bpy.data.materials.new(name)
    tree = material.node_tree
    tree.nodes.clear()
    return material, tree, add(tree, "ShaderNodeOutputMaterial")


class PlateTexture:
    """A plate-space texture as a Blender image (the array's row 0, plate y = 0, at the image's top) and its
    resolution in texels per mm."""

    def __init__(self, image: bpy.types.Image, texels_per_mm: float) -> None:
        self.image = image
        self.texels_per_mm = texels_per_mm


def _lookup(tree: bpy.types.NodeTree, image: bpy.types.Image, column: Any, row: Any, periodic: bool) -> bpy.types.NodeSocket:
    """Bilinear value of a noise array at a fractional ``column`` and ``row``, as the raster renderer samples it:
    periodic tiles wrap, grids are clamped at their border."""
    width, height = image.size
    uv = feed(
        tree,
        add(tree, "ShaderNodeCombineXYZ"),
        X=math(tree, "MULTIPLY_ADD", column, 1.0 / width, 0.5 / width),
        Y=math(tree, "MULTIPLY_ADD", row, 1.0 / height, 0.5 / height),
    )
    texture = add(tree, "ShaderNodeTexImage", interpolation="Linear", extension="REPEAT" if periodic else "EXTEND")
    texture.image = image
    link(tree, uv, texture)
    return output(feed(tree, add(tree, "ShaderNodeSeparateColor"), Color=output(texture, "Color")), "Red")


def _plate_position(tree: bpy.types.NodeTree) -> tuple[bpy.types.NodeSocket, bpy.types.NodeSocket]:
    """The shading point's plate coordinates ``(u, v)`` in mm (x right, y down; the world's y is up)."""
    parts = feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=output(add(tree, "ShaderNodeTexCoord"), "Object"))
    return output(parts, "X"), math(tree, "MULTIPLY", output(parts, "Y"), -1.0)


def _in_cells(tree: bpy.types.NodeTree, position_mm: Any, shift_mm: Any, cell_mm: Any) -> bpy.types.NodeSocket:
    """``(position + shift) / cell``: a plate coordinate in a texture's cells (no node for a zero shift)."""
    shifted = position_mm if isinstance(shift_mm, float) and shift_mm == 0.0 else math(tree, "ADD", position_mm, shift_mm)
    return math(tree, "DIVIDE", shifted, cell_mm)


def _attribute(tree: bpy.types.NodeTree, name: str, socket: str = "Fac") -> bpy.types.NodeSocket:
    node = add(tree, "ShaderNodeAttribute", attribute_type="GEOMETRY", attribute_name=name)
    return node.outputs[socket]


def _value(tree: bpy.types.NodeTree, name: str, value: float) -> bpy.types.NodeSocket:
    """A named Value node: a plate-wide parameter a person or another tool can change in the .blend."""
    node = add(tree, "ShaderNodeValue", name=name)
    node.outputs[0].default_value = value
    return node.outputs[0]


def _rgb(tree: bpy.types.NodeTree, name: str, rgb: tuple[float, float, float]) -> bpy.types.NodeSocket:
    node = add(tree, "ShaderNodeRGB", name=name)
    node.outputs[0].default_value = (*rgb, 1.0)
    return node.outputs[0]


def _seeded(tree: bpy.types.NodeTree, vector: Any, seed: Any) -> bpy.types.NodeSocket:
    """``vector`` moved far away by ``seed``: a different pattern of the same texture per seed."""
    shift = feed(tree, add(tree, "ShaderNodeCombineXYZ"), X=math(tree, "MULTIPLY", seed, 7.31), Y=math(tree, "MULTIPLY", seed, 3.17))
    return output(vector_math(tree, "ADD", vector, shift), "Vector")


def _unit_noise(tree: bpy.types.NodeTree, vector: Any, cell_mm: Any, seed: Any) -> bpy.types.NodeSocket:
    """Smooth noise with mean 0 and standard deviation 1, blotches about ``cell_mm`` across (like the raster
    renderer's), a different pattern for each ``seed``."""
    node = add(tree, "ShaderNodeTexNoise", noise_dimensions="3D")
    scale = 1.0 / max(cell_mm, 1e-3) if isinstance(cell_mm, float) else math(tree, "DIVIDE", 1.0, math(tree, "MAXIMUM", cell_mm, 1e-3))
    feed(tree, node, Vector=_seeded(tree, vector, seed), Scale=scale, Detail=0.0)
    return output(math(tree, "DIVIDE", math(tree, "SUBTRACT", output(node, "Factor"), 0.5), _NOISE_SD), "Value")


def _plate_texture(tree: bpy.types.NodeTree, texture: PlateTexture) -> bpy.types.NodeSocket:
    """The colour of a plate-space texture at the surface's world position ``(x, -y)`` (bilinear)."""
    position = output(add(tree, "ShaderNodeTexCoord"), "Object")
    k = texture.texels_per_mm
    height_mm, width_mm = texture.image.size[1] / k, texture.image.size[0] / k
    uv = add(tree, "ShaderNodeMapping", vector_type="POINT")
    feed(tree, uv, Vector=position, Location=(0.0, 1.0, 0.0), Scale=(1.0 / width_mm, 1.0 / height_mm, 0.0))
    node = add(tree, "ShaderNodeTexImage", interpolation="Linear", extension="EXTEND")
    node.image = texture.image
    link(tree, uv, node)
    return output(node, "Color")


def floor_material(
    floor: PlateTexture, tint_rgb: tuple[float, float, float], transmittance: float, crescent: Mapping[str, float]
) -> bpy.types.Material:
    """The well floors: the appearance model's transmittance texture, times the plate's plastic under it.

    Where the ray, beyond the floor, meets the plane of the walls' top edge (``crescent["height"]``) more than
    ``crescent["radius"]`` from its well's centre (the ``well_center`` attribute), it came through the wall: the
    texture moves toward ``CRESCENT_LIGHT`` by ``crescent["veil"]`` there (the raster renderer's ``past_top_edge``), the edge
    smeared over ``crescent["smear"]`` mm."""
    material, tree, out = _new_material("platesynth.monolayer")
    film = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY", clamp_result=False)
    layer = _plate_texture(tree, floor)
    if crescent["veil"] > 0.0:
        veiled = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="MIX", clamp_result=False)
        feed(tree, veiled, Factor=_past_top_edge(tree, crescent), A=layer, B=(CRESCENT_LIGHT, CRESCENT_LIGHT, CRESCENT_LIGHT, 1.0))
        layer = output(veiled, "Result")
    feed(tree, film, Factor=1.0, A=layer, B=_plastic_colour(tree, tint_rgb, transmittance))
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=output(film, "Result")), out)
    return material


def _past_top_edge(tree: bpy.types.NodeTree, crescent: Mapping[str, float]) -> bpy.types.NodeSocket:
    """``veil * clip((d - radius) / smear + 0.5)``: ``d`` the distance from the well's centre at which the ray
    through the shading point meets the plane ``z = height``."""
    crossing = _ray_at_height(tree, _value(tree, "Top Edge Height", crescent["height"]))
    across = vector_math(tree, "MULTIPLY", vector_math(tree, "SUBTRACT", crossing, _attribute(tree, "well_center", "Vector")), (1.0, 1.0, 0.0))
    outside = math(tree, "SUBTRACT", output(vector_math(tree, "LENGTH", across), "Value"), _value(tree, "Top Edge Radius", crescent["radius"]))
    past = math(tree, "ADD", math(tree, "DIVIDE", outside, _value(tree, "Top Edge Smear", max(crescent["smear"], 1e-3))), 0.5)
    past.use_clamp = True
    return math(tree, "MULTIPLY", past, _value(tree, "Crescent Veil", crescent["veil"]))


def _ray_at_height(tree: bpy.types.NodeTree, height: Any) -> bpy.types.NodeSocket:
    """The point where the camera's ray through the shading point (along ``Incoming``) meets the plane
    ``z = height``."""
    geometry = add(tree, "ShaderNodeNewGeometry")
    position, incoming = output(geometry, "Position"), output(geometry, "Incoming")
    height_of = [output(feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=v), "Z") for v in (position, incoming)]
    along = math(tree, "DIVIDE", math(tree, "SUBTRACT", height_of[0], height), height_of[1])
    back = feed(tree, add(tree, "ShaderNodeVectorMath", operation="SCALE"), Vector=incoming, Scale=along)
    return output(vector_math(tree, "SUBTRACT", position, output(back, "Vector")), "Vector")


def _plastic_colour(tree: bpy.types.NodeTree, tint_rgb: tuple[float, float, float], transmittance: float) -> bpy.types.NodeSocket:
    colour = add(tree, "ShaderNodeVectorMath", operation="SCALE")
    feed(tree, colour, Vector=_rgb(tree, "Plastic Tint", tint_rgb), Scale=_value(tree, "Plastic Transmittance", transmittance))
    return output(colour, "Vector")


def _relief_factor(tree: bpy.types.NodeTree, relief: PlateTexture, strength: float) -> bpy.types.NodeSocket:
    """``1 - strength * relief`` with the plate-space relief (embossed labels, label rings and ribs)."""
    darkening = math(tree, "MULTIPLY", _plate_texture(tree, relief), _value(tree, "Label Strength", strength))
    return math(tree, "MAXIMUM", math(tree, "SUBTRACT", 1.0, darkening), 0.0)


def _skirt_shade(tree: bpy.types.NodeTree, plate: Mapping[str, float]) -> bpy.types.NodeSocket:
    """The raster renderer's skirt shading: ``1 - SKIRT_DARKENING * clip((d + skirt) / skirt)`` with ``d`` the signed
    distance to the plate's outline (a rounded rectangle with the A1 corner chamfered; negative inside)."""
    u, v = _plate_position(tree)
    half_l, half_w, corner = plate["length_mm"] / 2, plate["width_mm"] / 2, plate["corner_radius_mm"]
    qx = math(tree, "SUBTRACT", math(tree, "ABSOLUTE", math(tree, "SUBTRACT", u, half_l)), half_l - corner)
    qy = math(tree, "SUBTRACT", math(tree, "ABSOLUTE", math(tree, "SUBTRACT", v, half_w)), half_w - corner)
    outside = math(tree, "SQRT", math(tree, "ADD", math(tree, "POWER", math(tree, "MAXIMUM", qx, 0.0), 2.0), math(tree, "POWER", math(tree, "MAXIMUM", qy, 0.0), 2.0)))
    signed = math(tree, "SUBTRACT", math(tree, "ADD", outside, math(tree, "MINIMUM", math(tree, "MAXIMUM", qx, qy), 0.0)), corner)
    chamfered = math(tree, "MULTIPLY", math(tree, "SUBTRACT", math(tree, "SUBTRACT", plate["chamfer_mm"], u), v), 0.5**0.5)
    signed = math(tree, "MAXIMUM", signed, chamfered)
    skirt = max(float(plate["skirt_mm"]), 1e-3)
    shade = math(tree, "MULTIPLY_ADD", math(tree, "ADD", signed, skirt), 1.0 / skirt, 0.0)
    shade.use_clamp = True
    return math(tree, "MULTIPLY_ADD", shade, -SKIRT_DARKENING, 1.0)


def plastic_material(
    name: str,
    tint_rgb: tuple[float, float, float],
    transmittance: float,
    rim_darkness: float,
    relief: tuple[PlateTexture, float] | None = None,
    plate: Mapping[str, float] | None = None,
) -> bpy.types.Material:
    """Polystyrene: tinted see-through plastic whose grazing faces (the walls seen edge-on) pass less light;
    ``relief`` = (texture, label strength) adds the embossed labels, label rings and ribs, ``plate``
    (the scene's plate geometry) the skirt's shading along the outline."""
    material, tree, out = _new_material(name)
    facing = feed(tree, add(tree, "ShaderNodeLayerWeight"), Blend=0.5)
    # only faces seen nearly edge-on darken (the walls' outlines), not the whole wall seen at a slant
    outline = math(tree, "MULTIPLY", math(tree, "POWER", output(facing, "Facing"), 12.0), _value(tree, "Rim Darkness", rim_darkness))
    colour = add(tree, "ShaderNodeVectorMath", operation="SCALE")
    passing = math(tree, "SUBTRACT", 1.0, outline)
    passing.use_clamp = True  # Facing leaves [0, 1] on back faces seen at a grazing angle
    if relief is not None:
        passing = math(tree, "MULTIPLY", passing, _relief_factor(tree, *relief))
    if plate is not None:
        passing = math(tree, "MULTIPLY", passing, _skirt_shade(tree, plate))
    feed(tree, colour, Vector=_plastic_colour(tree, tint_rgb, transmittance), Scale=passing)
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=output(colour, "Vector")), out)
    return material


def glow_material(
    name: str,
    rgb: tuple[float, float, float],
    strength: float,
    texture: float = 0.0,
    seed: float = 0.0,
    panel: tuple[float, float, float, float] | None = None,
) -> bpy.types.Material:
    """A self-lit surface: the light box's panel (``strength`` = its brightness), its frame, a desk; with
    low-frequency texture of amplitude ``texture`` (8 mm blotches). ``panel`` = (left, top, right, bottom), mm
    from the plate's centre along the image axes, the frame of the surface's UV map: dims the glow towards the
    panel's edges as the raster renderer does, by ``GLOW_DIP exp(-d / GLOW_FALLOFF_MM)`` at ``d`` from the nearest
    edge."""
    material, tree, out = _new_material(name)
    emit = feed(tree, add(tree, "ShaderNodeEmission"), Color=_rgb(tree, "Colour", rgb))
    strength_socket: Any = _value(tree, "Strength", strength)
    if panel is not None:
        left, top, right, bottom = panel
        uv = feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=output(add(tree, "ShaderNodeTexCoord"), "UV"))
        bx, by = output(uv, "X"), output(uv, "Y")
        to_edge = math(tree, "MINIMUM", math(tree, "SUBTRACT", bx, left), math(tree, "SUBTRACT", right, bx))
        to_edge = math(tree, "MINIMUM", to_edge, math(tree, "MINIMUM", math(tree, "SUBTRACT", by, top), math(tree, "SUBTRACT", bottom, by)))
        falloff = math(tree, "EXPONENT", math(tree, "DIVIDE", math(tree, "MAXIMUM", to_edge, 0.0), -GLOW_FALLOFF_MM))
        strength_socket = math(tree, "MULTIPLY", strength_socket, math(tree, "MULTIPLY_ADD", falloff, -GLOW_DIP, 1.0))
    if texture > 0:
        coordinates = add(tree, "ShaderNodeTexCoord")
        grain = _unit_noise(tree, output(coordinates, "Object"), 8.0, seed)
        gain = math(tree, "MAXIMUM", math(tree, "MULTIPLY_ADD", grain, _value(tree, "Texture", texture), 1.0), 0.0)
        strength_socket = math(tree, "MULTIPLY", gain, strength_socket)
    link(tree, strength_socket, emit.inputs["Strength"])
    link(tree, emit, out)
    material.cycles.emission_sampling = "NONE"  # seen directly only: it lights nothing (no diffuse bounces either)
    return material


def ruler_material() -> bpy.types.Material:
    """A dark ruler with light tick marks every mm (longer every 5 and 10 mm); its UV map holds (along, across)
    in mm from the ruler's inner corner."""
    material, tree, out = _new_material("platesynth.ruler")
    uv = feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=output(add(tree, "ShaderNodeTexCoord"), "UV"))
    along, across = math(tree, "ABSOLUTE", output(uv, "X")), output(uv, "Y")
    nearest = math(tree, "ROUND", along)
    tenth = math(tree, "COMPARE", math(tree, "FLOORED_MODULO", nearest, 10.0), 0.0, 0.01)
    fifth = math(tree, "COMPARE", math(tree, "FLOORED_MODULO", nearest, 5.0), 0.0, 0.01)
    short, middle, long = RULER_TICKS_MM
    length = math(tree, "ADD", short, math(tree, "ADD", math(tree, "MULTIPLY", fifth, middle - short), math(tree, "MULTIPLY", tenth, long - middle)))
    on_tick = math(tree, "LESS_THAN", math(tree, "ABSOLUTE", math(tree, "SUBTRACT", along, nearest)), RULER_TICK_HALF_WIDTH_MM)
    tick = math(tree, "MULTIPLY", on_tick, math(tree, "LESS_THAN", across, length))
    emit = add(tree, "ShaderNodeEmission")
    link(tree, math(tree, "MULTIPLY_ADD", tick, RULER_TICK, RULER_DARK), emit.inputs["Strength"])
    link(tree, emit, out)
    material.cycles.emission_sampling = "NONE"
    return material


def ink_material() -> bpy.types.Material:
    """Marker ink and blots on the plastic: a film multiplying the light by its ``ink`` attribute (linear RGB)."""
    material, tree, out = _new_material("platesynth.ink")
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=_attribute(tree, "ink", "Color")), out)
    return material


def blot_material(unevenness: PlateTexture) -> bpy.types.Material:
    """A smudge on the plastic, as the raster renderer draws it: its opacity falls off as a Gaussian distorted by
    the unevenness grid ``g``, ``opacity * exp(-(d / radius)**2 * (1 + BLOT_DISTORTION g))``, and the light
    passing it is multiplied by ``1 - a * (1 - colour)``."""
    material, tree, out = _new_material("platesynth.blot")
    position = output(add(tree, "ShaderNodeTexCoord"), "Object")
    flat = feed(tree, add(tree, "ShaderNodeVectorMath", operation="MULTIPLY"), Vector=position, Vector_1=(1.0, 1.0, 0.0))
    distance = output(vector_math(tree, "DISTANCE", flat, _attribute(tree, "blot_center", "Vector")), "Value")
    relative = math(tree, "DIVIDE", distance, _attribute(tree, "blot_radius"))
    u, v = _plate_position(tree)
    cell = 1.0 / unevenness.texels_per_mm
    grain = _lookup(tree, unevenness.image, _in_cells(tree, u, 0.0, cell), _in_cells(tree, v, 0.0, cell), periodic=False)
    distortion = math(tree, "MULTIPLY_ADD", grain, BLOT_DISTORTION, 1.0)
    falloff = math(tree, "MULTIPLY", math(tree, "MULTIPLY", math(tree, "POWER", relative, 2.0), distortion), -1.0)
    opacity = math(tree, "MULTIPLY", _attribute(tree, "blot_opacity"), math(tree, "EXPONENT", falloff))
    tinted = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="MIX", clamp_result=False)
    feed(tree, tinted, Factor=opacity, A=(1.0, 1.0, 1.0, 1.0), B=_attribute(tree, "blot_rgb", "Color"))
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=output(tinted, "Result")), out)
    return material


def rim_material(well_radius: float) -> bpy.types.Material:
    """The walls' bands and outlines: ink (the ``ink`` attribute) over the share of the ring that a ring of
    ``ring_half_width`` about ``ring_radius`` (plus its wobble around the well, :func:`_wobble`) smeared over
    ``ring_smear`` covers (as the raster renderer's
    ``smeared_ring``; all of it without a smear), faded towards white by the share ``rim_hidden_inside`` where the ray
    crossed the floors' plane (``z = 0``) within ``well_radius`` of the ring's ``rim_center``. The ink changes around
    the ring by the factor ``1 + sum_k a_k cos(k t) + b_k sin(k t)`` (the raster renderer's ``band_sheen``), ``t``
    the world angle about the centre, ``(a1, a2, a3)`` the ``sheen_cosines`` and ``(b1, b2, b3)`` the
    ``sheen_sines``."""
    material, tree, out = _new_material("platesynth.rims")
    position = output(add(tree, "ShaderNodeNewGeometry"), "Position")
    centre = _attribute(tree, "rim_center", "Vector")
    across = vector_math(tree, "MULTIPLY", vector_math(tree, "SUBTRACT", position, centre), (1.0, 1.0, 0.0))  # in the ring's plane
    harmonics = _harmonics(tree, across)
    radius = math(tree, "ADD", _attribute(tree, "ring_radius"), _wobble(tree, harmonics))
    offset = math(tree, "SUBTRACT", output(vector_math(tree, "LENGTH", across), "Value"), radius)
    sheen = _sheen(tree, harmonics)
    half_width = _attribute(tree, "ring_half_width")
    smear = math(tree, "MAXIMUM", _attribute(tree, "ring_smear"), 1e-3)  # a micrometre: float32 keeps the ratio
    half_smear = math(tree, "MULTIPLY", smear, 0.5)
    overlap = math(tree, "SUBTRACT", math(tree, "MINIMUM", math(tree, "ADD", offset, half_smear), half_width),
                   math(tree, "MAXIMUM", math(tree, "SUBTRACT", offset, half_smear), math(tree, "MULTIPLY", half_width, -1.0)))
    coverage = math(tree, "DIVIDE", math(tree, "MAXIMUM", overlap, 0.0), smear)
    coverage.use_clamp = True
    covered = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="MIX", clamp_result=False)
    sheened = feed(tree, add(tree, "ShaderNodeVectorMath", operation="SCALE"), Vector=_attribute(tree, "ink", "Color"),
                   Scale=math(tree, "ADD", sheen, 1.0))
    feed(tree, covered, Factor=coverage, A=(1.0, 1.0, 1.0, 1.0), B=output(sheened, "Vector"))
    crossing = _ray_at_height(tree, 0.0)  # where the ray crossed the floors' plane
    off_centre = output(vector_math(tree, "DISTANCE", crossing, centre), "Value")
    through_floor = math(tree, "MULTIPLY", math(tree, "LESS_THAN", off_centre, _value(tree, "Well Radius", well_radius)), _attribute(tree, "rim_hidden_inside"))
    ink = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="MIX", clamp_result=False)
    feed(tree, ink, Factor=through_floor, A=output(covered, "Result"), B=(1.0, 1.0, 1.0, 1.0))
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=output(ink, "Result")), out)
    return material


def _harmonics(tree: bpy.types.NodeTree, across: Any) -> tuple[tuple[Any, Any, Any], tuple[Any, Any, Any]]:
    """``(cos t, cos 2t, cos 3t)`` and ``(sin t, sin 2t, sin 3t)``: ``t`` the angle of the in-plane vector
    ``across``."""
    unit = feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=output(vector_math(tree, "NORMALIZE", across), "Vector"))
    c1, s1 = output(unit, "X"), output(unit, "Y")
    c2 = math(tree, "SUBTRACT", math(tree, "MULTIPLY", c1, c1), math(tree, "MULTIPLY", s1, s1))
    s2 = math(tree, "MULTIPLY", math(tree, "MULTIPLY", c1, s1), 2.0)
    c3 = math(tree, "SUBTRACT", math(tree, "MULTIPLY", c1, c2), math(tree, "MULTIPLY", s1, s2))
    s3 = math(tree, "ADD", math(tree, "MULTIPLY", s1, c2), math(tree, "MULTIPLY", c1, s2))
    return (c1, c2, c3), (s1, s2, s3)


def _sheen(tree: bpy.types.NodeTree, harmonics: tuple[tuple[Any, Any, Any], tuple[Any, Any, Any]]) -> bpy.types.NodeSocket:
    """``sum_k a_k cos(k t) + b_k sin(k t)`` for k = 1, 2, 3 (:func:`_harmonics`), ``a`` and ``b`` the
    ``sheen_cosines`` and ``sheen_sines`` attributes."""
    (c1, c2, c3), (s1, s2, s3) = harmonics
    cosines = feed(tree, add(tree, "ShaderNodeCombineXYZ"), X=c1, Y=c2, Z=c3)
    sines = feed(tree, add(tree, "ShaderNodeCombineXYZ"), X=s1, Y=s2, Z=s3)
    along_cosines = output(vector_math(tree, "DOT_PRODUCT", _attribute(tree, "sheen_cosines", "Vector"), cosines), "Value")
    along_sines = output(vector_math(tree, "DOT_PRODUCT", _attribute(tree, "sheen_sines", "Vector"), sines), "Value")
    return math(tree, "ADD", along_cosines, along_sines)


def _wobble(tree: bpy.types.NodeTree, harmonics: tuple[tuple[Any, Any, Any], tuple[Any, Any, Any]]) -> bpy.types.NodeSocket:
    """``x cos 2t + y sin 2t``: how far the ring lies out at angle ``t``, ``(x, y)`` the ``ring_wobble``
    attribute."""
    (_, c2, _), (_, s2, _) = harmonics
    second = feed(tree, add(tree, "ShaderNodeCombineXYZ"), X=c2, Y=s2)
    return output(vector_math(tree, "DOT_PRODUCT", _attribute(tree, "ring_wobble", "Vector"), second), "Value")


def mask_material() -> bpy.types.Material:
    """The mask pass's override material: opaque, writing each surface's rounded ids to the AOVs."""
    material, tree, out = _new_material("platesynth.mask")
    for name in MASK_AOVS:
        aov = add(tree, "ShaderNodeOutputAOV", aov_name=name)
        link(tree, math(tree, "ROUND", _attribute(tree, name)), aov.inputs["Value"])
    # a holdout ends the camera path at the first surface (a zero emission would let it pass on, and the
    # AOVs of the surfaces behind would add up)
    link(tree, add(tree, "ShaderNodeHoldout"), out)
    return material
