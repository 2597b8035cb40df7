"""Materials: the stained monolayer (dye), the plaques, the plate's plastic, the background and the mask pass.

The monolayer is a thin absorbing film: a Transparent BSDF whose colour is its transmittance
``T = translucency + (1 - translucency) * stain_rgb ** D`` (Beer-Lambert with the stain's nominal colour as the
transmittance at relative density ``D = 1``). ``D`` is built in the shared group ``platesynth.stain`` from the
well's attributes: low-frequency unevenness, an elongated dark centre, high-frequency drying detail and a paler
band along the rim. A plaque is a disc just above the monolayer whose Transparent colour is the ratio of the
cleared transmittance to the intact one, so light passing plaque and monolayer sees exactly the stain that is
left. Per-element values come from point attributes; plate-wide values are named Value/RGB nodes.
"""

from __future__ import annotations

from typing import Any

import bpy

from platesynth.render.blender.inside.nodes import add, feed, link, math, output, vector_math

WELL_ATTRIBUTES = (
    "density",
    "unevenness",
    "unevenness_scale_mm",
    "centre_gradient",
    "centre_elongation",
    "centre_angle_deg",
    "drying_detail",
    "rim_clearing_mm",
    "translucency",
    "emptied",
    "lysed",
    "texture_seed",
)
"""Float point attributes describing a well's monolayer (also copied onto its plaques)."""

MASK_AOVS = ("well_id", "plaque_id")
"""Shader AOVs of the mask pass: each holds the integer id of the well / plaque seen in the pixel (0: none)."""


def _new_material(name: str) -> tuple[bpy.types.Material, bpy.types.NodeTree, bpy.types.Node]:
    material = bpy.data.materials.new(name)
    tree = material.node_tree
    tree.nodes.clear()
    return material, tree, add(tree, "ShaderNodeOutputMaterial")


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


def _noise(tree: bpy.types.NodeTree, vector: Any, scale: Any, w: Any, detail: float = 2.0, roughness: float = 0.5) -> bpy.types.NodeSocket:
    node = add(tree, "ShaderNodeTexNoise", noise_dimensions="4D")
    feed(tree, node, Vector=vector, Scale=scale, W=w, Detail=detail, Roughness=roughness)
    return output(node, "Factor")


def _signed(tree: bpy.types.NodeTree, noise: Any) -> bpy.types.Node:
    """Noise in [0, 1] (centred near 0.5) to roughly [-1, 1]."""
    return math(tree, "MULTIPLY_ADD", noise, 2.0, -1.0)


def _smoothstep(tree: bpy.types.NodeTree, value: Any, low: Any, high: Any) -> bpy.types.Node:
    node = add(tree, "ShaderNodeMapRange", interpolation_type="SMOOTHSTEP")
    return feed(tree, node, Value=value, From_Min=low, From_Max=high, To_Min=0.0, To_Max=1.0)


