"""Every transform of the default's descriptors' part, and every weight of its solid term, judged
at once: one scoring pass records each ring pairing's (descriptors' part, solid term) of the
default (``real_levers.Recombined.pairings``) for every comparison of the bench's tiers, real
tiers, bars and people, every retrieval pair and every step of the slide check; a transform is
then scored from them as the runtime would score it (the least over the pairings of the part's
transform plus the term), with the bench's own summaries. The default here is
``real_levers.NOW_LEVER``, the default before its window; the knee rows repeat
``real_levers.py``'s part levers to the digit; the window rows (``match_rules.moderated_part``)
chose the window the default has since.

It keeps the records of the tiers' variants, and says which misorderings no such transform can
mend: a pair whose higher-tier variant has, for each pairing of the lower one, a pairing with
no larger part and no larger term scores at most as high under every non-decreasing transform
and every weight.

    python bench/part_transforms.py --out bench/results/part_transforms.json \\
        --other DIR --relabel spot/smoothed=invisible,teapot/smoothed=invisible --human DIR

A candidate (``RULE``, the one ``real_levers_part_knee_milder.json`` was chosen by) keeps every
synthetic pair the default orders, the real training side's invisible < surface and its checks,
the slide check, the bars, retrieval and people's judgments; among candidates the best training
surface < structural wins, then the best synthetic invisible < surface, then the milder slope,
then the narrower window.
"""

from __future__ import annotations

import argparse
import itertools
import json
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from drkfs_lab import real_levers as levers
from drkfs_lab.benchmark import human, sets, torch_checks
from drkfs_lab.benchmark.methods import DrkfsOnnx, Placed
from drkfs_lab.benchmark.run import (
    bars_summary,
    lever_summary,
    real_sides,
    retrieval_summary,
    score_everything,
)
from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract import match_rules

TIERS = ("invisible", "surface", "structural")
KNEES = [(q, k) for q in (1.25, 1.5, 1.75, 2.0) for k in (0.005, 0.01, 0.02)]
WINDOWS = [
    (s, low, high)
    for s, low, high in itertools.product(
        (0.2, 0.3, 0.4, 0.5, 0.6, 0.75), (0.005, 0.01, 0.02, 0.04), (0.05, 0.1, 0.15, 0.18, 0.3)
    )
]
WEIGHTS = (0.8, 1.25, 1.5, 2.0, 3.0, 4.0)  # the solid term's, against the default's
RULE = (
    "keeps every synthetic pair the default orders, real training invisible < surface and both "
    "checks, the slide check (<= 3), the bars (>= 1.6), retrieval (>= 0.83), people (<= -0.60 / "
    "-0.43); then best training surface < structural, best synthetic invisible < surface, the "
    "milder slope, the narrower window"
)


def recorded_config() -> PipelineConfig:
    """``real_levers.NOW_LEVER``'s config, the default before its window: parts in full, as
    every transform here is judged from them."""
    return levers.trained_at(PipelineConfig().nets).replace(**levers.LEVERS[levers.NOW_LEVER])


class Recorded(levers.Recombined):
    """The default's scorer, whose outputs are its score and each ring pairing's part and term."""

    def __init__(self, method: DrkfsOnnx, threads: int, pairings: int):
        super().__init__(method, "score", threads, both_rings="max",
                         both_parts=method.scorer.config.turned_part_share)  # fmt: skip
        self.outputs = ("score", *(f"{what}{n}" for n in range(pairings) for what in "pt"))

    def compare(self, a, b):
        pairs = self.pairings(a, b)
        return (min(p + t for p, t in pairs), *(x for pair in pairs for x in pair))


