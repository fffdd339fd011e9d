"""``drkfs bench``: every method on the same inputs, the summary numbers, the stability table."""

from __future__ import annotations

import json
import os
import platform
import time
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.contract.versions import metric_name
from drkfs_onnx.synthetic.variants import structural_wins

from . import as_they_come, sets
from .chart import pareto_front, write_chart
from .human import add_human, agreement_ceiling, dataset_agreement, human_agreement
from .methods import (
    DEFAULT_NAME,
    PAPER_NAME,
    PREVIOUS_NAME,
    RETRIEVAL_SAMPLES,
    STRUCTURE_NAME,
    SURFACE_SAMPLES,
    DrkfsOnnx,
    DrkfsTorch,
    Method,
    Placed,
    build_methods,
)
from .peers import LightField, find_lfd
from .tiers import TIERS
from .torch_checks import gradient_check, self_score, slide

CHARTED = "invisible_vs_structural"  # the accuracy on the chart's y axis
# the real tiers' third side: meshes from outside the repository, never chosen on (--other DIR)
OTHER_SIDE = "other"


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
    """Every method on every comparison (each mesh placed in its reference's frame) and on
    every retrieval pair (each shape in its own frame, through ``Method.for_retrieval``). The
    costs are the comparisons'."""
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
        searcher = method.for_retrieval()
        prepared = _prepare_all(searcher, placed, Cost())
        for q in keys:
            for r in keys:
                if q == r or (searcher.symmetric and (r, q) in scores.retrieval[method.outputs[0]]):
                    continue
                values = searcher.compare(prepared[q], prepared[r])
                for name, value in zip(method.outputs, values, strict=True):
                    scores.retrieval[name][q, r] = value
                    if searcher.symmetric:
                        scores.retrieval[name][r, q] = value
        progress(f"retrieval: {method.outputs[0]}")
    return scores, {name: costs[id(m)].summary() for m in methods for name in m.outputs}


TIER_PAIRS = {
    "invisible_vs_structural": ("invisible", "structural"),
    "surface_vs_structural": ("surface", "structural"),
    "invisible_vs_surface": ("invisible", "surface"),
}  # name -> (the tier that should score lower, the one that should score higher)


def _tier_values(bench: sets.BenchSet, values: dict[int, float | None], group: str) -> dict:
    """base -> tier -> variant -> value, for the comparisons of ``group``."""
    groups: dict[str, dict[str, dict[str, float]]] = defaultdict(lambda: defaultdict(dict))
    for i, c in enumerate(bench.comparisons):
        if c.group == group and values.get(i) is not None:
            groups[c.base][c.kind][c.label] = values[i]
    return groups


# the real tiers' two sides of the repository's meshes, and the checks ``real_checks`` makes
REAL_SIDES = ("training", "held_out")
REAL_CHECKS = ("turn_below_every_surface", "every_turn_below_every_surface",
               "salient_above_every_invisible")  # fmt: skip


def real_sides(bases: list[str]) -> dict[str, list[str]]:
    """The real tiers' bases by side: the meshes levers are chosen on ("training"), the
    held-out ones, and, where any are scored, ``OTHER_SIDE``: meshes from outside the
    repository."""
    training, held_out = REAL_SIDES
    side = {sets.REAL_PREFIX + name: training for name in sets.TRAINING_MESHES}
    side |= {sets.REAL_PREFIX + name: held_out for name in sets.HELDOUT_MESHES}
    found = {b: side.get(b, OTHER_SIDE) for b in bases}
    sides = [*REAL_SIDES, *([OTHER_SIDE] if OTHER_SIDE in found.values() else [])]
    return {name: [b for b in bases if found[b] == name] for name in sides}


def _halves(group: str, bases: list[str]) -> dict[str, list[str]]:
    """The tier set's halves (synthetic bases, shared meshes); the real tiers' sides
    (``real_sides``); the sides of "meshes as they come"; any other group whole ("all")."""
    if group == "real":
        return real_sides(bases)
    if group == as_they_come.GROUP:
        sides = as_they_come.sides().items()
        return {side: [b for b in keys if b in bases] for side, keys in sides}
    if group != "tiers":
        return {"all": bases}
    return {
        "synthetic": [b for b in bases if b not in sets.SHARED_MESHES],
        "shared": [b for b in bases if b in sets.SHARED_MESHES],
    }


