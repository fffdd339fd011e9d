"""bench/turn_alignment.py: drkfs-1.1 against each compared mesh turned onto its reference
first (``contract.alignment``), recording the turns it applies."""

import argparse

from drkfs_lab import turn_alignment
from drkfs_lab.benchmark.methods import DrkfsOnnx, Placed
from drkfs_onnx import load_mesh
from drkfs_onnx.contract.cameras import rotation
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.contract.versions import metric_config

CHAIR = load_mesh(turn_alignment.EXAMPLES / "chair.obj")


def test_a_tilted_mesh_turned_onto_its_reference_scores_as_the_mesh_itself_and_is_recorded():
    options = argparse.Namespace(
        most_degrees=4.0, reference_samples=2048, samples=1024, steps=3, fitted=0.6
    )
    config = turn_alignment.turning_config(0.1, options)
    assert config == metric_config("drkfs-1.2")  # the study's defaults are the version's
    plain = DrkfsOnnx("default", metric_config("drkfs-1.1"), None, threads=2)
    aligned = turn_alignment.Recorded(DrkfsOnnx("aligned", config, None, threads=2))
    frame = frame_of(CHAIR.vertices)
    centre = frame[0]
    tilted_verts = (CHAIR.vertices - centre) @ rotation(0, 2.0).T + centre
    chair = Placed("chair", place(CHAIR.vertices, frame), CHAIR.faces)
    tilted = Placed("tilted", place(tilted_verts, frame), CHAIR.faces)
    before = plain.compare(plain.prepare(tilted)[0], plain.prepare(chair)[0])[0]
    after = aligned.compare(aligned.prepare(tilted)[0], aligned.prepare(chair)[0])[0]
    assert before > 0.01
    assert after < 0.01 * before
    assert abs(aligned.degrees["tilted"] - 2.0) < 0.05 and aligned.searches == 1
