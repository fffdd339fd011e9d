"""``drkfs-score``: DR-KFS on servers with onnxruntime (base install; torch never imported)."""

from __future__ import annotations

import csv
import hashlib
import json
import sys
import time
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer

from drkfs_onnx.contract.cli_options import (
    CONFIG_OPTIONS,
    DESCRIBING_OPTIONS,
    Normalize,
    ReferenceNormalize,
    at_least,
    choices,
    config_options,
    pair_report,
    with_options,
)
from drkfs_onnx.contract.config import NETS
from drkfs_onnx.contract.mesh import MeshError

from .batch import RowScorer, ScorerSpec, ray_results, serial_results
from .output_lock import OutputLocked, output_lock
from .pairs_file import read_pairs
from .scorer import MAX_FACES, Scorer, reference_of
from .sessions import ModelMismatch

app = typer.Typer(
    help="DR-KFS visual similarity of 3D meshes, scored with onnxruntime.",
    no_args_is_help=True,
    rich_markup_mode=None,  # plain help: flags without <bool>, paragraphs rewrapped
)

Threads = Annotated[
    int | None,
    typer.Option(
        callback=at_least(1),
        help="onnxruntime and renderer threads, at least 1 (default: all cores).",
    ),
]
Width = Annotated[
    float | None,
    typer.Option(help="HardNet width of a shipped model (default: the preset's; see --nets)."),
]
Nets = Annotated[
    str | None,
    typer.Option(
        metavar=choices(NETS),
        help="Override the preset's nets. The tolerant nets (the default's) "
        "come at width 0.5, the metric and correspondence nets at 1, 0.5 and 0.25.",
    ),
]
Model = Annotated[
    Path | None, typer.Option(help="A feature-graph ONNX file instead of the shipped one.")
]
MaxFaces = Annotated[
    int,
    typer.Option(
        callback=at_least(0),
        help="Refuse a mesh with more faces, before it is rendered (rendering costs about 0.8 GB "
        "a million faces); 0: no bound.",
    ),
]

BATCH_COLUMNS = [
    "row", "mesh_a", "mesh_b", "score", "metric", "seconds", "error", "settings", "model_version",
    "content",
]  # fmt: skip
# a results file written before scores named their metric version resumes (its records read as
# of no named version until this run's settings rescore or adopt them)
UNNAMED_COLUMNS = [c for c in BATCH_COLUMNS if c != "metric"]


PICTURES = (".png", ".pdf", ".svg")  # explain's formats, by the --out suffix


@contextmanager
def _exit_on(*errors: type[Exception]):
    """Print an expected error as 'error: ...' and exit with status 2."""
    try:
        yield
    except errors as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from exc


def _spec(config, threads, normalize, width, nets, model, max_faces) -> ScorerSpec:
    """What builds a scorer for ``config`` with the scorer options' overrides."""
    picked = {"descriptor_width": width, "nets": nets}
    config = config.replace(**{k: v for k, v in picked.items() if v is not None})
    model = None if model is None else str(model)
    return ScorerSpec(config, model, threads, normalize, max_faces or None)


# the options of the scorer beside the config's: the nets, a graph of one's own, a mesh's bound
SCORER_OPTIONS = {
    "width": (Width, None),
    "nets": (Nets, None),
    "model": (Model, None),
    "max_faces": (MaxFaces, MAX_FACES),
}


def scoring_options(names: tuple[str, ...] = tuple(CONFIG_OPTIONS)):
    """A command takes the config options ``names`` and the scorer's, and is called with the
    ``ScorerSpec`` they make as its ``spec`` argument (it has ``threads`` and ``normalize``)."""
    needs = ("config", "threads", "normalize")
    scorer = with_options(SCORER_OPTIONS, "spec", _spec, needs)
    return lambda command: config_options(names)(scorer(command))


def _scorer(spec: ScorerSpec, progress: bool = True) -> Scorer:
    """The scorer, printing what it does on a large mesh unless ``progress`` is False."""
    with _exit_on(ModelMismatch, FileNotFoundError, ValueError):
        return spec.build(_say if progress else None)


