"""The lab's commands on ``drkfs``: bench, train, tune-tolerant and choose-loss. The library's
command line adds this app's commands through the ``drkfs_onnx.commands`` entry point
(bench/pyproject.toml); each imports its torch-side modules when it runs."""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path
from typing import Annotated

import typer

from drkfs_onnx.contract.cli_options import RUNS

app = typer.Typer()
# the modules the lab requires beside the library's torch extra (bench/pyproject.toml), as imported
LAB_REQUIRES = ("matplotlib", "scipy", "fast_simplification")


def needs_the_lab(command):
    """``command``, with a missing module of the lab's named with its install instead of a
    traceback."""

    @functools.wraps(command)
    def run(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except ModuleNotFoundError as exc:
            if exc.name not in LAB_REQUIRES:
                raise
            typer.echo(
                f"error: this drkfs command needs {exc.name}; install the lab from a checkout: "
                "pip install -e ./bench",
                err=True,
            )
            raise typer.Exit(2) from None

    return run


RealMeshes = Annotated[
    Path | None,
    typer.Option(
        help="The folder of the real meshes (meshes/README.md); default: the checkout's meshes/ "
        "folder, or DRKFS_MESHES.",
        show_default=False,
    ),
]


def use_meshes(folder: Path | None) -> None:
    """Read the real meshes from ``folder`` (the benchmark's set reads DRKFS_MESHES)."""
    if folder is None:
        return
    if not (folder / "cow.obj").is_file():
        typer.echo(f"error: --meshes {folder}: no real meshes there (no cow.obj)", err=True)
        raise typer.Exit(2)
    os.environ["DRKFS_MESHES"] = str(folder.resolve())


@app.command()
@needs_the_lab
def train(
    out: Annotated[
        Path, typer.Option(help="Where the weights and manifest.json go (--out models ships them).")
    ] = RUNS / "models",
    work: Annotated[Path, typer.Option(help="Data cache and checkpoints (resumed from).")] = Path(
        ".drkfs-train"
    ),
    seed: int = 0,
    quick: Annotated[bool, typer.Option(help="A tiny plan that runs in seconds (tests).")] = False,
) -> None:
    """Render synthetic data, train the PoI detector and HardNet on view-pair correspondences
    (the paper preset's nets), fine-tune them for the metric (the metric nets, which drkfs
    tune-tolerant turns into the default's), write weights and a new manifest.

    Rerunning after an interruption resumes from the last checkpoint in WORK.
    """
    from dataclasses import replace

    from .training.run import QUICK_TRAIN, TrainPlan
    from .training.run import train as run_training

    plan = replace(QUICK_TRAIN if quick else TrainPlan(), seed=seed)
    command = f"drkfs train --out {out} --work {work} --seed {seed}" + (" --quick" if quick else "")
    manifest = run_training(plan, out, work, command)
    for row in manifest["detectors"]:
        typer.echo(f"detector {row['detector']:8} repeatability {row['repeatability']:.3f}")
    for row in manifest["descriptors"]:
        typer.echo(
            f"hardnet width {row['width']:<5g} FPR95 {row['fpr95']:5.1f}% "
            f"(untrained {row['fpr95_untrained']:5.1f}%)"
        )
    stage = manifest["metric"]
    for name, row in stage["objectives"].items():
        typer.echo(
            f"objective {name:38} benchmark accuracy {row['accuracy']:.3f} bars "
            f"{row['bars']:.2f} retrieval {row['retrieval']:.2f}"
        )
    typer.echo(
        f"chosen {manifest['choice']}; metric nets: {stage['objective']}, width "
        f"{stage['width']:g}; {sum(manifest['seconds'].values()):.0f} s"
    )


@app.command("tune-tolerant")
@needs_the_lab
def tune_tolerant(
    out: Annotated[
        Path, typer.Option(help="Where the weights go, entered in its manifest (--out models).")
    ] = RUNS / "models",
    work: Annotated[Path, typer.Option(help="Data cache and checkpoint (resumed from).")] = Path(
        ".drkfs-train/tolerant"
    ),
    quick: Annotated[bool, typer.Option(help="Two bases and 2 steps (tests).")] = False,
) -> None:
    """Fine-tune the metric nets for a viewer's tolerance (the default's nets): small turns and
    shifts rank below surface defects, those below missing parts, and coarser simplifications
    above finer ones. It starts from the metric nets of OUT's manifest where drkfs train wrote
    them there (else the shipped ones) and adds its entry to that manifest: run it after drkfs
    train, which writes a new one, then drkfs export.

    Rerunning after an interruption resumes from the checkpoint in WORK.
    """
    from .training.tolerance import ship_tolerant

    command = f"drkfs tune-tolerant --out {out} --work {work}" + (" --quick" if quick else "")
    try:
        entry = ship_tolerant(out, work, command, quick)
    except ValueError as exc:  # MissingWeights among them
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from exc
    made = entry["made_by"]
    typer.echo(
        f"{out / entry['file']}: objective {made['objective']['before']:.3f} -> "
        f"{made['objective']['after']:.3f}; {made['seconds']:.0f} s"
    )


@app.command()
@needs_the_lab
def bench(
    out: Annotated[Path, typer.Option(help="Where results.json, the chart and the set go.")] = RUNS
    / "bench",
    quick: Annotated[bool, typer.Option(help="The small subset the tests run.")] = False,
    threads: Annotated[int, typer.Option(help="Threads for onnxruntime and the renderer.")] = 2,
    human: Annotated[
        Path | None,
        typer.Option(
            help="A Geo-metric clone with its simplification stimuli checked out "
            "(docs/benchmark.md): adds the human-judgment check."
        ),
    ] = None,
    meshes: RealMeshes = None,
) -> None:
    """Speed against accuracy: every method on the same variant sets, the chart, stability."""
    from .benchmark.run import REAL_CHECKS, TIER_PAIRS, run_bench

    use_meshes(meshes)

    try:
        results = run_bench(out, quick, threads, lambda line: typer.echo(line, err=True), human)
    except ValueError as exc:  # a --human folder without the stimuli
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from exc
    header = ("method", "inv<str", "sur<str", "inv<sur", "human", "retrieval", "bars", "s/pair")
    typer.echo(f"{header[0]:36}" + "".join(f"{h:>10}" for h in header[1:]))
    for name, row in results["methods"].items():
        tiers, people = row["tiers"], row["human"]
        cells = [tiers[key] for key in TIER_PAIRS]
        cells += [None if people is None else people["close_normal"]]
        cells += [row["retrieval"]["nearest_neighbour_accuracy"]]
        cells += [row["bars"]["deletion_over_max_shift"], row["seconds_per_pair"]]
        typer.echo(f"{name:36}" + "".join(f"{_fmt(c):>10}" for c in cells))
    typer.echo(
        "real-mesh tiers (second side; validation: it chose a default): inv<str, sur<str, "
        "inv<sur, turn<surface, every turn, salient"
    )
    for name, row in results["methods"].items():
        real = row["real_tiers"]
        checks = real["checks"]["held_out"]
        cells = [real["held_out"][key] for key in TIER_PAIRS]
        cells += [checks[key]["share"] for key in REAL_CHECKS]
        typer.echo(f"{name:36}" + "".join(f"{_fmt(c):>10}" for c in cells))
    seconds = results["seconds_total"]
    typer.echo(f"{out / 'results.json'}, {out / 'speed_accuracy.png'} in {seconds:.0f} s")


@app.command("choose-loss")
@needs_the_lab
def choose_loss_command(
    reconstructions: Annotated[
        Path,
        typer.Argument(
            help="CSV: a 'target' column of held-out shapes, then one column per loss (the "
            "baseline first) with that loss's network's reconstruction of the shape."
        ),
    ],
    baseline: Annotated[
        str | None, typer.Option(help="The loss column to beat (default: the first after target).")
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="Write the judged table and the choice as JSON here.")
    ] = None,
    threads: Annotated[int, typer.Option(help="Threads for the judge's numpy renderer.")] = 2,
    lfd: Annotated[bool, typer.Option(help="Judge with LFD too, where it is installed.")] = True,
) -> None:
    """Choose the loss whose reconstructions beat the baseline's on the most visual cells of
    your held-out shapes (the network study's rule; bench/records/fitting.md)."""
    from .judging.choice import JUDGE_CONFIG, judge_and_choose, read_reconstructions
    from .judging.judges import Judge

    progress = lambda line: typer.echo(line, err=True)  # noqa: E731
    try:
        if out and not out.parent.is_dir():
            raise ValueError(f"{out}: its folder does not exist")
        listed = read_reconstructions(reconstructions, baseline)
        judge = Judge(JUDGE_CONFIG, threads, lfd=lfd)
        try:
            result = judge_and_choose(listed, judge, progress)
        finally:
            judge.close()
    except ValueError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from exc
    base = result["baseline"]
    for name, won in result["shares"].items():
        ratio = result["chamfer_l1_ratio"][name]
        typer.echo(
            f"{name} beats {base} on {won['wins']}/{won['cells']} visual cells "
            f"({won['share']:.0%}) at {_fmt(ratio)} x its Chamfer-L1"
        )
    typer.echo(f"chosen: {result['chosen']} ({len(result['table'])} shapes; {result['lfd']})")
    if result["skipped"]:
        typer.echo(f"{len(result['skipped'])} rows skipped (see above)", err=True)
    if out:
        out.write_text(json.dumps(result, indent=1))
        typer.echo(str(out))


def _fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.3f}"