def record(bench: sets.BenchSet, config: PipelineConfig, threads: int, progress) -> dict:
    """-> each comparison's, retrieval pair's and slide step's (pairings, 2) parts and terms."""
    pairings = 3 if config.turn_degrees else 1
    with tempfile.TemporaryDirectory() as folder:
        graph = levers.feature_graph(config, Path(folder))
        method = Recorded(DrkfsOnnx("default", config, graph, threads), threads, pairings)
        scores, _ = score_everything(bench, [method], progress)
        steps = []

        def against(reference):
            prepared = method.prepare(Placed("chair", *reference))[0]

            def score(verts, faces):
                steps.append(method.compare(method.prepare(Placed("slid", verts, faces))[0],
                                            prepared)[1:])  # fmt: skip
                return 0.0

            return score

        torch_checks.slide_of(against)

    def stacked(values: dict) -> tuple[list, np.ndarray]:
        keys = list(values["score"])
        flat = np.array([[values[name][k] for name in method.outputs[1:]] for k in keys])
        return keys, flat.reshape(len(keys), pairings, 2)

    return {"comparisons": stacked(scores.comparisons), "retrieval": stacked(scores.retrieval),
            "slide": np.array(steps).reshape(len(steps), pairings, 2)}  # fmt: skip


def scored(parts: np.ndarray, transform, weight: float = 1.0) -> np.ndarray:
    """(N, pairings, 2) parts and terms -> (N,) scores: the least over the pairings of the
    transformed part plus the weighted term."""
    return (transform(parts[..., 0]) + weight * parts[..., 1]).min(axis=-1)


def judged(bench, recorded: dict, transform, weight: float = 1.0, jod=None, default=None) -> dict:
    """A transform's row, in real_levers.py's layout (people's four Spearman figures alone), with
    the synthetic pairs it orders the wrong way: all of them, or against ``default``'s misordered
    ones those it loses and those it wins."""
    keys, parts = recorded["comparisons"]
    values = dict(zip(keys, scored(parts, transform, weight).tolist(), strict=True))
    pairs, parts = recorded["retrieval"]
    found = dict(zip(pairs, scored(parts, transform, weight).tolist(), strict=True))
    slide = scored(recorded["slide"], transform, weight)
    return {
        **lever_summary(bench, values),
        "bars": bars_summary(bench, values),
        "retrieval": retrieval_summary(bench, found),
        "slide": {
            "max_over_mean_step": torch_checks.jump_ratio(slide),
            "limit": torch_checks.JUMP_LIMIT,
        },  # fmt: skip
        "human": None if jod is None else {
            name: value for name, value in human.human_agreement(bench, values, jod).items()
            if name in ("close_flipped", "close_normal", "far_flipped", "far_normal")
        },
        **synthetic_pairs(misordered(bench, values, "tiers"), default),
    }  # fmt: skip


def synthetic_pairs(wrong: set, default: dict | None) -> dict:
    if default is None:
        return {"synthetic_misordered": sorted(wrong)}
    before = set(map(tuple, default["synthetic_misordered"]))
    return {"synthetic_lost": sorted(wrong - before), "synthetic_won": sorted(before - wrong)}


def misordered(bench, values: dict, group: str) -> set[tuple[str, str, str]]:
    """(base, lower-tier variant, higher-tier variant) of every pair scored the wrong way."""
    by_base = defaultdict(list)
    for i, c in enumerate(bench.comparisons):
        if c.group == group and values.get(i) is not None:
            by_base[c.base].append((TIERS.index(c.kind), c.label, values[i]))
    return {(base, low[1], high[1])
            for base, rows in by_base.items() for low, high in itertools.permutations(rows, 2)
            if low[0] < high[0] and low[2] >= high[2]}  # fmt: skip


def dominated(lower: np.ndarray, higher: np.ndarray) -> bool:
    """Whether ``higher`` ((pairings, 2) parts and terms) scores at most ``lower`` under every
    non-decreasing transform of the part and every weight of the term: for each of ``lower``'s
    pairings one of ``higher``'s has no larger part and no larger term."""
    return all((higher <= pair).all(axis=1).any() for pair in lower)


def unorderable(bench, recorded: dict) -> dict:
    """Per real side and pair of tiers: how many pairs there are and which no transform mends."""
    keys, parts = recorded["comparisons"]
    row = {k: n for n, k in enumerate(keys)}
    by_base = defaultdict(list)
    for i, c in enumerate(bench.comparisons):
        if c.group == "real" and i in row:
            by_base[c.base].append((TIERS.index(c.kind), c.label, parts[row[i]]))
    result = {}
    for side, bases in real_sides(list(by_base)).items():
        result[side] = {}
        for lo, hi in itertools.combinations(range(3), 2):
            pairs = [(b, low, high) for b in bases for low in by_base[b] for high in by_base[b]
                     if low[0] == lo and high[0] == hi]  # fmt: skip
            stuck = [f"{b.removeprefix(sets.REAL_PREFIX)}: {high[1]} <= {low[1]}"
                     for b, low, high in pairs if dominated(low[2], high[2])]  # fmt: skip
            result[side][f"{TIERS[lo]}_vs_{TIERS[hi]}"] = {
                "pairs": len(pairs), "unorderable": stuck,
                "best_share": 1 - len(stuck) / len(pairs) if pairs else None,
            }  # fmt: skip
    return result


