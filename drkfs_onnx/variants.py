"""Structural and mild variants of part-based shapes.

Structural: a part removed or a part added. Mild: the same surface retessellated, vertices
jittered by 0.2% of the shape's size, a part thickened by 20%, a part shifted by 2.5% of the
shape's size, the whole shape rotated by 2 degrees. Sizes are relative to the bounding-box
diagonal, so a variant means the same thing for every family.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .shapes import Part, assemble

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


def _rotation_y(degrees: float) -> np.ndarray:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


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
    rotated = verts @ _rotation_y(2.0).T
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
