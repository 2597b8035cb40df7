"""The plate, its wells and the plaques as geometry-node groups fed by point clouds.

World units are millimetres. Plate coordinates (x right, y down, seen from above, origin at the A1 corner)
map to Blender's world as ``(x, -y, z)`` with ``z`` up and the plate's bottom at ``z = 0``; the cell monolayer
lies on the well floors at ``z = FLOOR_MM``.

Each group's parameters are modifier inputs (named sockets of the group's interface), so a saved .blend can be
re-driven by people or other tools; per-well and per-plaque values are attributes of the point clouds.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import bpy
import numpy as np

from platesynth.render.blender.inside.nodes import add, feed, link, math, output, vector_math

FLOOR_MM = 1.0
"""Height of the well floors (the plastic bottom's thickness), mm."""

LAYER_STEP_MM = 0.002
"""Height between stacked plaques (later plaques lie nearer the camera)."""

_ATTRIBUTE_TYPES = {"INT": ("INT", "value"), "FLOAT": ("FLOAT", "value"), "FLOAT_VECTOR": ("FLOAT_VECTOR", "vector")}


def point_cloud(name: str, positions: np.ndarray, attributes: Mapping[str, np.ndarray]) -> bpy.types.Object:
    """A mesh object of loose vertices at ``positions`` (n, 3) carrying point attributes.

    Integer arrays become INT attributes, (n,) floats FLOAT, (n, 3) floats FLOAT_VECTOR.
    """
    mesh = bpy.data.meshes.new(name)
    positions = np.asarray(positions, dtype=np.float32).reshape(-1, 3)
    mesh.vertices.add(len(positions))
    mesh.vertices.foreach_set("co", positions.ravel())
    for attribute_name, values in attributes.items():
        values = np.asarray(values)
        if values.ndim == 2:
            kind, field = _ATTRIBUTE_TYPES["FLOAT_VECTOR"]
            values = values.astype(np.float32)
        elif np.issubdtype(values.dtype, np.integer) or values.dtype == bool:
            kind, field = _ATTRIBUTE_TYPES["INT"]
            values = values.astype(np.int32)
        else:
            kind, field = _ATTRIBUTE_TYPES["FLOAT"]
            values = values.astype(np.float32)
        attribute = mesh.attributes.new(attribute_name, kind, "POINT")
        if len(values):
            attribute.data.foreach_set(field, values.ravel())
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def set_modifier_inputs(modifier: bpy.types.NodesModifier, values: Mapping[str, Any]) -> None:
    """Set a geometry-nodes modifier's inputs by their interface names."""
    by_name = {
        item.name: item.identifier
        for item in modifier.node_group.interface.items_tree
        if item.item_type == "SOCKET" and item.in_out == "INPUT"
    }
    for name, value in values.items():
        if name not in by_name:
            raise KeyError(f"{modifier.node_group.name} has no input {name!r}; inputs: {sorted(by_name)}")
        modifier[by_name[name]] = value


def add_modifier(obj: bpy.types.Object, group: bpy.types.NodeTree, inputs: Mapping[str, Any]) -> bpy.types.NodesModifier:
    """Put ``group`` on ``obj`` as a geometry-nodes modifier and set its inputs."""
    modifier = obj.modifiers.new(group.name, "NODES")
    modifier.node_group = group
    set_modifier_inputs(modifier, inputs)
    return modifier


def _new_group(name: str, inputs: Sequence[tuple[str, str, Any]]) -> tuple[bpy.types.NodeTree, bpy.types.Node, bpy.types.Node]:
    """A geometry-node group with a Geometry input, the given (name, socket type, default) inputs and a Geometry output."""
    group = bpy.data.node_groups.new(name, "GeometryNodeTree")
    group.interface.new_socket(name="Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    for socket_name, socket_type, default in inputs:
        item = group.interface.new_socket(name=socket_name, in_out="INPUT", socket_type=socket_type)
        if default is not None:
            item.default_value = default
    group.interface.new_socket(name="Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    return group, add(group, "NodeGroupInput"), add(group, "NodeGroupOutput")


def _named(tree: bpy.types.NodeTree, name: str, data_type: str = "FLOAT") -> bpy.types.NodeSocket:
    node = add(tree, "GeometryNodeInputNamedAttribute", data_type=data_type)
    feed(tree, node, Name=name)
    return output(node, "Attribute")


def _store(tree: bpy.types.NodeTree, geometry: Any, name: str, value: Any, data_type: str = "FLOAT", domain: str = "POINT") -> bpy.types.Node:
    node = add(tree, "GeometryNodeStoreNamedAttribute", data_type=data_type, domain=domain)
    return feed(tree, node, Geometry=geometry, Name=name, Value=value)


def _xyz(tree: bpy.types.NodeTree, vector: Any) -> bpy.types.Node:
    node = add(tree, "ShaderNodeSeparateXYZ")
    feed(tree, node, Vector=vector)
    return node


def wells_group(material: bpy.types.Material) -> bpy.types.NodeTree:
    """Geometry nodes turning well-centre points into monolayer discs (one per well, plus random emptying).

    Inputs: ``Well Radius`` (mm), ``Floor Height`` (mm), ``Segments``, ``Empty Probability`` and ``Seed`` (extra
    random emptying on top of the points' ``emptied`` attribute; 0 for a concrete scene). Point attributes are
    passed on to the discs (``well_id``, stain values...), plus ``center`` (the well centre) for the shader.
    """
    group, group_in, group_out = _new_group(
        "platesynth.wells",
        [
            ("Well Radius", "NodeSocketFloat", 11.0),
            ("Floor Height", "NodeSocketFloat", FLOOR_MM),
            ("Segments", "NodeSocketInt", 128),
            ("Empty Probability", "NodeSocketFloat", 0.0),
            ("Seed", "NodeSocketInt", 0),
        ],
    )
    points = _store(group, output(group_in, "Geometry"), "center", output(add(group, "GeometryNodeInputPosition"), "Position"), "FLOAT_VECTOR")
    chance = add(group, "FunctionNodeRandomValue", data_type="BOOLEAN")
    feed(group, chance, Probability=output(group_in, "Empty Probability"), ID=_named(group, "well_id", "INT"), Seed=output(group_in, "Seed"))
    emptied = math(group, "MAXIMUM", _named(group, "emptied"), output(chance, 3))
    points = _store(group, points, "emptied", emptied)
    disc = add(group, "GeometryNodeMeshCircle", fill_type="NGON")
    feed(group, disc, Vertices=output(group_in, "Segments"), Radius=output(group_in, "Well Radius"))
    instances = feed(group, add(group, "GeometryNodeInstanceOnPoints"), Points=points, Instance=disc)
    realized = feed(group, add(group, "GeometryNodeRealizeInstances"), Geometry=instances)
    lift = add(group, "ShaderNodeCombineXYZ")
    feed(group, lift, Z=output(group_in, "Floor Height"))
    placed = feed(group, add(group, "GeometryNodeSetPosition"), Geometry=realized, Offset=lift)
    shaded = feed(group, add(group, "GeometryNodeSetMaterial"), Geometry=placed, Material=material)
    link(group, shaded, group_out)
    return group


def plaques_group(material: bpy.types.Material, harmonics: int) -> bpy.types.NodeTree:
    """Geometry nodes turning plaque-centre points into irregular discs clipped to their wells.

    Each point carries ``radius``, ``layer`` (drawing order), ``well_center`` and the outline coefficients
    ``fourier_a{k}``/``fourier_b{k}`` for ``k = 2 .. harmonics + 1``; the outline is
    ``r(t) = radius * (1 + sum_k a_k cos(k t) + b_k sin(k t))`` with ``t`` the angle in plate coordinates (y down).
    Each disc gets the attribute ``rim``: 0 at its centre, 1 on its outline (the shader's centre-to-rim gradient).
    Inputs: ``Segments``, ``Well Radius`` (clip radius, mm), ``Floor Height``, ``Layer Step`` (mm between stacked
    plaques; negative when the camera looks from below), ``Radius Scale``, ``Irregularity Scale``.
    """
    group, group_in, group_out = _new_group(
        "platesynth.plaques",
        [
            ("Segments", "NodeSocketInt", 48),
            ("Well Radius", "NodeSocketFloat", 11.0),
            ("Floor Height", "NodeSocketFloat", FLOOR_MM),
            ("Layer Step", "NodeSocketFloat", LAYER_STEP_MM),
            ("Radius Scale", "NodeSocketFloat", 1.0),
            ("Irregularity Scale", "NodeSocketFloat", 1.0),
        ],
    )
    position = output(add(group, "GeometryNodeInputPosition"), "Position")
    points = _store(group, output(group_in, "Geometry"), "center", position, "FLOAT_VECTOR")
    radius = math(group, "MULTIPLY", _named(group, "radius"), output(group_in, "Radius Scale"))
    disc = add(group, "GeometryNodeMeshCircle", fill_type="TRIANGLE_FAN")
    feed(group, disc, Vertices=output(group_in, "Segments"), Radius=1.0)
    instances = feed(group, add(group, "GeometryNodeInstanceOnPoints"), Points=points, Instance=disc, Scale=radius)
    realized = feed(group, add(group, "GeometryNodeRealizeInstances"), Geometry=instances)

    # rim coordinate and outline angle from the offset to the plaque's centre
    center = _named(group, "center", "FLOAT_VECTOR")
    local = vector_math(group, "SUBTRACT", position, center)
    radius_after = math(group, "MULTIPLY", _named(group, "radius"), output(group_in, "Radius Scale"))
    rim = math(group, "DIVIDE", output(vector_math(group, "LENGTH", local), "Value"), radius_after)
    with_rim = _store(group, realized, "rim", rim)
    local_xyz = _xyz(group, local)
    angle = math(group, "ARCTAN2", math(group, "MULTIPLY", output(local_xyz, "Y"), -1.0), output(local_xyz, "X"))
    factor: Any = 1.0
    for k in range(2, harmonics + 2):
        cos_term = math(group, "MULTIPLY", _named(group, f"fourier_a{k}"), math(group, "COSINE", math(group, "MULTIPLY", angle, float(k))))
        sin_term = math(group, "MULTIPLY", _named(group, f"fourier_b{k}"), math(group, "SINE", math(group, "MULTIPLY", angle, float(k))))
        term = math(group, "MULTIPLY", math(group, "ADD", cos_term, sin_term), output(group_in, "Irregularity Scale"))
        factor = math(group, "ADD", factor, term)
    scaled = add(group, "ShaderNodeVectorMath", operation="SCALE")
    feed(group, scaled, Vector=local, Scale=factor)
    outline = vector_math(group, "ADD", center, scaled)

    # clip to the well: points beyond the well's radius are pulled back onto its circle
    well_center = _named(group, "well_center", "FLOAT_VECTOR")
    from_well = vector_math(group, "SUBTRACT", outline, well_center)
    distance = output(vector_math(group, "LENGTH", from_well), "Value")
    shrink = math(group, "MINIMUM", 1.0, math(group, "DIVIDE", output(group_in, "Well Radius"), math(group, "MAXIMUM", distance, 1e-6)))
    clipped = add(group, "ShaderNodeVectorMath", operation="SCALE")
    feed(group, clipped, Vector=from_well, Scale=shrink)
    clipped_xyz = _xyz(group, vector_math(group, "ADD", well_center, clipped))
    height = math(
        group,
        "MULTIPLY_ADD",
        math(group, "ADD", _named(group, "layer"), 1.0),
        output(group_in, "Layer Step"),
        output(group_in, "Floor Height"),
    )
    final = add(group, "ShaderNodeCombineXYZ")
    feed(group, final, X=output(clipped_xyz, "X"), Y=output(clipped_xyz, "Y"), Z=height)
    placed = feed(group, add(group, "GeometryNodeSetPosition"), Geometry=with_rim, Position=final)
    shaded = feed(group, add(group, "GeometryNodeSetMaterial"), Geometry=placed, Material=material)
    link(group, shaded, group_out)
    return group
