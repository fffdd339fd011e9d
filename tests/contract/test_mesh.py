"""Mesh input: every format trimesh reads, clear errors naming file and reason, normalisation."""

import numpy as np
import pytest
import trimesh
from conftest import ROOT

from drkfs_onnx.contract.mesh import Mesh, MeshError, check_mesh, load_mesh, normalize_pair

EXAMPLES = ROOT / "examples"


@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "off", "glb"])
def test_loads_common_formats(tmp_path, ext):
    path = tmp_path / f"box.{ext}"
    trimesh.creation.box(extents=(1, 2, 3)).export(path)
    mesh = load_mesh(path)
    assert mesh.faces.shape == (12, 3)
    assert np.allclose(np.ptp(mesh.vertices, axis=0), [1, 2, 3])
    assert mesh.source == str(path)


def test_scenes_are_merged(tmp_path):
    scene = trimesh.Scene(
        [
            trimesh.creation.box(),
            trimesh.creation.icosphere(subdivisions=1).apply_translation([3, 0, 0]),
        ]
    )
    path = tmp_path / "scene.glb"
    scene.export(path)
    assert len(load_mesh(path).faces) == 12 + 80


def _error(path) -> MeshError:
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    assert str(path) in str(info.value)
    return info.value


def test_missing_file(tmp_path):
    assert "no such file" in _error(tmp_path / "nope.obj").reason


def test_unreadable_file(tmp_path):
    path = tmp_path / "junk.ply"
    path.write_bytes(b"ply\nformat nonsense\n\x00\x01\x02")
    assert "unreadable" in _error(path).reason


def test_point_cloud_has_no_faces(tmp_path):
    path = tmp_path / "cloud.ply"
    trimesh.PointCloud(np.random.default_rng(0).random((20, 3))).export(path)
    assert _error(path).reason == "20 vertices and no faces (a point cloud?)"


def test_a_file_without_faces_says_what_it_holds(tmp_path):
    empty, noise, strips = tmp_path / "empty.obj", tmp_path / "noise.obj", tmp_path / "strips.ply"
    empty.write_bytes(b"")
    noise.write_bytes(np.random.default_rng(0).integers(0, 256, 2000, dtype=np.uint8).tobytes())
    strips.write_text(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement tristrips 1\nproperty list int int vertex_indices\n"
        "end_header\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3\n"
    )
    assert _error(empty).reason == "an empty file"
    assert _error(noise).reason == "no vertices and no faces: not a .obj file trimesh can read"
    assert "triangle strips (element tristrips)" in _error(strips).reason


def test_nan_and_inf_vertices(tmp_path):
    path = tmp_path / "nan.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 inf 1\nf 1 2 3\nf 1 2 4\n")
    assert _error(path).reason.startswith("2 vertices are NaN or infinite (first: vertex 2)")
    path.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 1 1\nf 1 2 3\nf 1 2 4\n")
    assert _error(path).reason.startswith("1 vertex is NaN or infinite (first: vertex 2)")


def test_all_degenerate_faces(tmp_path):
    path = tmp_path / "flat.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n")
    assert "no non-degenerate triangle" in _error(path).reason


def test_degenerate_faces_are_dropped():
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], dtype=float)
    mesh = check_mesh(verts, np.array([[0, 1, 2], [0, 1, 3], [1, 1, 2]]))
    assert mesh.faces.tolist() == [[0, 1, 2]]


def test_out_of_range_indices():
    with pytest.raises(MeshError, match="out of range"):
        check_mesh(np.zeros((3, 3)), np.array([[0, 1, 5]]))


def test_joint_normalisation_uses_the_reference_frame():
    ref = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0, 2.0]]) + 5
    other = ref * 1.1
    a, b = normalize_pair(other, ref, "joint")
    assert np.isclose(np.linalg.norm(b.max(0) - b.min(0)), 2.0)
    assert np.allclose(b.min(0) + b.max(0), 0)
    assert np.allclose(a, (other - 6) / np.sqrt(3))  # same map as the reference


def test_each_and_none_normalisation():
    ref = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0.0]])
    other = ref * 3 + 7
    a, b = normalize_pair(other, ref, "each")
    assert np.allclose(a, b)
    a, b = normalize_pair(other, ref, "none")
    assert a is other and b is ref
    with pytest.raises(ValueError, match="unknown normalisation"):
        normalize_pair(other, ref, "unit")


def test_textured_multi_part_obj_loads_geometry_without_pillow(real_meshes):
    """beast.obj references textures (trimesh would need Pillow) and has 20 parts."""
    mesh = load_mesh(real_meshes / "beast.obj")
    assert mesh.faces.shape == (64618, 3)


def test_a_mesh_in_other_units_and_off_the_origin_is_placed_in_the_unit_sphere():
    chair = load_mesh(EXAMPLES / "chair.obj")
    far = Mesh(chair.vertices * 40.0 + (100.0, -7.0, 3.0), chair.faces, "far.obj")
    placed = far.in_unit_sphere()
    np.testing.assert_allclose(placed.vertices, chair.in_unit_sphere().vertices, atol=1e-12)
    box = placed.vertices.min(0) + placed.vertices.max(0)
    np.testing.assert_allclose(box, 0.0, atol=1e-12)  # the box's centre at the origin
    assert np.linalg.norm(placed.vertices, axis=1).max() == pytest.approx(1.0)
    assert placed.faces is far.faces and placed.source == "far.obj"