def tier_accuracy(
    bench: sets.BenchSet, values: dict[int, float | None], group: str = "tiers"
) -> dict:
    """For each pair of tiers, the share of (lower-tier, higher-tier) variant pairs of one base
    where the higher tier's variant is further from the base: all bases pooled, and per half
    (``_halves``); with the pair counts, each tier's median value and ``misses``: per pair of
    tiers, how many bases order each pair of variants the wrong way."""
    groups = _tier_values(bench, values, group)

    def accuracy(bases: list[str], lower: str, higher: str) -> tuple[float | None, int]:
        wins = pairs = 0
        for base in bases:
            w, n = structural_wins(
                list(groups[base][higher].values()), list(groups[base][lower].values())
            )
            wins, pairs = wins + w, pairs + n
        return (wins / pairs if pairs else None), pairs

    def misses(lower: str, higher: str) -> dict[str, int]:
        found = Counter(
            f"{low} < {high}"
            for group in groups.values()
            for low, low_value in group[lower].items()
            for high, high_value in group[higher].items()
            if not structural_wins([high_value], [low_value])[0]
        )
        return dict(found.most_common())

    halves = _halves(group, list(groups))
    pooled = {name: accuracy(list(groups), *tiers) for name, tiers in TIER_PAIRS.items()}
    result: dict = {name: share for name, (share, _) in pooled.items()}
    for half, bases in halves.items():
        result[half] = {name: accuracy(bases, *tiers)[0] for name, tiers in TIER_PAIRS.items()}
    result["pairs"] = {name: pairs for name, (_, pairs) in pooled.items()}
    result["median"] = {
        tier: (
            float(np.median(found))
            if (found := [v for g in groups.values() for v in g[tier].values()])
            else None
        )
        for tier in TIERS
    }
    result["misses"] = {name: misses(*tiers) for name, tiers in TIER_PAIRS.items()}
    return result


def real_checks(bench: sets.BenchSet, values: dict[int, float | None]) -> dict:
    """Per side of the real tiers, the share of meshes where the 2-degree turn scores below
    every surface variant, where every turn (1, 2 and 3 degrees: a ring of cameras turned by
    exactly 2 degrees would match the 2-degree turn alone) does, and where the removed salient
    part scores above every invisible one (of the meshes where the method scores them); with
    the meshes each fails on."""
    groups = _tier_values(bench, values, "real")
    result = {}
    for half, bases in _halves("real", list(groups)).items():
        turn, turns, salient = {}, {}, {}
        for b in bases:
            tiers = groups[b]
            below = {
                label: all(value < v for v in tiers["surface"].values())
                for label, value in tiers["invisible"].items()
                if label.startswith("turned_") and tiers["surface"]
            }
            if "turned_2" in below:
                turn[b], turns[b] = below["turned_2"], all(below.values())
            if "salient_part_removed" in tiers["structural"] and tiers["invisible"]:
                top = tiers["structural"]["salient_part_removed"]
                salient[b] = all(top > v for v in tiers["invisible"].values())
        result[half] = {
            name: {
                "share": sum(passed.values()) / len(passed) if passed else None,
                "failed": sorted(b.removeprefix(sets.REAL_PREFIX) for b, ok in passed.items()
                                 if not ok),
            }  # fmt: skip
            for name, passed in zip(REAL_CHECKS, (turn, turns, salient), strict=True)
        }  # fmt: skip
    return result


def as_they_come_line(method: dict, side: str) -> str:
    """One side of a method's "meshes as they come" results (``tier_accuracy`` beside its
    ``as_they_come_checks`` as "checks") as a progress line: the three tier shares and the
    2-degree turns' check."""
    shares, turns = method[side], method["checks"][side]["turn_2_below_every_surface"]
    return (
        f"{side}: inv<sur {shares['invisible_vs_surface']:.3f} sur<str "
        f"{shares['surface_vs_structural']:.3f} inv<str {shares['invisible_vs_structural']:.3f}; "
        f"2-degree turns below every surface variant {turns['share']:.2f}"
    )


