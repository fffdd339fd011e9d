"""The benchmark's "meshes as they come": what files hold and a viewer never sees, beside what a
viewer does see, on the repository's real meshes and on part-based assets with small parts.

- invisible: the same surface as a file may hold it: a random half of the faces wound the
  other way, every face wound the other way, each face doubled for both sides, each face
  repeated, an unwelded soup (every face its own three corners); and turns of 1, 2 and 3
  degrees about each axis through the bounding box's centre;
- surface: the tier sets' surface variants (noise, smoothing; on a scan also heavy
  decimation) and a small hole (the faces within SMALL_HOLE of the diagonal of a random
  point of the surface that faces the cameras cut out);
- structural: on an asset, a small part removed (a wheel, a handle, a leg, an arm); on a real
  mesh, the real tiers' structural variants (a salient part, a hole of twice the small one's
  radius, a second piece).

Assets are built at their own seeds (``ASSET_SEEDS``, neither the benchmark's nor training's).
Both kinds are split once, the real meshes as the real tiers, the assets by seed: a lever is
chosen on the training side and judged on the held-out side.
"""

from __future__ import annotations

import numpy as np

from drkfs_onnx.contract.cameras import make_cameras, rotation
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import load_mesh
from drkfs_onnx.contract.render_equations import face_orientation
from drkfs_onnx.synthetic.shapes import assemble, random_shape
from drkfs_onnx.synthetic.variants import Variant, without_region

from .real_tiers import HELDOUT_MESHES, TRAINING_MESHES, real_variants
from .sets import BenchSet, add_variants, real_mesh
from .tiers import FINE_SUBDIVISIONS, part_tiers

GROUP = "as_they_come"
# family -> the parts removed together as one small part
ASSET_PARTS = {
    "car": ("wheel_0",),
    "bicycle": ("wheel_0",),
    "mug": ("handle_low", "handle_high", "handle_grip"),
    "chair": ("leg_0",),
    "stool": ("leg_0",),
    "sofa": ("arm_left",),
}
ASSET_SEEDS = {"training": (4000, 4001), "held_out": (4002, 4003)}
ASSET_PREFIX = "asset-"  # an asset's base key: ``asset_key``
REAL_PREFIX = "came-"  # a real mesh's base key here: came-<mesh>
FILES = ("half_flipped", "all_flipped", "double_sided", "repeated", "soup")
TURN_AXES = ("x", "y", "z")
TURNS = (1.0, 2.0, 3.0)  # degrees
SMALL_HOLE = 0.03  # of the diagonal: a hole a viewer sees, in a surface left whole
FACING = 0.5  # a face faces a camera: the cosine of its normal and the camera's direction
# the version the studies of this section's turns asked (bench/tilted_rings.py, view_reductions.py,
# turn_parts.py, turn_alignment.py): the default before drkfs-1.2 turned a mesh onto its reference
UNTURNED = "drkfs-1.1"
SEED = 2026


def file_variants(verts: np.ndarray, faces: np.ndarray, rng: np.random.Generator) -> list[Variant]:
    """The same surface as files hold it: faces wound either way, doubled, repeated, unwelded."""
    flips = rng.random(len(faces)) < 0.5
    corners = verts[faces].reshape(-1, 3)
    held = {
        "half_flipped": (verts, np.where(flips[:, None], faces[:, ::-1], faces)),
        "all_flipped": (verts, faces[:, ::-1].copy()),
        "double_sided": (verts, np.concatenate([faces, faces[:, ::-1]])),
        "repeated": (verts, np.concatenate([faces, faces])),
        "soup": (corners, np.arange(len(corners)).reshape(-1, 3)),
    }
    return [Variant(name, "invisible", *held[name]) for name in FILES]


