"""Structural and mild variants of part-based shapes.

Structural: a part removed or a part added. Mild: the same surface retessellated, vertices
jittered by 0.2% of the shape's size, a part thickened by 20%, a part shifted by 2.5% of the
shape's size, the whole shape rotated by 2 degrees. Sizes are relative to the bounding-box
diagonal, so a variant means the same thing for every family.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..contract.cameras import rotation_y
from .shapes import Part, assemble, subdivide

STRUCTURAL = ("part_removed", "part_added")
MILD = ("retessellated", "jittered", "part_thickened", "part_shifted", "rotated")


@dataclass(frozen=True)
class Variant:
    name: str
    kind: str  # "structural" or "mild"
    verts: np.ndarray
    faces: np.ndarray


def without(parts: list[Part], name: str) -> list[Part]:
    return [p for p in parts if p.name != name]


def shifted(parts: list[Part], name: str, offset: tuple[float, float, float]) -> list[Part]:
    return [
        replace(p, center=tuple(np.add(p.center, offset).tolist())) if p.name == name else p
        for p in parts
    ]


def thickened(parts: list[Part], name: str, factor: float) -> list[Part]:
    """Scale the part's two thinnest sides by ``factor`` (its length stays)."""
    out = []
    for p in parts:
        if p.name == name:
            size = np.array(p.size)
            thin = np.argsort(size)[:2]
            size[thin] *= factor
            p = replace(p, size=tuple(size.tolist()))
        out.append(p)
    return out


def diagonal(parts: list[Part]) -> float:
    verts, _ = assemble(parts)
    return float(np.linalg.norm(np.ptp(verts, axis=0)))


def make_variants(
    parts: list[Part], rng: np.random.Generator, subdivisions: int = 1
) -> list[Variant]:
    """One variant of each kind in STRUCTURAL and MILD, the edited part drawn from ``rng``."""
    size = diagonal(parts)
    name = parts[int(rng.integers(len(parts)))].name
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    source = parts[int(rng.integers(len(parts)))]
    # An added part: a copy of one part moved sideways by its own width plus a gap.
    step = np.zeros(3)
    axis = int(rng.integers(0, 3, endpoint=False))
    step[axis] = (source.size[axis] + 0.1 * size) * rng.choice([-1.0, 1.0])
    added = replace(source, name="added", center=tuple((np.add(source.center, step)).tolist()))

    def mesh(ps: list[Part], subdiv: int = subdivisions) -> tuple[np.ndarray, np.ndarray]:
        return assemble(ps, subdiv)

    verts, faces = mesh(parts)
    jitter = verts + rng.normal(size=verts.shape) * 0.002 * size
    rotated = verts @ rotation_y(2.0).T
    return [
        Variant("part_removed", "structural", *mesh(without(parts, name))),
        Variant("part_added", "structural", *mesh([*parts, added])),
        Variant("retessellated", "mild", *mesh(parts, subdivisions + 1)),
        Variant("jittered", "mild", jitter, faces),
        Variant("part_thickened", "mild", *mesh(thickened(parts, name, 1.2))),
        Variant(
            "part_shifted", "mild", *mesh(shifted(parts, name, tuple(0.025 * size * direction)))
        ),
        Variant("rotated", "mild", rotated, faces),
    ]


def region_of(verts: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray:
    """(V,) weights: 1 within radius / 2 of centre, a cosine fall-off to 0 at radius."""
    d = np.linalg.norm(verts - centre, axis=1) / radius
    return np.where(d < 0.5, 1.0, np.where(d < 1.0, 0.5 + 0.5 * np.cos(np.pi * (2 * d - 1)), 0.0))


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    cross = np.cross(
        verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]]
    )
    normals = np.zeros_like(verts)
    for i in range(3):
        np.add.at(normals, faces[:, i], cross)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)


def without_region(faces: np.ndarray, verts: np.ndarray, centre: np.ndarray, radius: float):
    """``faces`` less those whose centre lies within ``radius`` of ``centre``."""
    near = np.linalg.norm(verts[faces].mean(1) - centre, axis=1) < radius
    return faces[~near]


def face_areas(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,) twice each face's area."""
    corners = verts[faces]
    return np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )


def salient_tip(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(3,) the surface point furthest from the mesh's area-weighted centroid: the tip of what
    sticks out most (a horn, an ear, a tail)."""
    area = face_areas(verts, faces)
    centroid = (verts[faces].mean(1) * area[:, None]).sum(0) / area.sum()
    used = np.unique(faces)
    return verts[used[np.argmax(np.linalg.norm(verts[used] - centroid, axis=1))]]


def surface_variants(
    verts: np.ndarray, faces: np.ndarray, rng: np.random.Generator
) -> list[Variant]:
    """The variants of ``make_variants`` for a mesh without named parts (a scanned or modelled
    surface). A "part" is the surface within 15% of the diagonal of a random vertex:
    removed (its faces cut out), added (a box of 12% of the diagonal set into the surface there),
    thickened (pushed out along its normals by 1% of the diagonal, fading to its rim) or shifted
    (moved by 2.5% of the diagonal, fading to its rim). Retessellation splits every triangle in
    four at its edge midpoints."""
    size = float(np.linalg.norm(np.ptp(verts, axis=0)))
    radius = 0.15 * size
    centre = verts[int(rng.integers(len(verts)))]
    normals = vertex_normals(verts, faces)
    region = region_of(verts, centre, radius)
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    spot = verts[int(rng.integers(len(verts)))]
    side = 0.12 * size
    box_v, box_f = Part("added", tuple(spot), (side, side, side)).mesh()
    jitter = verts + rng.normal(size=verts.shape) * 0.002 * size
    return [
        Variant("part_removed", "structural", verts, without_region(faces, verts, centre, radius)),
        Variant(
            "part_added", "structural", np.concatenate([verts, box_v]),
            np.concatenate([faces, box_f + len(verts)]),
        ),
        Variant("retessellated", "mild", *subdivide(verts, faces)),
        Variant("jittered", "mild", jitter, faces),
        Variant("part_thickened", "mild", verts + 0.01 * size * region[:, None] * normals, faces),
        Variant("part_shifted", "mild", verts + 0.025 * size * region[:, None] * direction, faces),
        Variant("rotated", "mild", verts @ rotation_y(2.0).T, faces),
    ]  # fmt: skip


def structural_wins(structural: list[float], mild: list[float]) -> tuple[int, int]:
    """(wins, pairs): how many (structural, mild) pairs put the structural variant further."""
    wins = sum(s > m for s in structural for m in mild)
    return int(wins), len(structural) * len(mild)
