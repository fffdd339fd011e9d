"""The benchmark's real-mesh tiers: changes to the real meshes of ``meshes/`` ranked as a viewer
ranks them (bench/records/real_tiers.md shows their renders).

- invisible: the surface subdivided once, quadric decimation to half the faces, a turn of 1, 2
  or 3 degrees about the vertical;
- surface (a moderate defect of an intact shape): noise along the normals of a tenth of the
  mean edge, quadric decimation to a tenth of the faces, Taubin smoothing that erases detail
  (as many iterations as reach SMOOTHING_SCALE of the diagonal on the mesh's edges: 9 on the
  cow, 72 on the bunny, 152 on the beast);
- structural: a small salient part removed (the surface near the tip that sticks out furthest:
  a horn, an ear, a tail), a hole cut into the surface, and on a mesh of several pieces its
  second largest piece removed.

Decimation runs only on meshes of DECIMATED_FACES or more: on a coarser one (woody, the beetle)
half the faces already changes the outline, a tenth destroys the shape; and to half only from
HALF_FACES faces on: below, the flat-shaded renders of half the faces show speckled facets
(homer, the cheburashka), a defect rather than nothing. Where the renders show
another tier than the recipe's, ``RELABELLED`` says so: quadric decimation of the flat-faced
fandisk to a tenth is invisible, and so is smoothing the cheburashka and homer, smooth surfaces
with no detail to erase.

The meshes are split once: levers are chosen on the training side and judged on the held-out
side, so a change to the metric is never tuned on the meshes it is judged by.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import trimesh

from drkfs_onnx.synthetic.shapes import subdivide
from drkfs_onnx.synthetic.variants import (
    Variant,
    face_areas,
    salient_tip,
    vertex_normals,
    without_region,
)

from .tiers import TIERS, simplified, smoothed, turned

TRAINING_MESHES = ("alligator", "beetle", "cow", "fandisk", "woody")
HELDOUT_MESHES = ("beast", "cheburashka", "homer", "rocker-arm", "stanford-bunny")
TURNS = (1.0, 2.0, 3.0)  # degrees, each its own invisible variant
HALF = 0.5  # decimation a viewer does not see: the faces kept
HEAVY = 0.1  # decimation a viewer sees: the faces kept
NOISE_EDGES = 0.1  # surface noise's standard deviation, of the mean edge
DECIMATED_FACES = 5000  # the fewest faces a mesh is decimated from
HALF_FACES = 20000  # the fewest faces a mesh is decimated to half from
# Taubin smoothing's reach, of the diagonal: an iteration reaches about an edge, n of them about
# sqrt(n) edges, so a dense scan needs more iterations than a coarse model for the same detail
SMOOTHING_SCALE = 0.05
SALIENT_RADIUS = 0.06  # of the diagonal: the small part around the furthest tip
HOLE_RADIUS = 0.06  # of the diagonal: the hole around a random vertex
PIECE_SHARE = 0.01  # a second piece smaller than this share of the area is no part
# (mesh, variant) -> the tier its renders show, where that is not the recipe's
RELABELLED = {
    ("fandisk", "decimated_heavy"): "invisible",
    ("cheburashka", "smoothed"): "invisible",
    ("homer", "smoothed"): "invisible",
}


def parse_relabels(text: str) -> dict[tuple[str, str], str]:
    """Relabels written "mesh/variant=tier,..." -> {(mesh, variant): tier}: what the renders of
    meshes from outside the repository show where it is not the recipe's tier."""
    relabelled: dict[tuple[str, str], str] = {}
    for item in filter(None, text.split(",")):
        key, _, tier = item.partition("=")
        mesh, _, variant = key.partition("/")
        if not (mesh and variant and "/" not in variant and tier in TIERS):
            raise ValueError(f"{item!r}: a relabel is mesh/variant=tier, tier one of {TIERS}")
        if (mesh, variant) in relabelled:
            raise ValueError(f"{key!r} relabelled twice")
        relabelled[(mesh, variant)] = tier
    return relabelled


def mean_edge(verts: np.ndarray, faces: np.ndarray) -> float:
    """The mean length of the faces' edges (an edge of two faces counts twice)."""
    return float(np.linalg.norm(verts[faces[:, [1, 2, 0]]] - verts[faces], axis=-1).mean())


def second_piece(verts: np.ndarray, faces: np.ndarray) -> np.ndarray | None:
    """The faces of the mesh's second largest connected piece by area, or None where it has
    one piece, or the second holds less than PIECE_SHARE of the area."""
    labels = trimesh.graph.connected_component_labels(
        trimesh.Trimesh(verts, faces, process=False).face_adjacency, node_count=len(faces)
    )
    area = face_areas(verts, faces)
    per_piece = np.bincount(labels, area)
    if len(per_piece) < 2:
        return None
    order = np.argsort(-per_piece)
    if per_piece[order[1]] < PIECE_SHARE * area.sum():
        return None
    return labels == order[1]


def real_variants(
    name: str,
    verts: np.ndarray,
    faces: np.ndarray,
    rng: np.random.Generator,
    relabelled: dict[tuple[str, str], str] = RELABELLED,
) -> list[Variant]:
    """Every real-mesh tier's variants of the mesh ``name``, labelled as its renders show
    (the recipe's tier unless ``relabelled`` names the variant)."""
    size = float(np.linalg.norm(np.ptp(verts, axis=0)))
    used = np.unique(faces)
    hole_centre = verts[used[int(rng.integers(len(used)))]]
    edge = mean_edge(verts, faces)
    noise = rng.normal(size=len(verts)) * NOISE_EDGES * edge
    iterations = max(1, round((SMOOTHING_SCALE * size / edge) ** 2))
    variants = [
        Variant("subdivided", "invisible", *subdivide(verts, faces)),
        *(Variant(f"turned_{d:g}", "invisible", turned(verts, d), faces) for d in TURNS),
        Variant("noise", "surface", verts + noise[:, None] * vertex_normals(verts, faces), faces),
        Variant("smoothed", "surface", smoothed(verts, faces, iterations), faces),
        Variant("salient_part_removed", "structural", verts,
                without_region(faces, verts, salient_tip(verts, faces), SALIENT_RADIUS * size)),
        Variant("hole_cut", "structural", verts,
                without_region(faces, verts, hole_centre, HOLE_RADIUS * size)),
    ]  # fmt: skip
    if len(faces) >= HALF_FACES:
        variants.append(Variant("decimated_half", "invisible", *simplified(verts, faces, HALF)))
    if len(faces) >= DECIMATED_FACES:
        variants.append(Variant("decimated_heavy", "surface", *simplified(verts, faces, HEAVY)))
    piece = second_piece(verts, faces)
    if piece is not None:
        variants.append(Variant("piece_removed", "structural", verts, faces[~piece]))
    return [replace(v, kind=relabelled.get((name, v.name), v.kind)) for v in variants]
