"""The metric stage of ``drkfs train``: fine-tune the correspondence-trained nets for what the
metric must see, objective against objective and width against width, each judged on the
project's benchmark (``drkfs bench``'s tier, bars and retrieval sets)."""

from __future__ import annotations

import argparse
import copy
import json
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch

from drkfs_onnx.contract.config import NETS_TRAINED_AT, PipelineConfig
from drkfs_onnx.match import descriptor_score
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.synthetic.shapes import FAMILIES
from drkfs_onnx.synthetic.variants import structural_wins

from ..benchmark import sets
from ..benchmark.methods import DrkfsTorch, Surface
from ..benchmark.run import bars_summary, retrieval_summary, score_everything, tier_accuracy
from .metric_losses import LossFn, metric_ranking, patch_contrast
from .net_losses import correspondence_triplet
from .variant_views import VariantViews, render_variant_views

RETRIEVAL = 0.83  # the retrieval the correspondence nets reach on the benchmark: not to be lost
ACCURACY_TOLERANCE = 0.01  # ship the smallest width within 1 point of the best accuracy
REGULARISER_BATCH = 128  # correspondences per step when the correspondence triplet joins in


class Correspondences(NamedTuple):
    """The correspondence stage's training views as its chosen detector maps them, (N, 2, S, S),
    and their (C, 5) matches: what the paper-style triplet trains on."""

    maps: torch.Tensor
    matches: torch.Tensor


def _ranking_and_triplet(data: VariantViews, seed: int, pairs: Correspondences) -> LossFn:
    """The metric ranking plus the correspondence triplet on HardNet (the detector's maps of
    the view pairs are fixed): structure learned without forgetting what tells places apart."""
    ranking = metric_ranking(data, seed, tiers=False)

    def loss_fn(metric: DRKFS, step: int) -> torch.Tensor:
        rng = np.random.default_rng([seed, 5, step])
        size = metric.config.patch_size
        triplet = correspondence_triplet(
            metric.descriptor, pairs.maps, pairs.matches, rng, REGULARISER_BATCH, size
        )
        return ranking(metric, step) + triplet

    return loss_fn


# objective name -> (VariantViews, seed, Correspondences) -> loss function of (metric, step)
OBJECTIVES = {
    "ranking": lambda data, seed, _: metric_ranking(data, seed, tiers=False),
    "ranking with tiers": lambda data, seed, _: metric_ranking(data, seed, tiers=True),
    "patch contrast": lambda data, seed, _: patch_contrast(data, seed, 8, 32),
    "ranking + correspondence triplet": _ranking_and_triplet,
    "ranking + retrieval": lambda data, seed, _: metric_ranking(data, seed, False, retrieval=2),
}
# a plan config's detector fields: placeholders, each detector size's stage sets its own
PLAN_DETECTOR = {"detector_kernel": 5, "detector_n": 4, "detector_m": 4}
BASELINE = "correspondence triplet (paper-style)"


@dataclass(frozen=True)
class MetricPlan:
    """What decides the metric-trained nets, besides the correspondence stage they start from."""

    shapes_per_family: int = 5
    objectives: tuple[str, ...] = tuple(OBJECTIVES)
    objective_width: float = 0.5  # the width the objectives are compared at
    steps: int = 100
    lr: float = 1e-4
    quick_benchmark: bool = False  # the benchmark's quick subset (tests)
    # the cameras, image size and match the nets are trained and judged at: NETS_TRAINED_AT's
    # with the structure preset's match (the detector fields are placeholders, as in
    # TrainPlan.config)
    config: dict = field(
        default_factory=lambda: PipelineConfig.structure(
            nets="metric", **PLAN_DETECTOR, **NETS_TRAINED_AT
        ).to_dict()
    )

    @property
    def pipeline(self) -> PipelineConfig:
        return PipelineConfig.from_dict(self.config)


def benchmark_set(quick: bool) -> sets.BenchSet:
    """The benchmark's tier, bars and retrieval sets (``sets.build`` without the stability
    cases, which score no ranking). Retrieval keeps the training families, two shapes each,
    as the nets were chosen with."""
    bench = sets.tier_set(quick)
    if quick:
        sets.retrieval(bench, ["chair", "table", "lamp"], 2)
    else:
        sets.retrieval(bench, list(FAMILIES), 2)
    sets.bars(bench)
    return bench