def as_they_come_checks(
    bench: sets.BenchSet, values: dict[int, float | None], group: str = as_they_come.GROUP
) -> dict:
    """Per side of "meshes as they come" (or of another ``group`` built as it is), the share of
    bases where each 2-degree turn (about x, y and z) scores below every surface variant, where
    every turn does, where every file variant (winding, doubled, repeated, soup) does, and of
    the assets where the removed part scores above every surface variant; with the bases each
    fails on."""
    groups = _tier_values(bench, values, group)
    twos = {f"turned_{axis}_2" for axis in as_they_come.TURN_AXES}
    result = {}
    for half, bases in _halves(group, list(groups)).items():
        checks: dict[str, dict[str, bool]] = defaultdict(dict)
        for b in bases:
            surface, invisible = groups[b]["surface"].values(), groups[b]["invisible"]
            if not surface:
                continue
            below = {label: value < min(surface) for label, value in invisible.items()}
            checks["turn_2_below_every_surface"][b] = all(below[t] for t in twos)
            checks["every_turn_below_every_surface"][b] = all(
                ok for label, ok in below.items() if label.startswith("turned_")
            )
            checks["every_file_below_every_surface"][b] = all(below[f] for f in as_they_come.FILES)
            if "part_removed" in groups[b]["structural"]:
                part = groups[b]["structural"]["part_removed"]
                checks["part_above_every_surface"][b] = part > max(surface)
        result[half] = {
            name: {"share": sum(passed.values()) / len(passed),
                   "failed": sorted(b for b, ok in passed.items() if not ok)}
            for name, passed in checks.items()
        }  # fmt: skip
    return result


def lever_summary(bench: sets.BenchSet, values: dict[int, float | None]) -> dict:
    """What a lever is judged by: the synthetic tier set's three shares, each side's shares of
    the real tiers and the real checks (``tier_accuracy``, ``real_checks``)."""
    synthetic, real = tier_accuracy(bench, values), tier_accuracy(bench, values, "real")
    checks = real_checks(bench, values)  # one entry per side scored
    return {
        "tiers": {pair: synthetic[pair] for pair in TIER_PAIRS},
        "real": {side: {pair: real[side][pair] for pair in TIER_PAIRS} for side in checks},
        "checks": checks,
    }


def real_summary(bench: sets.BenchSet, values: dict[int, float | None]) -> dict:
    """The real tiers' shares (``tier_accuracy`` per side) with their ``checks``."""
    return {**tier_accuracy(bench, values, "real"), "checks": real_checks(bench, values)}


def bars_summary(bench: sets.BenchSet, values: dict[int, float | None]) -> dict:
    edits = {c.label: values.get(i) for i, c in enumerate(bench.comparisons) if c.group == "bars"}
    if None in edits.values():
        return {**edits, "deletion_over_max_shift": None}
    return {**edits, "deletion_over_max_shift": edits["deleted"] / max(edits["up"], edits["down"])}


def ranked_retrieval(
    bench: sets.BenchSet, values: dict[tuple[str, str], float | None]
) -> dict[str, list[tuple[str, float]]]:
    """Each retrieval query with a score -> the other shapes and their scores, nearest first."""
    ranked = {}
    for q in bench.retrieval:
        known = [(r, v) for (a, r), v in values.items() if a == q and v is not None]
        if known:
            ranked[q] = sorted(known, key=lambda found: found[1])
    return ranked


def retrieval_summary(bench: sets.BenchSet, values: dict[tuple[str, str], float | None]) -> dict:
    ranked = ranked_retrieval(bench, values)
    hits = sum(bench.retrieval[found[0][0]] == bench.retrieval[q] for q, found in ranked.items())
    total = len(ranked)
    return {"nearest_neighbour_accuracy": hits / total if total else None, "queries": total}


def verdict(expectation: str, value: float | None, median: dict, rows: dict) -> bool | None:
    """Pass/fail of one stability value; None when the method does not apply. ``median``: the
    method's median value per tier. ignore: below the median surface defect (not mistaken for
    a visible defect); detect: above the median invisible change (noticed); same:<case>: within
    1% of that case's value."""
    if value is None:
        return None
    if not np.isfinite(value):
        return False
    if expectation.startswith("same:"):
        other = rows.get(expectation.split(":", 1)[1])
        return other is not None and abs(value - other) <= 0.01 * abs(other) + 1e-12
    threshold = median["surface" if expectation == "ignore" else "invisible"]
    if threshold is None:
        return None
    return value < threshold if expectation == "ignore" else value > threshold


