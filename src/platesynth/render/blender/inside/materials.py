"""Materials: the stained monolayer (dye), the plaques, the plate's plastic, the background and the mask pass.

The monolayer is a thin absorbing film: a Transparent BSDF whose colour is its transmittance
``T = translucency + (1 - translucency) * stain_rgb ** D`` (Beer-Lambert with the stain's nominal colour as the
transmittance at relative density ``D = 1``). ``D`` is built in the shared group ``platesynth.stain`` from the
well's attributes: low-frequency unevenness, an elongated dark centre, high-frequency drying detail and a paler
band along the rim (``platesynth.transmittance`` turns a density into a colour). Its noise is the scene's own
(:mod:`platesynth.render.textures`, the raster renderer's arrays) looked up as image textures at the same
plate positions, so both renderers draw the same stain. A plaque, scratch or speck is a
film just in front of the monolayer whose Transparent colour is the ratio of the changed transmittance to the
intact one, so light passing film and monolayer sees the stain that is left. The plastic multiplies by its tint
and transmittance. Per-element values come from point attributes; plate-wide values are named Value/RGB nodes.
The mask pass overrides every material with :func:`mask_material`.
"""

from __future__ import annotations

from collections.abc import Mapping
from math import tau
from typing import Any

import bpy

from platesynth.render.appearance import EDGE_SPAN, FRAY_AMPLITUDE, FRAY_ROWS_PER_PLAQUE, RESIDUAL_MAX, RESIDUAL_MEAN, RESIDUAL_SPREAD
from platesynth.render.blender.inside.nodes import add, feed, link, math, output, vector_math
from platesynth.render.textures import FIBRE_CELL_MM, FINE_CELL_MM, FUZZ_CELL_MM, RESIDUAL_CELL_MM

WELL_VECTORS = {
    "well_stain": ("well_density", "well_centre_gradient", "well_drying_detail"),
    "well_state": ("well_emptied", "well_lysed", None),
    "well_centre": ("well_centre_offset_x", "well_centre_offset_y", "well_centre_angle_deg"),
    "well_noise": ("well_noise_x", "well_noise_y", None),
}
"""A well's monolayer, packed three values to a vector point attribute (each attribute the shader reads costs
time at every sample): the vectors' names and their components' names (the stain group's inputs; ``None``: an
unused component). ``well_noise`` is the well's shift into the periodic noise tiles (mm). Wells and their
plaques and marks carry them, plus ``well_center`` (world mm). Prefixed names: Cycles reserves some plain
ones (``density`` is the volume density)."""

WELL_ATTRIBUTES = tuple(name for components in WELL_VECTORS.values() for name in components if name)

PLATE_STAIN_INPUTS = ("Unevenness", "Unevenness Scale", "Centre Elongation", "Rim Clearing", "Translucency")
"""Plate-wide stain parameters: inputs of the stain group, fed by named Value nodes in each material."""

MASK_AOVS = ("well_id", "plaque_id")
"""Shader AOVs of the mask pass: each holds the integer id of the well / plaque seen in the pixel (0: none)."""

_NOISE_SD = 0.123
"""Standard deviation of Blender's 3-D Noise Texture factor (detail 0, mean 0.5), measured on a large plane."""


def _new_material(name: str) -> tuple[bpy.types.Material, bpy.types.NodeTree, bpy.types.Node]:
    material = bpy.data.materials.new(name)
    tree = material.node_tree
    tree.nodes.clear()
    return material, tree, add(tree, "ShaderNodeOutputMaterial")


class NoiseImages:
    """The scene's noise textures (:class:`platesynth.render.textures.SceneTextures`) as Blender images (each
    array's row 0 at the image's bottom), with the cell of the unevenness grid."""

    def __init__(self, low_grid: bpy.types.Image, low_cell_mm: float, fibre_grid: bpy.types.Image | None, fine_tile: bpy.types.Image, residual_tile: bpy.types.Image) -> None:
        self.low_grid = low_grid
        self.low_cell_mm = low_cell_mm
        self.fibre_grid = fibre_grid
        self.fine_tile = fine_tile
        self.residual_tile = residual_tile


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


def _well_value(tree: bpy.types.NodeTree, name: str) -> bpy.types.NodeSocket:
    """One of the well's values (see :data:`WELL_VECTORS`) from its packed attribute."""
    for vector, components in WELL_VECTORS.items():
        if name in components:
            parts = feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=_attribute(tree, vector, "Vector"))
            return output(parts, "XYZ"[components.index(name)])
    raise KeyError(name)


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


