"""Build the whole Blender scene from a scene description: plate, wells, plaques, artifacts, light box or desk,
camera and the view layer's AOVs.

The description is ``{"scene": <Scene as JSON>, "view": {...}, "textures": {...}}`` (made on the host by
:func:`platesynth.render.blender.describe.describe_scene`). The world frame is the plate frame ``(x, -y, z)``
in millimetres with the well floors at ``z = 0``. Everything is seen by transmission: the light box (or desk)
glows, and the plastic, the well floors (the appearance model's texture: stain, plaques, lysis, scratches and
specks), ink and blots are thin films that multiply the light passing them, stacked along the camera's axis. The
plaques are geometry too, for the mask pass only, so that its AOV index masks stay exact.

Objects carry the custom property ``platesynth_pass``: ``"both"`` (image and mask pass), ``"image"`` (image
pass only) or ``"mask"``; :func:`show_pass` hides the others.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import bpy
import numpy as np
from mathutils import Matrix

from platesynth.render.blender.inside import geometry, materials, plate
from platesynth.render.look import (
    BLOT_REACH,
    FLOOR_TRANSMITTANCE,
    FRAME_BRIGHTNESS,
    OUTLINE_WEIGHTS,
    OUTLINE_WIDTH_MM,
    RULER_WIDTH_MM,
    TOP_EDGE_OFFSET_MM,
    WALL_HIGHLIGHT_PLACES,
    WALL_LINE_PLACES,
    WALL_LINE_WOBBLE_MM,
)

PASS_PROPERTY = "platesynth_pass"


def reset() -> None:
    """Start from an empty file (the process stays warm: no restart between images)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)


def _tag(obj: bpy.types.Object, which: str) -> bpy.types.Object:
    obj[PASS_PROPERTY] = which
    return obj


def _world_xy(points_mm: Sequence[Sequence[float]]) -> np.ndarray:
    """Plate millimetres (x right, y down) to world xy (y up)."""
    points = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    return np.stack([points[:, 0], -points[:, 1]], axis=1)


def _with_z(xy: np.ndarray, z: float) -> np.ndarray:
    return np.column_stack([xy, np.full(len(xy), z)])