def stain_group() -> bpy.types.NodeTree:
    """Shader group ``platesynth.stain``: the monolayer's transmittance at a point of a well.

    Inputs are the offset from the well centre in plate millimetres (x right, y down), the well's radius, the
    stain colour, the well's stain attributes (see :data:`WELL_ATTRIBUTES`) and ``Clearing``, the fraction of
    the stain removed (a plaque). Output ``Transmittance``.
    """
    group = bpy.data.node_groups.new("platesynth.stain", "ShaderNodeTree")
    sockets = [("Offset", "NodeSocketVector"), ("Well Radius", "NodeSocketFloat"), ("Stain Colour", "NodeSocketColor")]
    sockets += [(name, "NodeSocketFloat") for name in WELL_ATTRIBUTES]
    sockets += [("Centre Offset", "NodeSocketVector"), ("Clearing", "NodeSocketFloat")]
    for name, kind in sockets:
        group.interface.new_socket(name=name, in_out="INPUT", socket_type=kind)
    group.interface.new_socket(name="Transmittance", in_out="OUTPUT", socket_type="NodeSocketColor")
    g_in, g_out = add(group, "NodeGroupInput"), add(group, "NodeGroupOutput")
    inp = {name: output(g_in, name) for name, _ in sockets}

    offset = inp["Offset"]
    radius = inp["Well Radius"]
    seed = inp["texture_seed"]
    # low-frequency unevenness
    low = _noise(group, offset, math(group, "DIVIDE", 1.0, math(group, "MAXIMUM", inp["unevenness_scale_mm"], 0.1)), seed, 2.0, 0.5)
    density = math(group, "MULTIPLY", inp["density"], math(group, "MULTIPLY_ADD", _signed(group, low), inp["unevenness"], 1.0))
    # elongated dark centre: a Gaussian in the rotated, stretched frame around the (offset) centre
    centred = add(group, "ShaderNodeSeparateXYZ")
    feed(group, centred, Vector=vector_math(group, "SUBTRACT", offset, inp["Centre Offset"]))
    angle = math(group, "RADIANS", inp["centre_angle_deg"])
    cos_a, sin_a = math(group, "COSINE", angle), math(group, "SINE", angle)
    along = math(group, "ADD", math(group, "MULTIPLY", output(centred, "X"), cos_a), math(group, "MULTIPLY", output(centred, "Y"), sin_a))
    across = math(group, "SUBTRACT", math(group, "MULTIPLY", output(centred, "Y"), cos_a), math(group, "MULTIPLY", output(centred, "X"), sin_a))
    along = math(group, "DIVIDE", along, math(group, "MAXIMUM", inp["centre_elongation"], 0.1))
    spread = math(group, "MULTIPLY", radius, 0.45)
    squared = math(group, "ADD", math(group, "POWER", math(group, "DIVIDE", along, spread), 2.0), math(group, "POWER", math(group, "DIVIDE", across, spread), 2.0))
    centre = math(group, "EXPONENT", math(group, "MULTIPLY", squared, -1.0))
    density = math(group, "MULTIPLY", density, math(group, "MULTIPLY_ADD", centre, inp["centre_gradient"], 1.0))
    # high-frequency drying detail
    fine = _noise(group, offset, 2.5, math(group, "ADD", seed, 17.0), 6.0, 0.65)
    density = math(group, "MULTIPLY", density, math(group, "MULTIPLY_ADD", _signed(group, fine), inp["drying_detail"], 1.0))
    # paler band along the rim
    to_rim = math(group, "SUBTRACT", radius, output(vector_math(group, "LENGTH", offset), "Value"))
    band = _smoothstep(group, to_rim, 0.0, math(group, "MAXIMUM", inp["rim_clearing_mm"], 1e-3))
    density = math(group, "MULTIPLY", density, math(group, "MULTIPLY_ADD", output(band, "Result"), 0.6, 0.4))
    # lysed wells keep patches of the layer; emptied wells none; plaques clear a fraction
    patches = _noise(group, offset, 0.35, math(group, "ADD", seed, 41.0), 3.0, 0.6)
    lysed_keep = math(group, "MULTIPLY_ADD", inp["lysed"], math(group, "SUBTRACT", math(group, "MULTIPLY", patches, 0.4), 0.95), 1.0)
    density = math(group, "MULTIPLY", density, math(group, "MAXIMUM", lysed_keep, 0.0))
    density = math(group, "MULTIPLY", density, math(group, "SUBTRACT", 1.0, inp["emptied"]))
    density = math(group, "MULTIPLY", density, math(group, "SUBTRACT", 1.0, inp["Clearing"]))
    density = math(group, "MAXIMUM", density, 0.0)

    channels = feed(group, add(group, "ShaderNodeSeparateColor"), Color=inp["Stain Colour"])
    combined = add(group, "ShaderNodeCombineColor")
    opaque = math(group, "SUBTRACT", 1.0, inp["translucency"])
    for channel in ("Red", "Green", "Blue"):
        absorbed = math(group, "POWER", math(group, "MAXIMUM", output(channels, channel), 1e-4), density)
        feed(group, combined, **{channel: math(group, "MULTIPLY_ADD", absorbed, opaque, inp["translucency"])})
    link(group, combined, g_out.inputs["Transmittance"])
    return group


