"""The sweep that chose DR-KFS's default config: views x pixels x HardNet width x matching x
direction x reduction, on the benchmark's own sensitivity, bars, retrieval and stability sets.

    python bench/match_study.py --out bench/results/match_study.json [--threads 2] [--quick]

Each (views, pixels, width) describes every mesh once (numpy renderer + the shipped ONNX
graphs); every match variant is then scored from the same descriptors, so the variants differ
only in their match. Per variant the JSON holds the structural-ranking accuracy (overall,
synthetic, shared meshes), the bars ratio, retrieval and the stability cases it failed (``drkfs
bench``'s definitions), and per feature config the seconds per new mesh and per match.
``chosen`` applies the rule that picked the default (``choose``); ``holdout`` checks it, the
paper preset and Chamfer-L1 on synthetic bases of other seeds. A rerun with the same --out
resumes.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from drkfs_onnx import match_rules
from drkfs_onnx.benchmark import sets
from drkfs_onnx.benchmark.methods import Method, Placed, Surface, _timed
from drkfs_onnx.benchmark.run import _accuracy, _bars, _retrieval, _verdict, score_everything
from drkfs_onnx.config import PipelineConfig
from drkfs_onnx.runtime.match import best_matches
from drkfs_onnx.runtime.scorer import Scorer

WINDOWS = (0, 1, 2)
TOLERANCE = 0.01  # "within 1 point of the best accuracy"
RETRIEVAL = 0.83  # the retrieval the paper config had on this benchmark, not to be lost
# the stability cases a default must pass (the hidden cavity is DR-KFS's known blind spot)
REQUIRED_STABILITY = (
    "retessellated", "misaligned_1pct", "duplicated_faces", "flipped_faces",
    "far_from_origin", "other_scale",
)  # fmt: skip
DIRECTIONS = ("forward", "backward", "both")
REDUCTIONS = (
    [("sum", {}), ("mean", {})]
    + [("tail", {"tail_fraction": q}) for q in (0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2)]
    + [("power", {"power": p}) for p in (2.0, 4.0, 8.0, 16.0)]
    + [("softmax", {"temperature": t}) for t in (0.01, 0.03, 0.1, 0.3)]
)


def match_variants(base: PipelineConfig) -> dict[str, PipelineConfig]:
    """Every match setting swept, by name."""
    matchings = [("global", {"matching": "global"})] + [
        (f"window r{r}", {"matching": "window", "window": r}) for r in WINDOWS
    ]
    variants = {}
    for match_name, match in matchings:
        for direction in DIRECTIONS:
            for reduction, params in REDUCTIONS:
                label = " ".join(f"{v:g}" for v in params.values())
                name = f"{match_name} {direction} {reduction} {label}".strip()
                variants[name] = base.replace(
                    **match, direction=direction, reduction=reduction, **params
                )
    return variants


class Sweep(Method):
    """One feature config; ``compare`` returns every match variant's score, computing each
    matching's best-match distances once and reducing them every way."""

    def __init__(self, config: PipelineConfig, threads: int, prefix: str = ""):
        self.scorer = Scorer(config, threads=threads)  # the shipped graphs serve every config
        self.variants = match_variants(config)
        self.outputs = tuple(prefix + name for name in self.variants)
        self.match_seconds = {"global": 0.0, "window r1": 0.0}
        self.matches = 0

    def prepare(self, placed: Placed):
        images, render_s = placed.views(self.scorer.renderer)
        features, seconds = _timed(self.scorer.describe, images)
        return features, render_s + seconds

    def compare(self, a, b):
        cache = {}
        values = []
        for config in self.variants.values():
            scores = []
            for index, (queries, targets) in enumerate(match_rules.directions(a, b, config)):
                # B -> A is the only search of 'backward' and the second of 'both'
                side = "backward" if config.direction == "backward" or index else "forward"
                key = (config.matching, config.window, side)
                if key not in cache:
                    start = time.perf_counter()
                    cache[key] = best_matches(queries, targets, config)
                    label = "global" if config.matching == "global" else f"window r{config.window}"
                    if label in self.match_seconds and side == "forward":
                        self.match_seconds[label] += time.perf_counter() - start
                distances, weights = cache[key]
                scores.append(float(match_rules.reduce(distances, weights, config)))
            values.append(float(np.mean(scores)))
        self.matches += 1
        return tuple(values)


