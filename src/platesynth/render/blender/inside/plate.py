"""The plate's plastic as geometry nodes: a deck with one hole per well, tapered well walls, the outer wall.

Heights are in the world frame: well floors at ``z = 0`` (the plate's bottom ``Floor Thickness`` below), the
walls' top edge at ``z = Well Depth`` with inner radius ``Well Radius + Taper``. The plastic under the floors is
folded into the monolayer's material. The deck, the sheet that carries the plastic's tint, its labels and ribs
around the wells, lies at ``Deck Height`` with one hole of ``Well Radius`` per well: the renderer puts it just
behind the floors, so that each ray crosses the plastic once, as the raster renderer draws it (a deck at the
walls' top edge would tint the floors a second time in a crescent where parallax puts it behind them).
"""

from __future__ import annotations

from typing import Any

import bpy

from platesynth.render.blender.inside.geometry import new_group
from platesynth.render.blender.inside.nodes import add, feed, link, math, output

PLATE_INPUTS = [
    ("Length", "NodeSocketFloat", 127.76),
    ("Width", "NodeSocketFloat", 85.48),
    ("Height", "NodeSocketFloat", 20.0),
    ("Corner Radius", "NodeSocketFloat", 3.0),
    ("Well Radius", "NodeSocketFloat", 11.0),
    ("Taper", "NodeSocketFloat", 0.3),
    ("Wall", "NodeSocketFloat", 1.3),
    ("Well Depth", "NodeSocketFloat", 17.5),
    ("Floor Thickness", "NodeSocketFloat", 1.0),
    ("Deck Height", "NodeSocketFloat", 17.5),
    ("Segments", "NodeSocketInt", 128),
    ("Walls", "NodeSocketBool", False),
]
"""The plate groups' modifier inputs: name, socket type, default (mm)."""


def _outline(group: bpy.types.NodeTree, group_in: bpy.types.Node) -> bpy.types.Node:
    """The plate's footprint: a rounded rectangle from (0, 0) to (Length, -Width) in the xy plane."""
    rectangle = add(group, "GeometryNodeCurvePrimitiveQuadrilateral", mode="RECTANGLE")
    feed(group, rectangle, Width=output(group_in, "Length"), Height=output(group_in, "Width"))
    fillet = add(group, "GeometryNodeFilletCurve")
    feed(group, fillet, Curve=rectangle, Radius=output(group_in, "Corner Radius"), Mode="Poly", Count=6)
    return _moved(group, fillet, math(group, "MULTIPLY", output(group_in, "Length"), 0.5), math(group, "MULTIPLY", output(group_in, "Width"), -0.5), 0.0)


def _moved(group: bpy.types.NodeTree, geometry: Any, x: Any, y: Any, z: Any) -> bpy.types.Node:
    offset = feed(group, add(group, "ShaderNodeCombineXYZ"), X=x, Y=y, Z=z)
    return feed(group, add(group, "GeometryNodeTransform"), Geometry=geometry, Translation=offset)


def _on_points(group: bpy.types.NodeTree, points: Any, instance: Any) -> bpy.types.Node:
    instances = feed(group, add(group, "GeometryNodeInstanceOnPoints"), Points=points, Instance=instance)
    return feed(group, add(group, "GeometryNodeRealizeInstances"), Geometry=instances)


def plate_group(material: bpy.types.Material, side_material: bpy.types.Material) -> bpy.types.NodeTree:
    """Geometry nodes making the plate body from the well-centre points (see :data:`PLATE_INPUTS`): the deck
    (``material``) and the outer wall (``side_material``), or with ``Walls`` on the wells' walls (``material``)."""
    group, group_in, group_out = new_group("platesynth.plate", PLATE_INPUTS)
    points = output(group_in, "Geometry")
    outline = _outline(group, group_in)
    depth = output(group_in, "Well Depth")
    top_radius = math(group, "ADD", output(group_in, "Well Radius"), output(group_in, "Taper"))

    # the deck: the footprint with one hole per well floor
    hole = add(group, "GeometryNodeCurvePrimitiveCircle", mode="RADIUS")
    feed(group, hole, Resolution=output(group_in, "Segments"), Radius=output(group_in, "Well Radius"))
    deck_curves = add(group, "GeometryNodeJoinGeometry")
    link(group, outline, deck_curves)
    link(group, _on_points(group, points, hole), deck_curves)
    deck = feed(group, add(group, "GeometryNodeFillCurve"), Curve=deck_curves, Mode="N-gons")
    deck = _moved(group, deck, 0.0, 0.0, output(group_in, "Deck Height"))  # one sheet: seen through, a second face would only cost time

    # the wells' walls: open cones from the floor's radius up to the top edge's, a hair short of the floor and
    # the deck (edges shared by two surfaces can trap a ray passing exactly there: black pixels)
    wall = add(group, "GeometryNodeMeshCone", fill_type="NONE")
    gap = 0.01
    feed(group, wall, Vertices=output(group_in, "Segments"), Radius_Top=top_radius, Radius_Bottom=output(group_in, "Well Radius"), Depth=math(group, "SUBTRACT", depth, 2 * gap))
    wall = _moved(group, output(wall, "Mesh"), 0.0, 0.0, gap)  # the cone's base is at its origin
    walls = _on_points(group, points, wall)

    # the outer wall along the footprint, from the bottom sheet to the plate's full height
    side_profile = add(group, "GeometryNodeCurvePrimitiveQuadrilateral", mode="RECTANGLE")
    feed(group, side_profile, Width=1.2, Height=output(group_in, "Height"))
    side = feed(group, add(group, "GeometryNodeCurveToMesh"), Curve=outline, Profile_Curve=side_profile, Fill_Caps=True)
    side_z = math(group, "SUBTRACT", math(group, "MULTIPLY", output(group_in, "Height"), 0.5), output(group_in, "Floor Thickness"))
    side = _moved(group, side, 0.0, 0.0, side_z)

    body = add(group, "GeometryNodeJoinGeometry")
    link(group, feed(group, add(group, "GeometryNodeSetMaterial"), Geometry=deck, Material=material), body)
    link(group, feed(group, add(group, "GeometryNodeSetMaterial"), Geometry=side, Material=side_material), body)
    walls = feed(group, add(group, "GeometryNodeSetMaterial"), Geometry=walls, Material=material)
    part = feed(group, add(group, "GeometryNodeSwitch", input_type="GEOMETRY"), Switch=output(group_in, "Walls"), **{"False": body, "True": walls})
    link(group, part, group_out)
    return group

