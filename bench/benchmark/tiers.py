"""The benchmark's three tiers of change, as a viewer sees them.

- invisible: what a viewer cannot tell from the original: the same surface retessellated, a 2°
  turn about the vertical through the shape's centre, vertices jittered by a twentieth of their
  local edge, a part shifted by 1% of the diagonal or thickened by 10% (on a scan: a region
  pushed out by 0.5% of the diagonal or moved by 1%, fading to its rim);
- surface: a moderate, visible defect on an intact shape: noise of 0.3 local edges along the
  normals of a finely tessellated surface (0.1 on a part-based shape's flat faces), quadric
  simplification to 15% of the faces, smoothing that erases detail;
- structural: a part removed or added (``variants``' structural edits).

Part-based shapes are boxes and cylinders: quadric simplification removes their flat faces'
extra triangles without any visible change, so their surface tier has noise and smoothing, and
a scan's all three. Sizes are relative to the mesh (its diagonal, a vertex's local edge: the
shortest edge at it, so a thin part of a coarse shape is not crumpled by a noise its large faces
would hide), so a tier means the same thing on every shape.
"""

from __future__ import annotations

import numpy as np
import trimesh

from drkfs_onnx.contract.cameras import rotation_y
from drkfs_onnx.synthetic.shapes import Part, assemble, subdivide
from drkfs_onnx.synthetic.variants import (
    Variant,
    diagonal,
    make_variants,
    region_of,
    shifted,
    surface_variants,
    thickened,
    vertex_normals,
)

STRUCTURAL = ("part_removed", "part_added")
INVISIBLE = ("retessellated", "jittered", "part_thickened", "part_shifted", "rotated")
SURFACE = ("noise", "simplified", "smoothed")
TIERS = ("invisible", "surface", "structural")

JITTER_EDGES = 0.05  # jitter: normal with this many local edges of standard deviation
TINY_SHIFT = 0.01  # of the diagonal
TINY_THICKENING = 1.1  # a part's two thin sides
SCAN_PUSH = 0.005  # of the diagonal, a scan region pushed out along its normals
NOISE_EDGES = 0.3  # noise along the normals: this many local edges of standard deviation
# on a part-based shape's flat faces noise shows far more than on a scan's curved surface: a
# third of the amount looks as moderate there (0.3 crumples a chair's seat)
PART_NOISE_EDGES = 0.1
FINE_SUBDIVISIONS = 4  # a part-based shape's fine tessellation for noise and smoothing
SIMPLIFIED_SHARE = 0.15  # the faces quadric simplification keeps
SMOOTHING = 30  # Taubin iterations (lambda 0.5, mu -0.53: smooths without shrinking)
ROTATION_DEGREES = 2.0


def turned(verts: np.ndarray, degrees: float = ROTATION_DEGREES) -> np.ndarray:
    """(V, 3): ``verts`` turned about the vertical through their bounding box's centre. About the
    file's origin, which on a scan can lie most of a diagonal away (0.7 on homer), a 2° turn
    would also shift the shape by up to 2.4% of its diagonal: a visible move, not a turn."""
    centre = (verts.min(0) + verts.max(0)) / 2
    return (verts - centre) @ rotation_y(degrees).T + centre


