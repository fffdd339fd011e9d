"""Levers for a viewer's tolerance and attention, measured without retraining: a config's nets
(the default's unless ``--nets``) under other matches, reductions, camera counts and view sizes,
on the benchmark's synthetic tiers and on both sides of its real-mesh tiers (a lever is chosen
on the training side and judged on the held-out one), with the bench's targets a default must
keep (the bars test, retrieval, the slide check; people's judgments with --human). Each lever
moves the config the nets were trained at (``NETS_TRAINED_AT``: 6 views of 128 px, t = 0.1,
the default's until the lever "5 cameras, 144 px, softmax t = 0.05" became the default), named
"default" in the results.

    python bench/real_levers.py --out bench/results/real_levers_tolerant.json
    python bench/real_levers.py --nets metric --out bench/results/real_levers.json
    python bench/real_levers.py --out ... --levers default "192 px" --human DIR  # and people

A view size with no shipped feature graph for the nets is exported for the run into a
temporary folder (the nets are convolutions: any size is the same weights).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from drkfs_onnx import PipelineConfig
from drkfs_onnx.benchmark import human, sets, torch_checks
from drkfs_onnx.benchmark.methods import DrkfsOnnx
from drkfs_onnx.benchmark.real_tiers import HELDOUT_MESHES, TRAINING_MESHES
from drkfs_onnx.benchmark.run import (
    bars_summary,
    lever_summary,
    retrieval_summary,
    score_everything,
    tier_accuracy,
)
from drkfs_onnx.contract.config import NETS_TRAINED_AT
from drkfs_onnx.contract.model_files import features_file, models_dir, shipped_entry
from drkfs_onnx.export.onnx_files import export_features
from drkfs_onnx.metric import DRKFS

LEVERS = {  # name -> the settings the lever moves (from NETS_TRAINED_AT's config)
    "default": {},
    "window r1": {"window": 1},
    "softmax t = 0.05": {"temperature": 0.05},
    "softmax t = 0.03": {"temperature": 0.03},
    "tail 10%": {"reduction": "tail", "tail_fraction": 0.1},
    "12 cameras": {"num_views": 12},
    "12 cameras, window r1": {"num_views": 12, "window": 1},
    "160 px": {"image_size": 160},
    "192 px": {"image_size": 192},
    "256 px": {"image_size": 256},
    "256 px, softmax t = 0.05": {"image_size": 256, "temperature": 0.05},
    # finer views at about the default's cost a mesh (from 144 px, with fewer cameras)
    "144 px, softmax t = 0.05": {"image_size": 144, "temperature": 0.05},
    "5 cameras, 144 px, softmax t = 0.05": {"num_views": 5, "image_size": 144, "temperature": 0.05},
    "4 cameras, 144 px, softmax t = 0.05": {"num_views": 4, "image_size": 144, "temperature": 0.05},
    # the neighbours of the default's 5 cameras of 144 px at t = 0.05
    "5 cameras, 144 px": {"num_views": 5, "image_size": 144},
    "5 cameras, 144 px, softmax t = 0.07": {"num_views": 5, "image_size": 144, "temperature": 0.07},
    "5 cameras, 144 px, softmax t = 0.04": {"num_views": 5, "image_size": 144, "temperature": 0.04},
    "5 cameras, 128 px, softmax t = 0.05": {"num_views": 5, "temperature": 0.05},
    "5 cameras, 160 px, softmax t = 0.05": {"num_views": 5, "image_size": 160, "temperature": 0.05},
    "4 cameras, 192 px": {"num_views": 4, "image_size": 192},
    "4 cameras, 192 px, softmax t = 0.05": {"num_views": 4, "image_size": 192, "temperature": 0.05},
    "3 cameras, 256 px, softmax t = 0.05": {"num_views": 3, "image_size": 256, "temperature": 0.05},
    "4 cameras, 256 px, softmax t = 0.05": {"num_views": 4, "image_size": 256, "temperature": 0.05},
}


def feature_graph(config: PipelineConfig, folder: Path) -> Path | None:
    """The shipped feature graph for ``config`` (None: the scorer finds it), else one exported
    into ``folder`` from the shipped weights."""
    if (models_dir() / features_file(config)).is_file():
        return None
    path = folder / features_file(config)
    if not path.exists():
        export_features(DRKFS.pretrained(config), path, shipped_entry(config, True)["sha256"])
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--nets", default=PipelineConfig().nets, help="the default's unless set")
    parser.add_argument(
        "--levers", nargs="+", choices=list(LEVERS), default=list(LEVERS), help="all unless set"
    )
    parser.add_argument("--human", type=Path, help="a Geo-metric clone (see drkfs bench --human)")
    args = parser.parse_args()
    start = time.perf_counter()
    default = PipelineConfig(nets=args.nets, **NETS_TRAINED_AT)
    configs = {name: default.replace(**LEVERS[name]) for name in args.levers}
    bench = sets.tier_set(quick=False)
    sets.real_tiers(bench, [*TRAINING_MESHES, *HELDOUT_MESHES])
    sets.bars(bench)  # the benchmark's own targets a default must keep
    sets.retrieval(bench, list(sets.ALL_FAMILIES), sets.RETRIEVAL_PER_FAMILY)
    jod = human.add_human(bench, args.human) if args.human else None
    with tempfile.TemporaryDirectory() as folder:
        methods = [
            DrkfsOnnx(name, config, feature_graph(config, Path(folder)), args.threads)
            for name, config in configs.items()
        ]
        scores, costs = score_everything(bench, methods, print)
    rows = {}
    for name, values in scores.comparisons.items():
        rows[name] = {
            "config": configs[name].to_dict(),
            "seconds_per_mesh": costs[name]["seconds_per_mesh"],
            **lever_summary(bench, values),
            "real_misses": tier_accuracy(bench, values, "real")["misses"],
            "bars": bars_summary(bench, values),
            "retrieval": retrieval_summary(bench, scores.retrieval[name]),
            "slide": torch_checks.slide(DRKFS.pretrained(configs[name])),
            "human": None if jod is None else human.human_agreement(bench, values, jod),
        }
        shown = ("tiers", "real", "checks", "bars", "human")
        print(name, json.dumps({k: rows[name][k] for k in shown}))
    results = {
        "command": f"python bench/real_levers.py --nets {args.nets} --out {args.out}"
        + ("" if args.levers == list(LEVERS) else " --levers " + " ".join(map(repr, args.levers)))
        + (" --human DIR" if args.human else ""),
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
