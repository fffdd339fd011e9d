"""The benchmark's real-mesh tiers alone (``drkfs bench`` runs them with everything else): each
method's tier shares on both sides and the turn and salient-part checks (docs/benchmark.md).

    python bench/real_tiers.py --out bench/results/real_tiers.json [--methods "DR-KFS,LFD"]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from drkfs_onnx.benchmark import sets
from drkfs_onnx.benchmark.methods import build_methods
from drkfs_onnx.benchmark.real_tiers import HELDOUT_MESHES, TRAINING_MESHES
from drkfs_onnx.benchmark.run import peer_methods, real_checks, score_everything, tier_accuracy

DEFAULT_METHODS = "DR-KFS,DR-KFS paper,DR-KFS structure,pixel MSE,Chamfer-L1,F-score 1%,LFD"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--methods", default=DEFAULT_METHODS, help="outputs, comma-separated")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--work", type=Path, default=Path("runs/real_tiers"))
    args = parser.parse_args()
    start = time.perf_counter()
    wanted = args.methods.split(",")
    bench = sets.BenchSet()
    sets.real_tiers(bench, [*TRAINING_MESHES, *HELDOUT_MESHES])
    methods = [m for m in build_methods(args.work / "models", args.threads)
               if set(m.outputs) & set(wanted)]  # fmt: skip
    peers, notes = peer_methods() if "LFD" in wanted else ([], {})
    try:
        scores, costs = score_everything(bench, [*methods, *peers], print)
    finally:
        for peer in peers:
            peer.close()
    results = {
        "command": f"python bench/real_tiers.py --out {args.out} --methods '{args.methods}'",
        "threads": args.threads,
        "peers": notes,
        "sides": {"training": list(TRAINING_MESHES), "held_out": list(HELDOUT_MESHES)},
        "labels": {f"{c.base}/{c.label}": c.kind for c in bench.comparisons},
        "methods": {
            name: {
                **tier_accuracy(bench, values, "real"),
                "checks": real_checks(bench, values),
                "seconds_per_pair": costs[name]["seconds_per_pair"],
            }
            for name, values in scores.comparisons.items()
            if name in wanted
        },
        "values": {
            name: {f"{c.base}/{c.label}": values.get(i) for i, c in enumerate(bench.comparisons)}
            for name, values in scores.comparisons.items()
            if name in wanted
        },
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1))
    for name, row in results["methods"].items():
        held, checks = row["held_out"], row["checks"]["held_out"]
        print(
            f"{name:24} held-out inv<str {held['invisible_vs_structural']}, sur<str "
            f"{held['surface_vs_structural']}, inv<sur {held['invisible_vs_surface']}; turn "
            f"{checks['turn_below_every_surface']}, "
            f"salient {checks['salient_above_every_invisible']}"
        )


if __name__ == "__main__":
    main()
