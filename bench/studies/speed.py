"""The single-view study's speed work (``python bench/single_view.py --speed``): what a training
step costs with DR-KFS at a full step and at each cheaper one (``CHEAPER``: from one group of its
cameras a step, ``DrkfsLoss``'s ``view_groups``, the loss on average; or with HardNet's convs in
bfloat16, its ``conv_precision``), timed in one run beside SoftRas' IoU; then whether a cheaper
step loses anything: the cheaper losses asked for trained at every seed for the study's steps and
judged on the validation shapes beside the study's networks of the same losses at a full step."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import torch

from .shape_generator import ShapeGenerator
from .single_view import (
    CAMERA_GROUPS,
    CHEAPER,
    DRKFS_SHADED,
    FULL,
    QUICK,
    RECIPE,
    SOFTRAS,
    TIMED_STEPS,
    VALIDATION_SEED,
    Networks,
    Terms,
    by_name,
    judge_seeds,
    means,
    means_table,
    run_header,
    shares,
    study_sets,
    timed,
    views_of,
    wins_table,
    write_json,
)
from .views import CHANNELS, IMAGE_SIZE, ViewRenderer

# each cheaper loss -> the same loss at a full step
FULL_STEP = {
    **dict.fromkeys(CHEAPER, DRKFS_SHADED),
    **{f"{name} + 3 x Chamfer-L2": RECIPE for name in CHEAPER},
}
TIMED = (
    SOFTRAS, DRKFS_SHADED, *CHEAPER,
    RECIPE, *(name for name, full in FULL_STEP.items() if full == RECIPE),
)  # fmt: skip


def judged_rows(names: list[str]) -> list[str]:
    """Each cheaper loss of ``names`` after its full-step loss, each once."""
    return list(dict.fromkeys(n for name in names for n in (FULL_STEP[name], name)))


def run_speed(
    out: Path,
    names: list[str],
    seeds: tuple[int, ...] = (0, 1, 2),
    quick: bool = False,
    device: str = "cpu",
    threads: int = 2,
    progress=print,
    steps: int | None = None,
) -> dict:
    """Every ``TIMED`` loss's seconds a step in one run; then ``names`` (cheaper losses) and
    their full-step losses at each seed (OUT/networks, the study's; trained there if
    missing), judged on the validation shapes -> OUT/speed.json. With ``steps``, the cheaper
    losses trained for that many steps instead (OUT/networks-<steps>-steps; as many as take
    the full-step loss's time at the study's steps compare them at equal cost) ->
    OUT/speed-<steps>-steps.json."""
    unknown = [n for n in names if n not in FULL_STEP]
    if unknown:
        raise ValueError(f"not a cheaper loss: {unknown}; the cheaper: {', '.join(FULL_STEP)}")
    began = time.perf_counter()
    plan = QUICK if quick else FULL
    dev = torch.device(device)
    train_set, validation_set, _ = study_sets(plan)
    cache, renderer = out / "data" / "views.pt", ViewRenderer()
    sets = {"train": train_set, "validation": validation_set}
    views = {name: views_of(shapes, cache, renderer) for name, shapes in sets.items()}
    terms = Terms(train_set, views["train"], ShapeGenerator(CHANNELS, IMAGE_SIZE).faces.to(dev), 0)
    timing = {name: timed(plan, by_name(name), views["train"], terms, progress) for name in TIMED}
    cheaper_plan = plan if steps is None else replace(plan, steps=steps)
    study = Networks(out / "networks", plan, dev)
    longer = Networks(out / f"networks-{steps}-steps", cheaper_plan, dev) if steps else study

    def store(name: str) -> Networks:
        return longer if name in FULL_STEP else study

    rows = judged_rows(names)
    for seed in seeds:
        for name in rows:
            at = cheaper_plan if name in FULL_STEP else plan
            store(name).trained(seed, name, at, views["train"], terms, progress)
    tables, lfd = judge_seeds(
        plan, threads, seeds, lambda seed: {n: store(n).get(seed, n)["model"] for n in rows},
        validation_set, views["validation"], progress,
    )  # fmt: skip
    flag = f"--speed --losses '{','.join(names)}'" + (f" --steps {steps}" if steps else "")
    results = {
        **run_header(flag, quick, seeds, dev, out, lfd),
        "steps": plan.steps,
        **({} if steps is None else {"grouped_steps": steps}),
        "timed_steps": TIMED_STEPS,
        "camera_groups": CAMERA_GROUPS,
        "seconds_per_step": timing,
        "validation_seeds": [VALIDATION_SEED, VALIDATION_SEED + plan.validation_per_family - 1],
        "losses": names,
        "tables": {f"seed {s}": t for s, t in tables.items()},
        **summarise_speed(tables, validation_set, names),
        "seconds_total": time.perf_counter() - began,
    }
    name = "speed.json" if steps is None else f"speed-{steps}-steps.json"
    return write_json(out / name, results)


def summarise_speed(tables: dict[int, dict], shapes, names: list[str]) -> dict:
    """Each cheaper loss's and its full-step loss's means on the validation shapes, and the
    cheaper one's cells closer than the other's, per seed and pooled."""
    rows = judged_rows(names)
    per = {"pooled": list(tables.values()), **{f"seed {s}": [t] for s, t in tables.items()}}
    return {
        "means": {key: means(ts, shapes, rows)["mean"] for key, ts in per.items()},
        "shares": {
            key: {f"{n} | {FULL_STEP[n]}": shares(ts, n, FULL_STEP[n]) for n in names}
            for key, ts in per.items()
        },
    }


def speed_markdown(results: dict) -> str:
    """bench/records/single_view.md's speed tables (OUT/speed.json): each loss's seconds a step
    against SoftRas' IoU's in the same run; the cheaper and full-step losses' pooled means on
    the validation shapes; the cheaper one's cells closer, pooled and per seed (LFD, unseen
    silhouettes). A run at equal cost (OUT/speed-<steps>-steps.json): the last two."""
    first, blocks = "loss (validation shapes)", []
    if "grouped_steps" in results:  # the timings are the run at equal steps'
        first = f"loss (validation shapes; full step {results['steps']} steps, cheaper "
        first += f"{results['grouped_steps']})"
    else:
        timing = results["seconds_per_step"]
        lines = ["| loss | s a step | x SoftRas' IoU |", "|---|---:|---:|"]
        for name, seconds in timing.items():
            lines.append(f"| {name} | {seconds:.2f} | {seconds / timing[SOFTRAS]:.1f} |")
        blocks.append(lines)
    blocks.append(means_table(results["means"]["pooled"], first))
    blocks.append(wins_table(results["shares"], "cheaper"))
    return "\n\n".join("\n".join(block) for block in blocks) + "\n"
