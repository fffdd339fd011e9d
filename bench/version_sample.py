"""A fixed sample of the benchmark's pairs scored under every named metric version: what a
version scores, kept so that the version can be held to it after any default has moved.

    python bench/version_sample.py --out bench/results/version_sample.json

The sample: every ``EVERY``-th pair of the synthetic and real tiers (invisible, surface and
structural variants of synthetic shapes, shared and real meshes) and the stability cases that
read a file's faces (``WINDING_CASES``: what drkfs-1.1 changed), each scored against its base as
``drkfs bench`` scores it (the runtime, the mesh placed in its base's frame). The tests score
the sample again under each version; bench/check_results.py holds the newest versions' values
to the committed benchmark's.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from drkfs_lab.benchmark import sets
from drkfs_onnx.contract.mesh import Mesh
from drkfs_onnx.contract.versions import VERSIONS, metric_config
from drkfs_onnx.runtime import Scorer

EVERY = 60  # of the tier sets' pairs: 5 pairs
WINDING_CASES = ("flipped_faces", "duplicated_faces")


def sample() -> list[tuple[str, Mesh, Mesh]]:
    """("base/variant", the variant, its base) of every ``EVERY``-th pair of the tier sets and
    of the ``WINDING_CASES``."""
    bench = sets.tier_set(quick=False)
    sets.real_tiers(bench, [*sets.TRAINING_MESHES, *sets.HELDOUT_MESHES])
    tiers = bench.comparisons[::EVERY]
    sets.stability(bench, "cow", None)  # the benchmark's cases, but the 200k-face one
    cases = [c for c in bench.comparisons if c.group == "stability" and c.label in WINDING_CASES]
    return [
        (f"{c.base}/{c.label}", Mesh(*bench.shapes[c.shape], c.shape),
         Mesh(*bench.shapes[c.reference], c.reference))
        for c in [*tiers, *cases]
    ]  # fmt: skip


def scores(version: str, pairs: list[tuple[str, Mesh, Mesh]], threads: int = 2) -> dict:
    scorer = Scorer(metric_config(version), threads=threads)
    return {key: scorer.score(a, b) for key, a, b in pairs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    pairs = sample()
    found = {
        "command": f"python bench/version_sample.py --out {args.out}",
        "versions": {version: scores(version, pairs) for version in VERSIONS},
    }
    args.out.write_text(json.dumps(found, indent=1) + "\n")
    for version, values in found["versions"].items():
        print(version, ", ".join(f"{k} {v:.4g}" for k, v in values.items()))


if __name__ == "__main__":
    main()
