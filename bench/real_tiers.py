"""The benchmark's real-mesh tiers alone (``drkfs bench`` runs them with everything else): each
method's tier shares on both sides and the turn and salient-part checks
(bench/records/real_tiers.md).

    python bench/real_tiers.py --out bench/results/real_tiers.json [--methods "DR-KFS,LFD"]
    python bench/real_tiers.py --renders bench/results/real_tiers.png   # what the labels rest on
                                                  # (and real_tiers_pixels.json: pixel changes)
    python bench/real_tiers.py --parts bench/results/real_tiers_parts.json  # the default's two
                                                  # terms: descriptors' and solid change's
    python bench/real_tiers.py --scan-renders bench/results/scan_tiers.png  # the synthetic
                                                  # tiers' variants of the same meshes, drawn alike
    python bench/real_tiers.py --other DIR --relabel mesh/variant=tier,... --renders ... --out ...
                                                  # the same for meshes from outside the
                                                  # repository (bench/records/real_tiers.md says
                                                  # which)
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from drkfs_lab.benchmark import sets
from drkfs_lab.benchmark.methods import build_methods
from drkfs_lab.benchmark.real_tiers import HELDOUT_MESHES, TRAINING_MESHES, parse_relabels
from drkfs_lab.benchmark.run import (
    OTHER_SIDE,
    kept_from_run,
    real_sides,
    real_summary,
    score_with_peers,
    tier_accuracy,
)
from drkfs_onnx import PipelineConfig

DEFAULT_METHODS = "DR-KFS,DR-KFS paper,DR-KFS structure,pixel MSE,Chamfer-L1,F-score 1%,LFD"
RENDER = PipelineConfig(num_views=6, turn_degrees=0.0, image_size=256)  # the figure's: view VIEW
VIEW = 1
PIXEL_CHANGE = 0.1  # a grey level change a viewer sees at once


def write_renders(bench: sets.BenchSet, path: Path, threads: int, command: str) -> None:
    """One row a mesh: the base and each variant from one camera, cropped to the base, titled
    with the variant and its tier: the renders the labels were chosen by. Beside the PNG, a
    JSON (``<name>_pixels.json``) of each variant's pixel change against its base over all the
    figure's cameras: the mean absolute change where either shows the mesh, and the share of
    those pixels that change by more than PIXEL_CHANGE."""
    from drkfs_onnx.contract.mesh import frame_of, place
    from drkfs_onnx.runtime.render import NumpyRenderer

    renderer = NumpyRenderer(RENDER, threads=threads)
    rows: dict[str, list] = {}
    changes: dict[str, dict] = {}
    for c in bench.comparisons:
        rows.setdefault(c.base, [("base", c.base)]).append((f"{c.kind[:3]}: {c.label}", c.shape))
    width = max(len(row) for row in rows.values())
    figure = Figure(figsize=(1.6 * width, 1.7 * len(rows)))
    for i, (base, row) in enumerate(rows.items()):
        frame = frame_of(bench.shapes[base][0])
        views = [renderer.render(place(v, frame), f) for v, f in
                 (bench.shapes[key] for _, key in row)]  # fmt: skip
        images = [v[VIEW] for v in views]
        for (title, key), other in zip(row[1:], views[1:], strict=True):
            seen = (views[0] != RENDER.background) | (other != RENDER.background)
            change = np.abs(other - views[0])[seen]
            changes[key] = {"label": title, "mean_abs_change": float(change.mean()),
                            "share_over": float((change > PIXEL_CHANGE).mean())}  # fmt: skip
        ys, xs = np.nonzero(images[0] != RENDER.background)
        crop = np.s_[max(ys.min() - 4, 0) : ys.max() + 4, max(xs.min() - 4, 0) : xs.max() + 4]
        for j, ((title, _), image) in enumerate(zip(row, images, strict=True)):
            axes = figure.add_subplot(len(rows), width, i * width + j + 1)
            axes.imshow(image[crop], cmap="gray", vmin=0, vmax=1)
            axes.set_axis_off()
            axes.set_title(base.removeprefix(sets.REAL_PREFIX) if j == 0 else title, fontsize=6)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)
    pixels = {"command": command, "config": RENDER.to_dict(),
              "share_over_threshold": PIXEL_CHANGE, "variants": changes}  # fmt: skip
    path.with_name(f"{path.stem}_pixels.json").write_text(json.dumps(pixels, indent=1) + "\n")


def write_parts(bench: sets.BenchSet, path: Path, threads: int, command: str) -> None:
    """Each variant's default score split into the descriptors' part and the solid change's
    (``runtime.explain``), and per side each misordered pair of tiers (a structural variant at
    or below an invisible or surface one of its mesh) with both variants' parts: which term
    ranks what."""
    from drkfs_onnx.contract.mesh import Mesh
    from drkfs_onnx.runtime.explain import explain
    from drkfs_onnx.runtime.scorer import Scorer

    scorer = Scorer(PipelineConfig(), threads=threads)
    parts, rows = {}, {}
    for c in bench.comparisons:
        shown = explain(scorer, Mesh(*bench.shapes[c.shape], c.shape),
                        Mesh(*bench.shapes[c.reference], c.reference))  # fmt: skip
        key = f"{c.base}/{c.label}"
        parts[key] = {"kind": c.kind, "score": shown.score,
                      "descriptors": shown.score - shown.solid_change,
                      "solid_change": shown.solid_change}  # fmt: skip
        rows.setdefault(c.base, []).append(key)
    sides = real_sides(list(rows))
    misses: dict[str, list] = {side: [] for side in sides}
    for base, keys in rows.items():
        side = next(name for name, bases in sides.items() if base in bases)
        for lower in (k for k in keys if parts[k]["kind"] in ("invisible", "surface")):
            for upper in (k for k in keys if parts[k]["kind"] == "structural"):
                if parts[upper]["score"] <= parts[lower]["score"]:
                    misses[side].append({"below": upper, "above": lower})
    results = {
        "command": command,
        "config": PipelineConfig().to_dict(),
        "variants": parts,
        "misses": misses,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=1) + "\n")


def shares_without(bench: sets.BenchSet, results: dict, left_out: list[str]) -> dict:
    """Each method's real-tier shares (``tier_accuracy``) from a results file's scores, with the
    variants ``left_out`` ("mesh/variant") taken out of every pair: what a label would move.
    The file's labels must be the bench's (the same relabels): its scores are read by them."""
    keys = [f"{c.base}/{c.label}" for c in bench.comparisons]
    labels = {f"{c.base}/{c.label}": c.kind for c in bench.comparisons}
    if results["labels"] != labels:
        differ = sorted(k for k in {*labels, *results["labels"]}
                        if labels.get(k) != results["labels"].get(k))  # fmt: skip
        raise SystemExit(f"the results' labels are not these: {', '.join(differ)}")
    dropped = {sets.REAL_PREFIX + name for name in left_out}
    if unknown := dropped - set(keys):
        raise SystemExit(f"no such real-tier variant: {', '.join(sorted(unknown))}")
    return {
        method: tier_accuracy(
            bench,
            {i: values.get(key) for i, key in enumerate(keys) if key not in dropped},
            "real",
        )
        for method, values in results["values"].items()
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="the results' JSON")
    parser.add_argument("--renders", type=Path, help="a PNG of every variant's render")
    parser.add_argument("--parts", type=Path, help="a JSON of the default's two terms")
    parser.add_argument(
        "--scan-renders", type=Path, help="a PNG of the synthetic tiers' variants of the meshes"
    )
    parser.add_argument("--methods", default=DEFAULT_METHODS, help="outputs, comma-separated")
    parser.add_argument(
        "--shares-from", type=Path, help="a results JSON whose shares to recompute (no scoring)"
    )
    parser.add_argument(
        "--leave-out", default="", help="with --shares-from: mesh/variant,... to take out"
    )
    parser.add_argument(
        "--other", type=Path, help="a folder of meshes from outside the repository, scored alone"
    )
    parser.add_argument(
        "--relabel", default="", help="with --other: mesh/variant=tier,... as the renders show"
    )
    parser.add_argument(
        "--keep", type=Path, help="an earlier run's JSON whose other methods' rows are kept"
    )
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--work", type=Path, default=Path("runs/real_tiers"))
    args = parser.parse_args()
    if args.relabel and args.other is None:
        parser.error("--relabel names meshes of --other DIR")
    start = time.perf_counter()
    wanted = args.methods.split(",")
    bench = sets.BenchSet()
    if args.other is None:
        sides = {"training": list(TRAINING_MESHES), "held_out": list(HELDOUT_MESHES)}
        sets.real_tiers(bench, [*sides["training"], *sides["held_out"]])
    else:
        try:
            sides = {OTHER_SIDE: sets.other_tiers(bench, args.other, parse_relabels(args.relabel))}
        except ValueError as exc:  # a bad folder or relabel: say which, no traceback
            parser.error(str(exc))
    chosen = f" --other DIR --relabel '{args.relabel}'" if args.other is not None else ""
    if args.renders is not None:
        write_renders(bench, args.renders, args.threads,
                      f"python bench/real_tiers.py{chosen} --renders {args.renders}")  # fmt: skip
    if args.scan_renders is not None:
        # the synthetic tiers' scan variants (``benchmark.tiers.scan_tiers``) of the swept
        # meshes, labelled by their recipe, not by looking
        scans = sets.tier_set(quick=False)
        scans.comparisons = [c for c in scans.comparisons if c.base in sets.SWEPT_MESHES]
        write_renders(scans, args.scan_renders, args.threads,
                      f"python bench/real_tiers.py --scan-renders {args.scan_renders}")  # fmt: skip
    if args.parts is not None:
        write_parts(bench, args.parts, args.threads,
                    f"python bench/real_tiers.py{chosen} --parts {args.parts}")  # fmt: skip
    if args.shares_from is not None:
        left_out = [name for name in args.leave_out.split(",") if name]
        shares = shares_without(bench, json.loads(args.shares_from.read_text()), left_out)
        for name, row in shares.items():
            print(f"{name:24}", ", ".join(f"{side} {row[side]}" for side in sides))
        if args.out is not None:
            command = (f"python bench/real_tiers.py{chosen} --shares-from {args.shares_from} "
                       f"--leave-out {args.leave_out} --out {args.out}")  # fmt: skip
            record = {"command": command, "left_out": left_out, "methods": shares}
            args.out.write_text(json.dumps(record, indent=1))
        return
    if args.out is None:
        return
    # an earlier run's rows kept are checked before any scoring
    labels = {f"{c.base}/{c.label}": c.kind for c in bench.comparisons}
    kept, kept_summaries, kept_values = kept_from_run(args.keep, labels, wanted)
    methods = [m for m in build_methods(args.work / "models", args.threads)
               if set(m.outputs) & set(wanted)]  # fmt: skip
    scores, costs, notes = score_with_peers(bench, methods, print, wanted)
    rows, values_by_name = {}, {}
    for name, values in scores.comparisons.items():
        if name in wanted:
            rows[name] = {
                **real_summary(bench, values),
                "seconds_per_pair": costs[name]["seconds_per_pair"],
            }
            values_by_name[name] = {
                f"{c.base}/{c.label}": values.get(i) for i, c in enumerate(bench.comparisons)
            }
    keep = f" --keep {args.keep}" if args.keep is not None else ""
    results = {
        "command": f"python bench/real_tiers.py{chosen} --out {args.out} --methods "
        f"'{args.methods}'{keep}",
        "threads": args.threads,
        "peers": {**kept["peers"], **notes},
        "sides": sides,
        "labels": labels,
        "kept": kept,
        "methods": {**rows, **kept_summaries},
        "values": {**values_by_name, **kept_values},
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1))
    last = list(sides)[-1]  # the held-out side, or the other meshes
    for name, row in results["methods"].items():
        held, checks = row[last], row["checks"][last]
        print(
            f"{name:24} {last} inv<str {held['invisible_vs_structural']}, sur<str "
            f"{held['surface_vs_structural']}, inv<sur {held['invisible_vs_surface']}; turn "
            f"{checks['turn_below_every_surface']}, every turn "
            f"{checks['every_turn_below_every_surface']}, "
            f"salient {checks['salient_above_every_invisible']}"
        )


if __name__ == "__main__":
    main()
