"""bench/view_reductions.py: the solid change's views reduced by a power mean instead of their
mean, each score recomposed from its ring pairings' parts."""

import math

import numpy as np

from drkfs_lab import view_reductions
from drkfs_lab.benchmark import sets
from drkfs_lab.tilted_rings import EXAMPLES
from drkfs_onnx import load_mesh
from drkfs_onnx.runtime import Scorer


def test_a_power_mean_runs_from_the_views_mean_to_their_largest():
    views = np.array([0.0, 0.1, 0.0, 0.0, 0.4])
    found = [view_reductions.power_mean(views, p) for p in view_reductions.ORDERS]
    assert found[0] == np.mean(views) and found[-1] == 0.4
    assert found == sorted(found) and math.isinf(view_reductions.ORDERS[-1])


def test_the_default_recomposed_from_its_pairings_is_the_default():
    chair = load_mesh(EXAMPLES / "chair.obj")
    bench = sets.BenchSet()
    sets.add_variants(bench, "chair", chair.vertices, chair.faces, [])
    bench.add("chair/noisy", chair.vertices + 0.01 * np.sin(7 * chair.vertices), chair.faces)
    bench.comparisons.append(
        sets.Comparison("as they come", "chair", "noisy", "surface", "chair/noisy", "chair")
    )
    found = view_reductions.scores(bench, Scorer(threads=2), lambda line: None)
    default = found["the default"][0]
    assert default > 0.01
    assert abs(found["p = 1, weight 1.2"][0] - default) < 1e-6
    assert found["p = inf, weight 1.2"][0] >= default
