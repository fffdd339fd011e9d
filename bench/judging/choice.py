"""``drkfs choose-loss``: the network study's rule for choosing a loss, on your own held-out
shapes (bench/records/fitting.md, "Six seeds": pooled over the seeds, choosing per run beat every
fixed loss).

Train a network with the baseline loss (Chamfer, say) and with each candidate, reconstruct the
same held-out shapes with each, and list them in a CSV: a ``target`` column (the true shape),
then one column per loss, named by the loss, holding that network's reconstruction. The
candidate whose reconstructions beat the baseline's on the most visual cells (one shape judged
by one of ``judges.VISUAL``) is chosen, a tie going to the earlier column. Every mesh is judged
in its target's normalised frame by the network study's judge, so the numbers read like the
study's.
"""

from __future__ import annotations

import csv
import subprocess
from pathlib import Path
from typing import NamedTuple

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import MeshError, frame_of, load_mesh, place

from .judges import Judge
from .rule import choose

TARGET = "target"
JUDGE_CONFIG = PipelineConfig.paper()  # the network study's judge


class Row(NamedTuple):
    line: int  # the CSV's line number, for messages
    target: str
    reconstructions: dict[str, str]  # loss -> mesh path


class Reconstructions(NamedTuple):
    path: Path
    baseline: str
    candidates: list[str]
    rows: list[Row]


def read_reconstructions(path: Path, baseline: str | None = None) -> Reconstructions:
    """The CSV ``path``: its header names ``target`` and at least two losses, and ``baseline``
    (default: the first loss column) must be one of them. Paths are read as written, relative
    ones from the working directory. Raises ValueError naming the file and what is wrong."""
    if not path.is_file():
        raise ValueError(f"{path}: no such reconstructions file")
    with open(path, newline="") as handle:
        lines = [
            (line, [cell.strip() for cell in cells])
            for line, cells in enumerate(csv.reader(handle), 1)
            if any(cell.strip() for cell in cells)
        ]
    if not lines or TARGET not in lines[0][1]:
        raise ValueError(f"{path}: the header must name a '{TARGET}' column, then one per loss")
    header = lines[0][1]
    losses = [name for name in header if name != TARGET]
    if len(losses) < 2 or "" in losses or len(set(header)) < len(header):
        raise ValueError(
            f"{path}: the header must name the baseline and at least one candidate loss, each "
            f"once (found {','.join(header)})"
        )
    baseline = losses[0] if baseline is None else baseline
    if baseline not in losses:
        raise ValueError(f"{path}: no column named {baseline!r} (losses: {', '.join(losses)})")
    rows = []
    for line, cells in lines[1:]:
        by_column = dict(zip(header, cells + [""] * (len(header) - len(cells)), strict=False))
        rows.append(Row(line, by_column[TARGET], {loss: by_column[loss] for loss in losses}))
    return Reconstructions(path, baseline, [n for n in losses if n != baseline], rows)


def judge_row(row: Row, judge: Judge) -> dict[str, dict[str, float | None]]:
    """Each loss's reconstruction judged against the row's target, all in the target's
    normalised frame. Raises MeshError naming the first file that cannot be judged."""
    if not all((row.target, *row.reconstructions.values())):
        raise MeshError(f"line {row.line}", "an empty cell: every column needs a mesh")
    target = load_mesh(row.target)
    frame = frame_of(target.vertices)
    meshes = {loss: load_mesh(source) for loss, source in row.reconstructions.items()}
    prepared = judge.prepare(place(target.vertices, frame), target.faces)
    return {
        loss: judge.compare(judge.prepare(place(mesh.vertices, frame), mesh.faces), prepared)
        for loss, mesh in meshes.items()
    }


def judge_and_choose(reconstructions: Reconstructions, judge: Judge, progress=print) -> dict:
    """Judge every row and choose a candidate -> {"baseline", "candidates", "judge_config",
    "lfd", "table": target -> loss -> judged row, "skipped": [{"line", "reason"}], and
    ``study.choose``'s "chosen", "shares" and "chamfer_l1_ratio"}. A row that cannot be judged
    is skipped with its reason while the others count; ValueError where none could be judged."""
    table, skipped = {}, []
    for row in reconstructions.rows:
        name = row.target if row.target not in table else f"{row.target} (line {row.line})"
        try:
            table[name] = judge_row(row, judge)
        except (MeshError, subprocess.CalledProcessError) as exc:
            # CalledProcessError: LFD's 3DAlignment failed on one of the line's meshes
            reason = str(exc) if isinstance(exc, MeshError) else f"LFD failed ({exc})"
            skipped.append({"line": row.line, "reason": reason})
            progress(f"skipped line {row.line}: {reason}")
            continue
        progress(f"judged line {row.line}: {row.target}")
    if not table:
        raise ValueError(f"{reconstructions.path}: no row could be judged ({len(skipped)} skipped)")
    return {
        "baseline": reconstructions.baseline,
        "candidates": reconstructions.candidates,
        "judge_config": judge.config.to_dict(),
        "lfd": judge.lfd_note,
        "table": table,
        "skipped": skipped,
        **choose(table, reconstructions.candidates, reconstructions.baseline),
    }