def _smoothstep(tree: bpy.types.NodeTree, value: Any, low: Any, high: Any) -> bpy.types.NodeSocket:
    node = add(tree, "ShaderNodeMapRange", interpolation_type="SMOOTHSTEP")
    return output(feed(tree, node, Value=value, From_Min=low, From_Max=high, To_Min=0.0, To_Max=1.0), "Result")


def transmittance_group() -> bpy.types.NodeTree:
    """Shader group ``platesynth.transmittance``: ``T = t + (1 - t) * stain ** density`` per channel (Beer-Lambert
    with the stain's colour as the transmittance at density 1; ``t``, the translucency, passes unabsorbed)."""
    group = bpy.data.node_groups.new("platesynth.transmittance", "ShaderNodeTree")
    for name, kind in (("Density", "NodeSocketFloat"), ("Stain Colour", "NodeSocketColor"), ("Translucency", "NodeSocketFloat")):
        group.interface.new_socket(name=name, in_out="INPUT", socket_type=kind)
    group.interface.new_socket(name="Transmittance", in_out="OUTPUT", socket_type="NodeSocketColor")
    g_in, g_out = add(group, "NodeGroupInput"), add(group, "NodeGroupOutput")
    channels = feed(group, add(group, "ShaderNodeSeparateColor"), Color=output(g_in, "Stain Colour"))
    translucency = output(g_in, "Translucency")
    opaque = math(group, "SUBTRACT", 1.0, translucency)
    combined = add(group, "ShaderNodeCombineColor")
    for channel in ("Red", "Green", "Blue"):
        absorbed = math(group, "POWER", math(group, "MAXIMUM", output(channels, channel), 1e-3), output(g_in, "Density"))
        feed(group, combined, **{channel: math(group, "MULTIPLY_ADD", absorbed, opaque, translucency)})
    link(group, combined, g_out.inputs["Transmittance"])
    return group


