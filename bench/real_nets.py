"""Nets with a viewer's tolerance (bench/records/real_levers.md), fine-tuned and judged.

    python bench/real_nets.py --out bench/results/real_nets.json [--steps N] [--quick]
    python bench/real_nets.py --out ... --save-nets FILE   # also the fine-tuned nets' state
    python bench/real_nets.py --out ... --simplification   # also simplification series
    python bench/real_nets.py --out ... --salient   # also a removed tip and a cut hole a base
    python bench/real_nets.py --out ... --simplification --series-weight 3   # that term x3
    python bench/real_nets.py --out ... --image-size 192   # trained and judged at 192-px views
    python bench/real_nets.py --out ... --num-views 5 --image-size 144  # at the default's views
    python bench/real_nets.py --out ... --from-default --work DIR  # the default's nets, judged
                                                                    # at the default
    python bench/real_nets.py --out ... --slides   # also a part slid evenly (the slide check)
    python bench/real_nets.py --out ... --slides-below-removed   # and below the part removed

1. The shipped metric nets (the default's before the tolerant ones) fine-tuned with
   ``training.tolerance.tolerance_ranking`` on synthetic tiers of other seeds than the
   benchmark's (work folder ``--work``, resumable);
   with ``--simplification``, also ranking simplifications of smoothed synthetic shapes; with
   ``--salient``, each base also has the real tiers' two small structural changes
   (``tolerance.small_regions_removed``); with ``--slides``, also slide series of a part, asked
   to score up evenly (``tolerance.uneven_rise``).
2. Both judged as ``bench/real_levers.py`` judges a lever: the benchmark's synthetic tiers,
   both sides of the real tiers and their checks, the bars test and the slide check, at each
   config of ``CONFIGS`` (the same nets, at the views trained at); with ``--human DIR``, their
   agreement with people on Geo-metric's simplifications (as ``drkfs bench --human``). The
   results committed so far name the metric nets' rows "shipped nets".

With ``--from-default`` the nets fine-tuned are the default's own (the tolerant nets) at its
views, one ring of them, and both are judged at the default itself (its turned ring and solid
change); a run of its own needs a ``--work`` folder of its own, since a checkpoint's name does
not say which nets it started from.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from drkfs_lab.benchmark import human, sets, torch_checks
from drkfs_lab.benchmark.methods import DrkfsTorch
from drkfs_lab.benchmark.real_tiers import HELDOUT_MESHES, TRAINING_MESHES
from drkfs_lab.benchmark.run import (
    TIER_PAIRS,
    bars_summary,
    lever_summary,
    score_everything,
    tier_accuracy,
)
from drkfs_lab.training import tolerance
from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract.config import NETS_TRAINED_AT
from drkfs_onnx.metric import DRKFS, with_nets

# the nets fine-tuned: the metric nets (the default's before the tolerant nets), at their config
DEFAULT = PipelineConfig(nets="metric", **NETS_TRAINED_AT)
CONFIGS = {
    "": DEFAULT,
    ", softmax t = 0.05": DEFAULT.replace(temperature=0.05),
    ", softmax t = 0.03": DEFAULT.replace(temperature=0.03),
}


def judged(bench: sets.BenchSet, metrics: dict[str, DRKFS], jod: dict | None) -> dict:
    """Each metric's synthetic tier shares, real tier shares per side and real checks, the bars
    test and the slide check, and with ``jod`` its agreement with people."""
    scores, _ = score_everything(bench, [DrkfsTorch(name, m) for name, m in metrics.items()], print)
    rows = {}
    for name, values in scores.comparisons.items():
        synthetic = tier_accuracy(bench, values)
        rows[name] = {
            **lever_summary(bench, values),
            "tier_halves": {half: {k: synthetic[half][k] for k in TIER_PAIRS}
                            for half in ("synthetic", "shared")},
            "tier_misses": synthetic["misses"],
            "real_misses": tier_accuracy(bench, values, "real")["misses"],
            "bars": bars_summary(bench, values),
            "slide": torch_checks.slide(metrics[name]),
            "values": {f"{c.base}/{c.label}": values.get(i) for i, c in enumerate(bench.comparisons)
                       if c.group == "real"},
            "human": None if jod is None else human.human_agreement(bench, values, jod),
        }  # fmt: skip
        print(name, json.dumps({k: rows[name][k] for k in ("tiers", "real", "human")}), flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--lr", type=float, default=2e-4)
    parser.add_argument("--work", type=Path, default=Path(".drkfs-train/real-nets"))
    parser.add_argument(
        "--temperature",
        type=float,
        default=DEFAULT.temperature,
        help="the softmax temperature the nets are fine-tuned at",
    )
    parser.add_argument(
        "--simplification",
        action="store_true",
        help="also rank quadric simplifications of smoothed synthetic shapes, coarser above finer",
    )
    parser.add_argument(
        "--salient",
        action="store_true",
        help="also a removed tip and a cut hole of each synthetic base as structural changes",
    )
    parser.add_argument(
        "--series-weight",
        type=float,
        default=1.0,
        help="the simplification term's weight against the tiers' (with --simplification)",
    )
    parser.add_argument(
        "--image-size",
        type=int,
        default=DEFAULT.image_size,
        help="the views' size, for the training data and the judging (NETS_TRAINED_AT's if unset)",
    )
    parser.add_argument(
        "--num-views",
        type=int,
        default=DEFAULT.num_views,
        help="the cameras, for the training data and the judging (NETS_TRAINED_AT's if unset)",
    )
    parser.add_argument(
        "--slides",
        action="store_true",
        help="also ask a part slid sideways step by step to score up evenly",
    )
    parser.add_argument(
        "--slides-below-removed",
        action="store_true",
        help="the slide series also ranked below the slid part removed (implies --slides)",
    )
    parser.add_argument(
        "--from-default",
        action="store_true",
        help="fine-tune the default's nets at its views and judge both at the default",
    )
    parser.add_argument("--save-nets", type=Path)
    parser.add_argument("--human", type=Path, help="a Geo-metric clone (see drkfs bench --human)")
    parser.add_argument("--quick", action="store_true", help="two bases, the quick benchmark")
    args = parser.parse_args()
    torch.set_num_threads(2)
    start = time.perf_counter()
    work = args.work / ("quick" if args.quick else "full")
    work.mkdir(parents=True, exist_ok=True)
    if args.from_default:  # the default's nets at its views, one ring (the ranking's)
        start_config = PipelineConfig().one_ring()
        views = {"image_size": start_config.image_size, "num_views": start_config.num_views}
    else:
        views = {"image_size": args.image_size, "num_views": args.num_views}
        start_config = DEFAULT.replace(**views)
    metric_nets = DRKFS.pretrained(start_config).eval()
    data = tolerance.tier_views(work, start_config, args.quick, args.salient)
    series = (
        tolerance.simplified_views(work, start_config, args.quick) if args.simplification else None
    )
    slides = (
        tolerance.slide_views(work, start_config, args.quick, args.slides_below_removed)
        if args.slides or args.slides_below_removed
        else None
    )
    began = time.perf_counter()
    tuned = tolerance.fine_tune(
        metric_nets,
        data,
        args.steps,
        args.lr,
        args.temperature,
        work,
        series,
        args.salient,
        args.series_weight,
        slides,
    )
    train_seconds = time.perf_counter() - began
    if args.save_nets is not None:
        args.save_nets.parent.mkdir(parents=True, exist_ok=True)
        torch.save(tuned.state_dict(), args.save_nets)
    bench = sets.tier_set(args.quick)
    sets.real_tiers(bench, ["woody"] if args.quick else [*TRAINING_MESHES, *HELDOUT_MESHES])
    sets.bars(bench)
    jod = human.add_human(bench, args.human) if args.human else None
    metrics = {}
    judged_at = {", the default": PipelineConfig()} if args.from_default else CONFIGS
    names = {True: ("default's nets", "fine-tuned nets"), False: ("metric nets", "tolerant nets")}
    before, after = names[args.from_default]
    for suffix, named in judged_at.items():
        config = named.replace(**views)  # with --from-default, the default's own views
        for nets, metric in ((before, metric_nets), (after, tuned)):
            metrics[nets + suffix] = with_nets(config, metric.detector, metric.descriptor).eval()
    results = {
        "command": f"python bench/real_nets.py --out {args.out} --steps {args.steps} "
        f"--lr {args.lr:g} --temperature {args.temperature:g}"
        + (" --simplification" if args.simplification else "")
        + (" --salient" if args.salient else "")
        + (f" --series-weight {args.series_weight:g}" if args.series_weight != 1.0 else "")
        + (f" --image-size {args.image_size}" if args.image_size != DEFAULT.image_size else "")
        + (f" --num-views {args.num_views}" if args.num_views != DEFAULT.num_views else "")
        + (" --slides" if args.slides else "")
        + (" --slides-below-removed" if args.slides_below_removed else "")
        + (" --from-default" if args.from_default else "")
        + (" --quick" if args.quick else "")
        + (" --human DIR" if args.human else ""),
        "data": {
            "bases": len(data),
            "variants": list(data.kinds),
            "seed": tolerance.TRAIN_SEED,
            "simplification_series": None if series is None else len(series),
            "simplification_seed": None if series is None else tolerance.SIMPLIFY_SEED,
            "slide_series": None if slides is None else len(slides),
            "slide_seed": None if slides is None else tolerance.SLIDE_SEED,
        },
        "train_seconds": train_seconds,
        "rows": judged(bench, metrics, jod),
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
