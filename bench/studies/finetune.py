"""The single-view study's fine-tuning protocol (``python bench/single_view.py --finetune``),
the way a perceptual loss is often adopted: a network trained for the study's steps with SoftRas'
loss (or Chamfer's) is trained as many steps again with its own loss alone, with DR-KFS beside
it, and with another image term of DR-KFS's weight beside it (the matched control;
``single_view.FINETUNE``). At a seed every arm starts from the same weights and sees the same
batches, drawn afresh (seed + ``BATCH_SEED_SHIFT``); each is judged on the study's test shapes
beside the network it started from. ``single_view.FINETUNE_TUNED`` adds a second DR-KFS arm to
each start, the loss's fine-tuned nets in the shipped ones' place."""

from __future__ import annotations

import time
from pathlib import Path

import torch

from .single_view import (
    FINETUNE,
    FINETUNE_TUNED,
    FULL,
    QUICK,
    Networks,
    by_name,
    checked,
    judge_seeds,
    means,
    means_table,
    run_header,
    saved_run,
    sha256_of,
    shares,
    study_sets,
    train,
    training_data,
    views_of,
    wins_table,
    write_json,
)
from .views import ViewRenderer

BATCH_SEED_SHIFT = 1000  # the fine-tuning's batches: none of the first training's order


def arm(start: str, recipe: str) -> str:
    """The name of a network trained from ``start``'s with ``recipe``."""
    return f"{start}, then {recipe}"


def judged(protocol: dict = FINETUNE) -> list[str]:
    """Every start network and each of its arms, in the protocol's order."""
    return [
        n for start, recipes in protocol.items() for n in (start, *(arm(start, r) for r in recipes))
    ]


def compared(start: str, protocol: dict = FINETUNE) -> list[tuple[str, str]]:
    """(challenger, against) pairs of one start's arms (its own loss's, DR-KFS's, the
    control's, then any other DR-KFS arms): each DR-KFS arm against its own loss's and the
    control's, the control against its own loss's, and each other DR-KFS arm against the
    first."""
    own, drkfs, control, *others = (arm(start, r) for r in protocol[start])
    pairs = [(drkfs, own), (drkfs, control), (control, own)]
    for other in others:
        pairs += [(other, own), (other, control), (other, drkfs)]
    return pairs


def run_finetune(
    out: Path,
    seeds: tuple[int, ...] = (0, 1, 2),
    quick: bool = False,
    device: str = "cpu",
    threads: int = 2,
    progress=print,
    tuned_nets: bool = False,
) -> dict:
    """Every start network (OUT/networks, trained there first if missing) fine-tuned with each
    of its arms at every seed (OUT/networks-finetuned, resumable), judged on the test shapes
    -> OUT/finetune.json; with ``tuned_nets`` by ``FINETUNE_TUNED`` ->
    OUT/finetune-tuned-nets.json. The JSON holds each network's sha256: no CPU but the one
    that trained them remakes them to the bit, and ``judge_finetuned`` judges only these."""
    protocol, flag, stem = _run_of(tuned_nets)
    began = time.perf_counter()
    plan = QUICK if quick else FULL
    dev = torch.device(device)
    test_set, views, terms = training_data(out, plan, dev)
    starts, tuned, store = _stores(out, plan, dev, protocol)
    seconds: dict = {}
    for seed in seeds:
        for start, recipes in protocol.items():
            weights = starts.trained(seed, start, plan, views["train"], terms, progress)
            weights = weights["model"].state_dict()
            for recipe in recipes:
                name = arm(start, recipe)
                saved = tuned.get(seed, name)
                if saved is None:
                    saved = train(plan, by_name(recipe), seed + BATCH_SEED_SHIFT,
                                  views["train"], terms, progress, start=weights)  # fmt: skip
                    tuned.put(seed, name, saved)
                seconds.setdefault(name, {})[f"seed {seed}"] = saved["seconds_per_step"]
    tables, lfd = _judge(store, plan, threads, seeds, test_set, views["test"], progress)
    results = {
        **run_header(flag, quick, seeds, dev, out, lfd),
        "quick": quick,
        "networks": _digests(store, seeds),
        **_protocol_record(plan, protocol),
        "tables": {f"seed {s}": t for s, t in tables.items()},
        **summarise_finetune(tables, test_set, protocol),
        "seconds_per_step": seconds,
        "seconds_total": time.perf_counter() - began,
    }
    return write_json(out / f"{stem}.json", results)