def stain_group(transmittance: bpy.types.NodeTree, noise: NoiseImages) -> bpy.types.NodeTree:
    """Shader group ``platesynth.stain``: the monolayer's density and transmittance at a point of a well.

    The density follows the raster renderer's model with the scene's noise textures: the well's density with
    low-frequency unevenness, an elongated darker centre, a thinner band along the rim and high-frequency drying
    texture; lysed wells keep a cloud and strands of the layer, emptied wells nothing. Without a fibre grid
    (no lysed well in the scene) the lysed wells' remnants are left out.
    """
    group = bpy.data.node_groups.new("platesynth.stain", "ShaderNodeTree")
    sockets = [("Offset", "NodeSocketVector"), ("Well Radius", "NodeSocketFloat"), ("Stain Colour", "NodeSocketColor")]
    sockets += [(name, "NodeSocketFloat") for name in PLATE_STAIN_INPUTS + WELL_ATTRIBUTES]
    for name, kind in sockets:
        group.interface.new_socket(name=name, in_out="INPUT", socket_type=kind)
    group.interface.new_socket(name="Density", in_out="OUTPUT", socket_type="NodeSocketFloat")
    group.interface.new_socket(name="Transmittance", in_out="OUTPUT", socket_type="NodeSocketColor")
    g_in, g_out = add(group, "NodeGroupInput"), add(group, "NodeGroupOutput")
    inp = {name: output(g_in, name) for name, _ in sockets}

    offset, radius = inp["Offset"], inp["Well Radius"]
    u, v = _plate_position(group)
    low_cell = math(group, "MULTIPLY", math(group, "MAXIMUM", inp["Unevenness Scale"], 1e-3), 0.5)
    low = _lookup(group, noise.low_grid, _in_cells(group, u, 0.0, low_cell), _in_cells(group, v, 0.0, low_cell), periodic=False)
    density = math(group, "MULTIPLY", inp["well_density"], math(group, "MULTIPLY_ADD", low, inp["Unevenness"], 1.0))
    # the elongated darker centre: a Gaussian in the rotated, stretched frame around the offset centre
    centre_offset = feed(group, add(group, "ShaderNodeCombineXYZ"), X=inp["well_centre_offset_x"], Y=inp["well_centre_offset_y"])
    centred = feed(group, add(group, "ShaderNodeSeparateXYZ"), Vector=vector_math(group, "SUBTRACT", offset, centre_offset))
    angle = math(group, "RADIANS", inp["well_centre_angle_deg"])
    cos_a, sin_a = math(group, "COSINE", angle), math(group, "SINE", angle)
    cu, cv = output(centred, "X"), output(centred, "Y")
    along = math(group, "ADD", math(group, "MULTIPLY", cu, cos_a), math(group, "MULTIPLY", cv, sin_a))
    across = math(group, "SUBTRACT", math(group, "MULTIPLY", cv, cos_a), math(group, "MULTIPLY", cu, sin_a))
    stretch = math(group, "SQRT", math(group, "MAXIMUM", inp["Centre Elongation"], 0.01))
    spread = math(group, "MULTIPLY", radius, 0.55)
    along = math(group, "DIVIDE", along, math(group, "MULTIPLY", spread, stretch))
    across = math(group, "DIVIDE", math(group, "MULTIPLY", across, stretch), spread)
    gradient = math(group, "EXPONENT", math(group, "MULTIPLY", math(group, "ADD", math(group, "POWER", along, 2.0), math(group, "POWER", across, 2.0)), -1.0))
    density = math(group, "MULTIPLY", density, math(group, "MULTIPLY_ADD", gradient, inp["well_centre_gradient"], 1.0))
    # thinner layer along the rim
    to_rim = math(group, "MAXIMUM", math(group, "SUBTRACT", radius, output(vector_math(group, "LENGTH", offset), "Value")), 0.0)
    band = math(group, "EXPONENT", math(group, "DIVIDE", to_rim, math(group, "MULTIPLY", math(group, "MAXIMUM", inp["Rim Clearing"], 1e-4), -1.0)))
    density = math(group, "MULTIPLY", density, math(group, "MULTIPLY_ADD", band, -0.5, 1.0))
    # high-frequency drying texture: the fine tile, shifted by the well's offset
    fine_column = _in_cells(group, u, inp["well_noise_x"], FINE_CELL_MM)
    fine = _lookup(group, noise.fine_tile, fine_column, _in_cells(group, v, inp["well_noise_y"], FINE_CELL_MM), periodic=True)
    density = math(group, "MULTIPLY", density, math(group, "MAXIMUM", math(group, "MULTIPLY_ADD", math(group, "MULTIPLY", fine, 2.0), inp["well_drying_detail"], 1.0), 0.0))
    if noise.fibre_grid is not None:  # what is left of a lysed layer: a cloud around the centre and a network of strands
        fibre = _lookup(group, noise.fibre_grid, _in_cells(group, u, 0.0, FIBRE_CELL_MM), _in_cells(group, v, 0.0, FIBRE_CELL_MM), periodic=False)
        strands = math(group, "POWER", math(group, "SUBTRACT", 1.0, math(group, "MINIMUM", math(group, "ABSOLUTE", fibre), 1.0)), 2.0)
        strands = math(group, "MULTIPLY", strands, math(group, "MULTIPLY_ADD", fine, 0.4, 0.6))
        cloud_noise = _lookup(group, noise.low_grid, math(group, "ADD", _in_cells(group, u, 0.0, low_cell), 17.0), _in_cells(group, v, 0.0, low_cell), periodic=False)
        cloud = math(group, "MULTIPLY_ADD", gradient, 0.55, math(group, "MULTIPLY", cloud_noise, 0.25))
        remnant = math(group, "MULTIPLY_ADD", cloud, math(group, "MULTIPLY_ADD", strands, 0.6, 0.4), math(group, "MULTIPLY_ADD", strands, 0.15, 0.04))
        remnant = math(group, "MINIMUM", math(group, "MAXIMUM", remnant, 0.0), 1.0)
        near_rim = math(group, "MULTIPLY_ADD", math(group, "EXPONENT", math(group, "DIVIDE", to_rim, -1.5)), -0.7, 1.0)
        remnant = math(group, "MULTIPLY", math(group, "MULTIPLY", remnant, 0.6), near_rim)
        keep = math(group, "MULTIPLY_ADD", inp["well_lysed"], math(group, "SUBTRACT", remnant, 1.0), 1.0)
        density = math(group, "MULTIPLY", density, keep)
    density = math(group, "MAXIMUM", math(group, "MULTIPLY", density, math(group, "SUBTRACT", 1.0, inp["well_emptied"])), 0.0)
    link(group, density, g_out.inputs["Density"])
    link(group, _transmittance(group, transmittance, density, inp["Stain Colour"], inp["Translucency"]), g_out.inputs["Transmittance"])
    return group