def _say(line: str) -> None:
    typer.echo(line, err=True)


def _warn(message, *_) -> None:
    """A warning (a mesh's winding, say) as one line on stderr."""
    typer.echo(f"warning: {message}", err=True)


@app.callback()
def _warnings_in_one_line() -> None:
    warnings.showwarning = _warn


def _check_out(out: Path) -> None:
    """Refuse an --out that cannot be written before any work is done."""
    problem = None
    if out.is_dir():
        problem = "is a folder; give a file name"
    elif not out.parent.is_dir():
        problem = f"its folder {out.parent} does not exist; create it or choose another"
    if problem:
        typer.echo(f"error: --out {out}: {problem}", err=True)
        raise typer.Exit(2)


@app.command()
@scoring_options()
def pair(
    mesh_a: Path,
    mesh_b: Annotated[
        Path, typer.Argument(help="The reference (ground truth): a mesh or a features .npz.")
    ],
    spec: ScorerSpec,
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON object.")] = False,
    threads: Threads = None,
    normalize: Normalize = "joint",
) -> None:
    """Score MESH_A against the reference MESH_B (0 for identical meshes)."""
    scorer = _scorer(spec)
    start = time.perf_counter()
    with _exit_on(MeshError, ValueError):
        value = scorer.score(mesh_a, reference_of(mesh_b))
    seconds = time.perf_counter() - start
    if as_json:
        more = {"seconds": seconds, "model_version": scorer.model_version}
        typer.echo(json.dumps(pair_report(value, scorer.config, mesh_a, mesh_b, normalize, **more)))
    else:
        typer.echo(f"{value:.6g}")


@app.command()
@scoring_options()
def explain(
    mesh_a: Path,
    mesh_b: Annotated[Path, typer.Argument(help="The reference (ground truth) mesh.")],
    out: Annotated[
        Path, typer.Option(help="The picture to write: .png (the default suffix), .pdf or .svg.")
    ],
    spec: ScorerSpec,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print the score and the top patches as JSON.")
    ] = False,
    top: Annotated[
        int,
        typer.Option(
            callback=at_least(1), help="How many patches to outline and list (at least 1)."
        ),
    ] = 5,
    threads: Threads = None,
    normalize: Normalize = "joint",
) -> None:
    """Show where the score of MESH_A against MESH_B comes from: each view of both, every
    patch's best-match distance as a heat overlay, the patches carrying most of it outlined."""
    try:
        from .explain_plot import write_explanation
    except ImportError:
        typer.echo('error: explain draws with matplotlib: pip install "drkfs-onnx[plot]"', err=True)
        raise typer.Exit(2) from None
    from .explain import explain as explain_pair

    out = out if out.suffix else out.with_suffix(".png")
    if out.suffix.lower() not in PICTURES:
        typer.echo(f"error: --out {out}: write a {', '.join(PICTURES)} picture", err=True)
        raise typer.Exit(2)
    _check_out(out)
    scorer = _scorer(spec)
    with _exit_on(MeshError, ValueError):
        explanation = explain_pair(scorer, mesh_a, mesh_b)
    with _exit_on(OSError, ValueError):
        write_explanation(out, explanation, top)
    if as_json:
        more = {"solid_change": explanation.solid_change, "picture": str(out),
                "top_patches": explanation.top_patches(top)}  # fmt: skip
        report = pair_report(explanation.score, scorer.config, mesh_a, mesh_b, normalize, **more)
        typer.echo(json.dumps(report))
    else:
        typer.echo(f"{explanation.score:.6g} ({out})")


@app.command()
@scoring_options(DESCRIBING_OPTIONS)
def features(
    mesh: Path,
    out: Annotated[Path, typer.Option(help="The .npz file to write.")],
    spec: ScorerSpec,
    threads: Threads = None,
    normalize: ReferenceNormalize = "joint",
) -> None:
    """Describe a reference mesh once; pass the .npz as MESH_B to ``pair`` or in a batch CSV."""
    out = out if out.suffix == ".npz" else out.with_name(out.name + ".npz")  # numpy adds it
    _check_out(out)
    scorer = _scorer(spec)
    with _exit_on(MeshError):
        result = scorer.features(mesh)
    with _exit_on(OSError):
        result.save(out)
    typer.echo(f"{out}: {len(result.descriptors)} patch descriptors, {result.empty} empty patches")


