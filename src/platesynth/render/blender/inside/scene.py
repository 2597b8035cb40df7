"""Build the whole Blender scene from a scene description: plate, wells, plaques, artifacts, background, light,
camera and view-layer AOVs.

The description is ``{"scene": <Scene as JSON>, "view": {...}}`` (see
:func:`platesynth.render.blender.describe.describe_scene`). Objects are tagged with the custom property
``platesynth_pass``: ``"both"`` (drawn in the image and the mask pass), ``"image"`` (image only: lights,
background, artifacts, the plate's bottom sheet) or ``"mask"``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import bpy
import numpy as np
from mathutils import Matrix

from platesynth.render.blender.inside import geometry, materials, plate
from platesynth.render.blender.inside.geometry import FLOOR_MM

PASS_PROPERTY = "platesynth_pass"


def reset() -> None:
    """Start from an empty file (keeps the process warm: no restart between images)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)


def _tag(obj: bpy.types.Object, which: str) -> bpy.types.Object:
    obj[PASS_PROPERTY] = which
    return obj


def _stain_rgb(stain: Mapping[str, float]) -> tuple[float, float, float]:
    import colorsys

    return colorsys.hsv_to_rgb((stain["hue_deg"] % 360.0) / 360.0, stain["saturation"], stain["value"])


def _world_xy(points_mm: Sequence[Sequence[float]]) -> np.ndarray:
    """Plate millimetres (x right, y down) to the plate's local frame (x right, y up)."""
    points = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    return np.stack([points[:, 0], -points[:, 1]], axis=1)


def _with_z(xy: np.ndarray, z: float | np.ndarray) -> np.ndarray:
    return np.column_stack([xy, np.broadcast_to(z, (len(xy),))])


def build(description: Mapping[str, Any]) -> dict[str, Any]:
    """Create every object of the scene in the current (empty) Blender file.

    Returns
    -------
    dict
        Handles the render passes need (``plaques``: the plaque object, ...).
    """
    scene_data = description["scene"]
    view = description["view"]
    bl_scene = bpy.context.scene
    geometry_data = scene_data["plate"]
    well_radius = float(geometry_data["well_radius_mm"])
    stain_rgb = _stain_rgb(scene_data["stain"])
    from_below = bool(scene_data["camera"]["from_below"])

    root = bpy.data.objects.new("platesynth.plate_root", None)
    bl_scene.collection.objects.link(root)
    root.matrix_world = Matrix(view["plate_matrix"])

    def parented(obj: bpy.types.Object) -> bpy.types.Object:
        obj.parent = root
        return obj

    look = scene_data["plate_look"]
    plastic = materials.plastic_material(tuple(look["tint_rgb"]), float(look["transmittance"]), float(look["rim_darkness"]))
    stain_group = materials.stain_group()

    # wells: one point per well, carrying its id and stain values
    wells = scene_data["wells"]
    well_xy = _world_xy([w["center_mm"] for w in wells])
    well_attributes = _well_attributes(wells, scene_data["seed"])
    well_points = parented(geometry.point_cloud("platesynth.wells", _with_z(well_xy, 0.0), well_attributes))
    geometry.add_modifier(
        well_points,
        geometry.wells_group(materials.monolayer_material(stain_group, stain_rgb, well_radius)),
        {"Well Radius": well_radius, "Floor Height": FLOOR_MM},
    )
    _tag(well_points, "both")

    plate_inputs = {
        "Length": geometry_data["length_mm"],
        "Width": geometry_data["width_mm"],
        "Height": geometry_data["height_mm"],
        "Corner Radius": geometry_data["corner_radius_mm"],
        "Well Radius": well_radius,
        "Wall": geometry_data["wall_mm"],
    }
    body_mesh = bpy.data.meshes.new("platesynth.plate_body")
    body = parented(bpy.data.objects.new("platesynth.plate_body", body_mesh))
    bl_scene.collection.objects.link(body)
    # the body is generated from the well centres: share the wells' point cloud as its input geometry
    body.data = well_points.data
    geometry.add_modifier(body, plate.plate_group(plastic), plate_inputs)
    _tag(body, "both")
    bottom = parented(bpy.data.objects.new("platesynth.plate_bottom", bpy.data.meshes.new("platesynth.plate_bottom")))
    bl_scene.collection.objects.link(bottom)
    geometry.add_modifier(bottom, plate.plate_bottom_group(plastic), plate_inputs)
    _tag(bottom, "image")

    # plaques: one point per plaque, carrying its outline and the stain values of its well
    plaques = scene_data["plaques"]
    harmonics = max((len(p["fourier"]) for p in plaques), default=0)
    plaque_points = parented(
        geometry.point_cloud(
            "platesynth.plaques",
            _with_z(_world_xy([p["center_mm"] for p in plaques]), 0.0),
            _plaque_attributes(plaques, wells, well_attributes, harmonics),
        )
    )
    first_depth = 1 if from_below else 0  # the bottom sheet lies between the camera and the plaques
    geometry.add_modifier(
        plaque_points,
        geometry.plaques_group(materials.plaque_material(stain_group, stain_rgb, well_radius, first_depth), harmonics),
        {"Well Radius": well_radius, "Floor Height": FLOOR_MM, "Layer Step": -geometry.LAYER_STEP_MM if from_below else geometry.LAYER_STEP_MM},
    )
    _tag(plaque_points, "both")

    _background(scene_data, view)
    _lights(scene_data, view)
    _camera(view, bl_scene)
    for name in materials.MASK_AOVS:
        aov = bl_scene.view_layers[0].aovs.add()
        aov.name, aov.type = name, "VALUE"
    return {"root": root, "plaques": plaque_points}


