"""Meshes finer than the images can show are simplified before rendering.

At the pipeline's resolution a triangle much smaller than a pixel only adds rasteriser work: the
soft rasteriser averages it away. Above a face budget tied to the image size, vertices are
clustered on a grid whose cell starts at half a pixel's footprint and doubles until the mesh fits
the budget (vertex clustering: crude topology, but images change by less than the cell).
"""

from __future__ import annotations

import math

import numpy as np

from drkfs_onnx.config import PipelineConfig


def face_budget(config: PipelineConfig) -> int:
    """Faces a normalised mesh needs at most: one per two pixels of the image (32,768 at 256)."""
    return config.image_size**2 // 2


def pixel_footprint(config: PipelineConfig) -> float:
    """World size of one pixel at the nearest depth a normalised mesh reaches."""
    near = config.camera_distance - 1.0
    return 2.0 * near * math.tan(math.radians(config.fov_degrees) / 2.0) / config.image_size


def cluster_vertices(
    vertices: np.ndarray, faces: np.ndarray, cell: float
) -> tuple[np.ndarray, np.ndarray]:
    """Merge the vertices in each grid cell into their mean; drop collapsed and repeated faces."""
    keys = np.floor(vertices / cell).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    merged = np.stack([np.bincount(inverse, vertices[:, i]) / counts for i in range(3)], axis=1)
    new_faces = inverse[faces]
    alive = (
        (new_faces[:, 0] != new_faces[:, 1])
        & (new_faces[:, 1] != new_faces[:, 2])
        & (new_faces[:, 2] != new_faces[:, 0])
    )
    new_faces = new_faces[alive]
    _, first = np.unique(np.sort(new_faces, axis=1), axis=0, return_index=True)
    return merged, new_faces[np.sort(first)]


def decimate(
    vertices: np.ndarray, faces: np.ndarray, config: PipelineConfig, budget: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """A normalised mesh with at most ``budget`` faces (default ``face_budget``); meshes within
    the budget come back unchanged."""
    budget = face_budget(config) if budget is None else budget
    cell = pixel_footprint(config) / 2.0
    while len(faces) > budget:
        clustered = cluster_vertices(vertices, faces, cell)
        if len(clustered[1]) == 0:
            break
        vertices, faces = clustered
        cell *= 2.0
    return vertices, faces
