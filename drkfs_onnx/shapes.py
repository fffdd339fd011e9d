"""Procedural part-based shapes: the project's own example meshes, built from code.

A shape is a list of named parts (closed boxes), so variants can drop, move or reshape one part.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

# Unit cube corners and outward-facing triangles (counter-clockwise seen from outside).
_CUBE_CORNERS = np.array(
    [[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)], dtype=np.float64
)
_CUBE_FACES = np.array(
    [
        [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5],  # x = -0.5, x = +0.5
        [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],  # y = -0.5, y = +0.5
        [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],  # z = -0.5, z = +0.5
    ],
    dtype=np.int64,
)  # fmt: skip


@dataclass(frozen=True)
class Box:
    """An axis-aligned box part: centre and full size, y up."""

    name: str
    center: tuple[float, float, float]
    size: tuple[float, float, float]

    def mesh(self, subdivisions: int = 0) -> tuple[np.ndarray, np.ndarray]:
        verts, faces = _CUBE_CORNERS, _CUBE_FACES
        for _ in range(subdivisions):
            verts, faces = _subdivide(verts, faces)
        return verts * np.array(self.size) + np.array(self.center), faces


def _subdivide(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split every triangle into four at its edge midpoints (the surface does not move)."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    mids = len(verts) + inverse.reshape(-1, 3)
    verts = np.concatenate([verts, verts[unique].mean(axis=1)])
    a, b, c = faces.T
    ab, bc, ca = mids.T
    children = np.array([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]])  # (4, 3, F)
    return verts, children.transpose(2, 0, 1).reshape(-1, 3)


def assemble(parts: list[Box], subdivisions: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate part meshes into one (V, 3) float64, (F, 3) int64 mesh."""
    verts, faces, offset = [], [], 0
    for part in parts:
        v, f = part.mesh(subdivisions)
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
    return np.concatenate(verts), np.concatenate(faces)


def chair(
    seat_height: float = 0.45, seat_width: float = 0.5, back_height: float = 0.5, leg: float = 0.05
) -> list[Box]:
    """A four-legged chair with a backrest."""
    half = seat_width / 2 - leg / 2
    legs = [
        Box(f"leg_{i}", (sx * half, seat_height / 2, sz * half), (leg, seat_height, leg))
        for i, (sx, sz) in enumerate([(-1, -1), (1, -1), (-1, 1), (1, 1)])
    ]
    seat = Box("seat", (0.0, seat_height + 0.025, 0.0), (seat_width, 0.05, seat_width))
    back = Box(
        "back",
        (0.0, seat_height + 0.05 + back_height / 2, -half),
        (seat_width, back_height, leg),
    )
    return [*legs, seat, back]


def without(parts: list[Box], name: str) -> list[Box]:
    return [p for p in parts if p.name != name]


def shifted(parts: list[Box], name: str, offset: tuple[float, float, float]) -> list[Box]:
    return [
        replace(p, center=tuple(np.add(p.center, offset).tolist())) if p.name == name else p
        for p in parts
    ]