def _write_in_input_order(out, earlier, todo, contents, settings, metric, done, fresh) -> None:
    """OUT rewritten whole: the records of other settings as they were, then one record per
    row of ``todo`` in input order (a row done earlier keeps its score under this run's row
    number and paths). At these settings OUT holds this CSV's rows and no others: a record of
    what a file held before it was overwritten is gone."""
    rows = []
    for index, (a, b) in enumerate(todo):
        record = fresh.get(index) or done[(contents[index], settings)]
        rows.append({**record, "row": index, "mesh_a": a, "mesh_b": b, "metric": metric})
    others = [r for r in earlier if r["settings"] != settings]
    partial = out.with_name(out.name + ".partial")
    with open(partial, "w", newline="") as handle:
        writer = csv.DictWriter(handle, BATCH_COLUMNS)
        writer.writeheader()
        writer.writerows([*others, *rows])
    partial.replace(out)


def _finished(out: Path) -> list[dict]:
    """The records of an earlier run of OUT that scored (failed ones are tried again); a line cut
    by a kill is dropped. OUT is rewritten with just these, so a rerun appends no duplicates."""
    if not out.exists() or out.stat().st_size == 0:
        return []
    text = out.read_text()
    text = text[: text.rfind("\n") + 1]  # a kill can cut the last line
    reader = csv.DictReader(text.splitlines())
    if reader.fieldnames not in (BATCH_COLUMNS, UNNAMED_COLUMNS):
        raise ValueError(
            f"{out}: not a results file of this drkfs-score (columns {reader.fieldnames}); "
            "write to a new --out"
        )
    kept = [record for record in reader if record["error"] == "" and record["score"] != ""]
    partial = out.with_name(out.name + ".partial")
    with open(partial, "w", newline="") as handle:
        writer = csv.DictWriter(handle, BATCH_COLUMNS)
        writer.writeheader()
        writer.writerows(kept)
    partial.replace(out)
    return kept


RayAddress = Annotated[
    str | None,
    typer.Option(
        "--ray",
        metavar="[local|auto|ADDRESS]",
        help="Score on Ray workers: local (a Ray instance on this machine), auto (the cluster this "
        "machine joined) or a cluster address (ray://head:10001). Needs the ray extra.",
    ),
]
Workers = Annotated[
    int | None,
    typer.Option(
        callback=at_least(1),
        help="Ray workers, at least 1, one scorer each (default: the cluster's CPUs/threads).",
    ),
]


@app.command()
@scoring_options()
def batch(
    pairs: Annotated[Path, typer.Argument(help="CSV with columns mesh_a, mesh_b (B: reference).")],
    out: Annotated[Path, typer.Option(help="CSV of results; rerunning resumes it.")],
    spec: ScorerSpec,
    threads: Annotated[
        int | None,
        typer.Option(
            callback=at_least(1),
            help="Threads per scorer, at least 1 (default: all cores; with --ray, 1 per worker).",
        ),
    ] = None,
    normalize: Normalize = "joint",
    ray: RayAddress = None,
    workers: Workers = None,
) -> None:
    """Score every row of PAIRS; results are written and flushed row by row, in input order.

    PAIRS: columns mesh_a, mesh_b (or, without a header, the first two); relative paths are
    read from the CSV's folder; other columns are ignored and named; blank rows are skipped and
    reported; a file with no pairs is an error.

    A pair already scored in OUT with the same settings and model is skipped: it is found by
    what its two files hold, wherever its row now is and whichever folder the batch runs from,
    so a file overwritten since is scored again. Failed rows are tried again and replace their
    old record; a row that fails records its error and the others go on. When the batch ends,
    OUT holds one record per row at these settings, in input order (records of other settings
    stay). Exits 1 when any row failed.
    """
    if out.resolve() == pairs.resolve():
        typer.echo(f"error: --out {out} is the pairs file; results go to another file", err=True)
        raise typer.Exit(2)
    if workers is not None and ray is None:
        typer.echo("error: --workers needs --ray", err=True)
        raise typer.Exit(2)
    _check_out(out)
    with _exit_on(ValueError, OSError):
        pairs_file = read_pairs(pairs)
    for warning in pairs_file.warnings:
        typer.echo(f"warning: {warning}", err=True)
    todo = pairs_file.pairs
    if ray is not None and threads is None:
        threads = 1
    # checks the model and config here, before any worker starts; the progress bar says the rest
    scorer = _scorer(spec, progress=False)
    with _exit_on(OutputLocked, OSError), output_lock(out):  # before _finished rewrites OUT
        _score_rows(out, todo, pairs_file.written, scorer, spec, ray, workers)


