"""bench/records/single_view.md's tables, as the single-view study's own printers make them from
its committed runs (bench/single_view/*.json), in the record's order: the comparison at 200
steps, the matched controls, 400 steps, the nets fine-tuned for the loss, other test shapes
(the study's networks', then the --steps runs'), the fine-tuning protocol, the learning curve,
the speed runs."""

from __future__ import annotations

from functools import partial
from pathlib import Path

from drkfs_lab.record_tables import Table, committed
from drkfs_lab.studies.finetune import finetune_markdown
from drkfs_lab.studies.single_view import (
    controls_markdown,
    curve_markdown,
    markdown,
    pooled_runs,
    steps_markdown,
    test_seeds_markdown,
    tuned_nets_markdown,
)
from drkfs_lab.studies.speed import speed_markdown

STUDY = "bench/single_view"


def _run(printer, name: str, root: Path) -> str:
    """``printer``'s tables of the study's run ``name``."""
    return printer(committed(root, f"{STUDY}/{name}"))


def tuned_nets(root: Path) -> str:
    """The nets fine-tuned for the loss, pooled over every seed's run at the study's steps."""
    runs = sorted((root / STUDY).glob("longer-200-steps-seed*.json"))
    return tuned_nets_markdown(
        pooled_runs([committed(root, str(path.relative_to(root))) for path in runs])
    )


def study_runs(printer, runs: tuple[str, ...], root: Path) -> str:
    """``printer``'s tables of ``runs``, in the record's order; every run named like the first
    (speed*.json for speed.json, the runs check_results recomputes) must be one of them, so that
    none goes unprinted (ValueError)."""
    found = {p.name for p in (root / STUDY).glob(f"{Path(runs[0]).stem}*.json")}
    if found - set(runs):
        raise ValueError(f"{STUDY}: {', '.join(sorted(found - set(runs)))} not in the record")
    return "\n\n".join(printer(committed(root, f"{STUDY}/{name}")) for name in runs)


FINETUNE_RUNS = (
    "finetune.json", "finetune-whole-replicate.json", "finetune-tuned-nets.json",
    "finetune-tuned-nets-test-seeds-6000.json",
)  # fmt: skip


TABLES: list[Table] = [
    partial(_run, markdown, "results.json"),
    partial(_run, controls_markdown, "controls.json"),
    partial(_run, steps_markdown, "longer-400-steps-seed0.json"),
    tuned_nets,
    partial(_run, test_seeds_markdown, "test-seeds-6000.json"),
    partial(_run, steps_markdown, "longer-400-steps-test-seeds-6000.json"),
    partial(_run, tuned_nets_markdown, "longer-200-steps-test-seeds-6000.json"),
    partial(study_runs, finetune_markdown, FINETUNE_RUNS),
    partial(_run, curve_markdown, "curve.json"),
    partial(study_runs, speed_markdown, ("speed.json", "speed-540-steps.json")),
]
