"""Reductions of the default's own best-match distances, on the tier set and people's judgments:
can a second component from the same descriptors (issue 30's "structure" and "surface") agree
with people better than the score does?

    python bench/reductions.py --out bench/results/reductions.json --human DIR

On the benchmark's tier set (``sets.tiers``) and, with ``--human``, Geo-metric's
simplification pairs (``human.add_human``; DIR as for ``drkfs bench --human``), the default's
feature graph describes every mesh once and finds each pair's best-match distances once
(``runtime.match.best_matches``, every direction the default searches). Each reduction of
REDUCTIONS then turns the same distances into a score (``match_rules.reduce``), the views' solid
term added as the default does (``runtime.match.pairing_solid``), scored by the
benchmark's own measures: the three tier accuracies (``run.tier_accuracy``) and the Spearman per
viewing setting (``human.human_agreement``). The default's own row reproduces the benchmark's.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import numpy as np

from drkfs_lab.benchmark import human, sets
from drkfs_lab.benchmark.methods import DrkfsOnnx, Placed
from drkfs_lab.benchmark.run import TIER_PAIRS, tier_accuracy
from drkfs_onnx.contract import match_rules
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.runtime.match import best_matches, pairing_solid

DEFAULT = PipelineConfig()
REDUCTIONS = {  # name -> the default with another reduction of the same distances
    f"default (softmax, t = {DEFAULT.temperature:g})": DEFAULT,
    "softmax, t = 0.03": DEFAULT.replace(temperature=0.03),
    "softmax, t = 1": DEFAULT.replace(temperature=1.0),
    "mean": DEFAULT.replace(reduction="mean"),
    "power 2": DEFAULT.replace(reduction="power", power=2.0),
    "power 8": DEFAULT.replace(reduction="power", power=8.0),
    "tail 10%": DEFAULT.replace(reduction="tail", tail_fraction=0.1),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--human", type=Path, help="a Geo-metric clone (see drkfs bench --human)")
    parser.add_argument("--quick", action="store_true", help="one synthetic base")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    start = time.perf_counter()
    bench = sets.tier_set(args.quick)
    jod = human.add_human(bench, args.human) if args.human else None
    method = DrkfsOnnx("DR-KFS", DEFAULT, None, args.threads)
    # comparison index -> (A's ring, B's ring) -> [(distances, weights)] per direction, for
    # every two rings a pairing's part may read (match_rules.pairing_part); a reduction's score
    # is the least over the pairings
    distances, solids = {}, {}  # and each pairing's solid term, which no reduction changes
    one = DEFAULT.one_ring()
    compared = list(itertools.product(range(len(DEFAULT.rings)), repeat=2))
    for reference in dict.fromkeys(c.reference for c in bench.comparisons):
        verts, faces = bench.shapes[reference]
        frame = frame_of(verts)
        described, _ = method.prepare(Placed(reference, place(verts, frame), faces))
        for i, c in enumerate(bench.comparisons):
            if c.reference == reference:
                shape_verts, shape_faces = bench.shapes[c.shape]
                shape, _ = method.prepare(Placed(c.shape, place(shape_verts, frame), shape_faces))
                distances[i] = {
                    (a, b): [
                        best_matches(queries, targets, one)
                        for queries, targets in match_rules.directions(
                            shape.ring(a), described.ring(b), one
                        )
                    ]
                    for a, b in compared
                }
                solids[i] = {
                    (a, b): pairing_solid(shape, described, a, b, DEFAULT)
                    for a, b in match_rules.ring_pairings(DEFAULT)
                }
    results = {
        "command": f"python bench/reductions.py --out {args.out}"
        + (" --human DIR" if args.human else "")
        + (" --quick" if args.quick else ""),
        "config": DEFAULT.to_dict(),
        "reductions": {name: config.to_dict() for name, config in REDUCTIONS.items()},
        "rows": {},
    }
    for name, config in REDUCTIONS.items():
        values = {i: _score(pairings, solids[i], config) for i, pairings in distances.items()}
        accuracy = tier_accuracy(bench, values)
        row = {
            "tiers": {pair: accuracy[pair] for pair in TIER_PAIRS},
            "human": None if jod is None else human.human_agreement(bench, values, jod),
        }
        results["rows"][name] = row
        agreement = "" if jod is None else [round(row["human"][s], 3) for s in human.SETTINGS]
        print(name, {p: round(a, 3) for p, a in row["tiers"].items()}, agreement, flush=True)
    results["seconds"] = time.perf_counter() - start
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")


def _score(pairings: dict, solids: dict, config: PipelineConfig) -> float:
    """One comparison's score under ``config`` from its distances and solid terms per pairing of
    rings: the least over the pairings of the descriptors' part plus the solid term."""

    def part(a: int, b: int) -> float:
        return float(np.mean([match_rules.reduce(d, w, config) for d, w in pairings[a, b]]))

    return min(
        match_rules.pairing_part(a, b, part, config) + solids[a, b]
        for a, b in match_rules.ring_pairings(config)
    )


if __name__ == "__main__":
    main()
