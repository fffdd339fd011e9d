"""bench/tilted_rings.py: what rings of the cameras turned about x and z could forgive, bounded
by the least score over the turns the rings would pair away."""

from drkfs_lab import tilted_rings
from drkfs_lab.benchmark import as_they_come, sets
from drkfs_onnx import load_mesh
from drkfs_onnx.runtime import Scorer


def test_a_tilt_by_the_rings_angle_is_paired_away_and_drkfs_1_1_still_sees_it():
    chair = load_mesh(tilted_rings.EXAMPLES / "chair.obj")
    centre = (chair.vertices.min(0) + chair.vertices.max(0)) / 2
    bench = sets.BenchSet()
    sets.add_variants(bench, "chair", chair.vertices, chair.faces, [])
    tilted = tilted_rings.turned(chair.vertices, centre, tilted_rings.AXES["z"], 2.5)
    bench.add("chair/tilted", tilted, chair.faces)
    bench.comparisons.append(
        sets.Comparison("as they come", "chair", "tilted", "invisible", "chair/tilted", "chair")
    )
    unturned = Scorer(metric=as_they_come.UNTURNED, threads=2)  # drkfs-1.2 turns it back
    found = tilted_rings.scores(bench, unturned, 2.5, lambda line: None)
    default, least = found["default"][0], found["least over the turns"][0]
    assert default > 0.01
    assert least < 1e-3 * default