def _stain_node(tree: bpy.types.NodeTree, group: bpy.types.NodeTree, stain_colour: Any, well_radius: Any, clearing: Any = 0.0) -> bpy.types.Node:
    """The stain group fed from the geometry's attributes (wells and plaques carry the same ones)."""
    node = add(tree, "ShaderNodeGroup")
    node.node_tree = group
    coordinates = add(tree, "ShaderNodeTexCoord")
    world_offset = vector_math(tree, "SUBTRACT", output(coordinates, "Object"), _attribute(tree, "well_center", "Vector"))
    flip = add(tree, "ShaderNodeVectorMath", operation="MULTIPLY")
    feed(tree, flip, Vector=world_offset, Vector_1=(1.0, -1.0, 0.0))  # world y up -> plate y down
    inputs: dict[str, Any] = {"Offset": flip, "Well Radius": well_radius, "Stain Colour": stain_colour, "Clearing": clearing}
    inputs |= {name: _attribute(tree, name) for name in WELL_ATTRIBUTES}
    inputs["Centre Offset"] = _attribute(tree, "centre_offset", "Vector")
    for key, value in inputs.items():
        target = node.inputs[key]
        if isinstance(value, (bpy.types.Node, bpy.types.NodeSocket)):
            link(tree, value, target)
        else:
            target.default_value = value
    return node


def monolayer_material(group: bpy.types.NodeTree, stain_rgb: tuple[float, float, float], well_radius: float) -> bpy.types.Material:
    """The stained cell layer on each well floor (a thin absorbing film)."""
    material, tree, out = _new_material("platesynth.monolayer")
    stain = _stain_node(tree, group, _rgb(tree, "Stain Colour", stain_rgb), _value(tree, "Well Radius", well_radius))
    film = feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=stain)
    link(tree, film, out)
    return material


def plaque_material(
    group: bpy.types.NodeTree, stain_rgb: tuple[float, float, float], well_radius: float, first_depth: int
) -> bpy.types.Material:
    """A plaque: the stain cleared by ``clearness``, fading out over ``softness`` towards the (noisy) rim.

    Only the plaque nearest the camera clears (``Transparent Depth == First Plaque Depth``); plaques it covers
    pass light unchanged, as the stain is removed only once.
    """
    material, tree, out = _new_material("platesynth.plaque")
    rim = _attribute(tree, "rim")
    coordinates = add(tree, "ShaderNodeTexCoord")
    wobble = _noise(tree, output(coordinates, "Object"), 3.0, _attribute(tree, "plaque_id"), 3.0, 0.6)
    noisy_rim = math(tree, "MULTIPLY", rim, math(tree, "MULTIPLY_ADD", _signed(tree, wobble), 0.12, 1.0))
    softness = math(tree, "MAXIMUM", _attribute(tree, "softness"), 0.02)
    edge = _smoothstep(tree, noisy_rim, math(tree, "SUBTRACT", 1.0, softness), 1.0)
    clearing = math(tree, "MULTIPLY", _attribute(tree, "clearness"), math(tree, "SUBTRACT", 1.0, output(edge, "Result")))
    path = add(tree, "ShaderNodeLightPath")
    topmost = math(tree, "COMPARE", output(path, "Transparent Depth"), _value(tree, "First Plaque Depth", float(first_depth)), 0.5)
    clearing = math(tree, "MULTIPLY", clearing, topmost)
    stain_colour = _rgb(tree, "Stain Colour", stain_rgb)
    well_radius_socket = _value(tree, "Well Radius", well_radius)
    cleared = _stain_node(tree, group, stain_colour, well_radius_socket, clearing)
    intact = _stain_node(tree, group, stain_colour, well_radius_socket, 0.0)
    ratio = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="DIVIDE")
    feed(tree, ratio, Factor=1.0, A=cleared, B=intact)
    film = feed(tree, add(tree, "ShaderNodeBsdfTransparent"), Color=output(ratio, "Result"))
    link(tree, film, out)
    return material


