"""Host side: turn a concrete :class:`~platesynth.scene.Scene` into the plain description the Blender side builds.

The description is JSON: ``{"scene": <the scene as JSON>, "view": {...}, "textures": {...}}``, plus texture
arrays saved as ``.npy`` files beside it (the boundary is plain data, as in BlenderProc: the Blender side
imports neither numba, nor the raster renderer, nor the scene model). ``view`` holds what is derived on the host
so that Blender draws the scene exactly where the raster renderer does: the camera, decomposed from the raster
renderer's plate-to-pixel homography (:func:`platesynth.render.camera.camera_view`), the lights' colour and the
placement of the light box. ``textures`` names the plate-space arrays, each ``{"path", "texels_per_mm"}``:

- ``floor``: the monolayer's linear RGB transmittance, plaques and marks included, computed by the appearance
  model (:func:`platesynth.render.appearance.floor_transmittance`) that the raster renderer also draws;
- ``relief``: the plate's embossed labels, rings and ribs (:func:`platesynth.render.raster.plate_relief`);
- ``unevenness``: the stain's low-frequency grid (its cell in ``texels_per_mm``), which distorts the blots.

Arrays have row 0 at plate y = 0 and texel ``(i, j)`` centred at ``((j + 0.5) / k, (i + 0.5) / k)`` mm.

Blender's world frame is the plate frame ``(x, -y, z)``: plate millimetres with y flipped (so that z points up,
out of the plate's bottom towards its lid) and the well floors at ``z = 0``, the plane the homography maps.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from platesynth.errors import RenderError
from platesynth.render.appearance import floor_texels_per_mm, floor_transmittance, stain_table, wall_sheen, wall_tints
from platesynth.render.camera import REFERENCE_WIDTH, View, camera_view
from platesynth.render.color import light_colour, srgb_to_linear
from platesynth.render.look import WALL_LINE_PLACES, wall_line_phase
from platesynth.render.raster import plate_relief, texels_per_mm
from platesynth.render.textures import SceneTextures, scene_textures
from platesynth.scene.concrete import Scene

SENSOR_WIDTH_MM = 36.0
FLOOR_THICKNESS_MM = 1.0
"""The plastic under the well floors: the bottom sheet lies at ``z = -FLOOR_THICKNESS_MM``."""

_BLENDER_FROM_OPENCV = np.diag([1.0, -1.0, -1.0])
"""Camera axes: OpenCV (x right, y down, z forward) to Blender (x right, y up, looking along -z)."""


def camera_pose(scene: Scene, view: View) -> tuple[np.ndarray, float, tuple[float, float]]:
    """The pinhole camera behind ``view``'s homography, in Blender's conventions.

    Returns
    -------
    matrix_world : (4, 4) camera-to-world matrix (world = the plate frame ``(x, -y, z)``).
    focal_px : focal length in pixels.
    principal_px : the principal point (x, y) in pixels from the image's top-left corner.
    """
    focal = view.px_per_mm * scene.camera.distance_mm
    principal = view.project(np.array(view.principal_mm))
    intrinsics = np.array([[focal, 0.0, principal[0]], [0.0, focal, principal[1]], [0.0, 0.0, 1.0]])
    # plate (x, y) -> the camera frame: K^-1 H = [r1 r2 t] up to scale, in homogeneous plate coordinates
    extrinsic = np.linalg.inv(intrinsics) @ view.plate_to_px
    scale = np.linalg.norm(extrinsic[:, 0])
    extrinsic = extrinsic / scale
    if extrinsic[2, 2] < 0:  # the plate lies in front of the camera
        extrinsic = -extrinsic
    r1, r2, t = extrinsic[:, 0], extrinsic[:, 1], extrinsic[:, 2]
    if abs(np.linalg.norm(r2) - 1.0) > 1e-6 or abs(float(r1 @ r2)) > 1e-6:
        raise RenderError("the raster camera is not a pinhole camera: its homography has no rotation part")
    # world (x, -y, z) -> camera: the columns are where the world's axes go; z completes a rotation
    rotation = np.column_stack([r1, -r2, -np.cross(r1, r2)])
    world_to_camera = np.eye(4)
    world_to_camera[:3, :3] = _BLENDER_FROM_OPENCV @ rotation
    world_to_camera[:3, 3] = _BLENDER_FROM_OPENCV @ t
    return np.linalg.inv(world_to_camera), float(focal), (float(principal[0]), float(principal[1]))


def describe_scene(scene: Scene, size: tuple[int, int], texture_dir: str | Path) -> dict[str, Any]:
    """The Blender side's input for drawing ``scene`` at ``size`` = (width, height) pixels.

    Parameters
    ----------
    scene : Scene
        A concrete scene.
    size : tuple of int
        (width, height) in pixels.
    texture_dir : str or Path
        An existing folder that receives the texture arrays (``.npy``); it must outlive the request.

    Returns
    -------
    dict
        JSON-serialisable ``{"scene": ..., "view": ..., "textures": ...}``.
    """
    width, height = (int(s) for s in size)
    view = camera_view(scene, width, height)
    camera_matrix, focal_px, (principal_x, principal_y) = camera_pose(scene, view)
    plate = scene.plate
    from_below = scene.camera.from_below
    gains = light_colour(scene.lighting.color_temperature_k)
    # what the plate rests on: its bottom sheet (seen from above) or its top (seen from below, upside down)
    support_z = plate.height_mm - FLOOR_THICKNESS_MM + 0.01 if from_below else -FLOOR_THICKNESS_MM - 0.01
    noise = scene_textures(scene)
    return {
        "scene": scene.model_dump(mode="json"),
        "textures": _write_textures(scene, view, noise, Path(texture_dir)),
        "view": {
            "width": width,
            "height": height,
            "camera_matrix": camera_matrix.tolist(),
            "sensor_width_mm": SENSOR_WIDTH_MM,
            "lens_mm": focal_px * SENSOR_WIDTH_MM / width,
            # Blender's lens shift is in units of the image width; y points up
            "shift_x": (width / 2 - principal_x) / width,
            "shift_y": (principal_y - height / 2) / width,
            "mirror": float(view.mirror),
            "plate_center_world": [plate.length_mm / 2, -plate.width_mm / 2, 0.0],
            "support_z": support_z,
            "toward_camera": -1.0 if from_below else 1.0,
            "floor_thickness_mm": FLOOR_THICKNESS_MM,
            "light_rgb": gains.tolist(),
            "desk_linear_rgb": srgb_to_linear(scene.background.color_rgb).tolist(),
            "marker_linear_rgb": [srgb_to_linear(s.color_rgb).tolist() for s in scene.artifacts.marker],
            "px_scale": width / REFERENCE_WIDTH,
            "pixel_mm": 1.0 / view.px_per_mm,
            # the band over each wall (scene.wells' order): the raster renderer's linear factors
            "wall_tints": wall_tints(scene, list(scene.wells), stain_table(scene, noise)[0]).tolist(),
            # and its brightness change around the well, (a1, b1, a2, b2, a3, b3) about plate angles
            "wall_sheens": wall_sheen(scene, list(scene.wells), view.principal_mm, noise.wall_glints).tolist(),
            # the phases of the lines each wall refracts (look.wall_line_phase of the well's noise shifts)
            "wall_line_phases": [[wall_line_phase(*offsets, line) for line in range(len(WALL_LINE_PLACES))]
                                 for offsets in noise.well_offsets.tolist()],
        },
    }


def _write_textures(scene: Scene, view: View, noise: SceneTextures, directory: Path) -> dict[str, dict[str, Any]]:
    """Save the plate-space textures of ``scene`` (its noise textures ``noise``) in ``directory``; return their
    entries for the description."""
    floor_k = floor_texels_per_mm(view.px_per_mm)
    relief_k = texels_per_mm(view.px_per_mm)
    arrays = {
        "floor": (floor_transmittance(scene, floor_k, noise), floor_k),
        "relief": (plate_relief(scene.plate, relief_k, scene.plate_look.labels_at_junction), relief_k),
        "unevenness": (noise.low_grid, 1.0 / noise.low_cell_mm),
    }
    entries = {}
    for name, (array, k) in arrays.items():
        path = directory / f"texture_{name}.npy"
        np.save(path, np.ascontiguousarray(array, dtype=np.float32), allow_pickle=False)
        entries[name] = {"path": str(path), "texels_per_mm": float(k)}
    return entries