def stability_table(bench: sets.BenchSet, scores: Scores, summary: dict) -> dict:
    cases = [(i, c) for i, c in enumerate(bench.comparisons) if c.group == "stability"]
    table = {}
    for name, values in scores.comparisons.items():
        raw = {c.label: values.get(i) for i, c in cases}
        median = summary[name]["tiers"]["median"]
        table[name] = {
            c.label: {"value": raw[c.label], "expect": c.kind,
                      "passed": verdict(c.kind, raw[c.label], median, raw)}
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


def peer_methods() -> tuple[list[Method], dict[str, str]]:
    """The outside metrics installed here, and a note for each one skipped."""
    found = find_lfd()
    if isinstance(found, str):
        return [], {"LFD": f"skipped: {found}"}
    return [LightField(*found)], {"LFD": f"light-field-distance 0.0.9 ({found[1].name})"}


def score_with_peers(
    bench: sets.BenchSet, methods: list[Method], progress, wanted: list[str] | None = None
) -> tuple[Scores, dict, dict[str, str]]:
    """``score_everything`` over ``methods`` and the outside metrics installed here
    (``peer_methods``; with ``wanted``, only where it names LFD), each peer closed after: the
    scores, the costs and a note per peer."""
    peers, notes = peer_methods() if wanted is None or "LFD" in wanted else ([], {})
    try:
        scores, costs = score_everything(bench, [*methods, *peers], progress)
    finally:
        for peer in peers:
            peer.close()
    for peer in peers:
        if peer.failed:
            notes[peer.outputs[0]] += f"; could not describe (pairs unscored): {peer.failed}"
    return scores, costs, notes


# the rows whose config follows PipelineConfig(): never kept from an earlier run
FOLLOW_THE_DEFAULT = (DEFAULT_NAME, STRUCTURE_NAME, PREVIOUS_NAME, "DR-KFS torch")


def kept_rows(earlier: dict, labels: dict, scored: list[str]) -> tuple[dict, dict, dict]:
    """An earlier run's rows of every method it scored that this run does not (``scored``), for
    a run of the same pairs (``labels``): a peer's or a frozen version's scores depend on the
    meshes and its own config alone, so they are kept, not scored again. Returns what the run
    records of them (the earlier run's command, the names and its notes on them), their
    summaries and their values; ValueError where the earlier run scored other pairs or a row
    follows the default."""
    if earlier.get("labels") != labels:
        raise ValueError("--keep: that run scored other pairs than this one")
    names = [name for name in earlier["methods"] if name not in scored]
    moving = [name for name in names if name in FOLLOW_THE_DEFAULT]
    if moving:
        raise ValueError(f"--keep: the rows of {', '.join(moving)} follow the default: score them")
    notes = {name: note for name, note in earlier.get("peers", {}).items() if name in names}
    kept = {"command": earlier["command"], "methods": names, "peers": notes}
    return (
        kept,
        {name: earlier["methods"][name] for name in names},
        {name: earlier["values"][name] for name in names},
    )


def kept_from_run(path: Path | None, labels: dict, scored: list[str]) -> tuple[dict, dict, dict]:
    """``kept_rows`` of the run a script's ``--keep`` names, read before any scoring; none kept
    where it names none."""
    if path is None:
        return {"methods": [], "peers": {}}, {}, {}
    return kept_rows(json.loads(path.read_text()), labels, scored)


def run_bench(
    out: Path, quick: bool, threads: int = 2, progress=print, human: Path | None = None
) -> dict:
    """Every method on the benchmark set (``sets.build``) and, with ``human`` (a Geo-metric
    folder, ``benchmark.human``), on the human-judgment pairs; results.json and the chart in
    ``out``."""
    start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    bench = sets.build(quick)
    jod = add_human(bench, human) if human is not None else None
    bench.write(out / "set")
    progress(f"{len(bench.shapes)} meshes, {len(bench.comparisons)} comparisons written")
    methods = build_methods(out / "models", threads, quick)
    scores, costs, peer_notes = score_with_peers(bench, methods, progress)
    summary = {}
    configs = {m.outputs[0]: m.scorer.config for m in methods if isinstance(m, DrkfsOnnx)}
    for name, values in scores.comparisons.items():
        summary[name] = {
            **(
                {"config": configs[name].to_dict(), "metric": metric_name(configs[name])}
                if name in configs
                else {}
            ),
            **({"default": True} if name == DEFAULT_NAME else {}),
            **({"preset": "paper"} if name == PAPER_NAME else {}),
            **({"preset": "structure"} if name == STRUCTURE_NAME else {}),
            **costs[name],
            "tiers": tier_accuracy(bench, values),
            "real_tiers": real_summary(bench, values),
            "human": human_agreement(bench, values, jod) if jod is not None else None,
            "bars": bars_summary(bench, values),
            "retrieval": retrieval_summary(bench, scores.retrieval[name]),
        }
    torch_method = next(m for m in methods if isinstance(m, DrkfsTorch))
    points = {n: (s["seconds_per_pair"], s["tiers"][CHARTED]) for n, s in summary.items()}
    front = pareto_front(points)
    results = {
        "command": f"drkfs bench{' --quick' if quick else ''} --out {out}"
        + (f" --human {human}" if human is not None else ""),
        "quick": quick,
        "threads": threads,
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "peers": peer_notes,
        "methods": summary,
        "human_dataset_metrics": None if jod is None else dataset_agreement(bench, human, jod),
        "human_ceiling": None if jod is None else agreement_ceiling(bench, jod),
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
    "tiers": "for two tiers of change (invisible < surface < structural, benchmark.tiers), the "
    "share of (lower-tier, higher-tier) variant pairs of one base where the higher tier's variant "
    "is further from the base; all bases pooled, and per half (synthetic bases, shared meshes); "
    "misses: per pair of tiers, how many bases order each pair of variants the wrong way (a tie "
    "counts as wrong)",
    "real_tiers": "the same shares on the real meshes' tiers (benchmark.real_tiers: changes a "
    "viewer ranks invisible, surface or structural on real meshes), per side (training: the "
    "meshes levers are chosen on; held_out: those they are judged on); checks, per side: the "
    "share of meshes whose 2-degree turn scores below every surface variant, and whose removed "
    "salient part scores above every invisible variant",
    "human": "Geo-metric's simplification stimuli: each face's 3.125% and 6.25% simplifications "
    "scored against its 12.5% one (a stand-in for the missing reference); Spearman of the scores "
    "against JOD(prediction) - JOD(stand-in) per viewing setting (negative: agrees with people), "
    "over all pairs and within each level",
    "human_ceiling": "what the human protocol lets any scorer reach, per setting: levels_only, "
    "the mean Spearman of a scorer that separates the two levels perfectly but orders faces "
    "within a level at random (levels_only_lucky: its 2.5th percentile over 2,000 orders); "
    "people_within_level, the within-level Spearman between this setting's JOD differences and "
    "the other settings' (people's own agreement within a level)",
    "seconds_per_pair": "2 x seconds per new mesh (render + features / samples / voxels) + "
    "seconds per comparison of prepared meshes, measured on the tier, bars, stability and human "
    "comparisons; renders shared between methods are charged to each",
    "frames": "every comparison in the reference's bounding-box frame (centre, half-diagonal); "
    "retrieval shapes each in their own; all methods see the same placed meshes",
    "distances": "lower is closer: F-score, normal consistency and IoU enter as 1 - value",
    "chamfer_fscore_nc": f"OccNet's definitions on {SURFACE_SAMPLES:,} area-weighted surface "
    f"samples per mesh ({RETRIEVAL_SAMPLES:,} for retrieval's all-pairs search), as OccNet; "
    "exact nearest neighbours (scipy's KD-tree); F-score threshold 1% of the reference's "
    "bounding-box diagonal",
    "volumetric_iou": "64^3 voxel centres over [-1.25, 1.25]^3, inside by the parity of +x ray "
    "crossings per connected component (outward components united, inward ones, cavities, "
    "removed); only when both meshes are watertight (every edge shared by exactly two faces), "
    "else not applicable",
    "image_mse": "mean squared difference of the 25 views at 256 px (pixel MSE), or of the PoI "
    "maps the shipped detector makes of them",
    "lfd": "the light-field distance (Chen et al. 2003) as light-field-distance 0.0.9 computes "
    "it, with the second shape's eccentricity read (lfd_setup.sh's Distance_fixed); it "
    "normalises pose and scale itself",
    "stability": "ignore: passes when the value is below the method's median surface-tier value "
    "(not mistaken for a visible defect); detect: above its median invisible-tier value "
    "(noticed); same:<case>: within 1% of that case's value",
    "retrieval": "leave-one-out nearest neighbour over the retrieval shapes (5 of each of 21 "
    "families, 12 of which no net was trained on); correct when the nearest shape is of the "
    "query's family",
}