def _transmittance(tree: bpy.types.NodeTree, group: bpy.types.NodeTree, density: Any, colour: Any, translucency: Any) -> bpy.types.NodeSocket:
    node = add(tree, "ShaderNodeGroup")
    node.node_tree = group
    feed(tree, node, Density=density, Stain_Colour=colour, Translucency=translucency)
    return output(node, "Transmittance")


class StainInputs:
    """The plate-wide stain values every stain-using material exposes as named nodes."""

    def __init__(self, stain_linear_rgb: tuple[float, float, float], well_radius: float, plate_stain: Mapping[str, float]) -> None:
        self.stain_linear_rgb = stain_linear_rgb
        self.well_radius = well_radius
        self.values = {
            "Unevenness": float(plate_stain["unevenness"]),
            "Unevenness Scale": float(plate_stain["unevenness_scale_mm"]),
            "Centre Elongation": float(plate_stain["centre_elongation"]),
            "Rim Clearing": float(plate_stain["rim_clearing_mm"]),
            "Translucency": float(plate_stain["translucency"]),
        }

    def sockets(self, tree: bpy.types.NodeTree) -> dict[str, bpy.types.NodeSocket]:
        sockets = {name: _value(tree, name, value) for name, value in self.values.items()}
        sockets["Stain Colour"] = _rgb(tree, "Stain Colour", self.stain_linear_rgb)
        sockets["Well Radius"] = _value(tree, "Well Radius", self.well_radius)
        return sockets


def _plate_offset(tree: bpy.types.NodeTree) -> bpy.types.Node:
    """The shading point's offset from its well's centre in plate millimetres (x right, y down)."""
    coordinates = add(tree, "ShaderNodeTexCoord")
    world_offset = vector_math(tree, "SUBTRACT", output(coordinates, "Object"), _attribute(tree, "well_center", "Vector"))
    flip = add(tree, "ShaderNodeVectorMath", operation="MULTIPLY")
    return feed(tree, flip, Vector=world_offset, Vector_1=(1.0, -1.0, 0.0))


def _stain_node(tree: bpy.types.NodeTree, group: bpy.types.NodeTree, shared: Mapping[str, Any], offset: Any) -> bpy.types.Node:
    """The stain group fed from the well's attributes."""
    node = add(tree, "ShaderNodeGroup")
    node.node_tree = group
    inputs: dict[str, Any] = {key: value for key, value in shared.items() if key in node.inputs} | {"Offset": offset}
    for vector, components in WELL_VECTORS.items():
        parts = feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=_attribute(tree, vector, "Vector"))
        inputs |= {name: output(parts, axis) for name, axis in zip(components, "XYZ") if name}
    for key, value in inputs.items():
        target = node.inputs[key]
        if isinstance(value, (bpy.types.Node, bpy.types.NodeSocket)):
            link(tree, value, target)
        else:
            target.default_value = value
    return node


def _change_ratio(
    tree: bpy.types.NodeTree, transmittance: bpy.types.NodeTree, shared: Mapping[str, Any], density: Any, clearing: Any, extra: Any = 0.0
) -> bpy.types.NodeSocket:
    """What a film over the monolayer must pass so that the light sees its stain changed: the transmittance
    of ``density`` with ``clearing`` removed and ``extra`` added, over that of ``density`` (``shared``: the
    stain's named sockets, :meth:`StainInputs.sockets`)."""
    changed = math(tree, "MULTIPLY_ADD", density, math(tree, "SUBTRACT", 1.0, clearing), extra)
    ratio = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="DIVIDE", clamp_result=False)
    feed(
        tree,
        ratio,
        Factor=1.0,
        A=_transmittance(tree, transmittance, changed, shared["Stain Colour"], shared["Translucency"]),
        B=_transmittance(tree, transmittance, density, shared["Stain Colour"], shared["Translucency"]),
    )
    return output(ratio, "Result")


def monolayer_material(group: bpy.types.NodeTree, stain: StainInputs, tint_rgb: tuple[float, float, float], transmittance: float) -> bpy.types.Material:
    """The stained cell layer on each well floor: a thin absorbing film, times the plate's plastic under it."""
    material, tree, out = _new_material("platesynth.monolayer")
    stain_transmittance = output(_stain_node(tree, group, stain.sockets(tree), _plate_offset(tree)), "Transmittance")
    film = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY", clamp_result=False)
    feed(tree, film, Factor=1.0, A=stain_transmittance, B=_plastic_colour(tree, tint_rgb, transmittance))
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=output(film, "Result")), out)
    return material