def local_edges(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V,) the length of the shortest edge at each vertex."""
    corners = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    length = np.linalg.norm(verts[corners[:, 0]] - verts[corners[:, 1]], axis=1)
    shortest = np.full(len(verts), np.inf)
    np.minimum.at(shortest, corners.reshape(-1), np.repeat(length, 2))
    return np.where(np.isfinite(shortest), shortest, 0.0)


def jittered(verts: np.ndarray, faces: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    scale = JITTER_EDGES * local_edges(verts, faces)[:, None]
    return verts + rng.normal(size=verts.shape) * scale


def noisy(
    verts: np.ndarray, faces: np.ndarray, rng: np.random.Generator, edges: float = NOISE_EDGES
) -> np.ndarray:
    """Every vertex moved along its normal by N(0, ``edges`` local edges)."""
    amount = rng.normal(size=len(verts)) * edges * local_edges(verts, faces)
    return verts + amount[:, None] * vertex_normals(verts, faces)


def smoothed(verts: np.ndarray, faces: np.ndarray, iterations: int = SMOOTHING) -> np.ndarray:
    mesh = trimesh.Trimesh(verts, faces, process=False)
    return np.asarray(trimesh.smoothing.filter_taubin(mesh, iterations=iterations).vertices)


def simplified(
    verts: np.ndarray, faces: np.ndarray, keep: float = SIMPLIFIED_SHARE
) -> tuple[np.ndarray, np.ndarray]:
    """Quadric edge-collapse simplification to ``keep`` of the faces (the fast-simplification
    package, through trimesh)."""
    mesh = trimesh.Trimesh(verts, faces, process=False)
    coarse = mesh.simplify_quadric_decimation(face_count=int(keep * len(faces)))
    return np.asarray(coarse.vertices), np.asarray(coarse.faces, dtype=np.int64)


def part_tiers(parts: list[Part], rng: np.random.Generator) -> list[Variant]:
    """Every tier's variants of a part-based shape (the base is ``assemble(parts, 1)``): the
    structural edits of ``variants.make_variants``, the invisible and the surface ones here."""
    size = diagonal(parts)
    structural = [v for v in make_variants(parts, rng) if v.kind == "structural"]
    name = parts[int(rng.integers(len(parts)))].name
    direction = rng.normal(size=3)
    offset = tuple(TINY_SHIFT * size * direction / np.linalg.norm(direction))
    verts, faces = assemble(parts, 1)
    fine_verts, fine_faces = assemble(parts, FINE_SUBDIVISIONS)
    thicker = thickened(parts, name, TINY_THICKENING)
    invisible = [
        Variant("retessellated", "invisible", *assemble(parts, 2)),
        Variant("jittered", "invisible", jittered(verts, faces, rng), faces),
        Variant("part_thickened", "invisible", *assemble(thicker, 1)),
        Variant("part_shifted", "invisible", *assemble(shifted(parts, name, offset), 1)),
        Variant("rotated", "invisible", turned(verts), faces),
    ]  # fmt: skip
    surface = [
        Variant(
            "noise", "surface", noisy(fine_verts, fine_faces, rng, PART_NOISE_EDGES), fine_faces
        ),
        Variant("smoothed", "surface", smoothed(fine_verts, fine_faces), fine_faces),
    ]
    return [*structural, *invisible, *surface]


def scan_tiers(verts: np.ndarray, faces: np.ndarray, rng: np.random.Generator) -> list[Variant]:
    """Every tier's variants of a mesh without named parts (a scan or a modelled surface): the
    structural edits of ``variants.surface_variants`` (a region cut out, a box set in), the
    invisible and the surface ones here (noise on the surface subdivided once)."""
    size = float(np.linalg.norm(np.ptp(verts, axis=0)))
    structural = [v for v in surface_variants(verts, faces, rng) if v.kind == "structural"]
    region = region_of(verts, verts[int(rng.integers(len(verts)))], 0.15 * size)[:, None]
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    normals = vertex_normals(verts, faces)
    fine_verts, fine_faces = subdivide(verts, faces)
    invisible = [
        Variant("retessellated", "invisible", fine_verts, fine_faces),
        Variant("jittered", "invisible", jittered(verts, faces, rng), faces),
        Variant("part_thickened", "invisible", verts + SCAN_PUSH * size * region * normals, faces),
        Variant("part_shifted", "invisible", verts + TINY_SHIFT * size * region * direction, faces),
        Variant("rotated", "invisible", turned(verts), faces),
    ]  # fmt: skip
    surface = [
        Variant("noise", "surface", noisy(fine_verts, fine_faces, rng), fine_faces),
        Variant("simplified", "surface", *simplified(verts, faces)),
        Variant("smoothed", "surface", smoothed(verts, faces), faces),
    ]
    return [*structural, *invisible, *surface]
