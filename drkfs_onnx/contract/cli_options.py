"""The command-line options that pick a pipeline config, shared by ``drkfs`` and ``drkfs-score``
(torch-free)."""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from .config import (
    DIRECTIONS,
    FULL_PARTS,
    MATCHINGS,
    NORMALIZATIONS,
    REDUCTIONS,
    TWO_SIDED,
    WINDINGS,
    PipelineConfig,
)
from .versions import LATEST, VERSIONS, metric_config, metric_name

# Where drkfs's commands write unless --out says otherwise: never the shipped models/ or the
# committed bench/ results, which only an explicit --out replaces.
RUNS = Path("runs")
PRESETS = {"default": LATEST, "paper": "drkfs-paper", "structure": "drkfs-structure-1.1"}


def at_least(low: float) -> Callable:
    """An option's callback refusing a value below ``low`` in the one line every other bad
    input gets, rc 2 (click's own range check prints its usage block)."""

    def check(param: typer.CallbackParam, value):
        if value is not None and not value >= low:  # NaN too
            typer.echo(f"error: {param.opts[0]} must be at least {low:g}, not {value:g}", err=True)
            raise typer.Exit(2)
        return value

    return check


def choices(values) -> str:
    """An option's metavar listing the values it takes: help shows them, not <str>."""
    return "[" + "|".join(values) + "]"


Normalize = Annotated[
    str,
    typer.Option(
        metavar=choices(NORMALIZATIONS),
        help="Frame of the two meshes: joint (both in the reference's box), each (each in its "
        "own) or none.",
    ),
]
# drkfs-score features describes one mesh: the frame is the one its later pairs will use
ReferenceNormalize = Annotated[
    str,
    typer.Option(
        "--normalize",
        metavar=choices(NORMALIZATIONS),
        help="The frame of the pairs this reference will be scored in: joint (predictions "
        "placed in its frame), each (every mesh in its own) or none; a pair refuses a features "
        "file made for another.",
    ),
]
Preset = Annotated[
    str,
    typer.Option(
        metavar=choices(PRESETS),
        help=f"default ({LATEST}, chosen by the benchmark), paper (drkfs-paper: 25 views, 256 "
        f"px, global sum) or structure ({PRESETS['structure']}: the default's nets, cameras and "
        "solid change, global match, power mean of order 8).",
    ),
]
Metric = Annotated[
    str | None,
    typer.Option(
        metavar=choices(VERSIONS),
        help=f"A named metric version, to reproduce scores quoted by name: {', '.join(VERSIONS)}"
        " (CHANGELOG.md). Replaces --preset.",
        show_default=False,
    ),
]
Matching = Annotated[
    str | None,
    typer.Option(metavar=choices(MATCHINGS), help="Override the preset's matching."),
]
Window = Annotated[int | None, typer.Option(help="Override the window matching's grid radius.")]
Direction = Annotated[
    str | None,
    typer.Option(
        metavar=choices(DIRECTIONS),
        help="Override the searched direction (moot where the window is 0: each patch meets "
        "the one at its own place either way).",
    ),
]
Reduction = Annotated[
    str | None,
    typer.Option(
        metavar=choices(REDUCTIONS),
        help="Override the reduction (another than the preset's "
        "counts the descriptors' part in full: the default's window is in its units).",
    ),
]
SolidWeight = Annotated[
    float | None,
    typer.Option(
        callback=at_least(0),
        help="Override the weight of the views' solid change (the default's 1.2; 0: the "
        "descriptors' match alone).",
    ),
]
Symmetric = Annotated[
    bool,
    typer.Option(
        "--symmetric",
        help="Search both directions (same as --direction both; the default and structure "
        "presets already do, the paper preset searches forward). The score is then order-free "
        "under --normalize each or none, but where the first mesh is turned onto the second "
        "(drkfs-1.2); under joint both meshes are placed in the second mesh's frame, so "
        "swapping them can change it.",
    ),
]

TwoSided = Annotated[
    bool,
    typer.Option(
        "--two-sided",
        help="Light faces seen from behind as their front (back_light 1, back_push 0), as "
        "drkfs-paper does: an opening's inside then reads as lit surface, and the faces' winding "
        "is read from the file (winding file), since this light does not look at it. A "
        "features file is described under one light and refused under the other.",
    ),
]

Winding = Annotated[
    str | None,
    typer.Option(
        metavar=choices(WINDINGS),
        help="Which side of a face is its outside, where openings are seen dark: geometry (read "
        "from the surface, so faces wound against their neighbours or doubled for both sides "
        "move no score: the default) or file (the file's winding, turned as a whole by the "
        "mesh's volume: drkfs-1.0).",
        show_default=False,
    ),
]


