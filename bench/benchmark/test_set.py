"""The test set: pairs no default was chosen on, frozen, and scored only when a metric version is
released (``python bench/test_set.py --release NAME``), so that its figures stay held out.

Every other set of the benchmark has chosen something (docs/benchmark.md, "Validation, not held
out"). This one is built by the benchmark's own recipes at seeds no other set, study or training
run uses: every synthetic family's tier variants (``sets.tiers``) at ``TIER_SEEDS``, and the
part-based assets of "meshes as they come" (``as_they_come.asset``: file variants, turns,
surface variants, a small hole, a small part removed) at ``ASSET_SEEDS``. The repository's real
meshes have all chosen something, so none is here. ``DIGEST`` freezes the set: a change to the
recipes that moves any of its meshes or labels fails the tests, and a new set takes new seeds.
Only ``bench/test_set.py`` imports this module (``tests/test_bench.py`` holds it).
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
DIGEST = "6e4093bd014221f6867a791446fe62cb8de5a8ec8ee57c1d38825aa9d669820d"
DECIMALS = 5  # coordinates are hashed at this rounding: the last bits of a sine may differ


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
    """sha256 of every mesh (key, rounded vertices, faces) and every comparison's labels."""
    sha = hashlib.sha256()
    for key in sorted(bench.shapes):
        verts, faces = bench.shapes[key]
        sha.update(key.encode())
        sha.update(np.round(verts, DECIMALS).astype(np.float64).tobytes())
        sha.update(np.asarray(faces, np.int64).tobytes())
    for c in bench.comparisons:
        sha.update("|".join((c.group, c.base, c.label, c.kind, c.shape, c.reference)).encode())
    return sha.hexdigest()
