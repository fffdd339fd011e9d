"""Levers for a viewer's tolerance and attention (issue 71), measured without retraining: the
default's nets under other matches, reductions and camera counts, on the benchmark's synthetic
tiers and on both sides of its real-mesh tiers (a lever is chosen on the training side and
judged on the held-out one).

    python bench/real_levers.py --out bench/results/real_levers.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from drkfs_onnx import PipelineConfig
from drkfs_onnx.benchmark import sets
from drkfs_onnx.benchmark.methods import DrkfsOnnx
from drkfs_onnx.benchmark.real_tiers import HELDOUT_MESHES, TRAINING_MESHES
from drkfs_onnx.benchmark.run import lever_summary, score_everything, tier_accuracy

# the default's config with the metric nets, the default's when the levers were measured
DEFAULT = PipelineConfig(nets="metric")
LEVERS = {  # name -> the default with one lever moved (the shipped feature graph serves each)
    "default": DEFAULT,
    "window r1": DEFAULT.replace(window=1),
    "softmax t = 0.03": DEFAULT.replace(temperature=0.03),
    "tail 10%": DEFAULT.replace(reduction="tail", tail_fraction=0.1),
    "12 cameras": DEFAULT.replace(num_views=12),
    "12 cameras, window r1": DEFAULT.replace(num_views=12, window=1),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    start = time.perf_counter()
    bench = sets.tier_set(quick=False)
    sets.real_tiers(bench, [*TRAINING_MESHES, *HELDOUT_MESHES])
    methods = [DrkfsOnnx(name, config, None, args.threads) for name, config in LEVERS.items()]
    scores, costs = score_everything(bench, methods, print)
    rows = {}
    for name, values in scores.comparisons.items():
        rows[name] = {
            "config": LEVERS[name].to_dict(),
            "seconds_per_mesh": costs[name]["seconds_per_mesh"],
            **lever_summary(bench, values),
            "real_misses": tier_accuracy(bench, values, "real")["misses"],
        }
        print(name, json.dumps({k: rows[name][k] for k in ("tiers", "real", "checks")}))
    results = {
        "command": f"python bench/real_levers.py --out {args.out}",
        "threads": args.threads,
        "levers": rows,
        "values": {
            name: {
                f"{c.base}/{c.label}": values.get(i)
                for i, c in enumerate(bench.comparisons)
                if c.group in ("tiers", "real")
            }
            for name, values in scores.comparisons.items()
        },  # fmt: skip
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