def _content(path: str) -> str:
    """What a row's file holds, as the first 16 hex digits of its sha256 ('-' where it cannot
    be read: the row is scored and fails, naming why)."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16] if path else "-"
    except OSError:
        return "-"


def _score_rows(
    out: Path,
    todo: list[tuple[str, str]],
    written: list[tuple[str, str]],
    scorer: Scorer,
    spec: ScorerSpec,
    ray: str | None,
    workers: int | None,
) -> None:
    """Score the rows of ``todo`` whose files' contents OUT holds no score of at these settings,
    append their records as they come, then rewrite OUT in input order (OUT is locked).

    A pair is found done by what its files hold, not by their path text: a file overwritten
    since is scored again, and the same CSV run from another folder is not."""
    with _exit_on(ValueError, OSError):
        earlier = _finished(out)
    settings, version = scorer.settings, scorer.model_version
    contents = [f"{_content(a)}:{_content(b)}" for a, b in todo]
    done = {(r["content"], r["settings"]): r for r in earlier if "-" not in r["content"].split(":")}
    rows = [(i, a, b) for i, (a, b) in enumerate(todo) if (contents[i], settings) not in done]
    if ray is None:
        results = serial_results(rows, RowScorer(scorer))
    else:
        try:
            import ray as _  # noqa: F401
        except ImportError:
            typer.echo('error: --ray needs the ray extra: pip install "drkfs-onnx[ray]"', err=True)
            raise typer.Exit(2) from None
        with _exit_on(ConnectionError, ValueError):
            results = ray_results(rows, spec, ray, workers)
    failed, fresh = [], {}
    with _exit_on(OSError, ValueError), open(out, "a", newline="") as handle:
        writer = csv.DictWriter(handle, BATCH_COLUMNS)
        if handle.tell() == 0:
            writer.writeheader()
        bar = typer.progressbar(
            results,
            length=len(rows),
            label=f"scoring {len(rows)} pair{'' if len(rows) == 1 else 's'}",
            file=sys.stderr,
        )
        with bar as stream:
            for index, result in stream:
                record = {"row": index, "mesh_a": written[index][0], "mesh_b": written[index][1]}
                record.update(score="" if result.score is None else repr(result.score))
                record.update(metric=scorer.metric)
                record.update(error=result.error, seconds=f"{result.seconds:.4f}")
                record.update(settings=settings, model_version=version, content=contents[index])
                writer.writerow(record)  # flushed row by row: a kill loses no finished row
                handle.flush()
                fresh[index] = record
                if result.error:
                    failed.append(index)
    with _exit_on(OSError):
        _write_in_input_order(out, earlier, written, contents, settings, scorer.metric, done, fresh)
    scored, skipped = len(rows) - len(failed), len(todo) - len(rows)
    typer.echo(
        f"{scored} scored, {len(failed)} failed, {skipped} already done; results in {out}",
        err=True,
    )
    if failed:
        typer.echo(f"failed rows: {', '.join(map(str, failed))} (see the error column)", err=True)
        raise typer.Exit(1)