def judge_finetuned(
    out: Path, test_seed: int, threads: int = 2, progress=print, tuned_nets: bool = False
) -> dict:
    """The networks of the fine-tuning run OUT/finetune.json (with ``tuned_nets``
    OUT/finetune-tuned-nets.json; its starts in OUT/networks, its arms in
    OUT/networks-finetuned) judged on test shapes of seeds from ``test_seed`` on, at that run's
    seeds and plan, as ``single_view.judge_saved`` judges the study's ->
    OUT/finetune[-tuned-nets]-test-seeds-<seed>.json. ``SavedRunError`` where the run or a
    network is missing, or a network is not the one the run judged (its sha256)."""
    protocol, flag, stem = _run_of(tuned_nets)
    began = time.perf_counter()
    run_path = out / f"{stem}.json"
    run = saved_run(run_path, f"`python bench/single_view.py {flag} --out {out}`")
    plan, seeds, cpu = (QUICK if run["quick"] else FULL), run["seeds"], torch.device("cpu")
    *_, store = _stores(out, plan, cpu, protocol)
    digests = {
        f"seed {s}": {n: checked(run_path, where.path(s, n), run["networks"][f"seed {s}"][n])
                      for n, where in store.items()}
        for s in seeds
    }  # fmt: skip
    _, _, test_set = study_sets(plan, test_seed)
    views = views_of(test_set, out / "data" / "views.pt", ViewRenderer())
    tables, lfd = _judge(store, plan, threads, seeds, test_set, views, progress)
    results = {
        **run_header(f"{flag} --test-seeds {test_seed}", run["quick"], seeds, cpu, out, lfd),
        "test_seeds": [test_seed, test_seed + plan.test_per_family - 1],
        "networks": digests,
        **_protocol_record(plan, protocol),
        "tables": {f"seed {s}": t for s, t in tables.items()},
        **summarise_finetune(tables, test_set, protocol),
        "seconds_total": time.perf_counter() - began,
    }
    return write_json(out / f"{stem}-test-seeds-{test_seed}.json", results)


def _stores(out: Path, plan, device: torch.device, protocol: dict) -> tuple:
    """(the starts' store OUT/networks, the arms' OUT/networks-finetuned, each network of
    ``judged(protocol)`` -> its store)."""
    starts, tuned = (Networks(out / folder, plan, device)
                     for folder in ("networks", "networks-finetuned"))  # fmt: skip
    return starts, tuned, {n: starts if n in protocol else tuned for n in judged(protocol)}


def _judge(store: dict[str, Networks], plan, threads: int, seeds, shapes, views, progress):
    """``judge_seeds`` of every network of ``store`` as saved there, on ``shapes``."""
    return judge_seeds(
        plan, threads, seeds,
        lambda seed: {n: where.get(seed, n, any_key=True)["model"] for n, where in store.items()},
        shapes, views, progress,
    )  # fmt: skip


def _digests(store: dict[str, Networks], seeds) -> dict:
    """ "seed S" -> network -> the sha256 of its saved file."""
    return {f"seed {s}": {n: sha256_of(where.path(s, n)) for n, where in store.items()}
            for s in seeds}  # fmt: skip


def _run_of(tuned_nets: bool) -> tuple[dict, str, str]:
    """(protocol, command-line flags, JSON name's stem) of a plain or a --tuned-nets run."""
    if tuned_nets:
        return FINETUNE_TUNED, "--finetune --tuned-nets", "finetune-tuned-nets"
    return FINETUNE, "--finetune", "finetune"


def _protocol_record(plan, protocol: dict) -> dict:
    """What a run's JSON says of its protocol: the steps, each start's arms, each recipe's
    terms."""
    return {
        "steps": {"start": plan.steps, "fine-tuning": plan.steps},
        "arms": {start: [arm(start, r) for r in recipes] for start, recipes in protocol.items()},
        "recipes": {
            r: [list(t) for t in by_name(r).terms] for recipes in protocol.values() for r in recipes
        },  # fmt: skip
    }


def protocol_of(results: dict) -> dict:
    """The protocol a run's JSON was made by: start -> its recipes, from its "arms"."""
    return {start: tuple(a.split(", then ", 1)[1] for a in arms)
            for start, arms in results["arms"].items()}  # fmt: skip


def summarise_finetune(tables: dict[int, dict], test_set, protocol: dict = FINETUNE) -> dict:
    """Every start's and arm's means, and each ``compared`` pair's shares of test cells, per
    seed and pooled."""
    names = judged(protocol)
    per = {"pooled": list(tables.values()), **{f"seed {s}": [t] for s, t in tables.items()}}
    pairs = [pair for start in protocol for pair in compared(start, protocol)]
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