def build(description: Mapping[str, Any]) -> dict[str, bpy.types.Object]:
    """Create every object of the scene in the current (empty) Blender file; return the main ones by name."""
    scene_data, view = description["scene"], description["view"]
    textures = {name: _plate_texture(name, entry) for name, entry in description["textures"].items()}
    plate_data = scene_data["plate"]
    well_radius = float(plate_data["well_radius_mm"])
    toward_camera = float(view["toward_camera"])
    objects: dict[str, bpy.types.Object] = {}

    look = scene_data["plate_look"]
    # the plate's plastic tints and dims all light passing the plate once: in the body's material where the
    # camera looks through the deck and walls, in the floors' inside the wells (no separate bottom sheet:
    # one transparent surface less for every ray)
    plastic = (tuple(look["tint_rgb"]), float(look["transmittance"]))

    wells = scene_data["wells"]
    well_attributes = _well_attributes(wells)
    well_points = geometry.point_cloud("platesynth.wells", _with_z(_world_xy([w["center_mm"] for w in wells]), 0.0), well_attributes)
    # seen from below, the floor past the walls' top edge (its plane a well's depth beyond the floors) is veiled
    crescent = {"veil": float(look["crescent_veil"]) if toward_camera < 0 else 0.0,
                "height": float(plate_data["well_depth_mm"]), "radius": well_radius + TOP_EDGE_OFFSET_MM,
                "smear": float(look["top_edge_blur_mm"])}
    floors = materials.floor_material(textures["floor"], plastic[0], FLOOR_TRANSMITTANCE, crescent)
    geometry.add_modifier(well_points, geometry.wells_group(floors), {"Well Radius": well_radius})
    objects["wells"] = _tag(well_points, "both")

    plate_inputs = {
        "Length": plate_data["length_mm"],
        "Width": plate_data["width_mm"],
        "Height": plate_data["height_mm"],
        "Corner Radius": plate_data["corner_radius_mm"],
        "Well Radius": well_radius,
        "Wall": plate_data["wall_mm"],
        "Well Depth": plate_data["well_depth_mm"],
        "Floor Thickness": view["floor_thickness_mm"],
        # behind the floors' films, the rims' and the marks' (see :mod:`.plate`)
        "Deck Height": -toward_camera * 0.45,
    }
    relief = (textures["relief"], float(look["label_strength"]))
    body_material = materials.plastic_material("platesynth.plastic", *plastic, float(look["rim_darkness"]), relief, plate_data)
    body = geometry.point_cloud("platesynth.plate_body", _with_z(_world_xy([w["center_mm"] for w in wells]), 0.0), {})
    # the deck tints the light once; the outer wall's faces only darken where they are seen edge-on
    side_material = materials.plastic_material("platesynth.plate_side", (1.0, 1.0, 1.0), 1.0, float(look["rim_darkness"]))
    plate_group = plate.plate_group(body_material, side_material)
    geometry.add_modifier(body, plate_group, plate_inputs)
    objects["plate_body"] = _tag(body, "both")
    # the walls hide parts of the floors from a camera above the plate: they matter for the masks; in the image
    # a ray grazing a wall's facets can be caught between them (black pixels), and the raster renderer draws the
    # floor there too
    walls = bpy.data.objects.new("platesynth.plate_walls", body.data)
    bpy.context.scene.collection.objects.link(walls)
    geometry.add_modifier(walls, plate_group, plate_inputs | {"Walls": True})
    objects["plate_walls"] = _tag(walls, "mask")

    _rims(scene_data, view, wells, objects)

    # the plaques' outlines, later plaques on top: the mask pass only (the image shows them in the floors' texture)
    plaques = scene_data["plaques"]
    harmonics = max((len(p["fourier"]) for p in plaques), default=0)
    outlines = geometry.point_cloud("platesynth.plaques", _with_z(_world_xy([p["center_mm"] for p in plaques]), 0.0), _plaque_attributes(plaques, wells, harmonics))
    step = toward_camera * geometry.LAYER_STEP_MM
    geometry.add_modifier(outlines, geometry.plaques_group(materials.mask_material(), harmonics), {"Well Radius": well_radius, "Layer Step": step})
    objects["plaques"] = _tag(outlines, "mask")

    _marker_and_blots(scene_data, view, textures["unevenness"], objects)
    _backdrop(scene_data, view, objects)
    _camera(view)
    world = bpy.data.worlds.new("platesynth.world")
    world.color = (0.0, 0.0, 0.0)
    bpy.context.scene.world = world
    for name in materials.MASK_AOVS:
        aov = bpy.context.scene.view_layers[0].aovs.add()
        aov.name, aov.type = name, "VALUE"
    return objects


def _plate_texture(name: str, entry: Mapping[str, Any]) -> materials.PlateTexture:
    """A texture of the description (``{"path": .npy, "texels_per_mm": k}``, row 0 at plate y = 0) as a packed,
    non-colour float image whose top row is the array's row 0."""
    values = np.load(entry["path"], allow_pickle=False)[::-1]
    channels = values[:, :, None] if values.ndim == 2 else values
    image = bpy.data.images.new(f"platesynth.{name}", values.shape[1], values.shape[0], float_buffer=True, is_data=True)
    rgba = np.ones((*values.shape[:2], 4), dtype=np.float32)
    rgba[..., :3] = channels
    image.pixels.foreach_set(rgba.ravel())
    image.pack()
    return materials.PlateTexture(image, float(entry["texels_per_mm"]))


