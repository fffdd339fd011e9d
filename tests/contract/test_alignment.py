"""A compared mesh is turned onto its reference before it is described
(``contract.alignment``): the turn a viewer would not see is found and undone, the same surface
in other faces is left alone, and a part moved does not pull the turn."""

import numpy as np
from conftest import ROOT

from drkfs_lab.benchmark.torch_checks import chair, diagonal, shifted
from drkfs_onnx import load_mesh
from drkfs_onnx.contract import alignment
from drkfs_onnx.contract.cameras import rotation
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.contract.versions import metric_config
from drkfs_onnx.synthetic.shapes import assemble

CHAIR = load_mesh(ROOT / "examples" / "chair.obj")
TURNING = metric_config("drkfs-1.2")


def _found_degrees(verts, faces, onto=None, **settings) -> np.ndarray:
    """The turn (axis times degrees) applied to a mesh before it is compared with ``onto``
    (verts, faces; the example chair unless given), both placed in its frame, under drkfs-1.2
    with ``settings`` changed."""
    ref_verts, ref_faces = (CHAIR.vertices, CHAIR.faces) if onto is None else onto
    config, frame = TURNING.replace(**settings), frame_of(ref_verts)
    reference = alignment.reference_surface(place(ref_verts, frame), ref_faces, config)
    turn = alignment.aligning_turn(place(verts, frame), faces, reference, config)
    return np.degrees(alignment.rotation_vector(turn))


def _turned(axis: int, degrees: float) -> np.ndarray:
    centre = frame_of(CHAIR.vertices)[0]
    return (CHAIR.vertices - centre) @ rotation(axis, degrees).T + centre


def test_a_two_degree_tilt_about_any_axis_is_found_and_turned_back_about_that_axis():
    for axis in range(3):
        found = _found_degrees(_turned(axis, 2.0), CHAIR.faces)
        expected = np.zeros(3)
        expected[axis] = -2.0  # the turn that lays the tilted chair back on the chair
        assert np.abs(found - expected).max() < 0.05, (axis, found)


def test_a_config_that_turns_nothing_finds_no_turn_and_samples_no_reference():
    plain = metric_config("drkfs-1.1")
    assert alignment.reference_surface(CHAIR.vertices, CHAIR.faces, plain) is None
    assert not _found_degrees(_turned(0, 2.0), CHAIR.faces, align_degrees=0.0).any()


def test_the_same_surface_in_other_faces_is_not_turned_and_a_large_turn_is_kept_to_the_bound():
    flipped = CHAIR.faces[:, ::-1]
    soup = CHAIR.vertices[CHAIR.faces].reshape(-1, 3)
    assert not _found_degrees(CHAIR.vertices, flipped).any()
    assert not _found_degrees(soup, np.arange(len(soup)).reshape(-1, 3)).any()
    bounded = _found_degrees(_turned(0, 3.0), CHAIR.faces, align_degrees=1.0)
    assert abs(np.linalg.norm(bounded) - 1.0) < 1e-9 and bounded[0] < 0


def test_a_surface_without_area_is_not_turned():
    flat = np.zeros_like(CHAIR.vertices)
    assert not _found_degrees(flat, CHAIR.faces).any()
    assert not _found_degrees(CHAIR.vertices, CHAIR.faces, onto=(flat, CHAIR.faces)).any()


def test_a_trimmed_fit_is_not_pulled_by_one_part_moved():
    parts = chair()
    slid = assemble(shifted(parts, "leg_3", (0.05 * diagonal(parts), 0.0, 0.0)), 1)
    every_point, trimmed = (
        np.linalg.norm(_found_degrees(*slid, onto=assemble(parts, 1), align_fitted=fitted))
        for fitted in (1.0, 0.6)
    )
    assert every_point > 0.5  # the slid leg turns the chair
    assert trimmed < 0.01


def test_the_kept_turn_grows_continuously_from_none_to_all_of_the_found_one():
    found = [0.05, 0.1, 0.12, 0.15, 0.18, 0.2, 1.0, 3.0, 5.0]
    kept = [
        np.degrees(np.linalg.norm(alignment.kept_turn(np.radians([d, 0, 0]), TURNING)))
        for d in found
    ]
    assert kept[:2] == [0.0, 0.0]
    assert np.allclose(kept[2:4], [0.12 * 0.104, 0.15 * 0.5])  # smoothstep at 0.2 and 0.5
    assert kept == sorted(kept)
    assert np.allclose(kept[5:], [0.2, 1.0, 3.0, 4.0])


def test_verts_not_turned_are_returned_as_they_are():
    placed = place(CHAIR.vertices, frame_of(CHAIR.vertices))
    reference = alignment.reference_surface(placed, CHAIR.faces, TURNING)
    assert alignment.turned(placed, CHAIR.faces, reference, TURNING) is placed
    tilted = place(_turned(1, 2.0), frame_of(CHAIR.vertices))
    back = alignment.turned(tilted, CHAIR.faces, reference, TURNING)
    assert np.abs(back - placed).max() < 0.05 * np.abs(tilted - placed).max()