def _well_attributes(wells: Sequence[Mapping[str, Any]], seed: int) -> dict[str, np.ndarray]:
    stains = [w["stain"] for w in wells]
    rng = np.random.default_rng(int(seed))
    attributes: dict[str, np.ndarray] = {
        "well_id": np.array([w["id"] for w in wells], dtype=np.int32),
        "emptied": np.array([float(w["emptied"]) for w in wells]),
        "lysed": np.array([float(w["lysed"]) for w in wells]),
        "texture_seed": rng.uniform(0.0, 1000.0, len(wells)),
        "centre_offset": np.array([[s["centre_offset_mm"][0], s["centre_offset_mm"][1], 0.0] for s in stains]).reshape(-1, 3),
    }
    for name in materials.WELL_ATTRIBUTES:
        if name not in attributes:
            attributes[name] = np.array([float(s[name]) for s in stains])
    return attributes


def _plaque_attributes(
    plaques: Sequence[Mapping[str, Any]],
    wells: Sequence[Mapping[str, Any]],
    well_attributes: Mapping[str, np.ndarray],
    harmonics: int,
) -> dict[str, np.ndarray]:
    row_of_well = {w["id"]: i for i, w in enumerate(wells)}
    rows = np.array([row_of_well[p["well"]] for p in plaques], dtype=np.int64)
    well_xy = _world_xy([w["center_mm"] for w in wells])
    attributes: dict[str, np.ndarray] = {
        "plaque_id": np.array([p["id"] for p in plaques], dtype=np.int32),
        "radius": np.array([p["radius_mm"] for p in plaques], dtype=np.float64),
        "softness": np.array([p["softness"] for p in plaques], dtype=np.float64),
        "clearness": np.array([p["clearness"] for p in plaques], dtype=np.float64),
        "layer": np.arange(len(plaques), dtype=np.float64),
        "well_center": _with_z(well_xy[rows], 0.0) if len(plaques) else np.zeros((0, 3)),
    }
    for k in range(harmonics):
        attributes[f"fourier_a{k + 2}"] = np.array([p["fourier"][k][0] if k < len(p["fourier"]) else 0.0 for p in plaques])
        attributes[f"fourier_b{k + 2}"] = np.array([p["fourier"][k][1] if k < len(p["fourier"]) else 0.0 for p in plaques])
    for name, values in well_attributes.items():  # the stain under each plaque is its well's
        attributes.setdefault(name, values[rows] if len(plaques) else values[:0])
    return attributes