def _rims(
    scene_data: Mapping[str, Any],
    view: Mapping[str, Any],
    wells: Sequence[Mapping[str, Any]],
    objects: dict[str, bpy.types.Object],
) -> None:
    """What the raster renderer draws of the walls, as films (image pass only): a band over the wall's thickness
    (``plate_look.wall_band`` brighter), and thin dark outlines at the wall's foot (radius, radius + wall) and top edge
    (``TOP_EDGE_OFFSET_MM`` further out, + wall) at their heights. The foot lies ``plate_look.floor_height_mm``
    below the floors; where its opening shows no floor, the inside of the wall below the floor takes the band's
    brightness (a disc at the foot, hidden where the ray passes a floor). Seen from below, all but the plate look's
    ``top_edge_through_floor`` of the top edge's outlines is hidden where the ray has passed a well's floor (the
    raster renderer's ``behind_layer``). The band and the disc take their well's tint (``view["wall_tints"]``) and
    its brightness change around the well (``view["wall_sheens"]``). With ``plate_look.wall_lines`` or
    ``wall_highlights``, thin dark lines and bright highlights lie across the band at the foot
    (``WALL_LINE_PLACES``), each wandering around the well in two waves (``view["wall_line_phases"]``)."""
    plate_data = scene_data["plate"]
    radius, wall, depth = (float(plate_data[k]) for k in ("well_radius_mm", "wall_mm", "well_depth_mm"))
    foot = -float(scene_data["plate_look"]["floor_height_mm"])
    darkness = float(scene_data["plate_look"]["rim_darkness"])
    from_below = float(view["toward_camera"]) < 0
    hidden_by_floor = (1.0 - float(scene_data["plate_look"]["top_edge_through_floor"])) if from_below else 0.0
    centres = _world_xy([w["center_mm"] for w in wells])
    line = OUTLINE_WIDTH_MM
    foot_inner, foot_outer, top_inner, top_outer = OUTLINE_WEIGHTS
    top = radius + TOP_EDGE_OFFSET_MM
    # just behind the floors' film, each ring at its own height: overlapping films must not coincide
    step = -float(view["toward_camera"]) * 0.05
    band = 1.0 + float(scene_data["plate_look"]["wall_band"])
    blur = float(scene_data["plate_look"]["top_edge_blur_mm"])  # the top edge is out of focus: smeared, as faint in all
    rings = [  # middle radius, half width, smeared over, height, colour, share hidden behind the floors, tinted
        (radius + wall / 2, wall / 2, 0.0, foot + step, band, 0.0, True),
        (radius, line / 2, 0.0, foot + 2 * step, 1.0 - foot_inner * darkness, 0.0, False),
        (radius + wall, line / 2, 0.0, foot + 3 * step, 1.0 - foot_outer * darkness, 0.0, False),
        (top, line / 2, blur, depth - 0.05, 1.0 - top_inner * darkness, hidden_by_floor, False),
        (top + wall, line / 2, blur, depth - 0.05, 1.0 - top_outer * darkness, hidden_by_floor, False),
    ]
    if foot < 0.0:  # the floor hides the disc's middle
        rings.append((0.75 * radius, 0.25 * radius, 0.0, foot + step, band, 1.0, True))
    n = len(centres)
    wobbles = [np.zeros((n, 2))] * len(rings)  # each ring's wobble around the well: (cos, sin) of its phase, scaled
    lines, highlights = (float(scene_data["plate_look"][k]) for k in ("wall_lines", "wall_highlights"))
    if lines > 0.0 or highlights > 0.0:  # the lines a wall refracts across its band, and highlights between them
        phases = np.asarray(view["wall_line_phases"], dtype=np.float64)
        for j, (place, highlight) in enumerate(zip(WALL_LINE_PLACES, WALL_HIGHLIGHT_PLACES, strict=True)):
            # about world angles (y flipped: the second harmonic's sine negated)
            wobble = WALL_LINE_WOBBLE_MM * np.column_stack([np.cos(phases[:, j]), -np.sin(phases[:, j])])
            for share, ink in ((place, 1.0 - lines * darkness), (highlight, 1.0 + highlights)):
                rings.append((radius + share * wall, line / 2, 0.0, foot + (len(rings) + 1) * step, ink, 0.0, False))
                wobbles.append(wobble)
    tints = np.asarray(view["wall_tints"], dtype=np.float64)
    inks = np.concatenate([r[4] * (tints if r[6] else np.ones((n, 3))) for r in rings])
    # the sheen's Fourier coefficients, relative to the band's ink, about world angles (y flipped: sines negated)
    sheens = np.asarray(view["wall_sheens"], dtype=np.float64).reshape(n, 3, 2) / band * np.array([1.0, -1.0])
    cosines = np.concatenate([sheens[:, :, 0] * r[6] for r in rings])
    sines = np.concatenate([sheens[:, :, 1] * r[6] for r in rings])
    reach = np.repeat([r[1] + r[2] / 2 for r in rings], n) + np.linalg.norm(np.concatenate(wobbles), axis=1)
    rims = geometry.annuli(
        "platesynth.rims",
        np.concatenate([centres] * len(rings)),
        np.repeat([r[0] for r in rings], n) - reach,
        np.repeat([r[0] for r in rings], n) + reach,
        np.repeat([r[3] for r in rings], n),
        {
            "ink": inks,
            "rim_center": _with_z(np.concatenate([centres] * len(rings)), 0.0),
            "rim_hidden_inside": np.repeat([r[5] for r in rings], n),
            "ring_radius": np.repeat([r[0] for r in rings], n),
            "ring_half_width": np.repeat([r[1] for r in rings], n),
            "ring_smear": np.repeat([r[2] for r in rings], n),
            "sheen_cosines": cosines,
            "sheen_sines": sines,
            "ring_wobble": _with_z(np.concatenate(wobbles), 0.0),
        },
    )
    rims.data.materials.append(materials.rim_material(radius))
    objects["rims"] = _tag(rims, "image")