def feature_configs(quick: bool) -> list[PipelineConfig]:
    if quick:
        return [PipelineConfig(num_views=6, image_size=128)]
    return [
        PipelineConfig(num_views=views, image_size=size, descriptor_width=width)
        for size in (128, 256)
        for views in (6, 12, 25)
        for width in (0.25, 0.5, 1.0)
    ]


def summarise(bench: sets.BenchSet, scores, costs, sweep: Sweep) -> dict:
    cases = [(i, c) for i, c in enumerate(bench.comparisons) if c.group == "stability"]
    rows = {}
    for name in sweep.outputs:
        values = scores.comparisons[name]
        accuracy = _accuracy(bench, values)
        stability = {c.label: values.get(i) for i, c in cases}
        rows[name] = {
            "accuracy": accuracy["accuracy"],
            "accuracy_synthetic": accuracy["accuracy_synthetic"],
            "accuracy_real": accuracy["accuracy_real"],
            "bars_ratio": _bars(bench, values)["deletion_over_max_shift"],
            "retrieval": _retrieval(bench, scores.retrieval[name])["nearest_neighbour_accuracy"],
            # drkfs bench's verdicts: ignore below the median mild value, detect above it
            "stability_failed": [
                c.label
                for _, c in cases
                if _verdict(c.kind, stability[c.label], accuracy["median_mild"], stability) is False
            ],
        }
    cost = costs[sweep.outputs[0]]
    return {
        "seconds_per_mesh": cost["seconds_per_mesh"],
        "seconds_per_match": {k: v / max(sweep.matches, 1) for k, v in sweep.match_seconds.items()},
        "variants": rows,
    }


def choose(feature_configs: dict, baseline: dict, tolerance: float = TOLERANCE) -> dict:
    """The default. Admissible: above ``baseline`` (Chamfer-L1's accuracy on the synthetic and
    the shared-mesh halves) on both halves, retrieval at least RETRIEVAL, every
    REQUIRED_STABILITY case passed. Among the
    admissible variants within ``tolerance`` of their best accuracy: those of the cheapest
    feature config (seconds per new mesh: the match costs far less), then the best accuracy,
    bars ratio and retrieval, then the order-free direction and the smaller window. The bars
    ratio is reported, not required: no variant above Chamfer-L1 on both halves reaches 1.6."""
    rows = [
        (name, variant, row, entry["seconds_per_mesh"])
        for name, entry in feature_configs.items()
        for variant, row in entry["variants"].items()
        if row["accuracy_synthetic"] > baseline["accuracy_synthetic"]
        and row["accuracy_real"] > baseline["accuracy_real"]
        and row["retrieval"] >= RETRIEVAL
        and not set(row["stability_failed"]) & set(REQUIRED_STABILITY)
    ]
    best = max(row["accuracy"] for _, _, row, _ in rows)
    near = [r for r in rows if r[2]["accuracy"] >= best - tolerance]
    cheapest = min(seconds for *_, seconds in near)
    name, variant, row, seconds = min(
        (r for r in near if r[3] == cheapest),
        key=lambda r: (
            -r[2]["accuracy"], -r[2]["bars_ratio"], -r[2]["retrieval"],
            " both " not in r[1], r[1],
        ),
    )  # fmt: skip
    config = match_variants(PipelineConfig.from_dict(feature_configs[name]["config"]))[variant]
    return {
        "config": config.to_dict(),
        "rule": f"above Chamfer-L1 on both halves, retrieval >= {RETRIEVAL}, stability cases "
        f"{', '.join(REQUIRED_STABILITY)} passed; the cheapest feature config within "
        f"{tolerance:g} of the best such accuracy; then accuracy, bars ratio, retrieval, "
        "direction 'both', the smaller window",
        "baseline": baseline,
        "admissible_variants": len(rows),
        "best_admissible_accuracy": best,
        "best_accuracy_any": max(
            row["accuracy"]
            for entry in feature_configs.values()
            for row in entry["variants"].values()
        ),
        "feature_config": name,
        "variant": variant,
        "seconds_per_mesh": seconds,
        **row,
    }