def structure_accuracy(tiers: dict) -> dict:
    """The structural ranking the nets are judged by, from ``tier_accuracy``'s result:
    structural above invisible, overall and per half."""
    key = "invisible_vs_structural"
    return {
        "accuracy": tiers[key],
        "accuracy_synthetic": tiers["synthetic"][key],
        "accuracy_real": tiers["shared"][key],
    }


def benchmark_row(metric: DRKFS, bench: sets.BenchSet) -> dict:
    """The metric's structural-ranking accuracy (overall and per half) on ``bench``, with the
    bars ratio and retrieval when it has those sets, as ``drkfs bench`` computes them."""
    name = "candidate"
    scores, _ = score_everything(bench, [DrkfsTorch(name, metric)], lambda _: None)
    row = structure_accuracy(tier_accuracy(bench, scores.comparisons[name]))
    if any(c.group == "bars" for c in bench.comparisons):
        row["bars"] = bars_summary(bench, scores.comparisons[name])["deletion_over_max_shift"]
    if bench.retrieval:
        found = retrieval_summary(bench, scores.retrieval[name])
        row["retrieval"] = found["nearest_neighbour_accuracy"]
    return row


def benchmark_rows_script(
    doc: str, script: str, candidates: Callable[[], Iterable[tuple[str, DRKFS]]]
) -> None:
    """The command line of the evaluation-only bench scripts (``--out``, ``--quick``): each named
    metric's ``benchmark_row``, printed as it comes and written to ``--out`` as {"command",
    "config", "rows", "seconds"}. ``candidates()`` is consumed after the benchmark set is built."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--quick", action="store_true", help="the benchmark's quick subset")
    args = parser.parse_args()
    torch.set_num_threads(2)
    start = time.perf_counter()
    bench = benchmark_set(args.quick)
    rows = {}
    for name, metric in candidates():
        rows[name] = benchmark_row(metric, bench)
        print(f"{name}: {rows[name]}", flush=True)
    results = {
        "command": f"python {script} --out {args.out}{' --quick' if args.quick else ''}",
        "config": PipelineConfig().to_dict(),
        "rows": rows,
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")


def heldout_set(quick: bool) -> sets.BenchSet:
    """Synthetic bases of the held-out seeds (``sets.HOLDOUT_SEEDS``; the quick run: one chair)
    with their variants: the benchmark's kind of set, shapes neither it nor training saw."""
    bench = sets.BenchSet()
    for seed in sets.HOLDOUT_SEEDS[:1] if quick else sets.HOLDOUT_SEEDS:
        families = ["chair"] if quick else list(FAMILIES)
        sets.tiers(bench, families, [], seed=seed, prefix=f"{seed}/")
    return bench


@torch.no_grad()
def training_accuracy(metric: DRKFS, data: VariantViews) -> dict:
    """The benchmark's accuracy on the training bases themselves: per base and variant source,
    the share of (structural, mild) pairs where the structural variant scores further."""
    wins = pairs = 0
    for views in data.images[:, :, :, None]:
        # a base's views and its variants' in one call: a call a variant took ~10 ms for a few views
        features = metric.describe(views.flatten(0, 1)).reshape(
            len(views), -1, metric.config.descriptor_dim
        )
        for mild, structural in VariantViews.sources():
            score = {j: float(descriptor_score(features[j], features[0], metric.config))
                     for j in mild + structural}  # fmt: skip
            won, count = structural_wins([score[j] for j in structural], [score[j] for j in mild])
            wins, pairs = wins + won, pairs + count
    return {"accuracy": wins / pairs, "pairs": pairs}


def chamfer_row(bench: sets.BenchSet, quick: bool) -> dict:
    """Chamfer-L1's accuracy on the same tier set (``quick``: the quick benchmark's samples a
    mesh): the bar both halves must clear."""
    tiered = sets.BenchSet(
        shapes=bench.shapes, comparisons=[c for c in bench.comparisons if c.group == "tiers"]
    )
    scores, _ = score_everything(tiered, [Surface.of_bench(quick)], lambda _: None)
    return structure_accuracy(tier_accuracy(tiered, scores.comparisons["Chamfer-L1"]))


