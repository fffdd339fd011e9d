"""``drkfs fit``: fit templates to targets with each loss and judge the results with metrics
independent of the loss.

The rendered losses run at the training config (``PipelineConfig.training()``: the default's
cameras and nets, a softer renderer); the judge renders at the paper's config (other cameras
than the loss saw). Every fitted mesh is saved as PLY beside results.json, for outside judges.
"""

from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import torch
import trimesh

from ..config import PipelineConfig
from ..metric import DRKFS
from ..synthetic.shapes import FAMILIES
from .gallery import write_gallery
from .judges import HIGHER_IS_BETTER, METRICS, SURFACE, VISUAL, Judge, better
from .landscape import probe
from .mesh_fit import (
    ChamferLoss,
    DrkfsLoss,
    FitSettings,
    Objective,
    PixelLoss,
    fit_mesh,
    float_tensor,
)
from .problems import Problem, shared, synthetic

LOSSES = ("Chamfer", "pixel MSE", "DR-KFS", "DR-KFS + lambda*Chamfer")
TIMING_STEPS = 2  # steps timed at the paper's config (the second pays no warm-up)
CONVERGENCE_WINDOW = 0.1  # a fit's last tenth of steps: how much the objective still fell there
LANDSCAPE_LOSSES = ("DR-KFS", "pixel MSE")  # the rendered losses (Chamfer resamples every call)


@dataclass(frozen=True)
class StudyPlan:
    fit_config: PipelineConfig
    judge_config: PipelineConfig
    settings: FitSettings
    problems: tuple[str, ...]  # "family:seed" (synthetic) or a shared mesh's name
    tuning: str  # the problem step sizes and lambda are chosen on (not among ``problems``)
    learning_rates: tuple[float, ...]  # candidates for each single loss
    smoothness: tuple[float, ...]  # candidate regulariser weights for each single loss
    weights: tuple[float, ...]  # candidate lambdas, at the settings chosen for DR-KFS
    # the first study's settings (before the training renderer), probed beside the new ones
    old_config: PipelineConfig
    old_settings: dict[str, FitSettings]


OLD_SETTINGS = {
    "DR-KFS": FitSettings(learning_rate=0.005),
    "pixel MSE": FitSettings(learning_rate=0.001),
}
FULL = StudyPlan(
    fit_config=PipelineConfig.training(),
    judge_config=PipelineConfig.paper(),
    settings=FitSettings(steps=300),
    problems=("chair:3", "table:3", "airplane:3", "cow", "homer", "fandisk"),
    tuning="sofa:3",
    learning_rates=(0.001, 0.003),
    smoothness=(10.0, 100.0),
    weights=(1.0, 10.0),
    old_config=PipelineConfig.paper(num_views=8, image_size=128),
    old_settings=OLD_SETTINGS,
)
QUICK_STUDY = StudyPlan(
    fit_config=PipelineConfig.training(num_views=2, image_size=64),
    judge_config=PipelineConfig.paper(num_views=4, image_size=128),
    settings=FitSettings(steps=3),
    problems=("chair:3", "cow"),
    tuning="sofa:3",
    learning_rates=(0.005,),
    smoothness=(100.0,),
    weights=(1.0,),
    old_config=PipelineConfig.paper(num_views=2, image_size=64),
    old_settings=OLD_SETTINGS,
)


def load_problem(spec: str) -> Problem:
    family, _, seed = spec.partition(":")
    return synthetic(family, int(seed)) if family in FAMILIES else shared(spec)


def objective(loss: str, weight: float, metric: DRKFS, problem: Problem, template, faces):
    """The Objective of ``loss`` for fitting ``template`` (tensor) to ``problem``'s target."""
    target = (problem.target_verts, problem.target_faces, faces)
    if loss == "Chamfer":
        terms = [(1.0, ChamferLoss(*target))]
    elif loss == "pixel MSE":
        terms = [(1.0, PixelLoss(metric, *target))]
    elif loss == "DR-KFS":
        terms = [(1.0, DrkfsLoss(metric, *target))]
    elif loss == "DR-KFS + lambda*Chamfer":
        terms = [(1.0, DrkfsLoss(metric, *target)), (weight, ChamferLoss(*target))]
    else:
        raise ValueError(f"unknown loss {loss!r}; use one of {', '.join(LOSSES)}")
    return Objective(terms, template)


def run_fit(problem: Problem, loss: str, weight: float, metric: DRKFS, settings: FitSettings):
    template = float_tensor(problem.template_verts)
    faces = torch.as_tensor(problem.template_faces)
    return fit_mesh(
        objective(loss, weight, metric, problem, template, faces), template, faces, settings
    )


def mean_ranks(rows: dict[str, dict[str, float | None]]) -> dict[str, float]:
    """Each candidate's rank (1 = best) averaged over the metrics every candidate has."""
    names = list(rows)
    metrics = [m for m in METRICS if all(rows[n].get(m) is not None for n in names)]
    ranks = {n: 0.0 for n in names}
    for m in metrics:
        sign = -1.0 if m in HIGHER_IS_BETTER else 1.0
        order = sorted(names, key=lambda n: sign * rows[n][m])
        for rank, n in enumerate(order, 1):
            ranks[n] += rank / len(metrics)
    return ranks


