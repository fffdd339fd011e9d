"""``drkfs``: the torch-side command line (needs the ``torch`` extra)."""

from __future__ import annotations

import json
import time
from importlib.metadata import entry_points
from pathlib import Path
from typing import Annotated

import typer

from .contract.cli_options import RUNS, Normalize, config_options, pair_report
from .contract.config import PipelineConfig
from .contract.mesh import MeshError, check_normalization, load_mesh
from .synthetic.examples import REFERENCE, example_meshes, write_examples

app = typer.Typer(
    help="DR-KFS visual similarity of 3D meshes (torch path). The lab (pip install -e ./bench "
    "in a checkout) adds bench, train, tune-tolerant and choose-loss.",
    no_args_is_help=True,
    rich_markup_mode=None,  # plain help: flags without <bool>, paragraphs rewrapped
)
# the modules of the torch extra (pyproject.toml), as imported: a command that needs one on the
# base install names the extra instead of a traceback
TORCH_EXTRA = ("torch", "onnx", "onnxscript")


def _metric(config: PipelineConfig, normalize: str = "joint"):
    from .metric import DRKFS, MissingWeights

    try:
        return DRKFS.pretrained(config, normalization=normalize)
    except MissingWeights as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from exc


def _score(metric, path_a: Path, path_b: Path) -> float:
    return metric.score_meshes(load_mesh(path_a), load_mesh(path_b))


@app.command()
@config_options()
def score(
    mesh_a: Path,
    mesh_b: Annotated[Path, typer.Argument(help="The reference (ground truth).")],
    config: PipelineConfig,
    normalize: Normalize = "joint",
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON object.")] = False,
) -> None:
    """Score MESH_A against the reference MESH_B (0 for identical meshes)."""
    try:
        check_normalization(normalize)  # before the nets load
        scorer = _metric(config, normalize)
        start = time.perf_counter()
        value = _score(scorer, mesh_a, mesh_b)
    except (MeshError, ValueError) as exc:  # a mesh the user gave, or an option's value
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from exc
    seconds = time.perf_counter() - start
    if as_json:
        # drkfs-score pair's report, less its graph's version: torch runs the nets themselves
        report = pair_report(value, config, mesh_a, mesh_b, normalize, seconds=seconds)
        typer.echo(json.dumps(report))
    else:
        typer.echo(f"{value:.6g}")


@app.command()
def export(
    out: Annotated[
        Path, typer.Option(help="Where the ONNX files go (--out models ships them).")
    ] = RUNS / "models",
) -> None:
    """Export the feature graph of every shipped weights file, and the match graph, to ONNX."""
    from .export import export_shipped

    for path in export_shipped(out):
        typer.echo(path)


@app.command()
def examples(folder: Annotated[Path, typer.Argument()] = Path("examples")) -> None:
    """Write the bundled example meshes (a chair and its variants) and pairs.csv, which scores
    each against the chair (drkfs-score batch FOLDER/pairs.csv --out scores.csv), to FOLDER."""
    for path in write_examples(folder):
        typer.echo(path)


@app.command()
def demo(
    folder: Annotated[
        Path, typer.Option(help="Where the example meshes are (written if absent).")
    ] = Path("examples"),
) -> None:
    """Score every example mesh against the reference chair and print a table."""
    metric = _metric(PipelineConfig())  # needs torch: said before anything is written
    if not (folder / REFERENCE).is_file():
        write_examples(folder)
    typer.echo(f"{'mesh':28} {'DR-KFS':>10} {'seconds':>8}  change")
    for name, (change, _) in example_meshes().items():
        start = time.perf_counter()
        value = _score(metric, folder / name, folder / REFERENCE)
        typer.echo(f"{name:28} {value:10.3f} {time.perf_counter() - start:8.2f}  {change}")


# an entry of ``drkfs_onnx.commands`` left out -> why (shown by every drkfs run)
UNAVAILABLE: dict[str, str] = {}


def add_installed_commands() -> None:
    """Add the commands of each installed ``drkfs_onnx.commands`` entry point (the lab's), each
    naming a typer app; a command added before is not added again. An entry that fails to load,
    or another command under a name this app has, is left out and named in ``UNAVAILABLE``: the
    library's own commands never depend on another distribution loading."""
    added = {command_name(command): command.callback for command in app.registered_commands}
    for entry in entry_points(group="drkfs_onnx.commands"):
        try:
            commands = entry.load().registered_commands
        except Exception as exc:  # a broken or half-removed install, whatever it raises
            UNAVAILABLE[entry.name] = f"{entry.value} did not load ({type(exc).__name__}: {exc})"
            continue
        for command in commands:
            name = command_name(command)
            if name not in added:
                app.registered_commands.append(command)
                added[name] = command.callback
            elif added[name] is not command.callback:
                UNAVAILABLE[entry.name] = f"{entry.value} has a command named {name}, as drkfs"


def command_name(command) -> str:
    """A registered command's name on the command line."""
    return command.name or command.callback.__name__.replace("_", "-")


add_installed_commands()


def main() -> None:
    """The ``drkfs`` command: the app, with a missing torch named as the extra to install
    instead of a traceback (the base install is the torch-free server scorer)."""
    for entry, reason in UNAVAILABLE.items():
        typer.echo(f"warning: drkfs_onnx.commands entry {entry!r} left out: {reason}", err=True)
    try:
        app()
    except ModuleNotFoundError as exc:
        if exc.name not in TORCH_EXTRA:
            raise
        typer.echo(
            f"error: this drkfs command needs {exc.name}; install the torch extra: "
            "pip install torch==2.13.0 && pip install 'drkfs-onnx[torch]' "
            "(drkfs-score scores without it)",
            err=True,
        )
        raise SystemExit(2) from None
