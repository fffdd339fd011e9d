"""The fitting and network studies of bench/records/fitting.md (the lab's): fit templates to
targets, or with --network train reconstruction networks, with DR-KFS, Chamfer and the others,
and judge every result by metrics no loss computes.

    python bench/fit.py --quick                  # seconds: the tests' plan
    python bench/fit.py --network --seed 0       # the network study (about 2 hours on 2 cores)

Output: runs/fit (runs/fit-network) unless --out says otherwise.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from drkfs_lab.cli import RealMeshes, use_meshes
from drkfs_onnx.contract.cli_options import RUNS

app = typer.Typer(add_completion=False, rich_markup_mode=None)  # plain help: flags without <bool>


@app.command()
def fit(
    out: Annotated[
        Path | None,
        typer.Option(help="Where results.json, gallery.png and meshes/ go.", show_default=False),
    ] = None,
    network: Annotated[
        bool, typer.Option(help="Train reconstruction networks instead of fitting templates.")
    ] = False,
    quick: Annotated[bool, typer.Option(help="A tiny plan that runs in seconds (tests).")] = False,
    threads: Annotated[int, typer.Option(help="Threads for the judge's numpy renderer.")] = 2,
    seed: Annotated[
        int, typer.Option(help="With --network: the seed of the initial weights and batch order.")
    ] = 0,
    meshes: RealMeshes = None,
) -> None:
    """Fit templates to targets (or, with --network, train a reconstruction network) with
    DR-KFS, Chamfer and the others; judge every result with metrics independent of the loss.
    Output: runs/fit (runs/fit-network) unless --out says otherwise."""
    progress = lambda line: typer.echo(line, err=True)  # noqa: E731
    use_meshes(meshes)
    if seed and not network:
        raise typer.BadParameter(
            "--seed is for --network: a template fit starts from its template, not random weights"
        )
    if network:
        from drkfs_lab.studies.network import run_network_study

        out = out or RUNS / "fit-network"
        results = run_network_study(out, quick, threads, progress, seed)
    else:
        from drkfs_lab.studies.study import run_study

        out = out or RUNS / "fit"
        results = run_study(out, quick, threads, progress)
        study = results["loss_study"]
        weights = study["pixel_weight"]["chosen"], study["chamfer_weight"]["chosen"]
        typer.echo(
            f"loss study: {study['forms']['chosen']} ranks first; {study['form']} beside pixel "
            f"MSE at weight {weights[0]:g}, beside Chamfer at {weights[1]:g}"
        )
    for against, key in (("Chamfer", "beats_chamfer"), ("pixel MSE", "beats_pixel_mse")):
        for loss, row in results[key].items():
            typer.echo(
                f"{loss} beats {against} on {row['wins']}/{row['cells']} visual cells "
                f"({row['share']:.0%})"
            )
    summary = results["summary"]
    typer.echo(
        f"best DR-KFS loss: {summary['best_drkfs_loss']}: beats Chamfer on "
        f"{summary['share_beats_chamfer']:.0%}, pixel MSE on "
        f"{summary['share_beats_pixel_mse']:.0%} of the visual cells at "
        f"{summary['chamfer_l1_ratio']:.2f} x Chamfer's Chamfer-L1"
    )
    typer.echo(f"{out / 'results.json'}, {out / 'gallery.png'} in {results['seconds_total']:.0f} s")


if __name__ == "__main__":
    app()