def pick_config(
    preset: str = "default",
    metric: str | None = None,
    matching: str | None = None,
    window: int | None = None,
    direction: str | None = None,
    reduction: str | None = None,
    symmetric: bool = False,
    solid_weight: float | None = None,
    two_sided: bool = False,
    winding: str | None = None,
    **changes,
) -> PipelineConfig:
    """The named version's config (``metric``, else the preset's) with the given overrides;
    ValueError names a bad value."""
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}; use one of {', '.join(PRESETS)}")
    if metric is not None and preset != "default":
        raise ValueError(f"--metric {metric} and --preset {preset} both name a metric: give one")
    if symmetric:
        if direction not in (None, "both"):
            raise ValueError(f"--symmetric searches both directions, not {direction!r}")
        direction = "both"
    picked = dict(
        matching=matching, window=window, direction=direction, reduction=reduction,
        solid_weight=solid_weight, winding=winding,
    )  # fmt: skip
    changes.update({key: value for key, value in picked.items() if value is not None})
    if two_sided:
        changes = {**TWO_SIDED, **changes}
    base = metric_config(metric or PRESETS[preset])
    if reduction is not None and reduction != base.reduction:
        # the window on the descriptors' part is in the preset reduction's units
        changes = {**FULL_PARTS, **changes}
    config = base.replace(**changes)
    if window is not None and config.matching != "window":
        if matching is not None:
            raise ValueError(
                f"--window {window} sets the window match's radius; --matching {matching} has "
                "none: drop --window"
            )
        named = metric or f"the {preset} preset"
        raise ValueError(
            f"--window {window} sets the window match's radius, but {named} matches "
            f"{config.matching}ly: add --matching window"
        )
    return config


# the options that pick a config: which metric (a preset or a named version) and its overrides
CONFIG_OPTIONS = {
    "preset": (Preset, "default"),
    "metric": (Metric, None),
    "matching": (Matching, None),
    "window": (Window, None),
    "direction": (Direction, None),
    "reduction": (Reduction, None),
    "symmetric": (Symmetric, False),
    "solid_weight": (SolidWeight, None),
    "two_sided": (TwoSided, False),
    "winding": (Winding, None),
}
# what shapes a mesh's descriptors alone (a reference described once)
DESCRIBING_OPTIONS = ("preset", "metric", "two_sided", "winding")


def with_options(
    options: dict[str, tuple[Any, Any]],
    into: str,
    build: Callable[..., Any],
    needs: tuple[str, ...] = (),
) -> Callable:
    """A decorator for a typer command: it takes ``options`` (name -> (annotated type, default))
    after its own and is called with ``build(**their values, **needs)`` as its ``into``
    argument, ``needs`` naming its own arguments (or an outer decorator's) that ``build`` reads
    too. A ValueError from ``build`` is one line, ``error: ...``, and exit status 2."""

    def decorate(command: Callable) -> Callable:
        signature = inspect.signature(command, eval_str=True)  # the real annotated types
        own = [p for p in signature.parameters.values() if p.name != into]
        named = {p.name for p in own}
        keyword = inspect.Parameter.KEYWORD_ONLY
        needed = [inspect.Parameter(n, keyword) for n in needs if n not in named]
        added = [
            inspect.Parameter(name, keyword, default=default, annotation=annotation)
            for name, (annotation, default) in options.items()
        ]

        @functools.wraps(command)
        def run(*args, **kwargs):
            picked = {name: kwargs.pop(name) for name in options}
            passed = {name: kwargs.pop(name) for name in needs if name not in named}
            try:
                built = build(**picked, **passed, **{n: kwargs[n] for n in needs if n in named})
            except ValueError as exc:
                typer.echo(f"error: {exc}", err=True)
                raise typer.Exit(2) from exc
            return command(*args, **kwargs, **{into: built})

        run.__annotations__ = {p.name: p.annotation for p in own + added}
        run.__signature__ = signature.replace(parameters=own + needed + added)
        return run

    return decorate


def config_options(names: tuple[str, ...] = tuple(CONFIG_OPTIONS)) -> Callable:
    """A typer command takes the options ``names`` and is called with the config they pick
    (``pick_config``) as its ``config`` argument."""
    return with_options({n: CONFIG_OPTIONS[n] for n in names}, "config", pick_config)


def pair_report(
    score: float, config: PipelineConfig, mesh_a: Path, mesh_b: Path, normalize: str, **more
) -> dict:
    """The JSON report of one scored pair, as every command prints it: the score, the metric
    version, what the command adds (``more``: seconds, the graph's version, a picture), the
    pair, the normalisation and the config."""
    report = {"score": score, "metric": metric_name(config), **more}
    return report | {"mesh_a": str(mesh_a), "mesh_b": str(mesh_b), "normalize": normalize,
                     "config": config.to_dict()}  # fmt: skip
