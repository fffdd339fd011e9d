"""Each loss idea's strongest recipe on the fitting study's problems, beside the committed fits
(bench/records/fitting.md: where the fitting target against pixel MSE is out of reach, every
idea's best).

    python bench/fit_ideas.py --study bench/fit/results.json --out bench/fit/ideas.json [--quick]

The fitting study fits one DR-KFS form, the shipped one, alone and in each combination. Its best
DR-KFS-containing recipe is all three terms (pixel MSE + w_p x form + w_c x Chamfer); here the
other ideas' best forms take the shipped form's place in that recipe, at the study's weights:

- the position-aligned match with a dense reduction at one scale (``window r0 mean``);
- the soft best match, annealed, after the coarse stage (``soft match, window r1, coarse to
  fine``, the loss study's first form);
- nets fine-tuned for the loss (``graded.fine_tune``) in the study's form;
- structure first, pixel MSE last: the study's three terms, whose DR-KFS and Chamfer terms fade
  out from half the fit (``PIXEL_MSE_LAST``) so that it ends on pixel MSE alone, the judges'
  renders polished from a start the structural terms chose.

Beside them, as a row of their own, the control (pixel MSE + w_c x Chamfer) on the same fade:
not an idea but what tells whether the fade's wins come from its DR-KFS term or from the
schedule.

Pixel MSE, the control and the shipped form's three terms are fitted again on this machine
(``here``). On the study's machine, torch build and thread count they equal the study's rows
(``reproduced``); on another CPU the float sums differ and the fits drift, so the ideas are also
compared with these refitted rivals (``shares_here``), like with like. ``--ideas-from`` takes the
judged rows of the rivals and ideas an earlier output has instead of fitting them again, once
pixel MSE fitted again on the first problem equals that output's row exactly (the same machine,
build and thread count is not proof of the same float sums: the processor is not recorded). The
fits are judged by the study's judges; their meshes are not saved.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from drkfs_lab.judging.judges import Judge
from drkfs_lab.judging.rule import chamfer_ratios
from drkfs_lab.studies.losses import (
    CHAMFER,
    FADED_CONTROL,
    PIXEL,
    Recipe,
    Terms,
    alone,
    pixel_mse_last,
    pixel_with_chamfer,
    with_both,
)
from drkfs_lab.studies.mesh_fit import Fade
from drkfs_lab.studies.network import reproduction
from drkfs_lab.studies.study import (
    FULL,
    QUICK_STUDY,
    Fitter,
    average_ranks,
    load_problem,
    machine,
    pair_shares,
)
from drkfs_lab.training import graded
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.synthetic.shapes import FAMILIES

TUNED = "fine-tuned nets"
# fixed before the run, not tuned: the structural terms at full weight for the first half, gone
# for the last fifth (tried first on the chair and the table without LFD, this one schedule)
PIXEL_MSE_LAST = Fade(0.5, 0.8)


def ideas(
    form: str, pixel_weight: float, chamfer_weight: float
) -> dict[str, tuple[Recipe, str | None]]:
    """Idea -> (its three-term recipe, its nets: None for the shipped ones); ``form`` is the
    study's (the shipped form in the full study), the weights the study's. The last row is the
    faded idea's control, without DR-KFS."""
    three = with_both(form, pixel_weight, chamfer_weight)
    return {
        "position-aligned, dense, one scale": (
            with_both("window r0 mean", pixel_weight, chamfer_weight),
            None,
        ),
        "soft best match, coarse to fine": (
            with_both("soft match, window r1, coarse to fine", pixel_weight, chamfer_weight),
            None,
        ),
        "nets fine-tuned for the loss": (three, TUNED),
        "structure first, pixel MSE last": (pixel_mse_last(three, PIXEL_MSE_LAST), None),
        FADED_CONTROL: (pixel_mse_last(pixel_with_chamfer(chamfer_weight), PIXEL_MSE_LAST), None),
    }


