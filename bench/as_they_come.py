"""The benchmark's "meshes as they come" section alone (``drkfs_lab.benchmark.as_they_come``):
each method's tier shares on both sides and the section's checks (docs/benchmark.md).

    python bench/as_they_come.py --out bench/results/as_they_come.json [--methods "DR-KFS,LFD"]
    python bench/as_they_come.py --renders bench/results/as_they_come.png   # what labels rest on

The DR-KFS rows are the default, drkfs-1.0 (each face's outside read from the file) and the
structure preset; beside them the outside metrics the README compares with.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from drkfs_lab.benchmark import as_they_come, sets
from drkfs_lab.benchmark.methods import DrkfsOnnx, build_methods
from drkfs_lab.benchmark.run import (
    as_they_come_checks,
    kept_from_run,
    score_with_peers,
    tier_accuracy,
)
from drkfs_lab.real_tiers import write_renders
from drkfs_onnx.contract.versions import metric_config

DEFAULT_METHODS = "DR-KFS,DR-KFS drkfs-1.0,DR-KFS structure,pixel MSE,Chamfer-L1,LFD"
FILE_WINDING = "DR-KFS drkfs-1.0"
# the variants drawn: what each label rests on (a file's variants render as its base under
# drkfs-1.1, so one stands for them)
DRAWN = ("half_flipped", "turned_x_3", "turned_z_3", "noise", "smoothed", "small_hole",
         "part_removed", "salient_part_removed", "hole_cut")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="the results' JSON")
    parser.add_argument("--renders", type=Path, help="a PNG of the variants each label rests on")
    parser.add_argument("--methods", default=DEFAULT_METHODS, help="outputs, comma-separated")
    parser.add_argument(
        "--keep", type=Path, help="an earlier run's JSON whose other methods' rows are kept"
    )
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--work", type=Path, default=Path("runs/as_they_come"))
    args = parser.parse_args()
    start = time.perf_counter()
    wanted = args.methods.split(",")
    bench = sets.BenchSet()
    as_they_come.add_section(bench)
    if args.renders is not None:
        drawn = sets.BenchSet(bench.shapes, [c for c in bench.comparisons if c.label in DRAWN])
        write_renders(drawn, args.renders, args.threads,
                      f"python bench/as_they_come.py --renders {args.renders}")  # fmt: skip
    if args.out is None:
        return
    # an earlier run's rows kept are checked before any scoring
    labels = {f"{c.base}/{c.label}": c.kind for c in bench.comparisons}
    kept, kept_summaries, kept_values = kept_from_run(args.keep, labels, wanted)
    methods = [m for m in build_methods(args.work / "models", args.threads)
               if set(m.outputs) & set(wanted)]  # fmt: skip
    if FILE_WINDING in wanted:
        methods.append(DrkfsOnnx(FILE_WINDING, metric_config("drkfs-1.0"), None, args.threads))
    scores, costs, notes = score_with_peers(bench, methods, print, wanted)
    scored = {name: values for name, values in scores.comparisons.items() if name in wanted}
    rows, values_by_name = {}, {}
    for name, values in scored.items():
        rows[name] = {
            **tier_accuracy(bench, values, as_they_come.GROUP),
            "checks": as_they_come_checks(bench, values),
            "seconds_per_pair": costs[name]["seconds_per_pair"],
        }
        values_by_name[name] = {
            f"{c.base}/{c.label}": values.get(i) for i, c in enumerate(bench.comparisons)
        }
    keep = f" --keep {args.keep}" if args.keep is not None else ""
    results = {
        "command": f"python bench/as_they_come.py --out {args.out} --methods '{args.methods}'"
        + keep,
        "threads": args.threads,
        "peers": {**kept["peers"], **notes},
        "sides": as_they_come.sides(),
        "labels": labels,
        "kept": kept,
        "methods": {**rows, **kept_summaries},
        "values": {**values_by_name, **kept_values},
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    for name, row in results["methods"].items():
        held, checks = row["held_out"], row["checks"]["held_out"]
        print(f"{name:24} held out {json.dumps(held)}; "
              + ", ".join(f"{k} {v['share']:.2f}" for k, v in checks.items()))  # fmt: skip


if __name__ == "__main__":
    main()
