"""Cameras as plain data: look-at rotations and a pinhole focal length, in numpy.

Both the torch renderer and the numpy runtime read cameras from here, so the two see the meshes
from exactly the same places. Camera frame: x right, y down, z forward (into the scene).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .array_ops import NUMPY_OPS
from .config import PipelineConfig
from .render_equations import to_camera

GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))
WORLD_UP = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class Cameras:
    """K pinhole cameras looking at the origin.

    rotations: (K, 3, 3) world-to-camera rotations (rows: camera x, y, z axes in world space).
    eyes: (K, 3) camera centres in world space.
    focal: focal length in normalised device units (image spans [-1, 1]).
    """

    rotations: np.ndarray
    eyes: np.ndarray
    focal: float

    def __len__(self) -> int:
        return len(self.eyes)

    def select(self, indices: np.ndarray) -> Cameras:
        """The cameras at ``indices``, in their order."""
        return Cameras(self.rotations[indices], self.eyes[indices], self.focal)

    def world_to_camera(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) world points -> (K, N, 3) camera-frame points."""
        return to_camera(points, self.rotations, self.eyes, NUMPY_OPS)


def hemisphere_directions(count: int) -> np.ndarray:
    """(count, 3) unit directions spread evenly over the upper (y > 0) hemisphere.

    A golden-angle spiral with equal-area height steps: any view count is evenly spread, so the
    25-view paper setting and cheaper 12- or 6-view variants come from one rule.
    """
    i = np.arange(count, dtype=np.float64)
    height = (i + 0.5) / count
    ring = np.sqrt(1.0 - height**2)
    azimuth = i * GOLDEN_ANGLE
    return np.stack([ring * np.cos(azimuth), height, ring * np.sin(azimuth)], axis=1)


def look_at(eyes: np.ndarray, target: np.ndarray | None = None) -> np.ndarray:
    """(K, 3) eyes -> (K, 3, 3) world-to-camera rotations looking at target (default origin)."""
    target = np.zeros(3) if target is None else target
    forward = target - eyes
    forward /= np.linalg.norm(forward, axis=1, keepdims=True)
    right = np.cross(forward, WORLD_UP)
    right /= np.linalg.norm(right, axis=1, keepdims=True)
    down = np.cross(forward, right)
    return np.stack([right, down, forward], axis=1)


def rotation(axis: int, degrees: float) -> np.ndarray:
    """(3, 3): a turn of ``degrees`` about the axis ``axis`` (0: x, 1: y, the vertical, 2: z),
    counter-clockwise seen from the axis' positive end."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = (axis + 1) % 3, (axis + 2) % 3  # the plane the turn moves in, in right-hand order
    turn = np.eye(3)
    turn[i, i], turn[i, j], turn[j, i], turn[j, j] = c, -s, s, c
    return turn


def rotation_y(degrees: float) -> np.ndarray:
    """(3, 3): a turn of ``degrees`` about the vertical (y) axis."""
    return rotation(1, degrees)


def make_cameras(config: PipelineConfig) -> Cameras:
    """The config's ``num_views`` hemisphere cameras, then the same turned by each further ring
    (``config.rings``): K * T cameras, ring after ring."""
    ring = hemisphere_directions(config.num_views)
    # cameras turned by -θ see a mesh turned by θ: the light is fixed in the camera frame
    directions = np.concatenate([ring @ rotation_y(-turn).T for turn in config.rings])
    eyes = directions * config.camera_distance
    focal = 1.0 / math.tan(math.radians(config.fov_degrees) / 2.0)
    return Cameras(rotations=look_at(eyes), eyes=eyes, focal=focal)
