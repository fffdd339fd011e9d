"""Each loss idea's strongest recipe on the fitting study's problems, beside the committed fits
(issue 32: where the fitting target against pixel MSE is out of reach, show every idea's best).

    python bench/fit_ideas.py --study bench/fit/results.json --out bench/fit/ideas.json [--quick]

The fitting study fits one DR-KFS form, the shipped one, alone and in each combination. Its best
DR-KFS-containing recipe is all three terms (pixel MSE + w_p x form + w_c x Chamfer); here the
other ideas' best forms take the shipped form's place in that recipe, at the study's weights:

- the position-aligned match with a dense reduction at one scale (``window r0 mean``);
- the soft best match, annealed, after the coarse stage (``soft match, window r1, coarse to
  fine``, the loss study's first form);
- nets fine-tuned for the loss (``graded.fine_tune``) in the study's form.

Pixel MSE, the control (pixel MSE + w_c x Chamfer) and the shipped form's three terms are
fitted again on this machine (``here``). On the study's machine, torch build and thread count
they equal the study's rows (``reproduced``); on another CPU the float sums differ and the fits
drift, so the ideas are also compared with these refitted rivals (``shares_here``), like with
like. ``--ideas-from`` takes the ideas' judged rows from an earlier output made on the same
machine, build and thread count instead of fitting them again. The fits are judged by the
study's judges; their meshes are not saved.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from drkfs_onnx.config import PipelineConfig
from drkfs_onnx.fitting.judges import Judge
from drkfs_onnx.fitting.losses import CHAMFER, PIXEL, Terms, alone, pixel_with_chamfer, with_both
from drkfs_onnx.fitting.network import reproduction
from drkfs_onnx.fitting.study import (
    FULL,
    QUICK_STUDY,
    Fitter,
    average_ranks,
    chamfer_ratios,
    load_problem,
    machine,
    pair_shares,
)
from drkfs_onnx.synthetic.shapes import FAMILIES
from drkfs_onnx.training import graded

TUNED = "fine-tuned nets"


def ideas(form: str) -> dict[str, tuple[str, str | None]]:
    """Idea -> (the DR-KFS form of its three-term recipe, its nets: None for the shipped ones);
    ``form`` is the study's (the shipped form in the full study)."""
    return {
        "position-aligned, dense, one scale": ("window r0 mean", None),
        "soft best match, coarse to fine": ("soft match, window r1, coarse to fine", None),
        "nets fine-tuned for the loss": (form, TUNED),
    }


def tuned_nets(quick: bool, work: Path):
    """``bench/loss_nets.py``'s fine-tuned nets (the same series, steps and checkpoint name)."""
    config = PipelineConfig.loss()
    families = ["chair"] if quick else list(FAMILIES)
    data = graded.render_graded_views(config, families, graded.TRAIN_SHAPES, graded.TRAIN_SEED)
    steps = 2 if quick else graded.FINE_TUNE_STEPS
    work.mkdir(parents=True, exist_ok=True)
    return graded.fine_tune(data, steps, work / "loss_nets.pt")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", type=Path, required=True, help="a fitting study's results")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--work", type=Path, default=Path(".drkfs-train/loss-nets"))
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--ideas-from", type=Path, help="an earlier output made here: its ideas")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    start = time.perf_counter()
    study = json.loads(args.study.read_text())
    quick = study["quick"]
    plan = QUICK_STUDY if quick else FULL
    choice = study["loss_study"]
    form = choice["form"]
    pixel_weight = choice["pixel_weight"]["chosen"]
    chamfer_weight = choice["chamfer_weight"]["chosen"]
    shipped = with_both(form, pixel_weight, chamfer_weight).name
    control = pixel_with_chamfer(chamfer_weight)
    earlier = json.loads(args.ideas_from.read_text()) if args.ideas_from else None
    if earlier is not None and any(earlier[k] != v for k, v in machine().items()):
        raise SystemExit(f"{args.ideas_from}: made on another machine, torch build or threads")
    nets = {None: Terms()}
    if earlier is None:
        nets[TUNED] = Terms(tuned_nets(quick, args.work / ("quick" if quick else "full")))
    judge = Judge(plan.judge_config, args.threads, plan.unseen_views, plan.lfd)
    committed = study["table"]
    refitted, table = {}, {}
    try:
        fitters = {name: Fitter(plan, judge, terms) for name, terms in nets.items()}
        for spec in plan.problems:
            problem = load_problem(spec)
            rows = committed[problem.name]
            refitted[problem.name] = {}
            for recipe in (alone(PIXEL), control, with_both(form, pixel_weight, chamfer_weight)):
                fit = fitters[None].fit(recipe, problem)
                refitted[problem.name][recipe.name] = fitters[None].judged(problem, fit.verts)
            new = {}
            for idea, (idea_form, idea_nets) in ideas(form).items():
                if earlier is not None:
                    new[idea] = earlier["table"][problem.name][idea]
                    continue
                recipe = with_both(idea_form, pixel_weight, chamfer_weight)
                fit = fitters[idea_nets].fit(recipe, problem)
                new[idea] = fitters[idea_nets].judged(problem, fit.verts)
                print(f"{problem.name}: {idea}: F-score {new[idea]['F-score 1%']:.3f}", flush=True)
            table[problem.name] = {**rows, **new}
    finally:
        judge.close()
    names = [*study["losses"], *ideas(form)]
    here = {p: {**rows, **{i: table[p][i] for i in ideas(form)}} for p, rows in refitted.items()}
    against = {"pixel MSE": PIXEL, "Chamfer": CHAMFER, "the control": control.name}
    against["the shipped form's three terms"] = shipped
    results = {
        "command": f"python bench/fit_ideas.py --study {args.study} --out {args.out}"
        + (f" --ideas-from {args.ideas_from}" if args.ideas_from else ""),
        **machine(),
        "lfd": judge.lfd_note,
        "study": str(args.study),
        "weights": {"pixel MSE": pixel_weight, "Chamfer": chamfer_weight},
        "ideas": {
            idea: {
                "recipe": with_both(f, pixel_weight, chamfer_weight).name,
                "nets": n or "shipped",
            }
            for idea, (f, n) in ideas(form).items()
        },
        "reproduced": {
            name: reproduction(
                {p: rows[name] for p, rows in refitted.items()},
                {p: committed[p][name] for p in refitted},
            )
            for name in (PIXEL, control.name, shipped)
        },
        "table": table,
        "here": refitted,
        "shares": {
            idea: pair_shares(table, {label: (idea, rival) for label, rival in against.items()})
            for idea in (shipped, *ideas(form))
        },
        "shares_here": {  # Chamfer is not fitted again
            idea: pair_shares(
                here, {label: (idea, rival) for label, rival in against.items() if rival != CHAMFER}
            )
            for idea in ideas(form)
        },
        "mean_rank": average_ranks(table, names),
        "chamfer_l1_over_chamfer_fit": chamfer_ratios(table, [shipped, *ideas(form)]),
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    for idea, shares in results["shares"].items():
        pixel = shares["pixel MSE"]["visual"]
        print(f"{idea}: beats pixel MSE in {pixel['wins']} of {pixel['cells']} visual cells")


if __name__ == "__main__":
    main()
