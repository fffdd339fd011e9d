"""A compared mesh turned onto its reference before it is described: the turn registration
finds, kept where a viewer would not see it (``PipelineConfig``'s alignment settings).

Both meshes are placed in one frame first (``mesh.place``); the turn is a rotation about that
frame's origin. It is found as point-to-plane ICP finds one, a rotation alone: points sampled on
the mesh are laid on the planes through their nearest of the reference's samples, the rotation
linearised at each Gauss-Newton step, the nearest points found anew each step. Numpy alone: the
torch path finds the same turn without gradients and applies it to its vertices.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .config import PipelineConfig
from .nearest import lift, nearest_lifted

REFERENCE_SEED, MESH_SEED = 0, 1  # each side's samples are fixed: a score is reproducible
# Bytes of one block of the nearest-point search: 16 points against 2,048, a product OpenBLAS
# runs on the calling thread (m n k <= 262,144). Its helper threads, woken by a larger product,
# busy-wait for about 0.1 s after it on the cores the next description needs: in a one-off
# look, a new chair compared with a described one cost 1.48x drkfs-1.1's in one block of the
# whole search, 1.12-1.14x in blocks of 8 points against 4,096.
SEARCH_BLOCK_BYTES = 1 << 17


class SurfaceSamples(NamedTuple):
    """points (N, 3) drawn on a surface, and normals (N, 3) the unit normals of their faces."""

    points: np.ndarray
    normals: np.ndarray


def sample_surface(verts, faces, count: int, seed: int = 0) -> SurfaceSamples:
    """``count`` points drawn uniformly by area, with their faces' unit normals; none on a
    surface without area."""
    corners = np.asarray(verts, dtype=np.float64)[np.asarray(faces)]
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = np.linalg.norm(cross, axis=1)
    if not area.sum() > 0:
        return SurfaceSamples(np.zeros((0, 3)), np.zeros((0, 3)))
    rng = np.random.default_rng(seed)
    face = rng.choice(len(corners), size=count, p=area / area.sum())
    u, v = rng.random((2, count))
    flip = u + v > 1  # fold the square onto the triangle
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    c = corners[face]
    points = c[:, 0] + u[:, None] * (c[:, 1] - c[:, 0]) + v[:, None] * (c[:, 2] - c[:, 0])
    return SurfaceSamples(points, cross[face] / area[face, None])


def reference_surface(verts, faces, config: PipelineConfig) -> SurfaceSamples | None:
    """(placed verts (V, 3), faces (F, 3)) -> the reference's samples a turn is fitted to;
    None where the config turns nothing."""
    if not config.align_degrees:
        return None
    return sample_surface(verts, faces, config.align_reference_points, REFERENCE_SEED)


def aligning_turn(
    verts, faces, reference: SurfaceSamples | None, config: PipelineConfig
) -> np.ndarray:
    """(3, 3) the rotation applied to a mesh, placed verts (V, 3) and faces (F, 3), before it is
    described against ``reference`` (``reference_surface``): the identity where the config
    turns nothing or either surface has no area. The first step fits every point; each later
    one the share ``align_fitted`` nearest their planes (a trimmed fit)."""
    if not config.align_degrees or reference is None or not len(reference.points):
        return np.eye(3)
    found = sample_surface(verts, faces, config.align_points, MESH_SEED)
    if not len(found.points):
        return np.eye(3)
    targets = lift(reference.points)
    turn = np.eye(3)
    for step in range(config.align_steps):
        moved, moved_normals = found.points @ turn.T, found.normals @ turn.T
        nearest = nearest_lifted(moved, targets, SEARCH_BLOCK_BYTES)
        offset = moved - reference.points[nearest]
        normals = reference.normals[nearest]
        kept = (np.linalg.norm(offset, axis=1) < config.align_reach) & (
            np.abs((moved_normals * normals).sum(1)) > config.align_facing
        )
        if kept.sum() < 3:
            break
        residual = (offset[kept] * normals[kept]).sum(1)
        rows = np.cross(moved[kept], normals[kept])
        if step and config.align_fitted < 1.0:
            near = np.abs(residual) <= np.quantile(np.abs(residual), config.align_fitted)
            rows, residual = rows[near], residual[near]
        turn = turn_of(np.linalg.lstsq(rows, -residual, rcond=None)[0]) @ turn
    return turn_of(kept_turn(rotation_vector(turn), config))


def kept_turn(vector: np.ndarray, config: PipelineConfig) -> np.ndarray:
    """The part of a found turn (axis times radians) that is applied: none up to
    ``align_from_degrees``, all of it from twice that, a smoothstep between (the applied turn
    grows continuously with the found one); at most ``align_degrees``."""
    angle, least = float(np.degrees(np.linalg.norm(vector))), config.align_from_degrees
    if angle <= least:
        return np.zeros(3)
    ramp = 1.0 if angle >= 2 * least else (angle - least) / least
    kept = ramp * ramp * (3 - 2 * ramp) * min(angle, config.align_degrees)
    return vector * kept / angle


def turn_of(vector: np.ndarray) -> np.ndarray:
    """(3, 3) the rotation by |vector| radians about ``vector`` (Rodrigues)."""
    angle = float(np.linalg.norm(vector))
    if angle == 0.0:
        return np.eye(3)
    k = np.cross(np.eye(3), vector / angle)  # the cross-product matrix of the unit axis
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def rotation_vector(turn: np.ndarray) -> np.ndarray:
    """The axis times the angle (radians) of a rotation matrix."""
    skew = np.array([turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0], turn[1, 0] - turn[0, 1]])
    sine, cosine = np.linalg.norm(skew) / 2, (np.trace(turn) - 1) / 2
    if sine == 0.0:
        return np.zeros(3)
    return skew / (2 * sine) * np.arctan2(sine, cosine)


def turned(verts, faces, reference: SurfaceSamples | None, config: PipelineConfig):
    """Placed verts (V, 3) turned onto ``reference`` (``aligning_turn``); ``verts`` itself where
    no turn is applied, so a caller can keep what it made of them."""
    turn = aligning_turn(verts, faces, reference, config)
    return verts if turns_nothing(turn) else verts @ turn.T


def turns_nothing(turn: np.ndarray) -> bool:
    """Whether a turn (3, 3) from ``aligning_turn`` leaves a mesh exactly where it is."""
    return bool(np.array_equal(turn, np.eye(3)))
