"""What is fitted: a target mesh and a template of the right topology, both in the target's
normalised frame (its bounding box fills the unit sphere)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import trimesh

from drkfs_lab.benchmark.sets import real_mesh
from drkfs_onnx.contract.mesh import frame_of, load_mesh, place
from drkfs_onnx.synthetic.shapes import Part, assemble, random_shape

TEMPLATE_SUBDIVISIONS = 1  # template parts get four times the faces: room to bend
SIZE_JITTER = 0.2  # a template part's size is the target's times U(1 - j, 1 + j) per axis
CENTRE_JITTER = 0.03  # and its centre moves by N(0, j) per axis (shape units, ~1 tall)
ICOSPHERE_LEVEL = 3  # 642 vertices, 1280 faces
ELLIPSOID_FILL = 0.8  # the icosphere template is the ellipsoid inscribed in 0.8 x the box


@dataclass(frozen=True)
class Problem:
    name: str
    description: str
    target_verts: np.ndarray  # (V, 3) float64
    target_faces: np.ndarray  # (F, 3) int64
    template_verts: np.ndarray
    template_faces: np.ndarray
    # the shared mesh the target was read from (not copied: ``mesh.frame_of`` normalises it)
    source: Path | None = None


def _in_frame_of(target: np.ndarray, *meshes: np.ndarray) -> list[np.ndarray]:
    frame = frame_of(target)
    return [place(v, frame) for v in (target, *meshes)]


def perturbed(parts: list[Part], rng: np.random.Generator) -> list[Part]:
    """The same parts with jittered sizes and centres: a template of the family's topology."""
    return [
        replace(
            p,
            size=tuple(np.array(p.size) * rng.uniform(1 - SIZE_JITTER, 1 + SIZE_JITTER, 3)),
            center=tuple(np.array(p.center) + rng.normal(0.0, CENTRE_JITTER, 3)),
        )
        for p in parts
    ]


def synthetic(family: str, seed: int) -> Problem:
    """A shape of ``family`` drawn from ``seed``; the template perturbs its part parameters."""
    parts = random_shape(family, seed)
    target_verts, target_faces = assemble(parts)
    template_verts, template_faces = assemble(
        perturbed(parts, np.random.default_rng(seed + 1)), TEMPLATE_SUBDIVISIONS
    )
    target_verts, template_verts = _in_frame_of(target_verts, template_verts)
    return Problem(
        f"{family} {seed}",
        f"synthetic {family} (seed {seed}); template: its {len(parts)} parts with sizes x "
        f"U({1 - SIZE_JITTER:g}, {1 + SIZE_JITTER:g}) and centres + N(0, {CENTRE_JITTER:g})",
        target_verts,
        target_faces,
        template_verts,
        template_faces,
    )


def shared(name: str) -> Problem:
    """A real mesh (read in place); the template is an icosphere stretched to the ellipsoid
    inscribed in ELLIPSOID_FILL times its bounding box (for genus-0 targets)."""
    source = real_mesh(name)
    mesh = load_mesh(source)
    sphere = trimesh.creation.icosphere(ICOSPHERE_LEVEL)
    lower, upper = mesh.vertices.min(0), mesh.vertices.max(0)
    template = (lower + upper) / 2 + sphere.vertices * (upper - lower) / 2 * ELLIPSOID_FILL
    target_verts, template_verts = _in_frame_of(mesh.vertices, template)
    return Problem(
        name,
        f"real mesh {name}.obj ({len(mesh.faces)} faces); template: icosphere level "
        f"{ICOSPHERE_LEVEL} as the ellipsoid in {ELLIPSOID_FILL:g} x its bounding box",
        target_verts,
        mesh.faces,
        template_verts,
        np.asarray(sphere.faces, dtype=np.int64),
        source,
    )