def records_by_variant(bench, recorded: dict) -> dict[str, list[list[float]]]:
    """Each tier and real-tier variant's recorded parts and terms, one [part, term] a ring
    pairing, by "base/variant": the numbers the study's findings quote."""
    keys, parts = recorded["comparisons"]
    named = ((bench.comparisons[i], parts[n]) for n, i in enumerate(keys))
    return {f"{c.base}/{c.label}": record.round(6).tolist()
            for c, record in named if c.group in ("tiers", "real")}  # fmt: skip


def candidate(row: dict, default: dict) -> bool:
    """``RULE``'s first half: every target the default keeps, kept (people's unless scored)."""
    people = row["human"]
    checks = row["checks"]["training"]
    return (
        not row["synthetic_lost"]
        and row["real"]["training"]["invisible_vs_surface"] >= default["real"]["training"][
            "invisible_vs_surface"]
        and all(check["share"] == 1.0 for check in checks.values())
        and row["slide"]["max_over_mean_step"] <= torch_checks.JUMP_LIMIT
        and row["bars"]["deletion_over_max_shift"] >= 1.6
        and row["retrieval"]["nearest_neighbour_accuracy"] >= 0.83
        and (people is None or (people["close_flipped"] <= -0.60
                                and people["far_normal"] <= -0.43))
    )  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--threads", type=int, default=2)
    levers.add_bench_options(parser)
    args = parser.parse_args()
    start = time.perf_counter()
    bench, jod = levers.lever_bench(parser, args)
    recorded = record(bench, recorded_config(), args.threads, print)
    scoring_seconds = time.perf_counter() - start

    def identity(part):
        return part

    default = judged(bench, recorded, identity, 1.0, jod)
    transforms = {f"solid term x{w:g}": (identity, w) for w in WEIGHTS}
    transforms |= {
        f"part^{q:g} above {k:g}": (lambda p, q=q, k=k: levers.powered_part(p, q, 1.0, k), 1.0)
        for q, k in KNEES
    }
    windows = {(s, low, high): f"part at slope {s:g} between {low:g} and {high:g}"
               for s, low, high in WINDOWS if high > low}  # fmt: skip
    transforms |= {
        name: (lambda p, w=w: match_rules.moderated_part(p, *w), 1.0) for w, name in windows.items()
    }
    rows = {"the default": default} | {
        name: judged(bench, recorded, transform, weight, jod, default)
        for name, (transform, weight) in transforms.items()
    }
    candidates = [w for w, name in windows.items() if candidate(rows[name], default)]
    chosen = max(
        candidates,
        key=lambda w: (
            rows[windows[w]]["real"]["training"]["surface_vs_structural"],
            rows[windows[w]]["tiers"]["invisible_vs_surface"],
            w[0],
            -w[2],
            w[1],
        ),  # fmt: skip
        default=None,
    )
    results = {
        "command": f"python bench/part_transforms.py --out {args.out}"
        + (" --human DIR" if args.human else "")
        + (f" --other DIR --relabel '{args.relabel}'" if args.other is not None else ""),
        "threads": args.threads,
        "rule": RULE,
        "candidates": [windows[w] for w in candidates],
        "chosen": None if chosen is None else windows[chosen],
        "unorderable": unorderable(bench, recorded),
        "records": records_by_variant(bench, recorded),
        "rows": rows,
        "scoring_seconds": scoring_seconds,
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1))
    for name, row in rows.items():
        real = row["real"]
        print(name, {side: round(real[side]["surface_vs_structural"], 3) for side in real},
              round(row["slide"]["max_over_mean_step"], 3))  # fmt: skip
    print("chosen:", results["chosen"])


if __name__ == "__main__":
    main()
