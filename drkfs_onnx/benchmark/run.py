"""``drkfs bench``: every method on the same inputs, the summary numbers, the stability table."""

from __future__ import annotations

import json
import os
import platform
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..mesh import frame_of, place
from ..synthetic.variants import structural_wins
from . import sets
from .chart import pareto_front, write_chart
from .methods import (
    DEFAULT_NAME,
    PAPER_NAME,
    STRUCTURE_NAME,
    SURFACE_SAMPLES,
    DrkfsOnnx,
    DrkfsTorch,
    Method,
    Placed,
    build_methods,
)
from .torch_checks import gradient_check, self_score, slide

QUICK_VIEWS = 6  # the quick run caps every DR-KFS config at this camera count


@dataclass
class Cost:
    meshes: int = 0
    mesh_seconds: float = 0.0
    pairs: int = 0
    pair_seconds: float = 0.0

    def summary(self) -> dict:
        per_mesh = self.mesh_seconds / max(self.meshes, 1)
        per_pair = self.pair_seconds / max(self.pairs, 1)
        return {
            "seconds_per_mesh": per_mesh,
            "seconds_per_cached_pair": per_pair,
            # two new meshes and their comparison: what scoring an unseen pair costs
            "seconds_per_pair": 2 * per_mesh + per_pair,
            "meshes": self.meshes,
            "pairs": self.pairs,
        }


@dataclass
class Scores:
    """Every method output's value per comparison (None: not applicable)."""

    comparisons: dict[str, dict[int, float | None]] = field(
        default_factory=lambda: defaultdict(dict)
    )
    retrieval: dict[str, dict[tuple[str, str], float | None]] = field(
        default_factory=lambda: defaultdict(dict)
    )


def _place(verts: np.ndarray, faces: np.ndarray, key: str, frame) -> Placed:
    return Placed(key, place(verts, frame), faces)


def _prepare_all(method: Method, placed: list[Placed], cost: Cost) -> dict[str, object]:
    prepared = {}
    for p in placed:
        prepared[p.key], seconds = method.prepare(p)
        cost.meshes += 1
        cost.mesh_seconds += seconds
    return prepared


def _compare(method: Method, a, b, cost: Cost) -> tuple:
    start = time.perf_counter()
    values = method.compare(a, b)
    cost.pairs += 1
    cost.pair_seconds += time.perf_counter() - start
    return values


def score_everything(bench: sets.BenchSet, methods: list[Method], progress) -> tuple[Scores, dict]:
    scores, costs = Scores(), {id(m): Cost() for m in methods}
    by_reference = defaultdict(list)
    for i, c in enumerate(bench.comparisons):
        by_reference[c.reference].append(i)
    for reference, indices in by_reference.items():
        frame = frame_of(bench.shapes[reference][0])
        keys = [reference, *(bench.comparisons[i].shape for i in indices)]
        placed = [_place(*bench.shapes[k], k, frame) for k in keys]
        for method in methods:
            prepared = _prepare_all(method, placed, costs[id(method)])
            for i in indices:
                c = bench.comparisons[i]
                values = _compare(
                    method, prepared[c.shape], prepared[c.reference], costs[id(method)]
                )
                for name, value in zip(method.outputs, values, strict=True):
                    scores.comparisons[name][i] = value
        progress(f"scored against {reference}")
    keys = list(bench.retrieval)
    placed = [_place(*bench.shapes[k], k, frame_of(bench.shapes[k][0])) for k in keys]
    for method in methods:
        prepared = _prepare_all(method, placed, costs[id(method)])
        for q in keys:
            for r in keys:
                if q == r or (method.symmetric and (r, q) in scores.retrieval[method.outputs[0]]):
                    continue
                values = _compare(method, prepared[q], prepared[r], costs[id(method)])
                for name, value in zip(method.outputs, values, strict=True):
                    scores.retrieval[name][q, r] = value
                    if method.symmetric:
                        scores.retrieval[name][r, q] = value
        progress(f"retrieval: {method.outputs[0]}")
    return scores, {name: costs[id(m)].summary() for m in methods for name in m.outputs}


def _accuracy(bench: sets.BenchSet, values: dict[int, float | None]) -> dict:
    groups: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for i, c in enumerate(bench.comparisons):
        if c.group == "sensitivity" and values.get(i) is not None:
            groups[c.base][c.kind].append(values[i])
    wins = pairs = 0
    real_wins = real_pairs = 0
    for base, kinds in groups.items():
        w, n = structural_wins(kinds["structural"], kinds["mild"])
        wins, pairs = wins + w, pairs + n
        if base in sets.SHARED_MESHES:
            real_wins, real_pairs = real_wins + w, real_pairs + n
    mild = [v for kinds in groups.values() for v in kinds["mild"]]
    structural = [v for kinds in groups.values() for v in kinds["structural"]]
    return {
        "accuracy": wins / pairs if pairs else None,
        "pairs": pairs,
        "accuracy_synthetic": (wins - real_wins) / (pairs - real_pairs)
        if pairs > real_pairs
        else None,
        "accuracy_real": real_wins / real_pairs if real_pairs else None,
        "median_mild": float(np.median(mild)) if mild else None,
        "median_structural": float(np.median(structural)) if structural else None,
    }


def _bars(bench: sets.BenchSet, values: dict[int, float | None]) -> dict:
    edits = {c.label: values.get(i) for i, c in enumerate(bench.comparisons) if c.group == "bars"}
    if None in edits.values():
        return {**edits, "deletion_over_max_shift": None}
    return {**edits, "deletion_over_max_shift": edits["deleted"] / max(edits["up"], edits["down"])}


