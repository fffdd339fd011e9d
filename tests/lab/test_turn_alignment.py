"""bench/turn_alignment.py: each compared mesh turned onto its reference before it is described,
by a fit of surface points, as registration finds a turn."""

import numpy as np

from drkfs_lab import turn_alignment
from drkfs_lab.benchmark.methods import DrkfsOnnx, Placed
from drkfs_lab.benchmark.torch_checks import chair, diagonal, shifted
from drkfs_onnx import PipelineConfig, load_mesh
from drkfs_onnx.contract.cameras import rotation
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.synthetic.shapes import assemble

CHAIR = load_mesh(turn_alignment.EXAMPLES / "chair.obj")


def _found_degrees(verts, faces, least=0.0, most=4.0, onto=None, **search) -> np.ndarray:
    """The turn (axis times degrees) found for a mesh onto ``onto`` (verts, faces; the example
    chair unless given), both placed in its frame, by a ``Search(**search)``."""
    ref_verts, ref_faces = (CHAIR.vertices, CHAIR.faces) if onto is None else onto
    frame = frame_of(ref_verts)
    found = turn_alignment.Search(**search)
    reference = found.reference(place(ref_verts, frame), ref_faces)
    turn = found.turn(place(verts, frame), faces, reference, least, most)
    return np.degrees(turn_alignment.rotation_vector(turn))


def _turned(axis: int, degrees: float) -> np.ndarray:
    centre = frame_of(CHAIR.vertices)[0]
    return (CHAIR.vertices - centre) @ rotation(axis, degrees).T + centre


def test_a_two_degree_tilt_is_found_and_turned_back_about_its_axis():
    for axis in range(3):
        found = _found_degrees(_turned(axis, 2.0), CHAIR.faces)
        expected = np.zeros(3)
        expected[axis] = -2.0  # the turn that lays the tilted chair back on the chair
        assert np.abs(found - expected).max() < 0.05, (axis, found)


def test_the_runtime_blas_search_finds_the_turn_the_kd_tree_finds():
    tilted = _turned(2, 2.0)
    kd = _found_degrees(tilted, CHAIR.faces, fitted=0.6)
    blas = _found_degrees(tilted, CHAIR.faces, fitted=0.6, nearest="blas")
    assert np.abs(blas - kd).max() < 1e-3 and abs(kd[2] + 2.0) < 0.05


def test_the_same_surface_in_other_faces_is_not_turned_and_a_large_turn_is_kept_past_the_bound():
    flipped = CHAIR.faces[:, ::-1]
    soup = CHAIR.vertices[CHAIR.faces].reshape(-1, 3)
    assert not _found_degrees(CHAIR.vertices, flipped, least=0.1).any()
    assert not _found_degrees(soup, np.arange(len(soup)).reshape(-1, 3), least=0.1).any()
    bounded = _found_degrees(_turned(0, 3.0), CHAIR.faces, most=1.0)
    assert abs(np.linalg.norm(bounded) - 1.0) < 1e-9 and bounded[0] < 0


def test_a_trimmed_fit_is_not_pulled_by_one_part_moved():
    parts = chair()
    slid = assemble(shifted(parts, "leg_3", (0.05 * diagonal(parts), 0.0, 0.0)), 1)
    every_point, trimmed = (
        np.linalg.norm(_found_degrees(*slid, fitted=fitted, onto=assemble(parts, 1)))
        for fitted in (1.0, 0.6)
    )
    assert every_point > 0.5  # the slid leg turns the chair
    assert trimmed < 0.01


def test_the_kept_turn_grows_continuously_from_none_to_all_of_the_found_one():
    found = [0.05, 0.1, 0.12, 0.15, 0.18, 0.2, 1.0, 3.0, 5.0]
    kept = [
        np.degrees(np.linalg.norm(turn_alignment.kept_turn(np.radians([d, 0, 0]), 0.1, 4.0)))
        for d in found
    ]
    assert kept[:2] == [0.0, 0.0]
    assert np.allclose(kept[2:4], [0.12 * 0.104, 0.15 * 0.5])  # smoothstep at 0.2 and 0.5
    assert kept == sorted(kept)
    assert np.allclose(kept[5:], [0.2, 1.0, 3.0, 4.0])


def test_a_tilted_mesh_scored_after_its_turn_is_searched_scores_as_the_mesh_itself():
    default = DrkfsOnnx("default", PipelineConfig(), None, threads=2)
    aligned = turn_alignment.Aligned(
        default, "aligned", 0.1, 4.0, turn_alignment.Search(fitted=0.6)
    )
    frame = frame_of(CHAIR.vertices)
    chair = Placed("chair", place(CHAIR.vertices, frame), CHAIR.faces)
    tilted = Placed("tilted", place(_turned(0, 2.0), frame), CHAIR.faces)
    plain = default.compare(default.prepare(tilted)[0], default.prepare(chair)[0])[0]
    turned_back = aligned.compare(aligned.prepare(tilted)[0], aligned.prepare(chair)[0])[0]
    assert plain > 0.01
    assert turned_back < 0.01 * plain
    assert abs(aligned.degrees["tilted"] - 2.0) < 0.05