def share(table: dict, challenger: str, metrics: tuple[str, ...]) -> dict:
    """The (problem, metric) cells where ``challenger``'s result beats the Chamfer one; a cell
    either side lacks (volumetric IoU of an open mesh) is not counted."""
    cells = {
        f"{p}/{m}": better(m, rows[challenger][m], rows["Chamfer"][m])
        for p, rows in table.items()
        for m in metrics
        if rows[challenger][m] is not None and rows["Chamfer"][m] is not None
    }
    wins = sum(cells.values())
    return {"wins": wins, "cells": len(cells), "share": wins / len(cells), "cell_wins": cells}


def chamfer_ratios(table: dict, losses: tuple[str, ...]) -> dict[str, float]:
    """Each loss's Chamfer-L1 over the Chamfer result's, averaged over the table's rows."""
    return {
        loss: float(
            np.mean(
                [
                    rows[loss]["Chamfer-L1"] / rows["Chamfer"]["Chamfer-L1"]
                    for rows in table.values()
                ]
            )
        )
        for loss in losses
    }


@dataclass(frozen=True)
class Choice:
    settings: FitSettings
    weight: float = 0.0  # lambda; used by the combination only


def tune(plan: StudyPlan, metric: DRKFS, judge: Judge, progress) -> tuple[dict, dict]:
    """Each single loss's step size and smoothness weight, then lambda at DR-KFS's settings: the
    candidate with the lowest mean rank over every metric on the tuning problem (ties: the first
    listed).

    -> ({loss: Choice}, the sweep's rows and ranks for the results)."""
    problem = load_problem(plan.tuning)
    target = judge.prepare(problem.target_verts, problem.target_faces)

    def pick(loss: str, candidates: dict[str, Choice]) -> tuple[Choice, dict]:
        rows = {}
        for label, c in candidates.items():
            result = run_fit(problem, loss, c.weight, metric, c.settings)
            rows[label] = judge.compare(judge.prepare(result.verts, problem.template_faces), target)
            progress(f"tuning {problem.name}: {loss} {label}: {_brief(rows[label])}")
        ranks = mean_ranks(rows)
        label = min(rows, key=lambda k: ranks[k])
        return candidates[label], {"results": rows, "mean_rank": ranks, "chosen": label}

    choices, report = {}, {"problem": problem.description}
    for loss in LOSSES[:3]:
        candidates = {
            f"lr={rate:g} smoothness={weight:g}": Choice(
                replace(plan.settings, learning_rate=rate, smoothness=weight)
            )
            for rate in plan.learning_rates
            for weight in plan.smoothness
        }
        choices[loss], report[loss] = pick(loss, candidates)
    at = choices["DR-KFS"].settings
    candidates = {f"lambda={w:g}": Choice(at, w) for w in plan.weights}
    choices[LOSSES[3]], report[LOSSES[3]] = pick(LOSSES[3], candidates)
    return choices, report


def slug(name: str) -> str:
    """A file name for a problem or loss: 'DR-KFS + lambda*Chamfer' -> 'dr-kfs_lambda_chamfer'."""
    return "_".join("".join(c if c.isalnum() or c == "-" else " " for c in name).lower().split())


def save_mesh(path: Path, verts, faces) -> str:
    """Write ``path`` (OUT/meshes/<problem>/<file>.ply) -> its path relative to OUT."""
    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.Trimesh(verts, faces, process=False).export(path)
    return str(path.relative_to(path.parents[2]))


def converged(history: list[float]) -> float:
    """How much the objective fell over the fit's last CONVERGENCE_WINDOW of steps, relative."""
    start = history[-max(1, round(len(history) * CONVERGENCE_WINDOW))]
    return (start - history[-1]) / max(abs(start), 1e-12)


def landscapes(plan: StudyPlan, problems: list[Problem], choices: dict, progress) -> dict:
    """The gradient probe (``landscape.probe``) of each rendered loss on every problem, at the
    study's config and chosen settings and at the first study's."""
    setups = {
        "new": (plan.fit_config, {loss: choices[loss].settings for loss in LANDSCAPE_LOSSES}),
        "old": (plan.old_config, plan.old_settings),
    }
    report = {}
    for key, (config, settings) in setups.items():
        metric = DRKFS.pretrained(config)
        report[key] = {"config": config.to_dict(), "problems": {}}
        for problem in problems:
            template = float_tensor(problem.template_verts)
            faces = torch.as_tensor(problem.template_faces)
            rows = {}
            for loss in LANDSCAPE_LOSSES:
                goal = objective(loss, 0.0, metric, problem, template, faces)
                rows[loss] = probe(goal, template, faces, settings[loss])
                rows[loss]["learning_rate"] = settings[loss].learning_rate
                progress(
                    f"landscape {key} {problem.name} {loss}: median relative error "
                    f"{rows[loss]['median_relative_error']:.3f}, monotone descent "
                    f"{rows[loss]['monotone_share']:.2f}"
                )
            report[key]["problems"][problem.name] = rows
        probes = report[key]["problems"].values()
        report[key]["summary"] = {
            loss: {
                "median_relative_error": float(
                    np.median([rows[loss]["median_relative_error"] for rows in probes])
                ),
                "monotone_share": float(np.mean([rows[loss]["monotone_share"] for rows in probes])),
                "monotone_at_start_everywhere": all(
                    rows[loss]["monotone_at_start"] for rows in probes
                ),
            }
            for loss in LANDSCAPE_LOSSES
        }
    return report


