"""The test set: pairs no default was chosen on, frozen, and scored only when a metric version is
released (``python bench/test_set.py --release NAME``), so that its figures stay held out.

Every other set of the benchmark has chosen something (docs/benchmark.md, "Validation, not held
out"). This one is built by the benchmark's own recipes at seeds no other set, study or training
run uses: every synthetic family's tier variants (``sets.tiers``) at ``TIER_SEEDS``, and the
part-based assets of "meshes as they come" (``as_they_come.asset``: file variants, turns,
surface variants, a small hole, a small part removed) at ``ASSET_SEEDS``. The repository's real
meshes have all chosen something, so none is here. ``DIGEST`` freezes the set: a change to the
recipes that moves any of its meshes or labels fails the tests, and a new set takes new seeds.
Only ``bench/test_set.py``, which scores it, and ``bench/check_results.py``, which reads the
committed scores, import this module (``tests/lab/benchmark/test_test_set.py`` holds it).
"""

from __future__ import annotations

import hashlib

import numpy as np

from drkfs_onnx.synthetic.shapes import FAMILIES

from . import as_they_come
from .sets import BenchSet, add_variants, tiers

TIER_SEEDS = (7000, 7001)  # every family's tier variants at each
ASSET_SEEDS = (7100, 7101)  # every asset family at each
TIERS_GROUP, ASSETS_GROUP = "test_tiers", "test_assets"
# sha256 of every mesh and label of the set (``digest``), taken when the set was made
DIGEST = "e103f1b44d42cd5b8dd7ee98c3fc2bcaa12847ba5a93bcc1cb571a17ace275d9"
# coordinates are hashed as integers on a grid of 1 / GRID, so that last bits that differ between
# machines move no hash: none of the set's coordinates lies within 1e-13 of a boundary of this
# binary grid, where 6,240 lie on one of a grid of 1e-5 ("nice" part sizes), and the sign of a
# coordinate within 1e-12 of 0 is lost
GRID = 2**16


def build() -> BenchSet:
    """The test set: the tier bases and the assets with their variants, in two groups."""
    bench = BenchSet()
    for seed in TIER_SEEDS:
        tiers(bench, list(FAMILIES), [], seed, f"test{seed}-", TIERS_GROUP)
    for seed in ASSET_SEEDS:
        for family in as_they_come.ASSET_PARTS:
            verts, faces, variants = as_they_come.asset(family, seed)
            key = "test-" + as_they_come.asset_key(family, seed)
            add_variants(bench, key, verts, faces, variants, ASSETS_GROUP)
    return bench


def digest(bench: BenchSet) -> str:
    """sha256 of every mesh (key, vertices on the grid ``GRID``, faces) and every comparison's
    labels."""
    sha = hashlib.sha256()
    for key in sorted(bench.shapes):
        verts, faces = bench.shapes[key]
        sha.update(key.encode())
        sha.update(np.rint(np.asarray(verts, np.float64) * GRID).astype(np.int64).tobytes())
        sha.update(np.asarray(faces, np.int64).tobytes())
    for c in bench.comparisons:
        sha.update("|".join((c.group, c.base, c.label, c.kind, c.shape, c.reference)).encode())
    return sha.hexdigest()
