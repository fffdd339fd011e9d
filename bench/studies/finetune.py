"""The single-view study's fine-tuning protocol (``python bench/single_view.py --finetune``),
the way a perceptual loss is often adopted: a network trained for the study's steps with SoftRas'
loss (or Chamfer's) is trained as many steps again with its own loss alone, with DR-KFS beside
it, and with another image term of DR-KFS's weight beside it (the matched control;
``single_view.FINETUNE``). At a seed every arm starts from the same weights and sees the same
batches, drawn afresh (seed + ``BATCH_SEED_SHIFT``); each is judged on the study's test shapes
beside the network it started from."""

from __future__ import annotations

import time
from pathlib import Path

import torch

from .single_view import (
    FINETUNE,
    FULL,
    QUICK,
    Networks,
    by_name,
    judge_seeds,
    means,
    means_table,
    run_header,
    shares,
    train,
    training_data,
    wins_table,
    write_json,
)

BATCH_SEED_SHIFT = 1000  # the fine-tuning's batches: none of the first training's order


def arm(start: str, recipe: str) -> str:
    """The name of a network trained from ``start``'s with ``recipe``."""
    return f"{start}, then {recipe}"


def judged() -> list[str]:
    """Every start network and each of its arms, in ``FINETUNE``'s order."""
    return [
        n for start, recipes in FINETUNE.items() for n in (start, *(arm(start, r) for r in recipes))
    ]


def compared(start: str) -> list[tuple[str, str]]:
    """(challenger, against) pairs of one start's arms: DR-KFS's arm against its own loss's and
    against the control's, and the control against its own loss's."""
    own, drkfs, control = (arm(start, r) for r in FINETUNE[start])
    return [(drkfs, own), (drkfs, control), (control, own)]


def run_finetune(
    out: Path,
    seeds: tuple[int, ...] = (0, 1, 2),
    quick: bool = False,
    device: str = "cpu",
    threads: int = 2,
    progress=print,
) -> dict:
    """Every start network (OUT/networks, trained there first if missing) fine-tuned with each
    of its arms at every seed (OUT/networks-finetuned, resumable), judged on the test shapes
    -> OUT/finetune.json."""
    began = time.perf_counter()
    plan = QUICK if quick else FULL
    dev = torch.device(device)
    test_set, views, terms = training_data(out, plan, dev)
    starts, tuned = (
        Networks(out / "networks", plan, dev),
        Networks(out / "networks-finetuned", plan, dev),
    )
    seconds: dict = {}
    for seed in seeds:
        for start, recipes in FINETUNE.items():
            weights = starts.trained(seed, start, plan, views["train"], terms, progress)
            weights = weights["model"].state_dict()
            for recipe in recipes:
                name = arm(start, recipe)
                if tuned.get(seed, name) is None:
                    trained = train(plan, by_name(recipe), seed + BATCH_SEED_SHIFT,
                                    views["train"], terms, progress, start=weights)  # fmt: skip
                    tuned.put(seed, name, trained)
                seconds.setdefault(name, {})[f"seed {seed}"] = tuned.get(seed, name)[
                    "seconds_per_step"
                ]
    names = judged()
    tables, lfd = judge_seeds(
        plan, threads, seeds,
        lambda seed: {n: (tuned.get(seed, n) or starts.get(seed, n))["model"] for n in names},
        test_set, views["test"], progress,
    )  # fmt: skip
    results = {
        **run_header("--finetune", quick, seeds, dev, out, lfd),
        "steps": {"start": plan.steps, "fine-tuning": plan.steps},
        "arms": {start: [arm(start, r) for r in recipes] for start, recipes in FINETUNE.items()},
        "recipes": {
            r: [list(t) for t in by_name(r).terms] for recipes in FINETUNE.values() for r in recipes
        },  # fmt: skip
        "tables": {f"seed {s}": t for s, t in tables.items()},
        **summarise_finetune(tables, test_set),
        "seconds_per_step": seconds,
        "seconds_total": time.perf_counter() - began,
    }
    return write_json(out / "finetune.json", results)


def summarise_finetune(tables: dict[int, dict], test_set) -> dict:
    """Every start's and arm's means, and each ``compared`` pair's shares of test cells, per
    seed and pooled."""
    names = judged()
    per = {"pooled": list(tables.values()), **{f"seed {s}": [t] for s, t in tables.items()}}
    pairs = [pair for start in FINETUNE for pair in compared(start)]
    return {
        "means": {key: means(ts, test_set, names)["mean"] for key, ts in per.items()},
        "shares": {
            key: {f"{c} | {a}": shares(ts, c, a) for c, a in pairs} for key, ts in per.items()
        },  # fmt: skip
    }


def finetune_markdown(results: dict) -> str:
    """bench/records/single_view.md's fine-tuning tables (OUT/finetune.json): every start's and
    arm's pooled means, and each arm's test cells closer than another's, pooled and (LFD,
    unseen silhouettes) per seed (bench/check_results.py checks the record holds them)."""
    lines = means_table(results["means"]["pooled"], "network")
    wins = wins_table(results["shares"], "fine-tuned with")
    return "\n\n".join("\n".join(block) for block in (lines, wins)) + "\n"
