"""The plate's plastic body (deck with well holes, walls, outer wall) and its bottom sheet, as geometry nodes."""

from __future__ import annotations

import bpy

from platesynth.render.blender.inside.geometry import FLOOR_MM, _new_group
from platesynth.render.blender.inside.nodes import add, feed, link, math, output

_PLATE_INPUTS = [
    ("Length", "NodeSocketFloat", 127.76),
    ("Width", "NodeSocketFloat", 85.48),
    ("Height", "NodeSocketFloat", 20.0),
    ("Corner Radius", "NodeSocketFloat", 3.0),
    ("Well Radius", "NodeSocketFloat", 11.0),
    ("Wall", "NodeSocketFloat", 1.3),
    ("Floor Height", "NodeSocketFloat", FLOOR_MM),
    ("Deck Thickness", "NodeSocketFloat", 1.5),
    ("Segments", "NodeSocketInt", 128),
]


def _outline(group: bpy.types.NodeTree, group_in: bpy.types.Node) -> bpy.types.Node:
    """The plate's footprint: a rounded rectangle from (0, 0) to (Length, -Width) in the world's xy plane."""
    rectangle = add(group, "GeometryNodeCurvePrimitiveQuadrilateral", mode="RECTANGLE")
    feed(group, rectangle, Width=output(group_in, "Length"), Height=output(group_in, "Width"))
    fillet = add(group, "GeometryNodeFilletCurve")
    feed(group, fillet, Curve=rectangle, Radius=output(group_in, "Corner Radius"), Mode="Poly", Count=6)
    shift = add(group, "ShaderNodeCombineXYZ")
    feed(group, shift, X=math(group, "MULTIPLY", output(group_in, "Length"), 0.5), Y=math(group, "MULTIPLY", output(group_in, "Width"), -0.5))
    return feed(group, add(group, "GeometryNodeTransform"), Geometry=fillet, Translation=shift)


def _extrude(group: bpy.types.NodeTree, mesh: bpy.types.Node, height: object) -> bpy.types.Node:
    up = add(group, "ShaderNodeCombineXYZ")
    feed(group, up, Z=height)
    return feed(group, add(group, "GeometryNodeExtrudeMesh"), Mesh=mesh, Offset=up, Offset_Scale=1.0)


def plate_group(material: bpy.types.Material) -> bpy.types.NodeTree:
    """Geometry nodes making the plate body from the well-centre points: a deck with one hole per well on top,
    a tube-shaped wall around each well and the plate's outer wall. Inputs are the plate's dimensions (mm)."""
    group, group_in, group_out = _new_group("platesynth.plate", _PLATE_INPUTS)
    points = output(group_in, "Geometry")
    outline = _outline(group, group_in)
    height = output(group_in, "Height")
    deck_thickness = output(group_in, "Deck Thickness")

    hole = add(group, "GeometryNodeCurvePrimitiveCircle", mode="RADIUS")
    outer_radius = math(group, "ADD", output(group_in, "Well Radius"), output(group_in, "Wall"))
    feed(group, hole, Resolution=output(group_in, "Segments"), Radius=outer_radius)
    holes = feed(group, add(group, "GeometryNodeRealizeInstances"), Geometry=feed(group, add(group, "GeometryNodeInstanceOnPoints"), Points=points, Instance=hole))
    deck_curves = add(group, "GeometryNodeJoinGeometry")
    link(group, outline, deck_curves)
    link(group, holes, deck_curves)
    deck = feed(group, add(group, "GeometryNodeFillCurve"), Curve=deck_curves, Mode="N-gons")
    deck = _extrude(group, deck, deck_thickness)
    deck_lift = add(group, "ShaderNodeCombineXYZ")
    feed(group, deck_lift, Z=math(group, "SUBTRACT", height, deck_thickness))
    deck = feed(group, add(group, "GeometryNodeTransform"), Geometry=output(deck, "Mesh"), Translation=deck_lift)

    # each well's wall: a tube from the floor to the top, its inner face at the well radius
    wall_path = add(group, "GeometryNodeCurvePrimitiveCircle", mode="RADIUS")
    feed(group, wall_path, Resolution=output(group_in, "Segments"), Radius=math(group, "ADD", output(group_in, "Well Radius"), math(group, "MULTIPLY", output(group_in, "Wall"), 0.5)))
    wall_height = math(group, "SUBTRACT", height, output(group_in, "Floor Height"))
    profile = add(group, "GeometryNodeCurvePrimitiveQuadrilateral", mode="RECTANGLE")
    feed(group, profile, Width=output(group_in, "Wall"), Height=wall_height)
    tube = feed(group, add(group, "GeometryNodeCurveToMesh"), Curve=wall_path, Profile_Curve=profile, Fill_Caps=True)
    tube_lift = add(group, "ShaderNodeCombineXYZ")
    feed(group, tube_lift, Z=math(group, "MULTIPLY_ADD", wall_height, 0.5, output(group_in, "Floor Height")))
    tube = feed(group, add(group, "GeometryNodeTransform"), Geometry=tube, Translation=tube_lift)
    walls = feed(group, add(group, "GeometryNodeRealizeInstances"), Geometry=feed(group, add(group, "GeometryNodeInstanceOnPoints"), Points=points, Instance=tube))

    # the outer wall along the footprint
    side_profile = add(group, "GeometryNodeCurvePrimitiveQuadrilateral", mode="RECTANGLE")
    feed(group, side_profile, Width=1.2, Height=height)
    side = feed(group, add(group, "GeometryNodeCurveToMesh"), Curve=outline, Profile_Curve=side_profile, Fill_Caps=True)
    side_lift = add(group, "ShaderNodeCombineXYZ")
    feed(group, side_lift, Z=math(group, "MULTIPLY", height, 0.5))
    side = feed(group, add(group, "GeometryNodeTransform"), Geometry=side, Translation=side_lift)

    body = add(group, "GeometryNodeJoinGeometry")
    for part in (deck, walls, side):
        link(group, part, body)
    link(group, feed(group, add(group, "GeometryNodeSetMaterial"), Geometry=body, Material=material), group_out)
    return group


def plate_bottom_group(material: bpy.types.Material) -> bpy.types.NodeTree:
    """Geometry nodes making the plate's bottom: one flat sheet over the whole footprint at z = 0."""
    group, group_in, group_out = _new_group("platesynth.plate_bottom", _PLATE_INPUTS)
    sheet = feed(group, add(group, "GeometryNodeFillCurve"), Curve=_outline(group, group_in), Mode="N-gons")
    link(group, feed(group, add(group, "GeometryNodeSetMaterial"), Geometry=sheet, Material=material), group_out)
    return group