def _plastic_colour(tree: bpy.types.NodeTree, tint_rgb: tuple[float, float, float], transmittance: float) -> bpy.types.NodeSocket:
    colour = add(tree, "ShaderNodeVectorMath", operation="SCALE")
    feed(tree, colour, Vector=_rgb(tree, "Plastic Tint", tint_rgb), Scale=_value(tree, "Plastic Transmittance", transmittance))
    return output(colour, "Vector")


def plaque_material(transmittance: bpy.types.NodeTree, stain_group: bpy.types.NodeTree, stain: StainInputs, noise: NoiseImages) -> bpy.types.Material:
    """A plaque, as the raster renderer draws it: the monolayer's local density cleared by ``clearness`` with a
    smooth edge ``softness * radius`` wide centred on the outline and frayed by radial fibres (the fine tile read
    with its 256 columns around the plaque and :data:`~platesynth.render.textures.FUZZ_CELL_MM` cells along its
    radius), and a little stain left inside (the residual tile).

    The geometry's ``signed_w`` attribute is the signed distance to the outline in edge widths (negative
    inside), ``center`` the plaque's centre, ``layer`` its index in the scene. Only the plaque surface nearest
    the camera clears (``Transparent Depth == First Plaque Depth``, 0: nothing transparent lies in front of the
    plaques), so stacked plaques clear once.
    """
    material, tree, out = _new_material("platesynth.plaque")
    shared = stain.sockets(tree)
    offset = _plate_offset(tree)
    from_centre = vector_math(tree, "SUBTRACT", output(add(tree, "ShaderNodeTexCoord"), "Object"), _attribute(tree, "center", "Vector"))
    parts = feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=from_centre)
    du, dv = output(parts, "X"), math(tree, "MULTIPLY", output(parts, "Y"), -1.0)
    distance = math(tree, "SQRT", math(tree, "ADD", math(tree, "POWER", du, 2.0), math(tree, "POWER", dv, 2.0)))
    tile_columns = noise.fine_tile.size[0]
    around = math(tree, "MULTIPLY", math(tree, "ARCTAN2", dv, du), tile_columns / tau)
    along = math(tree, "MULTIPLY_ADD", _attribute(tree, "layer"), FRAY_ROWS_PER_PLAQUE, math(tree, "DIVIDE", distance, FUZZ_CELL_MM))
    fray = _lookup(tree, noise.fine_tile, around, along, periodic=True)
    t = math(tree, "MULTIPLY_ADD", _attribute(tree, "signed_w"), -1.0 / EDGE_SPAN, math(tree, "MULTIPLY_ADD", fray, FRAY_AMPLITUDE, 0.5))
    edge = _smoothstep(tree, t, 0.0, 1.0)
    u, v = _plate_position(tree)
    residual_noise = _lookup(
        tree,
        noise.residual_tile,
        _in_cells(tree, u, _well_value(tree, "well_noise_y"), RESIDUAL_CELL_MM),
        _in_cells(tree, v, _well_value(tree, "well_noise_x"), RESIDUAL_CELL_MM),
        periodic=True,
    )
    residual = math(tree, "MINIMUM", math(tree, "MAXIMUM", math(tree, "MULTIPLY_ADD", residual_noise, RESIDUAL_SPREAD, RESIDUAL_MEAN), 0.0), RESIDUAL_MAX)
    clearing = math(tree, "MULTIPLY", math(tree, "MULTIPLY", _attribute(tree, "clearness"), edge), math(tree, "SUBTRACT", 1.0, residual))
    path = add(tree, "ShaderNodeLightPath")
    topmost = math(tree, "COMPARE", output(path, "Transparent Depth"), _value(tree, "First Plaque Depth", 0.0), 0.5)
    clearing = math(tree, "MULTIPLY", clearing, topmost)
    density = output(_stain_node(tree, stain_group, shared, offset), "Density")
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=_change_ratio(tree, transmittance, shared, density, clearing)), out)
    return material