def _plane(name: str, size_xy: tuple[float, float], location: tuple[float, float, float], material: bpy.types.Material) -> bpy.types.Object:
    mesh = bpy.data.meshes.new(name)
    half_x, half_y = size_xy[0] / 2, size_xy[1] / 2
    mesh.from_pydata([(-half_x, -half_y, 0), (half_x, -half_y, 0), (half_x, half_y, 0), (-half_x, half_y, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return _tag(obj, "image")


def _background(scene_data: Mapping[str, Any], view: Mapping[str, Any]) -> None:
    background = scene_data["background"]
    plate_data = scene_data["plate"]
    centre = view["plate_center_world"]
    under = view["support_z"]
    length, width = plate_data["length_mm"], plate_data["width_mm"]
    seed = float(scene_data["seed"] % 997)
    light_rgb = tuple(view["light_rgb"])
    if background["kind"] == "lightbox":
        margin = float(background["panel_margin_mm"])
        panel = materials.emission_material("platesynth.lightbox", light_rgb, float(background["brightness"]) * view["lightbox_strength"])
        _plane("platesynth.lightbox_panel", (length + 2 * margin, width + 2 * margin), (centre[0], centre[1], under - 0.5), panel)
        frame = materials.surface_material("platesynth.lightbox_frame", tuple(background["color_rgb"]), float(background["texture"]), seed)
        _plane("platesynth.lightbox_frame", (length * 6, width * 6), (centre[0], centre[1], under - 3.0), frame)
    else:
        desk = materials.surface_material("platesynth.desk", tuple(background["color_rgb"]), float(background["texture"]), seed)
        _plane("platesynth.desk", (length * 6, width * 6), (centre[0], centre[1], under - 0.5), desk)


def _lights(scene_data: Mapping[str, Any], view: Mapping[str, Any]) -> None:
    light_rgb = tuple(view["light_rgb"])
    centre = view["plate_center_world"]
    data = bpy.data.lights.new("platesynth.room_light", "AREA")
    data.shape = "DISK"
    data.size = 600.0
    data.color = light_rgb
    data.energy = float(view["room_light_w"])
    light = bpy.data.objects.new("platesynth.room_light", data)
    light.location = (centre[0] + 80.0, centre[1] + 60.0, 600.0)
    bpy.context.scene.collection.objects.link(light)
    _tag(light, "image")
    world = bpy.data.worlds.new("platesynth.world")
    world.color = (0.0, 0.0, 0.0)
    bpy.context.scene.world = world


def _camera(view: Mapping[str, Any], bl_scene: bpy.types.Scene) -> None:
    data = bpy.data.cameras.new("platesynth.camera")
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = float(view["sensor_width_mm"])
    data.lens = float(view["lens_mm"])
    data.shift_x, data.shift_y = float(view["shift_x"]), float(view["shift_y"])
    data.clip_start, data.clip_end = 1.0, 1e5
    camera = bpy.data.objects.new("platesynth.camera", data)
    camera.matrix_world = Matrix(view["camera_matrix"])
    bl_scene.collection.objects.link(camera)
    bl_scene.camera = camera


def show_pass(which: str) -> None:
    """Show the objects of the ``"image"`` or ``"mask"`` pass to the renderer and hide the others."""
    for obj in bpy.context.scene.objects:
        tag = obj.get(PASS_PROPERTY, "both")
        obj.hide_render = tag not in ("both", which)


__all__ = ["build", "reset", "show_pass", "math"]
