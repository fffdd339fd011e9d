"""What a score means: each preset's scores for the benchmark's three tiers of change (invisible,
surface, structural), from the values a ``drkfs bench`` run committed, so a reader knows where
0.05 or 0.6 falls.

    python bench/score_scale.py [--results bench/results/results.json] [--out FILE.json]

Prints a markdown table (the README's) and, with --out, writes it as JSON: per method and tier,
the median, the 10th and 90th percentiles and the range of the scores of that tier's variants
against their base (9 synthetic families and 8 real meshes; the tiers are ``benchmark.tiers``').
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np

from drkfs_lab.benchmark.sets import tier_set
from drkfs_lab.benchmark.tiers import TIERS

ROOT = Path(__file__).resolve().parents[1]
METHODS = {"DR-KFS": "default", "DR-KFS structure": "structure", "DR-KFS paper": "paper"}


def tier_scores(values: dict[str, float | None]) -> dict[str, list[float]]:
    """A method's scores (``values``: "base/variant" -> score) grouped by tier."""
    kinds = {(c.base, c.label): c.kind for c in tier_set(quick=False).comparisons}
    found = defaultdict(list)
    for (base, label), kind in kinds.items():
        value = values.get(f"{base}/{label}")
        if value is not None:
            found[kind].append(value)
    return found


def scale(results: dict) -> dict:
    """Per preset and tier: {"variants", "median", "p10", "p90", "min", "max"}."""
    table = {}
    for method, preset in METHODS.items():
        found = tier_scores(results["values"][method])
        table[preset] = {
            tier: {
                "variants": len(found[tier]),
                "median": float(np.median(found[tier])),
                "p10": float(np.percentile(found[tier], 10)),
                "p90": float(np.percentile(found[tier], 90)),
                "min": float(min(found[tier])),
                "max": float(max(found[tier])),
            }
            for tier in TIERS
        }
    return table


def markdown(table: dict) -> str:
    lines = [
        "| preset | invisible | surface | structural |",
        "|---|---|---|---|",
    ]
    for preset, tiers in table.items():
        cells = [
            f"{row['median']:.3g} ({row['p10']:.3g}–{row['p90']:.3g})"
            for row in (tiers[tier] for tier in TIERS)
        ]
        lines.append(f"| {preset} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=ROOT / "bench/results/results.json")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    results = json.loads(args.results.read_text())
    table = scale(results)
    print(markdown(table))
    if args.out is not None:
        report = {"command": "python bench/score_scale.py", "source": results["command"]}
        args.out.write_text(json.dumps({**report, "tiers": table}, indent=1) + "\n")


if __name__ == "__main__":
    main()