def admissible(row: dict, chamfer: dict) -> bool:
    """Above Chamfer-L1 on both halves and retrieval kept (a half the set lacks is skipped)."""
    halves = [
        row[key] > chamfer[key]
        for key in ("accuracy_synthetic", "accuracy_real")
        if chamfer[key] is not None
    ]
    return all(halves) and row["retrieval"] >= RETRIEVAL


def choose_objective(rows: dict[str, dict], chamfer: dict) -> str:
    """The trained objective with the best accuracy among the admissible ones; the best
    accuracy overall when none is admissible (the manifest says so)."""
    trained = {name: row for name, row in rows.items() if name != BASELINE}
    allowed = {n: r for n, r in trained.items() if admissible(r, chamfer)} or trained
    return max(allowed, key=lambda n: allowed[n]["accuracy"])


def choose_smallest(rows: dict, cost: dict, chamfer: dict):
    """The key of the cheapest row (by ``cost``) within ACCURACY_TOLERANCE of the best
    admissible accuracy (of the best accuracy when none is admissible)."""
    allowed = {k: r for k, r in rows.items() if admissible(r, chamfer)} or rows
    best = max(r["accuracy"] for r in allowed.values())
    return min((k for k, r in allowed.items() if r["accuracy"] >= best - ACCURACY_TOLERANCE),
               key=cost.get)  # fmt: skip


class MetricStage:
    """One run of a MetricPlan in a work folder; ``fit`` is ``training.run.fit``, ``timed``
    records a stage's seconds."""

    def __init__(
        self, plan: MetricPlan, work: Path, seed: int, pairs: Correspondences, train_steps, timed
    ):
        self.plan, self.work, self.seed, self.pairs = plan, work, seed, pairs
        self.config = plan.pipeline
        self.train_steps, self.timed = train_steps, timed
        work.mkdir(parents=True, exist_ok=True)
        self.bench = benchmark_set(plan.quick_benchmark)
        self.heldout = heldout_set(plan.quick_benchmark)

    @cached_property
    def data(self) -> VariantViews:
        """The training views, rendered once per work folder and loaded once per stage."""
        path = self.work / "variant_views.pt"
        if path.exists():
            return VariantViews(**torch.load(path, weights_only=True))
        start = time.perf_counter()
        data = render_variant_views(
            self.config, list(FAMILIES), self.plan.shapes_per_family, self.seed
        )
        torch.save(data.to_dict(), path)
        self.timed("variant_views", start)
        return data

    def row(self, name: str, metric: DRKFS | None) -> dict:
        """``metric``'s ``benchmark_row``, with its accuracy on the held-out bases and on the
        training bases (None: Chamfer-L1's ``chamfer_row``); computed once per work folder."""
        path = self.work / f"row_{name.replace(' ', '_')}.json"
        if not path.exists():
            start = time.perf_counter()
            if metric is None:
                row = chamfer_row(self.bench, self.plan.quick_benchmark)
            else:
                row = {
                    **benchmark_row(metric, self.bench),
                    "heldout": benchmark_row(metric, self.heldout)["accuracy"],
                    "training": training_accuracy(metric, self.data)["accuracy"],
                }
            path.write_text(json.dumps(row))
            self.timed(f"judge_{name}", start)
        return json.loads(path.read_text())

    def fine_tune(self, start: DRKFS, objective: str, name: str) -> DRKFS:
        metric = copy.deepcopy(start)
        metric.detector.requires_grad_(True)
        metric.descriptor.requires_grad_(True)
        loss_fn = OBJECTIVES[objective](self.data, self.seed, self.pairs)
        began = time.perf_counter()
        checkpoint = self.work / f"metric_{name.replace(' ', '_')}.pt"
        self.train_steps(metric, loss_fn, self.plan.steps, self.plan.lr, checkpoint, 20)
        self.timed(checkpoint.stem, began)
        return metric.requires_grad_(False)
