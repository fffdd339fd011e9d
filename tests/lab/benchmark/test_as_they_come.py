"""The benchmark's "meshes as they come" (``benchmark.as_they_come``): files holding the same
surface, small turns, a small hole and a small part removed, split once into two sides."""

import numpy as np
import pytest
import trimesh

from drkfs_lab.benchmark import as_they_come, sets
from drkfs_lab.benchmark.run import as_they_come_checks, tier_accuracy
from drkfs_onnx.contract.mesh import load_mesh
from drkfs_onnx.contract.render_equations import face_orientation
from drkfs_onnx.synthetic.variants import face_areas


@pytest.fixture(scope="module")
def cow():
    return load_mesh(sets.real_mesh("cow"))


def _surface(verts, faces) -> trimesh.Trimesh:
    """The surface a file holds: corners welded, each face once whichever way it is wound."""
    mesh = trimesh.Trimesh(verts, np.sort(faces, axis=1), process=False)
    mesh.merge_vertices()
    mesh.update_faces(mesh.unique_faces())
    return mesh


def _outward_share(verts: np.ndarray, faces: np.ndarray) -> float:
    """The share of faces whose outside read from the surface (``face_orientation``) looks
    away from the mesh's centre."""
    signs = face_orientation(verts, faces, np.eye(3) * 3)
    normals = np.cross(*(verts[faces[:, k]] - verts[faces[:, 0]] for k in (1, 2)))
    centres = verts[faces].mean(1) - (verts.min(0) + verts.max(0)) / 2
    return float((np.einsum("ij,ij->i", normals * signs[:, None], centres) > 0).mean())


def test_each_file_variant_holds_the_same_surface_and_reads_the_same_outside(cow):
    variants = as_they_come.file_variants(cow.vertices, cow.faces, np.random.default_rng(0))
    assert [v.name for v in variants] == list(as_they_come.FILES)
    base = _surface(cow.vertices, cow.faces)
    outward = _outward_share(cow.vertices, cow.faces)
    for v in variants:
        assert v.kind == "invisible"
        held = _surface(v.verts, v.faces)
        assert len(held.faces) == len(base.faces) and held.area == pytest.approx(base.area)
        assert _outward_share(v.verts, v.faces) == pytest.approx(outward, abs=1e-9), v.name


def test_the_turns_keep_the_shape_in_place_about_every_axis(cow):
    turns = as_they_come.turn_variants(cow.vertices, cow.faces)
    assert [v.name for v in turns] == [
        f"turned_{axis}_{d:g}" for axis in as_they_come.TURN_AXES for d in as_they_come.TURNS
    ]
    centre = (cow.vertices.min(0) + cow.vertices.max(0)) / 2
    for v in turns:
        moved = np.linalg.norm(v.verts - cow.vertices, axis=1)
        reach = np.linalg.norm(cow.vertices - centre, axis=1)
        degrees = float(v.name.rsplit("_", 1)[1])
        # a point moves by its distance from the axis times the angle: never more than its reach
        assert moved.max() <= np.radians(degrees) * reach.max() + 1e-9
        axis = as_they_come.TURN_AXES.index(v.name.split("_")[1])
        assert np.allclose(v.verts[:, axis] - centre[axis], cow.vertices[:, axis] - centre[axis])


def test_an_asset_loses_its_small_part_whole_and_the_small_hole_is_small():
    verts, faces, variants = as_they_come.asset("car", 4000)
    by_name = {v.name: v for v in variants}
    removed = by_name["part_removed"]
    assert removed.kind == "structural" and 0 < len(removed.faces) < len(faces)
    assert {v.kind for v in variants if v.name in as_they_come.FILES} == {"invisible"}
    hole = by_name["small_hole"]
    lost = 1 - face_areas(hole.verts, hole.faces).sum() / face_areas(verts, faces).sum()
    assert hole.kind == "surface" and 0 < lost < 0.05
    assert {"noise", "smoothed"} <= {v.name for v in variants if v.kind == "surface"}


def test_the_sides_split_the_bases_once_and_hold_every_base_of_the_section():
    sides = as_they_come.sides()
    training, held_out = set(sides["training"]), set(sides["held_out"])
    assert not training & held_out
    assert len(training) == len(held_out) == 5 + len(as_they_come.ASSET_PARTS) * 2


def test_the_checks_count_bases_on_each_side():
    bench, values = sets.BenchSet(), {}
    twos = {f"turned_{a}_2": 0.01 for a in as_they_come.TURN_AXES}
    files = dict.fromkeys(as_they_come.FILES, 0.0)
    rows = {
        # training: every check passes
        "asset-car-4000": {**twos, **files, "noise": 0.3, "small_hole": 0.2, "part_removed": 1.0},
        # held out: a turn about x above the small hole, a soup above it, the part below noise
        "asset-car-4002": {**twos, **files, "turned_x_2": 0.25, "soup": 0.3, "noise": 0.5,
                           "small_hole": 0.2, "part_removed": 0.4},
    }  # fmt: skip
    kinds = {"noise": "surface", "small_hole": "surface", "part_removed": "structural"}
    for base, row in rows.items():
        for label, value in row.items():
            kind = kinds.get(label, "invisible")
            values[len(bench.comparisons)] = value
            bench.comparisons.append(
                sets.Comparison(as_they_come.GROUP, base, label, kind, f"{base}/{label}", base)
            )
    checks = as_they_come_checks(bench, values)
    assert {c["share"] for c in checks["training"].values()} == {1.0}
    held = checks["held_out"]
    assert held["turn_2_below_every_surface"]["failed"] == ["asset-car-4002"]
    assert held["every_file_below_every_surface"]["failed"] == ["asset-car-4002"]
    assert held["part_above_every_surface"]["share"] == 0.0
    accuracy = tier_accuracy(bench, values, as_they_come.GROUP)
    assert accuracy["training"]["surface_vs_structural"] == 1.0
    assert accuracy["held_out"]["surface_vs_structural"] == 0.5  # above the hole, below noise