def _well_attributes(wells: Sequence[Mapping[str, Any]]) -> dict[str, np.ndarray]:
    """The wells' point attributes: their ids (for the mask pass) and centres."""
    return {
        "well_id": np.array([w["id"] for w in wells], dtype=np.int32),
        "well_center": _with_z(_world_xy([w["center_mm"] for w in wells]), 0.0),
    }


def _plaque_attributes(plaques: Sequence[Mapping[str, Any]], wells: Sequence[Mapping[str, Any]], harmonics: int) -> dict[str, np.ndarray]:
    """The plaques' point attributes: ids (the plaque's and, for the mask pass, its well's), radii, drawing
    order, their well's centre and outline harmonics."""
    centre_of_well = {w["id"]: w["center_mm"] for w in wells}
    attributes: dict[str, np.ndarray] = {
        "plaque_id": np.array([p["id"] for p in plaques], dtype=np.int32),
        "well_id": np.array([p["well"] for p in plaques], dtype=np.int32),
        "radius": np.array([p["radius_mm"] for p in plaques], dtype=np.float64),
        "layer": np.arange(len(plaques), dtype=np.float64),
        "well_center": _with_z(_world_xy([centre_of_well[p["well"]] for p in plaques]), 0.0),
    }
    for k in range(harmonics):
        for which, name in ((0, "a"), (1, "b")):
            attributes[f"fourier_{name}{k + 2}"] = np.array([p["fourier"][k][which] if k < len(p["fourier"]) else 0.0 for p in plaques])
    return attributes


def _marker_and_blots(
    scene_data: Mapping[str, Any], view: Mapping[str, Any], unevenness: materials.PlateTexture, objects: dict[str, bpy.types.Object]
) -> None:
    """Marker ink and blots on the plastic (image pass only)."""
    artifacts = scene_data["artifacts"]
    away = -float(view["toward_camera"])
    strokes = artifacts["marker"]
    if strokes:
        colours = np.array(view["marker_linear_rgb"], dtype=np.float64).reshape(-1, 3)
        pen = geometry.strips("platesynth.marker", [_world_xy(s["points_mm"]) for s in strokes], [0.5 * s["width_mm"] for s in strokes], away * 0.6, {"ink": colours})
        pen.data.materials.append(materials.ink_material())
        objects["marker"] = _tag(pen, "image")
    blots = artifacts["blots"]
    if blots:
        centres = _world_xy([b["center_mm"] for b in blots])
        radii = np.array([b["radius_mm"] for b in blots], dtype=np.float64)
        attributes = {
            "blot_center": _with_z(centres, 0.0),
            "blot_radius": radii,
            "blot_rgb": np.array([b["color_rgb"] for b in blots], dtype=np.float64).reshape(-1, 3),
            "blot_opacity": np.array([b["opacity"] for b in blots], dtype=np.float64),
        }
        smudges = geometry.discs("platesynth.blots", centres, BLOT_REACH * radii, away * 0.65, attributes)
        smudges.data.materials.append(materials.blot_material(unevenness))
        objects["blots"] = _tag(smudges, "image")


def _on_support(view: Mapping[str, Any], image_xy: np.ndarray, depth: float) -> np.ndarray:
    """World points, ``depth`` mm behind the support plane, that the camera sees where the raster renderer draws
    the image-aligned plate-plane points ``image_xy`` (mm from the plate centre, before the camera's rotation)."""
    plate_centre = np.asarray(view["plate_center_world"][:2])
    world = np.column_stack([plate_centre[0] + view["mirror"] * image_xy[:, 0], plate_centre[1] - image_xy[:, 1], np.zeros(len(image_xy))])
    camera = np.asarray(view["camera_matrix"])[:3, 3]
    z = float(view["support_z"]) - float(view["toward_camera"]) * depth
    return camera + (world - camera) * ((z - camera[2]) / (0.0 - camera[2]))