def marks_material(transmittance: bpy.types.NodeTree, stain: StainInputs) -> bpy.types.Material:
    """Scratches and specks on the monolayer: each mark's ``mark_clearing`` (stain scraped off) and ``mark_extra``
    (density added) attributes change the stain of the well under it, inside the well's floor only, where the
    mark is the first film the camera ray meets (marks lie in front of the plaques, whose films then leave the
    stain alone: clearing twice would overshoot the light)."""
    material, tree, out = _new_material("platesynth.marks")
    # only on the monolayer: a scratch running up the wall changes nothing beyond the floor's edge
    on_floor = math(tree, "LESS_THAN", output(vector_math(tree, "LENGTH", _plate_offset(tree)), "Value"), stain.well_radius)
    # only the film nearest the camera changes the stain (see :func:`plaque_material`)
    topmost = math(tree, "COMPARE", output(add(tree, "ShaderNodeLightPath"), "Transparent Depth"), 0.0, 0.5)
    on_floor = math(tree, "MULTIPLY", on_floor, topmost)
    clearing = math(tree, "MULTIPLY", _attribute(tree, "mark_clearing"), on_floor)
    extra = math(tree, "MULTIPLY", _attribute(tree, "mark_extra"), on_floor)
    ratio = _change_ratio(tree, transmittance, stain.sockets(tree), _well_value(tree, "well_density"), clearing, extra)
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=ratio), out)
    return material


def _relief_factor(tree: bpy.types.NodeTree, relief: bpy.types.Image, texels_per_mm: float, strength: float) -> bpy.types.NodeSocket:
    """``1 - strength * relief`` with the raster renderer's plate-space relief image (its row 0 at plate y = 0,
    stored bottom row first) looked up at the surface's world position ``(x, -y)``."""
    position = output(add(tree, "ShaderNodeTexCoord"), "Object")
    height_mm, width_mm = relief.size[1] / texels_per_mm, relief.size[0] / texels_per_mm
    uv = add(tree, "ShaderNodeMapping", vector_type="POINT")
    feed(tree, uv, Vector=position, Location=(0.0, 1.0, 0.0), Scale=(1.0 / width_mm, 1.0 / height_mm, 0.0))
    texture = add(tree, "ShaderNodeTexImage", interpolation="Linear", extension="CLIP")
    texture.image = relief
    link(tree, uv, texture)
    factor = math(tree, "SUBTRACT", 1.0, math(tree, "MULTIPLY", output(texture, "Color"), _value(tree, "Label Strength", strength)))
    return math(tree, "MAXIMUM", factor, 0.0)


def _skirt_shade(tree: bpy.types.NodeTree, plate: Mapping[str, float]) -> bpy.types.NodeSocket:
    """The raster renderer's skirt shading: ``1 - 0.25 * clip((d + skirt) / skirt)`` with ``d`` the signed
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
    return math(tree, "MULTIPLY_ADD", shade, -0.25, 1.0)


def plastic_material(
    name: str,
    tint_rgb: tuple[float, float, float],
    transmittance: float,
    rim_darkness: float,
    relief: tuple[bpy.types.Image, float, float] | None = None,
    plate: Mapping[str, float] | None = None,
) -> bpy.types.Material:
    """Polystyrene: tinted see-through plastic whose grazing faces (the walls seen edge-on) pass less light;
    ``relief`` = (image, texels per mm, label strength) adds the embossed labels, label rings and ribs, ``plate``
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
    panel's edges as the raster renderer does, by ``0.06 exp(-d / 6 mm)`` at ``d`` from the nearest edge."""
    material, tree, out = _new_material(name)
    emit = feed(tree, add(tree, "ShaderNodeEmission"), Color=_rgb(tree, "Colour", rgb))
    strength_socket: Any = _value(tree, "Strength", strength)
    if panel is not None:
        left, top, right, bottom = panel
        uv = feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=output(add(tree, "ShaderNodeTexCoord"), "UV"))
        bx, by = output(uv, "X"), output(uv, "Y")
        to_edge = math(tree, "MINIMUM", math(tree, "SUBTRACT", bx, left), math(tree, "SUBTRACT", right, bx))
        to_edge = math(tree, "MINIMUM", to_edge, math(tree, "MINIMUM", math(tree, "SUBTRACT", by, top), math(tree, "SUBTRACT", bottom, by)))
        falloff = math(tree, "EXPONENT", math(tree, "DIVIDE", math(tree, "MAXIMUM", to_edge, 0.0), -6.0))
        strength_socket = math(tree, "MULTIPLY", strength_socket, math(tree, "MULTIPLY_ADD", falloff, -0.06, 1.0))
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
    length = math(tree, "ADD", 3.0, math(tree, "ADD", math(tree, "MULTIPLY", fifth, 2.0), math(tree, "MULTIPLY", tenth, 2.0)))
    on_tick = math(tree, "LESS_THAN", math(tree, "ABSOLUTE", math(tree, "SUBTRACT", along, nearest)), 0.12)
    tick = math(tree, "MULTIPLY", on_tick, math(tree, "LESS_THAN", across, length))
    emit = add(tree, "ShaderNodeEmission")
    link(tree, math(tree, "MULTIPLY_ADD", tick, 0.6, 0.02), emit.inputs["Strength"])
    link(tree, emit, out)
    material.cycles.emission_sampling = "NONE"
    return material


