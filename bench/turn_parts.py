"""Where a 2-degree turn's score comes from, on the assets of "meshes as they come": each turn's
(and, beside them, each surface variant's and the removed part's) score split into the
descriptors' part and the solid change of its best ring pairing, and the descriptors' part of the
own-ring pairing alone (what the score would be without the second ring).

    python bench/turn_parts.py --out bench/results/turn_parts.json

A turn about the vertical is forgiven by the second ring; this says whether the nets forgive any
turn by themselves (then nets trained on tilts could forgive tilts) or only the ring does (then
only cameras turned about a horizontal axis could).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from drkfs_lab.benchmark import as_they_come
from drkfs_onnx import check_mesh
from drkfs_onnx.runtime import Scorer
from drkfs_onnx.runtime.match import best_pairing, pairing_part

LABELS = ("turned_x_2", "turned_y_2", "turned_z_2", "noise", "smoothed", "small_hole",
          "part_removed")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="the JSON to write (default: print only)")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    scorer = Scorer(metric=as_they_come.UNTURNED, threads=args.threads)
    rows: dict[str, dict[str, dict[str, float]]] = {}
    for seeds in as_they_come.ASSET_SEEDS.values():
        for seed in seeds:
            for family in as_they_come.ASSET_PARTS:
                verts, faces, variants = as_they_come.asset(family, seed)
                key = as_they_come.asset_key(family, seed)
                reference = scorer.features(check_mesh(verts, faces, key))
                for variant in (v for v in variants if v.name in LABELS):
                    mesh = check_mesh(variant.verts, variant.faces, f"{key}/{variant.name}")
                    a = scorer.compared(mesh, reference)
                    best = best_pairing(a, reference, scorer.config)
                    rows.setdefault(key, {})[variant.name] = {
                        "score": best.score,
                        "solid": best.solid,
                        "part": best.score - best.solid,
                        "own_ring_part": pairing_part(a, reference, 0, 0, scorer.config),
                    }
    medians = {
        label: {
            name: float(np.median([row[label][name] for row in rows.values()]))
            for name in ("score", "solid", "part", "own_ring_part")
        }
        for label in LABELS
    }
    results = {
        "command": "python bench/turn_parts.py" + (f" --out {args.out}" if args.out else ""),
        "metric": as_they_come.UNTURNED,
        "assets": len(rows),
        "medians": medians,
        "rows": rows,
    }
    for label, row in medians.items():
        print(f"{label:14}" + "".join(f" {k} {v:.4f}" for k, v in row.items()))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
