"""The benchmark's tables, from the values a ``drkfs bench`` run committed: the README's (each
preset and the outside metrics a reader compares with) and docs/benchmark.md's (every method of
the run, tiers split by synthetic and shared meshes, people's four subsets, the bars; the
targets; what the human check lets a scorer reach; each method's verdict on the stability cases;
"meshes as they come", from bench/as_they_come.py's JSON; the frozen test set's releases, from
bench/test_set.py's); docs/training.md's nets, from models/manifest.json; the README's loss on a
batch, from bench/torch_batch.py's runs.

    python bench/bench_tables.py [--results bench/results/results.json]

Prints both as markdown; bench/check_results.py holds the docs to them.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TIER_PAIRS = ("invisible_vs_structural", "invisible_vs_surface", "surface_vs_structural")
PEOPLE = ("close_flipped", "close_normal", "far_flipped", "far_normal")
# the README's rows: the run's method -> how the README names it
README_ROWS = {
    "DR-KFS": "**DR-KFS** (default)",
    "DR-KFS structure": "DR-KFS structure preset",
    "DR-KFS paper": "DR-KFS paper preset",
    "LFD": "LFD (light-field distance)",
    "Chamfer-L1": "Chamfer-L1 (100k samples)",
    "pixel MSE": "pixel MSE (paper renders)",
    "volumetric IoU": "volumetric IoU (64³)",
}


def _people(row: dict, subsets: tuple[str, ...], minus: str) -> str:
    """Spearman against people on ``subsets``, or n/a for a method that cannot score the scans
    (no volume to voxelise) or ties them all (F-score)."""
    human = row.get("human")
    if not human or any(math.isnan(human[s]) for s in subsets):
        return "n/a"
    return " / ".join(f"{human[s]:.2f}".replace("-", minus) for s in subsets)


def readme_table(results: dict) -> str:
    """Per preset and outside metric: the three tier shares pooled, people's Spearman on the
    close and far normal subsets, retrieval, seconds a pair."""
    lines = [
        "| method | invisible < structural | invisible < surface | surface < structural "
        "| people, close / far | retrieval | s / pair |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for method, label in README_ROWS.items():
        row = results["methods"].get(method)
        if row is None:
            continue
        tiers = " | ".join(f"{row['tiers'][t]:.3f}" for t in TIER_PAIRS)
        people = _people(row, ("close_normal", "far_normal"), "−")
        retrieval = row["retrieval"]["nearest_neighbour_accuracy"]
        lines.append(
            f"| {label} | {tiers} | {people} | {retrieval:.2f} | {row['seconds_per_pair']:.2f} |"
        )
    return "\n".join(lines)


def results_table(results: dict) -> str:
    """Every method of the run: each tier share pooled (synthetic / shared meshes), people's
    four subsets, retrieval, the bars' deletion over the largest shift, seconds a pair."""
    lines = [
        "| method | invisible < structural (synthetic / shared) | invisible < surface "
        "| surface < structural | people: close fl. / close n. / far fl. / far n. "
        "| retrieval | bars | s / pair |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for method, row in results["methods"].items():
        tiers = " | ".join(
            f"{row['tiers'][t]:.3f} ({row['tiers']['synthetic'][t]:.2f} / "
            f"{row['tiers']['shared'][t]:.2f})"
            for t in TIER_PAIRS
        )
        bars = (row.get("bars") or {}).get("deletion_over_max_shift")
        bars = "n/a" if bars is None else f"{bars:.2f}"
        retrieval = row["retrieval"]["nearest_neighbour_accuracy"]
        lines.append(
            f"| {method} | {tiers} | {_people(row, PEOPLE, '-')} | {retrieval:.2f} | {bars} "
            f"| {row['seconds_per_pair']:.3f} |"
        )
    return "\n".join(lines)


# people's goals per subset (Spearman, at most)
PEOPLE_GOALS = {"close_flipped": -0.65, "close_normal": -0.65, "far_flipped": -0.5,
                "far_normal": -0.5}  # fmt: skip


def _default(results: dict) -> dict:
    return next(row for row in results["methods"].values() if row.get("default"))


def targets_table(results: dict) -> str:
    """The targets the default was chosen to meet, what it measured, and whether it met each."""
    row, chamfer = _default(results), results["methods"]["Chamfer-L1"]
    tiers, human = row["tiers"], row["human"]
    halves = [tiers[h]["invisible_vs_structural"] for h in ("synthetic", "shared")]
    beaten = [chamfer["tiers"][h]["invisible_vs_structural"] for h in ("synthetic", "shared")]
    people = [human[s] <= goal for s, goal in PEOPLE_GOALS.items()]
    retrieval = row["retrieval"]["nearest_neighbour_accuracy"]
    bars = row["bars"]["deletion_over_max_shift"]
    rows = [
        ("invisible < structural ≥ 0.95, above Chamfer-L1 on both halves",
         f"{tiers['invisible_vs_structural']:.3f}; {halves[0]:.2f} / {halves[1]:.2f} against "
         f"{beaten[0]:.2f} / {beaten[1]:.2f}",
         tiers["invisible_vs_structural"] >= 0.95 and all(map(float.__gt__, halves, beaten))),
        ("invisible < surface ≥ 0.9", f"{tiers['invisible_vs_surface']:.3f}",
         tiers["invisible_vs_surface"] >= 0.9),
        ("surface < structural ≥ 0.8", f"{tiers['surface_vs_structural']:.3f}",
         tiers["surface_vs_structural"] >= 0.8),
        ("Spearman ≤ −0.65 close, ≤ −0.5 far (flipped, normal)",
         " / ".join(f"{human[s]:.2f}".replace("-", "−") for s in PEOPLE_GOALS),
         "yes" if all(people) else f"**no** ({4 - sum(people)} of 4 missed)"),
        ("retrieval ≥ 0.83 on 105 queries", f"{retrieval:.2f}", retrieval >= 0.83),
        ("bars ratio ≥ 1.6", f"{bars:.2f}", bars >= 1.6),
        ("LFD's row", "scored" if "LFD" in results["methods"] else "skipped",
         "LFD" in results["methods"]),
    ]  # fmt: skip
    lines = ["| target | measured | met |", "|---|---|---|"]
    for target, measured, met in rows:
        verdict = met if isinstance(met, str) else ("yes" if met else "**no**")
        lines.append(f"| {target} | {measured} | {verdict} |")
    return "\n".join(lines)


def ceiling_table(results: dict) -> str:
    """Per viewing setting: the default's Spearman, a perfect separator of the two levels that
    orders faces within a level at random (its mean and its luckiest 2.5%), people's own
    agreement within a level across viewings, and the goal."""
    human = _default(results)["human"]
    lines = [
        "| setting | the default | levels only: mean (luckiest 2.5%) | people's within-level "
        "agreement across viewings | goal |",
        "|---|---:|---:|---:|---:|",
    ]
    for setting, goal in PEOPLE_GOALS.items():
        c = results["human_ceiling"][setting]
        cells = (f"{human[setting]:.2f}", f"{c['levels_only']:.2f} ({c['levels_only_lucky']:.2f})",
                 f"{c['people_within_level']:+.2f}", f"{goal:g}")  # fmt: skip
        row = f"| {setting.replace('_', ' ')} | " + " | ".join(cells) + " |"
        lines.append(row.replace("-", "−"))
    return "\n".join(lines)


def stability_table(results: dict) -> str:
    """Every method's verdict on each stability case: pass, **fail**, or n/a where it cannot
    score the case."""
    rows = results["stability"]
    cases = list(next(iter(rows.values())))
    lines = [
        "| method | " + " | ".join(c.replace("_", " ") for c in cases) + " |",
        "|---|" + "---|" * len(cases),
    ]
    for method, row in rows.items():
        cells = (
            "n/a" if row[c]["passed"] is None else ("pass" if row[c]["passed"] else "**fail**")
            for c in cases
        )
        lines.append(f"| {method} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


AS_THEY_COME_CHECKS = {
    "turn_2_below_every_surface": "2° turns below every surface variant",
    "every_turn_below_every_surface": "every turn",
    "every_file_below_every_surface": "every file variant",
    "part_above_every_surface": "removed part above every surface variant (assets)",
}


def as_they_come_table(section: dict) -> str:
    """ "Meshes as they come" (bench/as_they_come.py's JSON): per method and side, the three
    tier shares and the share of bases passing each check."""
    lines = [
        "| method | side | invisible < structural | invisible < surface | surface < structural | "
        + " | ".join(AS_THEY_COME_CHECKS.values()) + " |",
        "|---|---|" + "---:|" * (3 + len(AS_THEY_COME_CHECKS)),
    ]  # fmt: skip
    for method, row in section["methods"].items():
        for side in section["sides"]:
            tiers = " | ".join(f"{row[side][t]:.3f}" for t in TIER_PAIRS)
            checks = " | ".join(
                f"{row['checks'][side][c]['share']:.2f}" for c in AS_THEY_COME_CHECKS
            )
            lines.append(f"| {method} | {side.replace('_', ' ')} | {tiers} | {checks} |")
    return "\n".join(lines)


def test_set_table(results: dict) -> str:
    """The frozen test set (bench/test_set.py's JSON): per release and method, the tier shares
    of its synthetic bases and of its assets, and the share of assets passing each check."""
    groups = {"test_tiers": "synthetic", "test_assets": "assets"}
    lines = [
        "| release | method | "
        + " | ".join(f"{g}: {t.replace('_vs_', ' < ').replace('_', ' ')}"
                     for g in groups.values() for t in TIER_PAIRS)
        + " | " + " | ".join(AS_THEY_COME_CHECKS.values()) + " |",
        "|---|---|" + "---:|" * (2 * len(TIER_PAIRS) + len(AS_THEY_COME_CHECKS)),
    ]  # fmt: skip
    for release, entry in results["releases"].items():
        for method, row in entry["methods"].items():
            cells = [_fmt3(row[g][t]) for g in groups for t in TIER_PAIRS]
            cells += [f"{row['asset_checks'][c]:.2f}" for c in AS_THEY_COME_CHECKS]
            lines.append(f"| {release} | {method} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


# the detectors' names in the manifest -> in docs/training.md
DETECTOR_NAMES = {"harris": "Harris", "dog": "DoG"}


def nets_tables(manifest: dict) -> str:
    """docs/training.md's tables of the correspondence stage's nets (models/manifest.json):
    each detector's size, cost and held-out repeatability, trained and untrained, the best in
    bold and the shipped one named; each HardNet width's size, cost and FPR95."""

    def bold(value: str, best: bool) -> str:
        return f"**{value}**" if best else value

    def flops(count: int) -> str:
        millions = count / 1e6
        return f"{millions:.0f} M" if millions >= 10 else f"{millions:.1f} M"

    detectors, widths = manifest["detectors"], manifest["descriptors"]
    best = max(d["repeatability"] for d in detectors)
    lines = ["| detector | params | FLOPs / view | repeatability | untrained |",
             "|---|---:|---:|---:|---:|"]  # fmt: skip
    for d in detectors:
        name = d["detector"]
        if name in DETECTOR_NAMES:
            label = DETECTOR_NAMES[name]
        else:  # "n4m4k9": TILDE's n (sums), m (maxes) and kernel size
            label = "TILDE " + name.replace("m", " m").replace("k", " k")
            label += " (shipped)" if name == manifest["choice"]["detector"] else ""
        cells = [f"{d['params']:,}", flops(d["flops_per_view"])] if "params" in d else ["–", "–"]
        untrained = f"{d['repeatability_untrained']:.3f}" if "params" in d else "–"
        score = bold(f"{d['repeatability']:.3f}", d["repeatability"] == best)
        lines.append(f"| {label} | {' | '.join(cells)} | {score} | {untrained} |")
    lowest = min(w["fpr95"] for w in widths)
    table = ["| HardNet width | params | FLOPs / patch | FPR95 trained | FPR95 untrained |",
             "|---|---:|---:|---:|---:|"]  # fmt: skip
    for w in widths:
        fpr = bold(f"{w['fpr95']:.1f}%", w["fpr95"] == lowest)
        table.append(f"| {w['width']:g} | {w['params']:,} | {flops(w['flops_per_patch'])} | "
                     f"{fpr} | {w['fpr95_untrained']:.1f}% |")  # fmt: skip
    return "\n".join(lines) + "\n\n" + "\n".join(table) + "\n"


# the README's batch table's runs of bench/torch_batch.py, in its order, and its batch size
BATCH_RUNS = ("torch_batch_cuda.json", "torch_batch.json")
README_BATCH = 32
# the loss's stages as bench/torch_batch.py names them -> what each renders
LOSS_STAGES = {"coarse": "12 views, 64 px", "fine": "6 views, 128 px"}


def _batch_time(seconds: float, gpu: bool) -> str:
    """A GPU's time in ms, a CPU's in s."""
    if gpu:
        return f"{seconds * 1e3:,.0f} ms" if seconds >= 0.01 else f"{seconds * 1e3:.1f} ms"
    return f"{seconds:.1f} s" if seconds >= 1 else f"{seconds:.2f} s"


def batch_table(runs: list[dict], batch: int = README_BATCH) -> str:
    """The README's table of the loss on a batch (bench/torch_batch.py's JSON, one run per
    device): each stage's one batched call forward and backward, a mesh's share of it, the
    per-mesh loop before batches, the peak memory and the call over the batch's Chamfer-L2, all
    of one run."""
    lines = ["| device, stage | one batched call | per mesh | before: the per-mesh loop "
             "| peak memory | over Chamfer-L2 of the batch |",
             "|---|---:|---:|---:|---:|---:|"]  # fmt: skip
    for run in runs:
        gpu = run["machine"]["gpu"]
        device = (
            gpu.removeprefix("NVIDIA ") if gpu else f"{run['machine']['cpu_threads']} CPU cores"
        )
        for row in run["rows"]:
            if row["batch"] != batch:
                continue
            call, ratio = row["batched"], row["batched_over_chamfer"]
            times = (call["seconds"], call["seconds_per_mesh"], row["before"]["seconds"])
            cells = [*(_batch_time(t, bool(gpu)) for t in times),
                     f"{call['peak_memory_bytes'] / 1e9:.1f} GB",
                     f"{ratio:.1f}×" if ratio >= 1 else f"{ratio:.2f}×"]  # fmt: skip
            stage = f"{row['stage']} ({LOSS_STAGES[row['stage']]})"
            lines.append(f"| {device}, {stage} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _fmt3(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.3f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=ROOT / "bench/results/results.json")
    parser.add_argument(
        "--as-they-come", type=Path, default=ROOT / "bench/results/as_they_come.json"
    )
    parser.add_argument("--test-set", type=Path, default=ROOT / "bench/results/test_set.json")
    args = parser.parse_args()
    results = json.loads(args.results.read_text())
    tables = (readme_table, results_table, targets_table, ceiling_table, stability_table)
    print(*(table(results) for table in tables), sep="\n\n")
    if args.as_they_come.is_file():
        print("", as_they_come_table(json.loads(args.as_they_come.read_text())), sep="\n")
    if args.test_set.is_file():
        print("", test_set_table(json.loads(args.test_set.read_text())), sep="\n")
    print("", nets_tables(json.loads((ROOT / "models" / "manifest.json").read_text())), sep="\n")
    runs = [json.loads((ROOT / "bench/results" / name).read_text()) for name in BATCH_RUNS]
    print("", batch_table(runs), sep="\n")


if __name__ == "__main__":
    main()