def plastic_material(tint_rgb: tuple[float, float, float], transmittance: float, rim_darkness: float) -> bpy.types.Material:
    """The plate's polystyrene: tinted see-through plastic whose grazing faces (the walls' outlines) look dark."""
    material, tree, out = _new_material("platesynth.plastic")
    tint = _rgb(tree, "Plastic Tint", tint_rgb)
    through = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY")
    feed(tree, through, Factor=1.0, A=tint, B=(1.0, 1.0, 1.0, 1.0))
    clear = add(tree, "ShaderNodeBsdfTransparent")
    scaled = add(tree, "ShaderNodeVectorMath", operation="SCALE")
    feed(tree, scaled, Vector=output(through, "Result"), Scale=_value(tree, "Plastic Transmittance", transmittance))
    link(tree, output(scaled, "Vector"), clear.inputs["Color"])
    gloss = feed(tree, add(tree, "ShaderNodeBsdfGlossy"), Color=(1.0, 1.0, 1.0, 1.0), Roughness=0.15)
    dark = feed(tree, add(tree, "ShaderNodeBsdfDiffuse"), Color=(0.05, 0.05, 0.06, 1.0))
    facing = add(tree, "ShaderNodeLayerWeight")
    feed(tree, facing, Blend=0.3)
    outline = math(tree, "MULTIPLY", math(tree, "POWER", output(facing, "Facing"), 3.0), _value(tree, "Rim Darkness", rim_darkness))
    glossy_mix = feed(tree, add(tree, "ShaderNodeMixShader"), Fac=math(tree, "MULTIPLY", output(facing, "Fresnel"), 0.5), Shader=clear, Shader_1=gloss)
    mix = feed(tree, add(tree, "ShaderNodeMixShader"), Fac=outline, Shader=glossy_mix, Shader_1=dark)
    link(tree, mix, out)
    return material


def emission_material(name: str, rgb: tuple[float, float, float], strength: float) -> bpy.types.Material:
    """A light-emitting surface (the light box's panel)."""
    material, tree, out = _new_material(name)
    emit = add(tree, "ShaderNodeEmission")
    link(tree, _rgb(tree, "Light Colour", rgb), emit.inputs["Color"])
    link(tree, _value(tree, "Light Strength", strength), emit.inputs["Strength"])
    link(tree, emit, out)
    return material


def surface_material(name: str, rgb: tuple[float, float, float], texture: float, seed: float, roughness: float = 0.8) -> bpy.types.Material:
    """A matte surface (desk, light-box frame, ruler) with a faint noise texture."""
    material, tree, out = _new_material(name)
    coordinates = add(tree, "ShaderNodeTexCoord")
    grain = _noise(tree, output(coordinates, "Object"), 0.15, seed, 8.0, 0.6)
    gain = math(tree, "MULTIPLY_ADD", _signed(tree, grain), _value(tree, "Texture", texture), 1.0)
    colour = add(tree, "ShaderNodeVectorMath", operation="SCALE")
    feed(tree, colour, Vector=_rgb(tree, "Colour", rgb), Scale=gain)
    bsdf = feed(tree, add(tree, "ShaderNodeBsdfPrincipled"), Roughness=roughness)
    link(tree, output(colour, "Vector"), bsdf.inputs["Base Color"])
    link(tree, bsdf, out)
    return material


def ink_material(name: str, rgb: tuple[float, float, float], opacity: float) -> bpy.types.Material:
    """Marker ink, stains: a coloured film that absorbs (and slightly scatters) light."""
    material, tree, out = _new_material(name)
    film = add(tree, "ShaderNodeBsdfTransparent")
    link(tree, _rgb(tree, "Colour", rgb), film.inputs["Color"])
    diffuse = feed(tree, add(tree, "ShaderNodeBsdfDiffuse"), Color=(*rgb, 1.0))
    mix = feed(tree, add(tree, "ShaderNodeMixShader"), Fac=1.0 - opacity, Shader=diffuse, Shader_1=film)
    link(tree, mix, out)
    return material


def mask_material() -> bpy.types.Material:
    """The mask pass's override material: opaque, writing each surface's rounded ids to the AOVs."""
    material, tree, out = _new_material("platesynth.mask")
    for name in MASK_AOVS:
        aov = add(tree, "ShaderNodeOutputAOV", aov_name=name)
        link(tree, math(tree, "ROUND", _attribute(tree, name)), aov.inputs["Value"])
    link(tree, feed(tree, add(tree, "ShaderNodeEmission"), Strength=0.0), out)
    return material