def chamfer_baseline(path: Path) -> dict:
    """Chamfer-L1's accuracy on the two halves, from ``drkfs bench``'s results (the same
    sensitivity set: the same seeds and meshes)."""
    sensitivity = json.loads(path.read_text())["methods"]["Chamfer-L1"]["sensitivity"]
    return {key: sensitivity[key] for key in ("accuracy_synthetic", "accuracy_real")}


def holdout(chosen: dict, seeds: range, threads: int) -> dict:
    """Structural-ranking accuracy of the chosen default, the paper preset and Chamfer-L1 (and of
    every match at the default's feature config) on synthetic bases from other seeds than the
    benchmark's and the training's: did the choice fit the benchmark's own shapes?"""
    bench = sets.BenchSet()
    for seed in seeds:
        sets.sensitivity(bench, list(sets.FAMILIES), [], seed=seed, prefix=f"{seed}/")
    default = PipelineConfig.from_dict(chosen["config"])
    paper = PipelineConfig.paper()
    sweeps = [Sweep(default, threads, "default: "), Sweep(paper, threads, "paper: ")]
    scores, _ = score_everything(bench, [*sweeps, Surface()], lambda _: None)
    rows = {
        "default": scores.comparisons[f"default: {chosen['variant']}"],
        "paper": scores.comparisons["paper: global forward sum"],
        "Chamfer-L1": scores.comparisons["Chamfer-L1"],
    }
    return {
        "seeds": [seeds.start, seeds.stop - 1],
        "bases": len(seeds) * len(sets.FAMILIES),
        **{name: _accuracy(bench, values) for name, values in rows.items()},
        # every match of the default's feature config: was the chosen one lucky?
        "default_feature_config_variants": {
            name: _accuracy(bench, scores.comparisons[f"default: {name}"])["accuracy"]
            for name in sweeps[0].variants
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument(
        "--baseline",
        type=Path,
        default=Path(__file__).parent / "results" / "results.json",
        help="drkfs bench results whose Chamfer-L1 halves a default must beat (read only)",
    )
    args = parser.parse_args()
    start = time.perf_counter()
    bench = sets.BenchSet()
    if args.quick:
        sets.sensitivity(bench, ["chair"], [])
        sets.retrieval(bench, ["chair", "table", "lamp"], 2)
    else:
        sets.sensitivity(bench, list(sets.FAMILIES), sets.SWEPT_MESHES)
        sets.retrieval(bench, list(sets.FAMILIES), 2)
        sets.stability(bench, "cow", "stanford-bunny")
    sets.bars(bench)
    results = {
        "command": f"python bench/match_study.py --out {args.out}"
        + (" --quick" if args.quick else ""),
        "threads": args.threads,
        "comparisons": len(bench.comparisons),
        "feature_configs": {},
    }
    if args.out.is_file():  # resume: keep the feature configs a previous run finished
        done = json.loads(args.out.read_text())
        if done["command"] == results["command"]:
            results = done
    for config in feature_configs(args.quick):
        name = f"{config.num_views} views {config.image_size} px w{config.descriptor_width:g}"
        if name in results["feature_configs"]:
            continue
        sweep = Sweep(config, args.threads)
        scores, costs = score_everything(bench, [sweep], lambda _: None)
        results["feature_configs"][name] = {
            "config": config.features_part().to_dict(),
            **summarise(bench, scores, costs, sweep),
        }
        start = _save(results, args.out, start)
        variants = results["feature_configs"][name]["variants"]
        best = max(variants, key=lambda variant: variants[variant]["accuracy"])
        print(f"{name}: best {best} {variants[best]}")
    results["chosen"] = choose(results["feature_configs"], chamfer_baseline(args.baseline))
    print(f"chosen: {results['chosen']}")
    if not args.quick and "holdout" not in results:
        results["holdout"] = holdout(results["chosen"], sets.HOLDOUT_SEEDS, args.threads)
        print(f"held out: {results['holdout']}")
    _save(results, args.out, start)


def _save(results: dict, path: Path, start: float) -> float:
    """Write the results with the seconds spent so far (resumed runs add up); the new start."""
    now = time.perf_counter()
    results["seconds_total"] = results.get("seconds_total", 0.0) + (now - start)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=1))
    return now


if __name__ == "__main__":
    main()