def turn_variants(verts: np.ndarray, faces: np.ndarray) -> list[Variant]:
    """Turns of each of ``TURNS`` about each axis through the bounding box's centre."""
    centre = (verts.min(0) + verts.max(0)) / 2
    return [
        Variant(
            f"turned_{name}_{d:g}",
            "invisible",
            (verts - centre) @ rotation(axis, d).T + centre,
            faces,
        )
        for axis, name in enumerate(TURN_AXES)
        for d in TURNS
    ]


def small_hole(verts: np.ndarray, faces: np.ndarray, rng: np.random.Generator) -> Variant:
    """The faces within ``SMALL_HOLE`` of the diagonal of a random point of the surface cut
    out: a face drawn by its area times the number of the default's cameras it faces
    (``FACING``), so that the hole shows."""
    size = float(np.linalg.norm(np.ptp(verts, axis=0)))
    corners = verts[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = np.linalg.norm(normals, axis=1)
    directions = make_cameras(PipelineConfig()).eyes
    directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    outward = normals * face_orientation(verts, faces, directions * size)[:, None]
    seen = (outward @ directions.T > FACING * area[:, None]).sum(1)
    weights = area * seen
    centre = corners[rng.choice(len(faces), p=weights / weights.sum())].mean(0)
    return Variant("small_hole", "surface", verts,
                   without_region(faces, verts, centre, SMALL_HOLE * size))  # fmt: skip


def asset(family: str, seed: int) -> tuple[np.ndarray, np.ndarray, list[Variant]]:
    """An asset of ``family`` at ``seed``: its mesh and every variant of this section."""
    rng = np.random.default_rng(seed)
    parts = random_shape(family, rng)
    verts, faces = assemble(parts, 1)  # the tier sets' tessellation of a part-based shape
    surface = [v for v in part_tiers(parts, rng) if v.kind == "surface"]
    removed = assemble([p for p in parts if p.name not in ASSET_PARTS[family]], 1)
    fine = assemble(parts, FINE_SUBDIVISIONS)  # faces finer than the hole, as noise's
    return (
        verts,
        faces,
        [
            *file_variants(verts, faces, rng),
            *turn_variants(verts, faces),
            *surface,
            small_hole(*fine, rng),
            Variant("part_removed", "structural", *removed),
        ],
    )


def real_mesh_variants(
    name: str, verts: np.ndarray, faces: np.ndarray, rng: np.random.Generator
) -> list[Variant]:
    """A real mesh's variants of this section: the file variants, the turns, the real tiers'
    surface and structural variants and a small hole."""
    tiers = [v for v in real_variants(name, verts, faces, rng) if v.kind != "invisible"]
    return [
        *file_variants(verts, faces, rng),
        *turn_variants(verts, faces),
        *tiers,
        small_hole(verts, faces, rng),
    ]


def asset_key(family: str, seed: int) -> str:
    """An asset's base key: asset-<family>-<seed>."""
    return f"{ASSET_PREFIX}{family}-{seed}"


def sides() -> dict[str, list[str]]:
    """The section's base keys by side: chosen on ("training"), judged on ("held_out")."""
    return {
        side: [REAL_PREFIX + m for m in meshes]
        + [asset_key(family, seed) for seed in ASSET_SEEDS[side] for family in ASSET_PARTS]
        for side, meshes in (("training", TRAINING_MESHES), ("held_out", HELDOUT_MESHES))
    }


def add_section(bench: BenchSet, seed: int = SEED) -> None:
    """Every base of this section and its variants into ``bench``, as the ``GROUP`` group."""
    rng = np.random.default_rng(seed)
    for name in (*TRAINING_MESHES, *HELDOUT_MESHES):
        mesh = load_mesh(real_mesh(name))
        variants = real_mesh_variants(name, mesh.vertices, mesh.faces, rng)
        add_variants(bench, REAL_PREFIX + name, mesh.vertices, mesh.faces, variants, GROUP)
    for seeds in ASSET_SEEDS.values():
        for asset_seed in seeds:
            for family in ASSET_PARTS:
                verts, faces, variants = asset(family, asset_seed)
                add_variants(bench, asset_key(family, asset_seed), verts, faces, variants, GROUP)