def _quad(
    name: str,
    view: Mapping[str, Any],
    box: tuple[float, float, float, float],
    depth: float,
    material: bpy.types.Material,
    uv_affine: tuple[float, float, float, float, float, float] | None = None,
) -> bpy.types.Object:
    """A rectangle ``(x0, y0, x1, y1)`` of the image-aligned backdrop, ``depth`` mm behind the support plane.

    ``uv_affine`` = ``(a, b, c, d, e, f)`` gives the UV map ``(a x + b y + c, d x + e y + f)``."""
    x0, y0, x1, y1 = box
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)
    points = _on_support(view, corners, depth)
    mesh = bpy.data.meshes.new(name)
    face = (0, 1, 2, 3) if view["mirror"] > 0 else (3, 2, 1, 0)  # keep the face's normal towards the camera
    mesh.from_pydata([tuple(p) for p in points], [], [face])
    if uv_affine is not None:
        a, b, c, d, e, f = uv_affine
        layer = mesh.uv_layers.new(name="UVMap")
        for loop in mesh.loops:
            x, y = corners[loop.vertex_index]
            layer.data[loop.index].uv = (a * x + b * y + c, d * x + e * y + f)
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return _tag(obj, "image")


def _backdrop(scene_data: Mapping[str, Any], view: Mapping[str, Any], objects: dict[str, bpy.types.Object]) -> None:
    """The glowing light-box panel, its frame, the ruler and the desk around them (or just a desk)."""
    background = scene_data["background"]
    seed = float(scene_data["seed"] % 997)
    desk_rgb = tuple(view["desk_linear_rgb"])
    far = 2000.0
    if background["kind"] == "desk":
        desk = materials.glow_material("platesynth.desk", desk_rgb, float(background["brightness"]), float(background["texture"]), seed)
        objects["desk"] = _quad("platesynth.desk", view, (-far, -far, far, far), 0.5, desk)
        return
    left, top, right, bottom = (float(v) for v in background["panel_mm"])
    frame_mm = float(background["frame_mm"])
    panel = materials.glow_material("platesynth.lightbox_panel", (1.0, 1.0, 1.0), float(background["brightness"]), panel=(left, top, right, bottom))
    # UV = the box's own frame (mm from the plate's centre along the image axes), for the glow's falloff
    objects["panel"] = _quad("platesynth.lightbox_panel", view, (left, top, right, bottom), 0.5, panel, (1.0, 0.0, 0.0, 0.0, 1.0, 0.0))
    frame = materials.glow_material("platesynth.lightbox_frame", (1.0, 1.0, 1.0), FRAME_BRIGHTNESS)
    objects["frame"] = _quad("platesynth.lightbox_frame", view, (left - frame_mm, top - frame_mm, right + frame_mm, bottom + frame_mm), 1.0, frame)
    desk = materials.glow_material("platesynth.desk", desk_rgb, 1.0, float(background["texture"]), seed)
    objects["desk"] = _quad("platesynth.desk", view, (-far, -far, far, far), 2.0, desk)
    if background["ruler"]:
        ruler = materials.ruler_material()
        width = RULER_WIDTH_MM
        # UV = (along, across): along the panel's left edge from its bottom end, along its bottom edge from its
        # left end; across from the ruler's inner edge
        objects["ruler_left"] = _quad("platesynth.ruler_left", view, (left - width, top, left, bottom + width), 0.25, ruler, (0.0, 1.0, -bottom, -1.0, 0.0, left))
        objects["ruler_bottom"] = _quad("platesynth.ruler_bottom", view, (left, bottom, right, bottom + width), 0.25, ruler, (1.0, 0.0, -left, 0.0, 1.0, -bottom))


def _camera(view: Mapping[str, Any]) -> None:
    data = bpy.data.cameras.new("platesynth.camera")
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = float(view["sensor_width_mm"])
    data.lens = float(view["lens_mm"])
    data.shift_x, data.shift_y = float(view["shift_x"]), float(view["shift_y"])
    data.clip_start, data.clip_end = 1.0, 1e5
    camera = bpy.data.objects.new("platesynth.camera", data)
    camera.matrix_world = Matrix(view["camera_matrix"])
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera


def show_pass(which: str) -> None:
    """Show the objects of the ``"image"`` or ``"mask"`` pass to the camera and hide the others (by ray
    visibility: the geometry stays loaded between the passes)."""
    for obj in bpy.context.scene.objects:
        if obj.type != "CAMERA":
            obj.visible_camera = obj.get(PASS_PROPERTY, "both") in ("both", which)