def run_study(out: Path, quick: bool, threads: int = 2, progress=print) -> dict:
    start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    plan = QUICK_STUDY if quick else FULL
    metric = DRKFS.pretrained(plan.fit_config)
    judge = Judge(plan.judge_config, threads)
    choices, tuning = tune(plan, metric, judge, progress)

    problems = [load_problem(spec) for spec in plan.problems]
    table, fits, gallery = {}, {}, []
    for problem in problems:
        folder = out / "meshes" / slug(problem.name)
        target = judge.prepare(problem.target_verts, problem.target_faces)
        template = judge.prepare(problem.template_verts, problem.template_faces)
        rows = {"template": judge.compare(template, target)}
        fits[problem.name] = {
            # a shared mesh stays where it is: the fits are in its frame_of frame
            "target": "/".join(problem.source.parts[-3:])  # shared/meshes/<name>.obj
            if problem.source
            else save_mesh(folder / "target.ply", problem.target_verts, problem.target_faces),
            "template": save_mesh(
                folder / "template.ply", problem.template_verts, problem.template_faces
            ),
        }
        meshes = [(problem.target_verts, problem.target_faces)]
        meshes.append((problem.template_verts, problem.template_faces))
        for loss in LOSSES:
            choice = choices[loss]
            result = run_fit(problem, loss, choice.weight, metric, choice.settings)
            rows[loss] = judge.compare(judge.prepare(result.verts, problem.template_faces), target)
            fits[problem.name][loss] = {
                "mesh": save_mesh(
                    folder / f"{slug(loss)}.ply", result.verts, problem.template_faces
                ),
                "objective_first": result.objective[0],
                "objective_last": result.objective[-1],
                "fall_over_last_tenth": converged(result.objective),
                "seconds_per_step": result.seconds_per_step,
            }
            meshes.append((result.verts, problem.template_faces))
            progress(f"{problem.name}: {loss:18} {_brief(rows[loss])}")
        table[problem.name] = rows
        gallery.append((problem.name, meshes))
    columns = ["TARGET", "TEMPLATE", "CHAMFER", "PIXEL MSE", "DR-KFS", "DR-KFS+CHAMFER"]
    write_gallery(out / "gallery.png", columns, gallery)

    # seconds per step at the judge's config (the paper's in a full run) on the first problem
    first = problems[0]
    step_seconds = {}
    for loss, choice in choices.items():
        timing = replace(choice.settings, steps=TIMING_STEPS)
        step_seconds[loss] = run_fit(
            first, loss, choice.weight, judge.metric, timing
        ).seconds_per_step
    results = {
        "command": f"drkfs fit{' --quick' if quick else ''} --out {out}",
        "quick": quick,
        "cpu_count": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "platform": platform.platform(),
        "fit_config": plan.fit_config.to_dict(),
        "judge_config": plan.judge_config.to_dict(),
        "settings": asdict(plan.settings),
        "problems": {problem.name: problem.description for problem in problems},
        "choices": {
            loss: {
                "learning_rate": c.settings.learning_rate,
                "smoothness": c.settings.smoothness,
                "lambda": c.weight,
            }
            for loss, c in choices.items()
        },
        "tuning": tuning,
        "table": table,
        "fits": fits,
        "drkfs_beats_chamfer": {
            "visual": share(table, "DR-KFS", VISUAL),
            "surface": share(table, "DR-KFS", SURFACE),
        },
        "combination_beats_chamfer": {
            "visual": share(table, LOSSES[3], VISUAL),
            "surface": share(table, LOSSES[3], SURFACE),
        },
        "chamfer_l1_over_chamfer_fit": chamfer_ratios(table, LOSSES),
        "seconds_per_step": {
            "config": plan.judge_config.to_dict(),
            "problem": first.description,
            "template_faces": len(first.template_faces),
            "losses": step_seconds,
        },
        "landscape": landscapes(plan, problems, choices, progress),
    }
    results["seconds_total"] = time.perf_counter() - start
    (out / "results.json").write_text(json.dumps(results, indent=1))
    return results


def _brief(row: dict[str, float | None]) -> str:
    return " ".join(f"{k} {v:.4g}" for k, v in row.items() if v is not None)