def rivals_of(idea: str, against: dict[str, str], *missing: str) -> dict[str, tuple[str, str]]:
    """(idea, rival) pairs for ``pair_shares``, each under its rival's label, but for the idea
    itself (named by its label or its recipe) and the ``missing`` rivals."""
    return {
        label: (idea, rival)
        for label, rival in against.items()
        if rival not in missing and idea not in (label, rival)
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
    parser.add_argument(
        "--ideas-from", type=Path, help="an earlier output made here: its rivals and ideas"
    )
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
    shipped = with_both(form, pixel_weight, chamfer_weight)
    control = pixel_with_chamfer(chamfer_weight)
    tried = ideas(form, pixel_weight, chamfer_weight)
    earlier = json.loads(args.ideas_from.read_text()) if args.ideas_from else None
    if earlier is not None and any(earlier[k] != v for k, v in machine().items()):
        raise SystemExit(f"{args.ideas_from}: made on another machine, torch build or threads")
    reused = set() if earlier is None else set(earlier["ideas"])
    for idea in reused:
        if idea not in tried or earlier["ideas"][idea]["recipe"] != tried[idea][0].name:
            raise SystemExit(f"{args.ideas_from}: {idea} is not an idea of this script's")
    nets = {None: Terms()}
    if any(n == TUNED for idea, (_, n) in tried.items() if idea not in reused):
        nets[TUNED] = Terms(tuned_nets(quick, args.work / ("quick" if quick else "full")))
    rivals = (alone(PIXEL), control, shipped)
    earlier_here = {} if earlier is None else earlier["here"]
    reused_rivals = [r.name for r in rivals if r.name in next(iter(earlier_here.values()), {})]
    judge = Judge(plan.judge_config, args.threads, plan.unseen_views, plan.lfd)
    committed = study["table"]
    refitted, table = {}, {}
    try:
        fitters = {name: Fitter(plan, judge, terms) for name, terms in nets.items()}
        problems = [load_problem(spec) for spec in plan.problems]
        if earlier is not None:
            first = problems[0]
            check = fitters[None].judged(first, fitters[None].fit(alone(PIXEL), first).verts)
            if check != earlier_here[first.name][PIXEL]:
                raise SystemExit(f"{args.ideas_from}: pixel MSE fits differently here")
        for problem in problems:
            rows = committed[problem.name]
            refitted[problem.name] = {}
            for recipe in rivals:
                if recipe.name in reused_rivals:
                    refitted[problem.name][recipe.name] = earlier_here[problem.name][recipe.name]
                    continue
                fit = fitters[None].fit(recipe, problem)
                refitted[problem.name][recipe.name] = fitters[None].judged(problem, fit.verts)
            new = {}
            for idea, (recipe, idea_nets) in tried.items():
                if idea in reused:
                    new[idea] = earlier["table"][problem.name][idea]
                    continue
                fit = fitters[idea_nets].fit(recipe, problem)
                new[idea] = fitters[idea_nets].judged(problem, fit.verts)
                print(f"{problem.name}: {idea}: F-score {new[idea]['F-score 1%']:.3f}", flush=True)
            table[problem.name] = {**rows, **new}
    finally:
        judge.close()
    names = [*study["losses"], *tried]
    here = {p: {**rows, **{i: table[p][i] for i in tried}} for p, rows in refitted.items()}
    against = {"pixel MSE": PIXEL, "Chamfer": CHAMFER, "the control": control.name}
    against["the shipped form's three terms"] = shipped.name
    against[FADED_CONTROL] = FADED_CONTROL  # a row of the ideas
    results = {
        "command": f"python bench/fit_ideas.py --study {args.study} --out {args.out}"
        + (f" --ideas-from {args.ideas_from}" if args.ideas_from else ""),
        **machine(),
        "lfd": judge.lfd_note,
        "study": str(args.study),
        "weights": {"pixel MSE": pixel_weight, "Chamfer": chamfer_weight},
        "ideas": {
            idea: {"recipe": recipe.name, "nets": n or "shipped", "reused": idea in reused}
            for idea, (recipe, n) in tried.items()
        },
        "rivals_reused": reused_rivals,
        "reproduced": {
            name: reproduction(
                {p: rows[name] for p, rows in refitted.items()},
                {p: committed[p][name] for p in refitted},
            )
            for name in (PIXEL, control.name, shipped.name)
        },
        "table": table,
        "here": refitted,
        "shares": {
            idea: pair_shares(table, rivals_of(idea, against)) for idea in (shipped.name, *tried)
        },
        "shares_here": {  # Chamfer is not fitted again
            idea: pair_shares(here, rivals_of(idea, against, CHAMFER)) for idea in tried
        },
        "mean_rank": average_ranks(table, names),
        "chamfer_l1_over_chamfer_fit": chamfer_ratios(table, [shipped.name, *tried]),
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    for idea, shares in results["shares"].items():
        pixel = shares["pixel MSE"]["visual"]
        print(f"{idea}: beats pixel MSE in {pixel['wins']} of {pixel['cells']} visual cells")


if __name__ == "__main__":
    main()