def _retrieval(bench: sets.BenchSet, values: dict[tuple[str, str], float | None]) -> dict:
    hits = total = 0
    for q in bench.retrieval:
        known = {r: v for (a, r), v in values.items() if a == q and v is not None}
        if known:
            nearest = min(known, key=known.get)
            hits += bench.retrieval[nearest] == bench.retrieval[q]
            total += 1
    return {"nearest_neighbour_accuracy": hits / total if total else None, "queries": total}


def _verdict(expectation: str, value: float | None, mild: float | None, rows: dict) -> bool | None:
    """Pass/fail of one stability value; None when the method does not apply."""
    if value is None:
        return None
    if not np.isfinite(value):
        return False
    if expectation.startswith("same:"):
        other = rows.get(expectation.split(":", 1)[1])
        return other is not None and abs(value - other) <= 0.01 * abs(other) + 1e-12
    if mild is None:
        return None
    return value < mild if expectation == "ignore" else value > mild


def stability_table(bench: sets.BenchSet, scores: Scores, summary: dict) -> dict:
    cases = [(i, c) for i, c in enumerate(bench.comparisons) if c.group == "stability"]
    table = {}
    for name, values in scores.comparisons.items():
        raw = {c.label: values.get(i) for i, c in cases}
        mild = summary[name]["sensitivity"]["median_mild"]
        table[name] = {
            c.label: {"value": raw[c.label], "expect": c.kind,
                      "passed": _verdict(c.kind, raw[c.label], mild, raw)}
            for _, c in cases
        }  # fmt: skip
    return table


def torch_stability(bench: sets.BenchSet, metric) -> dict:
    rows = {}
    for c in bench.comparisons:
        if c.group == "stability":
            a, b = bench.shapes[c.shape], bench.shapes[c.reference]
            rows[c.label] = {**gradient_check(metric, a, b), "self_score": self_score(metric, b)}
    return {"cases": rows, "slide": slide(metric)}


def run_bench(out: Path, quick: bool, threads: int = 2, progress=print) -> dict:
    start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    bench = sets.build(quick)
    bench.write(out / "set")
    progress(f"{len(bench.shapes)} meshes, {len(bench.comparisons)} comparisons written")
    methods = build_methods(out / "models", threads, QUICK_VIEWS if quick else None)
    scores, costs = score_everything(bench, methods, progress)
    summary = {}
    configs = {m.outputs[0]: m.scorer.config for m in methods if isinstance(m, DrkfsOnnx)}
    for name, values in scores.comparisons.items():
        summary[name] = {
            **({"config": configs[name].to_dict()} if name in configs else {}),
            **({"default": True} if name == DEFAULT_NAME else {}),
            **({"preset": "paper"} if name == PAPER_NAME else {}),
            **({"preset": "structure"} if name == STRUCTURE_NAME else {}),
            **costs[name],
            "sensitivity": _accuracy(bench, values),
            "bars": _bars(bench, values),
            "retrieval": _retrieval(bench, scores.retrieval[name]),
        }
    torch_method = next(m for m in methods if isinstance(m, DrkfsTorch))
    points = {n: (s["seconds_per_pair"], s["sensitivity"]["accuracy"]) for n, s in summary.items()}
    front = pareto_front(points)
    results = {
        "command": f"drkfs bench{' --quick' if quick else ''} --out {out}",
        "quick": quick,
        "threads": threads,
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "methods": summary,
        "pareto_front": front,
        "stability": stability_table(bench, scores, summary),
        "torch_stability": torch_stability(bench, torch_method.metric),
        "definitions": DEFINITIONS,
        "values": {
            name: {f"{c.base}/{c.label}": values.get(i) for i, c in enumerate(bench.comparisons)}
            for name, values in scores.comparisons.items()
        },
    }
    results["seconds_total"] = time.perf_counter() - start
    (out / "results.json").write_text(json.dumps(results, indent=1))
    presets = {DEFAULT_NAME: "default", PAPER_NAME: "paper preset", STRUCTURE_NAME: "structure"}
    write_chart(out / "speed_accuracy.png", points, front, presets)
    return results


DEFINITIONS = {
    "accuracy": "share of (structural, mild) variant pairs of one base where the structural "
    "variant is further from the base; all bases pooled",
    "seconds_per_pair": "2 x seconds per new mesh (render + features / samples / voxels) + "
    "seconds per comparison of prepared meshes; renders shared between methods are charged to "
    "each",
    "frames": "every comparison in the reference's bounding-box frame (centre, half-diagonal); "
    "retrieval shapes each in their own; all methods see the same placed meshes",
    "distances": "lower is closer: F-score, normal consistency and IoU enter as 1 - value",
    "chamfer_fscore_nc": f"OccNet's definitions on {SURFACE_SAMPLES:,} area-weighted surface "
    "samples per mesh, as OccNet; exact nearest neighbours (scipy's KD-tree); F-score "
    "threshold 1% of the reference's bounding-box diagonal",
    "volumetric_iou": "64^3 voxel centres over [-1.25, 1.25]^3, inside by the parity of +x ray "
    "crossings per connected component (outward components united, inward ones, cavities, "
    "removed); only when both meshes are watertight (every edge shared by exactly two faces), "
    "else not applicable",
    "image_mse": "mean squared difference of the 25 views at 256 px (pixel MSE), or of the PoI "
    "maps the shipped detector makes of them",
    "stability": "ignore: passes when the value is below the method's median mild-variant value "
    "on the sensitivity set; detect: above it; same:<case>: within 1% of that case's value",
    "retrieval": "leave-one-out nearest neighbour over the retrieval shapes; correct when the "
    "nearest shape is of the query's family",
}
