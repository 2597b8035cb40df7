"""The plate, its wells and the plaques as geometry-node groups fed by point clouds.

World units are millimetres. Plate coordinates (x right, y down, seen from above, origin at the A1 corner)
map to Blender's world as ``(x, -y, z)`` with ``z`` towards the plate's lid; the cell monolayer lies on the well
floors at ``z = 0``, the plane the raster renderer's homography maps.

Each group's parameters are modifier inputs (named sockets of the group's interface), so a saved .blend can be
re-driven by people or other tools; per-well and per-plaque values are attributes of the point clouds.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import bpy
import numpy as np

from platesynth.render.blender.inside.nodes import add, feed, link, math, output, vector_math

LAYER_STEP_MM = 1e-4
"""Distance between stacked plaques (later plaques lie nearer the camera): small enough to add no visible
parallax, large enough for Cycles to tell the surfaces apart."""

_ATTRIBUTE_TYPES = {"INT": ("INT", "value"), "FLOAT": ("FLOAT", "value"), "FLOAT_VECTOR": ("FLOAT_VECTOR", "vector")}


def point_cloud(name: str, positions: np.ndarray, attributes: Mapping[str, np.ndarray]) -> bpy.types.Object:
    """A mesh object of loose vertices at ``positions`` (n, 3) carrying point attributes.

    Integer arrays become INT attributes, (n,) floats FLOAT, (n, 3) floats FLOAT_VECTOR.
    """
    mesh = bpy.data.meshes.new(name)
    positions = np.asarray(positions, dtype=np.float32).reshape(-1, 3)
    mesh.vertices.add(len(positions))
    mesh.vertices.foreach_set("co", positions.ravel())
    _set_point_attributes(mesh, attributes)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _set_point_attributes(mesh: bpy.types.Mesh, attributes: Mapping[str, np.ndarray]) -> None:
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


def new_group(name: str, inputs: Sequence[tuple[str, str, Any]]) -> tuple[bpy.types.NodeTree, bpy.types.Node, bpy.types.Node]:
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
    """Geometry nodes turning well-centre points into floor discs (one per well), passing on the points'
    attributes (``well_id`` for the mask pass).

    Inputs: ``Well Radius`` (mm), ``Floor Height`` (mm), ``Segments``.
    """
    group, group_in, group_out = new_group(
        "platesynth.wells",
        [("Well Radius", "NodeSocketFloat", 11.0), ("Floor Height", "NodeSocketFloat", 0.0), ("Segments", "NodeSocketInt", 128)],
    )
    disc = add(group, "GeometryNodeMeshCircle", fill_type="NGON")
    feed(group, disc, Vertices=output(group_in, "Segments"), Radius=output(group_in, "Well Radius"))
    instances = feed(group, add(group, "GeometryNodeInstanceOnPoints"), Points=output(group_in, "Geometry"), Instance=disc)
    realized = feed(group, add(group, "GeometryNodeRealizeInstances"), Geometry=instances)
    lift = add(group, "ShaderNodeCombineXYZ")
    feed(group, lift, Z=output(group_in, "Floor Height"))
    placed = feed(group, add(group, "GeometryNodeSetPosition"), Geometry=realized, Offset=lift)
    shaded = feed(group, add(group, "GeometryNodeSetMaterial"), Geometry=placed, Material=material)
    link(group, shaded, group_out)
    return group


def plaques_group(material: bpy.types.Material, harmonics: int) -> bpy.types.NodeTree:
    """Geometry nodes turning plaque-centre points into irregular discs clipped to their wells (the mask pass).

    Each point carries ``radius``, ``layer`` (drawing order), ``well_center`` and the outline coefficients
    ``fourier_a{k}``/``fourier_b{k}`` for ``k = 2 .. harmonics + 1``; the outline is
    ``r(t) = radius * (1 + sum_k a_k cos(k t) + b_k sin(k t))`` with ``t`` the angle in plate coordinates
    (y down), the outline the raster renderer's ids follow. Points beyond the well's radius are pulled back onto
    its circle. Discs are stacked ``Layer Step`` apart (negative where the camera looks from below), starting
    ``Layer Offset`` steps above ``Floor Height``, in the order of ``layer``: later plaques on top.
    """
    group, group_in, group_out = new_group(
        "platesynth.plaques",
        [
            ("Segments", "NodeSocketInt", 48),
            ("Well Radius", "NodeSocketFloat", 11.0),
            ("Floor Height", "NodeSocketFloat", 0.0),
            ("Layer Step", "NodeSocketFloat", LAYER_STEP_MM),
            ("Layer Offset", "NodeSocketFloat", 0.0),
            ("Radius Scale", "NodeSocketFloat", 1.0),
            ("Irregularity Scale", "NodeSocketFloat", 1.0),
        ],
    )
    position = output(add(group, "GeometryNodeInputPosition"), "Position")
    points = _store(group, output(group_in, "Geometry"), "center", position, "FLOAT_VECTOR")
    disc = add(group, "GeometryNodeMeshCircle", fill_type="TRIANGLE_FAN")
    feed(group, disc, Vertices=output(group_in, "Segments"), Radius=1.0)
    radius = math(group, "MULTIPLY", _named(group, "radius"), output(group_in, "Radius Scale"))
    instances = feed(group, add(group, "GeometryNodeInstanceOnPoints"), Points=points, Instance=disc, Scale=radius)
    realized = feed(group, add(group, "GeometryNodeRealizeInstances"), Geometry=instances)

    # the outline: scale each rim point's offset from the centre by the Fourier factor at its angle
    center = _named(group, "center", "FLOAT_VECTOR")
    local = vector_math(group, "SUBTRACT", position, center)
    local_xyz = _xyz(group, local)
    angle = math(group, "ARCTAN2", math(group, "MULTIPLY", output(local_xyz, "Y"), -1.0), output(local_xyz, "X"))
    factor: Any = 1.0
    for k in range(2, harmonics + 2):
        kt = math(group, "MULTIPLY", angle, float(k))
        term = math(group, "MULTIPLY", _named(group, f"fourier_a{k}"), math(group, "COSINE", kt))
        term = math(group, "MULTIPLY_ADD", _named(group, f"fourier_b{k}"), math(group, "SINE", kt), term)
        factor = math(group, "MULTIPLY_ADD", term, output(group_in, "Irregularity Scale"), factor)
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
    layer = math(group, "ADD", math(group, "ADD", _named(group, "layer"), output(group_in, "Layer Offset")), 1.0)
    height = math(group, "MULTIPLY_ADD", layer, output(group_in, "Layer Step"), output(group_in, "Floor Height"))
    final = feed(group, add(group, "ShaderNodeCombineXYZ"), X=output(clipped_xyz, "X"), Y=output(clipped_xyz, "Y"), Z=height)
    placed = feed(group, add(group, "GeometryNodeSetPosition"), Geometry=realized, Position=final)
    shaded = feed(group, add(group, "GeometryNodeSetMaterial"), Geometry=placed, Material=material)
    link(group, shaded, group_out)
    return group


def strips(name: str, polylines: Sequence[np.ndarray], half_widths: Sequence[float], z: float, attributes: Mapping[str, np.ndarray]) -> bpy.types.Object:
    """One mesh of flat strips (scratches, specks, pen strokes) along world-xy polylines, each ``2 * half_width``
    wide with square ends extended by ``half_width``; ``attributes`` hold one value (or vector) per polyline."""
    vertices: list[np.ndarray] = []
    faces: list[tuple[int, int, int, int]] = []
    owner: list[int] = []
    for index, (line, half) in enumerate(zip(polylines, half_widths)):
        line = np.asarray(line, dtype=np.float64).reshape(-1, 2)
        if len(line) == 1:
            line = np.vstack([line, line + [1e-3, 0.0]])
        tangents = np.gradient(line, axis=0)
        tangents /= np.maximum(np.linalg.norm(tangents, axis=1, keepdims=True), 1e-9)
        line = line.copy()
        line[0] -= tangents[0] * half
        line[-1] += tangents[-1] * half
        normals = np.stack([-tangents[:, 1], tangents[:, 0]], axis=1) * half
        start = sum(len(v) for v in vertices)
        vertices.append(np.concatenate([line + normals, line - normals]))
        n = len(line)
        faces += [(start + i, start + i + 1, start + n + i + 1, start + n + i) for i in range(n - 1)]
        owner += [index] * (2 * n)
    mesh = bpy.data.meshes.new(name)
    points = np.concatenate(vertices) if vertices else np.zeros((0, 2))
    mesh.from_pydata([(x, y, z) for x, y in points], [], faces)
    _set_point_attributes(mesh, {key: np.asarray(values)[owner] for key, values in attributes.items()} if owner else {})
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def discs(name: str, centres: np.ndarray, radii: Sequence[float], z: float, attributes: Mapping[str, np.ndarray], segments: int = 32) -> bpy.types.Object:
    """One mesh of flat discs (blots) at world-xy ``centres``; ``attributes`` hold one value per disc."""
    angles = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    vertices = [np.asarray(c) + r * ring for c, r in zip(centres, radii)]
    faces = [tuple(range(i * segments, (i + 1) * segments)) for i in range(len(vertices))]
    mesh = bpy.data.meshes.new(name)
    points = np.concatenate(vertices) if vertices else np.zeros((0, 2))
    mesh.from_pydata([(x, y, z) for x, y in points], [], faces)
    owner = np.repeat(np.arange(len(vertices)), segments)
    _set_point_attributes(mesh, {key: np.asarray(values)[owner] for key, values in attributes.items()} if len(owner) else {})
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def annuli(
    name: str, centres: np.ndarray, inner: Sequence[float], outer: Sequence[float], z: Sequence[float], attributes: Mapping[str, np.ndarray], segments: int = 128
) -> bpy.types.Object:
    """One mesh of flat rings (well rims, wall outlines) around world-xy ``centres`` at heights ``z``;
    ``attributes`` hold one value (or vector) per ring."""
    angles = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    vertices, faces = [], []
    for index, (centre, r_in, r_out, height) in enumerate(zip(centres, inner, outer, z)):
        start = index * 2 * segments
        for radius in (r_in, r_out):
            vertices += [(x, y, height) for x, y in np.asarray(centre) + radius * ring]
        faces += [(start + i, start + (i + 1) % segments, start + segments + (i + 1) % segments, start + segments + i) for i in range(segments)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices, [], faces)
    owner = np.repeat(np.arange(len(centres)), 2 * segments)
    _set_point_attributes(mesh, {key: np.asarray(values)[owner] for key, values in attributes.items()} if len(owner) else {})
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj
