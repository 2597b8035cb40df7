"""The camera's mapping between plate millimetres and image pixels: a homography from the scene's camera."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from platesynth.scene.concrete import Scene

REFERENCE_WIDTH = 1024
"""Pixel-valued scene parameters (blur, noise lengths) are given for an image this wide."""


@dataclass(frozen=True)
class View:
    """The camera's mapping between plate millimetres and image pixels (pixel centres at ``i + 0.5``)."""

    width: int
    height: int
    plate_to_px: np.ndarray
    px_to_plate: np.ndarray
    px_per_mm: float
    principal_mm: tuple[float, float]
    mirror: float

    def project(self, points_mm: np.ndarray) -> np.ndarray:
        """Pixel positions ``(..., 2)`` of plate points ``(..., 2)`` in mm."""
        points = np.asarray(points_mm, dtype=np.float64)
        h = self.plate_to_px
        w = h[2, 0] * points[..., 0] + h[2, 1] * points[..., 1] + h[2, 2]
        x = (h[0, 0] * points[..., 0] + h[0, 1] * points[..., 1] + h[0, 2]) / w
        y = (h[1, 0] * points[..., 0] + h[1, 1] * points[..., 1] + h[1, 2]) / w
        return np.stack([x, y], axis=-1)


def camera_view(scene: Scene, width: int, height: int) -> View:
    """The homography of ``scene.camera`` for an image of ``width`` x ``height`` pixels."""
    cam, plate = scene.camera, scene.plate
    scale = cam.plate_fill * width / plate.length_mm
    mirror = -1.0 if cam.from_below else 1.0
    centre_x, centre_y = plate.length_mm / 2, plate.width_mm / 2
    to_view = np.array([[mirror, 0.0, -mirror * centre_x], [0.0, 1.0, -centre_y], [0.0, 0.0, 1.0]])
    rz, rx, ry = (math.radians(a) for a in (cam.rotation_deg, cam.tilt_x_deg, cam.tilt_y_deg))
    rot_z = np.array([[math.cos(rz), -math.sin(rz), 0], [math.sin(rz), math.cos(rz), 0], [0, 0, 1]])
    rot_x = np.array([[1, 0, 0], [0, math.cos(rx), -math.sin(rx)], [0, math.sin(rx), math.cos(rx)]])
    rot_y = np.array([[math.cos(ry), 0, math.sin(ry)], [0, 1, 0], [-math.sin(ry), 0, math.cos(ry)]])
    r = rot_z @ rot_x @ rot_y
    distance = cam.distance_mm
    focal = scale * distance
    ox = width / 2 + cam.offset[0] * width
    oy = height / 2 + cam.offset[1] * height
    projection = np.array(
        [
            [focal * r[0, 0] + ox * r[2, 0], focal * r[0, 1] + ox * r[2, 1], ox * distance],
            [focal * r[1, 0] + oy * r[2, 0], focal * r[1, 1] + oy * r[2, 1], oy * distance],
            [r[2, 0], r[2, 1], distance],
        ]
    )
    plate_to_px = projection @ to_view
    px_to_plate = np.linalg.inv(plate_to_px)
    principal = px_to_plate @ np.array([ox, oy, 1.0])
    return View(
        width=width,
        height=height,
        plate_to_px=plate_to_px,
        px_to_plate=px_to_plate,
        px_per_mm=scale,
        principal_mm=(float(principal[0] / principal[2]), float(principal[1] / principal[2])),
        mirror=mirror,
    )
