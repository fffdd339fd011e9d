"""The DR-KFS paper's single-view reconstruction experiment (bench/records/single_view.md), from a
checkout with the lab installed: SoftRas' shape generator trained with each loss at several
seeds, judged on held-out shapes and views by metrics no loss computes.

    python bench/single_view.py --quick                      # seconds: the tests' plan
    python bench/single_view.py --out bench/single_view      # the study (resumable)
    python bench/single_view.py --out bench/single_view --test-seeds 6000   # other test shapes
    python bench/single_view.py --out bench/single_view --controls  # the matched controls
    python bench/single_view.py --out bench/single_view --curve --until 3000   # learning curve
    python bench/single_view.py --out bench/single_view --finetune  # the fine-tuning protocol
    python bench/single_view.py --out bench/single_view --finetune --tuned-nets  # with the
                                                  # loss's fine-tuned nets too
    python bench/single_view.py --out bench/single_view --finetune --tuned-nets \
        --test-seeds 6000                         # its networks judged on other test shapes
    python bench/single_view.py --out bench/single_view --speed \
        --losses "DR-KFS (a third of the cameras a step)"           # cheaper steps
    python bench/single_view.py --out bench/single_view --steps 400 --seeds 0 \
        --losses "SoftRas (silhouette IoU),DR-KFS"                          # more steps
    python bench/single_view.py --out bench/single_view --steps 200 --seeds 0,1,2 \
        --test-seeds 6000                     # the --steps runs' networks on other test shapes

Output: runs/single-view unless --out says otherwise.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from drkfs_onnx.contract.cli_options import RUNS

app = typer.Typer(add_completion=False, rich_markup_mode=None)  # plain help: flags without <bool>


@app.command()
def single_view(
    out: Annotated[
        Path | None,
        typer.Option(help="Where results.json, gallery.png and networks/ go.", show_default=False),
    ] = None,
    quick: Annotated[bool, typer.Option(help="A tiny plan that runs in a minute (tests).")] = False,
    seeds: Annotated[
        str, typer.Option(help="Seeds of the initial weights and batch order, comma-separated.")
    ] = "0,1,2",
    device: Annotated[str, typer.Option(help="Where the networks train: cpu, cuda.")] = "cpu",
    threads: Annotated[int, typer.Option(help="Threads for the judges' renderer.")] = 2,
    test_seeds: Annotated[
        int | None,
        typer.Option(
            help="Judge the networks a finished study saved in OUT on test shapes from this "
            "seed on, on the CPU at the study's seeds and plan, instead of training (writes "
            "OUT/test-seeds-<seed>.json); with --finetune, the fine-tuning run's networks (writes "
            "OUT/finetune[-tuned-nets]-test-seeds-<seed>.json); with --steps, those the --steps "
            "runs of --seeds judged (writes OUT/longer-<steps>-steps-test-seeds-<seed>.json).",
            show_default=False,
        ),
    ] = None,
    steps: Annotated[
        int | None,
        typer.Option(
            help="Train --losses at each of --seeds for this many steps (networks beside the "
            "study's in OUT) and judge them beside the study's networks of that seed (writes "
            "OUT/longer-<steps>-steps-seed<seed>.json); with --speed, the cheaper losses' steps.",
            show_default=False,
        ),
    ] = None,
    losses: Annotated[
        str, typer.Option(help="With --steps: the losses, by name, comma-separated.")
    ] = "SoftRas (silhouette IoU),DR-KFS",
    curve: Annotated[
        bool,
        typer.Option(
            help="The learning curve: the main losses trained at the first of --seeds and "
            "judged at 200, 500, 1,000, 2,000 and 3,000 steps up to --until (writes "
            "OUT/curve.json and OUT/curve.png; resumes from --state)."
        ),
    ] = False,
    until: Annotated[int, typer.Option(help="With --curve: the last step judged.")] = 3000,
    state: Annotated[
        Path | None,
        typer.Option(
            help="With --curve: where training states and networks are kept between runs "
            "(outside the repository; default ~/.cache/drkfs-onnx/single-view-curve).",
            show_default=False,
        ),
    ] = None,
    controls: Annotated[
        bool,
        typer.Option(
            help="Train each DR-KFS recipe and its matched controls at every seed (networks "
            "beside the study's in OUT) and judge them (writes OUT/controls.json)."
        ),
    ] = False,
    speed: Annotated[
        bool,
        typer.Option(
            help="Time a step of each loss at a full step and at each cheaper one (a group of "
            "the cameras, HardNet in bfloat16), in one run; then train --losses (cheaper ones) "
            "at every seed and judge them beside the same losses at a full step on the "
            "validation shapes (writes OUT/speed.json)."
        ),
    ] = False,
    finetune: Annotated[
        bool,
        typer.Option(
            help="The fine-tuning protocol: SoftRas' and Chamfer's networks trained as long "
            "again with their own loss, with DR-KFS beside it and with the matched control "
            "beside it, at every seed (writes OUT/finetune.json)."
        ),
    ] = False,
    tuned_nets: Annotated[
        bool,
        typer.Option(
            help="With --finetune: a second DR-KFS arm from each start network, its nets "
            "fine-tuned for the loss (writes OUT/finetune-tuned-nets.json)."
        ),
    ] = False,
) -> None:
    """Train SoftRas' shape generator with each loss and judge the reconstructions."""
    from drkfs_lab.studies.single_view import (
        CURVE_STATE,
        SavedRunError,
        controls_markdown,
        curve_markdown,
        judge_longer,
        judge_saved,
        means_table,
        run_controls,
        run_curve,
        run_longer,
        run_single_view,
    )

    progress = lambda line: typer.echo(line, err=True)  # noqa: E731
    out = out or RUNS / "single-view"
    try:
        seed_list = tuple(int(s) for s in seeds.split(","))
    except ValueError:
        message = f"--seeds: expected integers like 0,1,2; got {seeds!r}"
        raise typer.BadParameter(message) from None
    if speed:
        from drkfs_lab.studies.speed import run_speed, speed_markdown

        try:
            results = run_speed(
                out, losses.split(","), seed_list, quick, device, threads, progress, steps
            )
        except ValueError as error:
            raise typer.BadParameter(str(error), param_hint="--losses") from None
        typer.echo(speed_markdown(results))  # bench/records/single_view.md's tables
        return
    if steps is not None and test_seeds is not None:
        try:
            results = judge_longer(out, steps, seed_list, test_seeds, threads, progress)
        except SavedRunError as error:
            raise typer.BadParameter(str(error), param_hint="--test-seeds") from None
        typer.echo("\n".join(means_table(results["means"]["mean"], "network")))
        return
    if steps is not None:
        for seed in seed_list:
            try:
                results = run_longer(
                    out, steps, losses.split(","), seed, quick, device, threads, progress
                )
            except ValueError as error:
                raise typer.BadParameter(str(error), param_hint="--losses") from None
            for name, row in results["means"]["mean"].items():
                judged = [
                    f"{judge} {value:.4g}" for judge, value in row.items() if value is not None
                ]
                typer.echo(f"seed {seed}, {name}: {', '.join(judged)}")
        return
    if curve:
        results = run_curve(
            out, until, seed_list[0], state or CURVE_STATE, quick, device, threads, progress
        )
        typer.echo(curve_markdown(results))  # bench/records/single_view.md's table
        return
    if finetune:
        from drkfs_lab.studies.finetune import (
            finetune_markdown,
            judge_finetuned,
            run_finetune,
        )

        if test_seeds is None:
            results = run_finetune(out, seed_list, quick, device, threads, progress, tuned_nets)
        else:
            try:
                results = judge_finetuned(out, test_seeds, threads, progress, tuned_nets)
            except SavedRunError as error:
                raise typer.BadParameter(str(error), param_hint="--test-seeds") from None
        typer.echo(finetune_markdown(results))  # bench/records/single_view.md's tables
        return
    if controls:
        results = run_controls(out, seed_list, quick, device, threads, progress)
        typer.echo(controls_markdown(results))  # bench/records/single_view.md's tables
        return
    if test_seeds is not None:
        results = judge_saved(out, test_seeds, threads, progress)
    else:
        results = run_single_view(out, quick, seed_list, device, threads, progress)
    pooled = results["shares"]["pooled"]
    for drkfs, rows in pooled.items():
        for baseline, row in rows.items():
            typer.echo(
                f"{drkfs} closer than {baseline}: "
                + ", ".join(f"{m} {v['wins']}/{v['cells']}" for m, v in row.items() if v["cells"])
            )
    typer.echo(f"goal: {results['goal']}")


if __name__ == "__main__":
    app()
