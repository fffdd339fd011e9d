"""DR-KFS beside pixel MSE and Chamfer at once, and the same without DR-KFS: what the DR-KFS
term adds to the losses it is combined with (issue 32's fifth idea, carried one step further).

    python bench/fit_combinations.py --out bench/fit/combinations.json [--quick]

On the fitting study's problems, plan and judges (``drkfs fit``), with the loss study's
committed choices (the DR-KFS loss, its weight beside pixel MSE and beside Chamfer; none is
chosen again here), every loss below is fitted in this run, so all rows share its threads:

- Chamfer and pixel MSE, the baselines;
- the study's two combinations (pixel MSE + w·DR-KFS, DR-KFS + w·Chamfer);
- all three together (pixel MSE + w·DR-KFS + w·Chamfer);
- the control, pixel MSE + w·Chamfer: the three-term loss without its DR-KFS term.

The three-term and control fits are saved as PLY under the fitting study's
``meshes/<problem>/`` (beside the output); the other fits are the study's own losses and are
not written over.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from drkfs_onnx.fitting.judges import Judge
from drkfs_onnx.fitting.losses import (
    CHAMFER,
    PIXEL,
    alone,
    pixel_with_chamfer,
    with_both,
    with_chamfer,
    with_pixel,
)
from drkfs_onnx.fitting.study import (
    FULL,
    QUICK_STUDY,
    Fitter,
    average_ranks,
    chamfer_ratios,
    load_problem,
    metric_means,
    pair_shares,
    save_mesh,
    slug,
)

QUICK_CHOICE = {  # the quick plan's only candidates
    "form": "window r0 mean",
    "pixel_weight": QUICK_STUDY.pixel_weights[0],
    "chamfer_weight": QUICK_STUDY.chamfer_weights[0],
}


def committed_choice(study: Path) -> dict:
    """The loss study's choices as ``drkfs fit`` made them (bench/fit/results.json)."""
    choice = json.loads(study.read_text())["loss_study"]
    return {
        "form": choice["forms"]["chosen"],
        "pixel_weight": choice["pixel_weight"]["chosen"],
        "chamfer_weight": choice["chamfer_weight"]["chosen"],
    }


def comparisons(table: dict, three: str, control: str, pair_with_chamfer: str) -> dict:
    """Shares of visual and surface cells each challenger wins against each rival."""
    return pair_shares(
        table,
        {
            f"{three} vs {PIXEL}": (three, PIXEL),
            f"{three} vs {CHAMFER}": (three, CHAMFER),
            f"{three} vs {control}": (three, control),  # what the DR-KFS term adds
            f"{three} vs {pair_with_chamfer}": (three, pair_with_chamfer),  # what pixel MSE adds
            f"{control} vs {PIXEL}": (control, PIXEL),
            f"{pair_with_chamfer} vs {control}": (pair_with_chamfer, control),  # DR-KFS for pixels
        },
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--study", type=Path, default=Path("bench/fit/results.json"))
    parser.add_argument("--quick", action="store_true", help="the quick study's plan")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    start = time.perf_counter()
    plan = QUICK_STUDY if args.quick else FULL
    choice = QUICK_CHOICE if args.quick else committed_choice(args.study)
    form, pixel_weight, chamfer_weight = (
        choice["form"], choice["pixel_weight"], choice["chamfer_weight"]
    )  # fmt: skip
    drkfs_with_chamfer = with_chamfer(form, chamfer_weight)
    three = with_both(form, pixel_weight, chamfer_weight)
    control = pixel_with_chamfer(chamfer_weight)
    recipes = [
        alone(CHAMFER),
        alone(PIXEL),
        with_pixel(form, pixel_weight),
        drkfs_with_chamfer,
        three,
        control,
    ]
    saved = (three.name, control.name)
    meshes = args.out.parent / "meshes"
    judge = Judge(plan.judge_config, args.threads, plan.unseen_views, plan.lfd)
    fitter = Fitter(plan, judge)
    table: dict[str, dict] = {}
    seconds: dict[str, dict[str, float]] = {}
    try:
        for spec in plan.problems:
            problem = load_problem(spec)
            table[problem.name], seconds[problem.name] = {}, {}
            for recipe in recipes:
                result = fitter.fit(recipe, problem)
                judged = table[problem.name][recipe.name] = fitter.judged(problem, result.verts)
                seconds[problem.name][recipe.name] = result.seconds_per_step
                if recipe.name in saved and not args.quick:
                    folder = meshes / slug(problem.name)
                    save_mesh(folder / f"{slug(recipe.name)}.ply", result.verts,
                              problem.template_faces)  # fmt: skip
                print(
                    f"{problem.name}: {recipe.name}: F-score {judged['F-score 1%']:.3f}", flush=True
                )
    finally:
        judge.close()
    names = [r.name for r in recipes]
    results = {
        "command": f"python bench/fit_combinations.py --out {args.out}"
        + (" --quick" if args.quick else ""),
        "torch_threads": torch.get_num_threads(),
        "lfd": judge.lfd_note,
        "choice": choice,
        "losses": names,
        "table": table,
        "means": metric_means(table, names),
        "mean_rank": average_ranks(table, names),
        "comparisons": comparisons(table, three.name, control.name, drkfs_with_chamfer.name),
        "chamfer_l1_over_chamfer_fit": chamfer_ratios(table, names),
        "seconds_per_step": seconds,
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