def ink_material() -> bpy.types.Material:
    """Marker ink and blots on the plastic: a film multiplying the light by its ``ink`` attribute (linear RGB)."""
    material, tree, out = _new_material("platesynth.ink")
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=_attribute(tree, "ink", "Color")), out)
    return material


def blot_material(noise: NoiseImages) -> bpy.types.Material:
    """A smudge on the plastic, as the raster renderer draws it: its opacity falls off as a Gaussian distorted by
    the unevenness grid ``g``, ``opacity * exp(-(d / radius)**2 * (1 + 0.3 g))``, and the light passing it is
    multiplied by ``1 - a * (1 - colour)``."""
    material, tree, out = _new_material("platesynth.blot")
    position = output(add(tree, "ShaderNodeTexCoord"), "Object")
    flat = feed(tree, add(tree, "ShaderNodeVectorMath", operation="MULTIPLY"), Vector=position, Vector_1=(1.0, 1.0, 0.0))
    distance = output(vector_math(tree, "DISTANCE", flat, _attribute(tree, "blot_center", "Vector")), "Value")
    relative = math(tree, "DIVIDE", distance, _attribute(tree, "blot_radius"))
    u, v = _plate_position(tree)
    cell = noise.low_cell_mm
    distortion = math(tree, "MULTIPLY_ADD", _lookup(tree, noise.low_grid, _in_cells(tree, u, 0.0, cell), _in_cells(tree, v, 0.0, cell), periodic=False), 0.3, 1.0)
    falloff = math(tree, "MULTIPLY", math(tree, "MULTIPLY", math(tree, "POWER", relative, 2.0), distortion), -1.0)
    opacity = math(tree, "MULTIPLY", _attribute(tree, "blot_opacity"), math(tree, "EXPONENT", falloff))
    tinted = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="MIX", clamp_result=False)
    feed(tree, tinted, Factor=opacity, A=(1.0, 1.0, 1.0, 1.0), B=_attribute(tree, "blot_rgb", "Color"))
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=output(tinted, "Result")), out)
    return material


def rim_material(well_radius: float) -> bpy.types.Material:
    """The walls' bands and outlines: ink (the ``ink`` attribute), except where ``rim_hidden_inside`` is set and
    the ray crossed the floors' plane (``z = 0``) within ``well_radius`` of the ring's ``rim_center``."""
    material, tree, out = _new_material("platesynth.rims")
    geometry = add(tree, "ShaderNodeNewGeometry")
    position, incoming = output(geometry, "Position"), output(geometry, "Incoming")
    # the point where the ray (towards the camera along ``incoming``) crossed the floors' plane
    to_floor = math(tree, "DIVIDE", output(feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=position), "Z"), output(feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=incoming), "Z"))
    back = feed(tree, add(tree, "ShaderNodeVectorMath", operation="SCALE"), Vector=incoming, Scale=to_floor)
    crossing = vector_math(tree, "SUBTRACT", position, output(back, "Vector"))
    off_centre = output(vector_math(tree, "DISTANCE", crossing, _attribute(tree, "rim_center", "Vector")), "Value")
    through_floor = math(tree, "MULTIPLY", math(tree, "LESS_THAN", off_centre, _value(tree, "Well Radius", well_radius)), _attribute(tree, "rim_hidden_inside"))
    ink = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="MIX", clamp_result=False)
    feed(tree, ink, Factor=through_floor, A=_attribute(tree, "ink", "Color"), B=(1.0, 1.0, 1.0, 1.0))
    link(tree, feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=output(ink, "Result")), out)
    return material


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
