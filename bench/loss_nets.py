"""Nets fine-tuned for the loss, measured (bench/records/fitting.md, "Nets fine-tuned for the
loss").

    python bench/loss_nets.py --out bench/fit/loss_nets.json [--quick]
    python bench/loss_nets.py --save-nets bench/single_view/loss_nets.pt   # the nets alone

1. Graded series (``drkfs_lab.training.graded``) of held-out bases: how fast the loss's score
   and its patches' distances grow with an edit, for the loss's shipped nets (correspondence),
   the scoring default's (metric) and the fine-tuned ones.
2. The correspondence nets fine-tuned with ``graded_monotone`` on series of other bases (work
   folder ``--work``, resumable).
3. The loss study's fits (``python bench/fit.py``'s tuning problems, plan and judges) of the
   shipped loss form with the shipped and with the fine-tuned nets, with their landscape probes.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from drkfs_lab.judging.judges import Judge
from drkfs_lab.studies.losses import Terms, alone
from drkfs_lab.studies.study import FULL, QUICK_STUDY, Fitter, average_ranks, load_problem
from drkfs_lab.training import graded
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.synthetic.shapes import FAMILIES

SHIPPED, TUNED = "shipped nets", "fine-tuned for the loss"


def fits(plan, form: str, nets: dict[str, DRKFS | None], threads: int) -> dict:
    """The form fitted to the plan's tuning problems with each set of nets, judged and probed,
    and each set's mean rank over the judged metrics (1: best), averaged over the problems."""
    judge = Judge(plan.judge_config, threads, plan.unseen_views, plan.lfd)
    recipe, rows = alone(form), {}
    problems = [load_problem(spec) for spec in plan.tuning]
    try:
        for name, metric in nets.items():
            fitter = Fitter(plan, judge, Terms(metric))
            rows[name] = {}
            for problem in problems:
                result = fitter.fit(recipe, problem)
                judged = fitter.judged(problem, result.verts)
                judged["landscape"] = fitter.landscape(recipe, problem)
                rows[name][problem.name] = judged
                print(f"{name} / {problem.name}: F-score {judged['F-score 1%']:.3f}", flush=True)
    finally:
        judge.close()
    return {
        "form": form,
        "lfd": judge.lfd_note,
        "rows": rows,
        "mean_rank": average_ranks(
            {p.name: {n: rows[n][p.name] for n in rows} for p in problems}, list(rows)
        ),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="the measurements' JSON")
    parser.add_argument("--save-nets", type=Path, help="write the fine-tuned nets' state dict here")
    parser.add_argument("--work", type=Path, default=Path(".drkfs-train/loss-nets"))
    parser.add_argument("--quick", action="store_true", help="one family, two steps")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    start = time.perf_counter()
    config = PipelineConfig.loss()
    families = ["chair"] if args.quick else list(FAMILIES)
    steps = 2 if args.quick else graded.FINE_TUNE_STEPS
    work = args.work / ("quick" if args.quick else "full")
    work.mkdir(parents=True, exist_ok=True)
    train = graded.render_graded_views(config, families, graded.TRAIN_SHAPES, graded.TRAIN_SEED)
    began = time.perf_counter()
    tuned = graded.fine_tune(train, steps, work / "loss_nets.pt")
    tuning_seconds = time.perf_counter() - began
    if args.save_nets is not None:
        args.save_nets.parent.mkdir(parents=True, exist_ok=True)
        torch.save(tuned.state_dict(), args.save_nets)
    if args.out is None:
        return
    heldout = graded.render_graded_views(
        config, families, graded.HELDOUT_SHAPES, graded.HELDOUT_SEED
    )
    growth = {
        "correspondence nets (the loss's)": graded.grade_stats(DRKFS.pretrained(config), heldout),
        "metric nets (the scoring default's)": graded.grade_stats(
            DRKFS.pretrained(config.replace(nets="metric")), heldout
        ),
        TUNED: graded.grade_stats(tuned, heldout),
    }
    for name, stats in growth.items():
        print(f"{name}: {stats['all']}", flush=True)
    plan = QUICK_STUDY if args.quick else FULL
    results = {
        "command": f"python bench/loss_nets.py --out {args.out}{' --quick' if args.quick else ''}",
        "torch_threads": torch.get_num_threads(),
        "config": config.to_dict(),
        "grades": graded.GRADES,
        "elasticity_asked": graded.ELASTICITY,
        "bases": {
            "families": families,
            "train": {
                "seed": graded.TRAIN_SEED,
                "per_family": graded.TRAIN_SHAPES,
                "series": len(train),
            },
            "heldout": {
                "seed": graded.HELDOUT_SEED,
                "per_family": graded.HELDOUT_SHAPES,
                "series": len(heldout),
            },
        },  # fmt: skip
        "fine_tuning": {
            "steps": steps,
            "learning_rate": graded.FINE_TUNE_RATE,
            "seconds": tuning_seconds,
        },
        "growth_heldout": growth,
        "fits": fits(plan, plan.form, {SHIPPED: None, TUNED: tuned}, args.threads),
    }
    results["seconds"] = time.perf_counter() - start
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
