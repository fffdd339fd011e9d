"""The pairs CSV of ``drkfs-score batch``: its rules, and what it reports about a file.

- Columns named ``mesh_a`` and ``mesh_b`` in a header, or, without a header, the first two.
  A first row that is neither is refused (a header with other names, ``pred,gt``, would
  otherwise be scored as a pair).
- A relative path is relative to the CSV's folder, so a CSV and its meshes move together and
  the batch runs from any directory; absolute paths stay as they are; ``~`` is the home
  folder. Results name each mesh as the CSV wrote it.
- Blank rows (``,`` included) are skipped and their line numbers reported; a row with one path
  is kept and fails as that row.
- Other columns are ignored and named in a warning, and so are a row's fields beyond the
  header's columns; a byte-order mark (a spreadsheet's UTF-8) is read as no part of the header.
- A file with no pairs, or one that is not UTF-8 text, is an error naming the file.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

COLUMNS = ("mesh_a", "mesh_b")


@dataclass
class PairsFile:
    """The pairs to score, as absolute paths to open and as the CSV wrote them, and warnings
    about the rows not read as pairs."""

    pairs: list[tuple[str, str]]
    written: list[tuple[str, str]]
    warnings: list[str] = field(default_factory=list)


def read_pairs(path: Path) -> PairsFile:
    """The pairs of a CSV; anything that makes the whole file unusable is a ValueError that
    names it."""
    if not path.is_file():
        raise ValueError(f"{path}: no such pairs file" + (" (a folder)" if path.is_dir() else ""))
    blank, rows = [], []  # line numbers of blank rows; (line number, stripped cells)
    for number, row in _rows(path):
        cells = [cell.strip() for cell in row]
        if any(cells):
            rows.append((number, cells))
        else:
            blank.append(number)
    if not rows:
        raise ValueError(f"{path}: no pairs (the file is empty); one row per pair: mesh_a,mesh_b")
    warnings = []
    if blank:
        warnings.append(f"{path}: blank rows skipped ({_numbers(blank)})")
    header = rows[0][1]
    folder = path.parent
    if all(name in header for name in COLUMNS):
        a, b = (header.index(name) for name in COLUMNS)
        rows = rows[1:]
        extra = [name or f"column {i + 1}" for i, name in enumerate(header) if i not in (a, b)]
        if extra:
            warnings.append(f"{path}: columns ignored: {', '.join(extra)}")
        longer = [number for number, row in rows if any(row[len(header) :])]
        if longer:
            warnings.append(
                f"{path}: fields beyond the header's {len(header)} columns ignored "
                f"({_numbers(longer)})"
            )
        if not rows:
            raise ValueError(f"{path}: no pairs below the header mesh_a,mesh_b")
    elif all(Path(_path(folder, cell)).exists() for cell in header[:2]) and len(header) >= 2:
        a, b = 0, 1
        wide = [number for number, row in rows if len(row) > 2 and any(row[2:])]
        if wide:
            warnings.append(
                f"{path}: only the first two columns are read (more on {_numbers(wide)})"
            )
    else:
        raise ValueError(
            f"{path}: the first row {','.join(header)} is neither the header mesh_a,mesh_b nor "
            "two existing files (relative paths are read from the CSV's folder); name the "
            "columns mesh_a and mesh_b"
        )
    cells = [(_cell(row, a), _cell(row, b)) for _, row in rows]
    opened = [(_path(folder, cell_a), _path(folder, cell_b)) for cell_a, cell_b in cells]
    return PairsFile(opened, cells, warnings)


def _rows(path: Path) -> list[tuple[int, list[str]]]:
    try:
        # utf-8-sig: a spreadsheet's UTF-8 starts with a byte-order mark, not part of the header
        with open(path, newline="", encoding="utf-8-sig") as handle:
            reader = csv.reader(handle)
            return [(reader.line_num, row) for row in reader]
    except UnicodeDecodeError as exc:
        raise ValueError(
            f"{path}: not a CSV of mesh pairs (byte {exc.start} is not UTF-8 text); give a CSV "
            "with columns mesh_a, mesh_b"
        ) from exc
    except csv.Error as exc:
        raise ValueError(f"{path}: not a readable CSV ({exc})") from exc


def _cell(row: list[str], column: int) -> str:
    """The row's cell in ``column``; a missing cell is empty (the row then fails as needing two
    meshes)."""
    return row[column] if column < len(row) else ""


def _path(folder: Path, cell: str) -> str:
    """The cell as an absolute path from the CSV's folder (an error then names the folder it
    looked in); an empty cell stays empty."""
    return str((folder / Path(cell).expanduser()).absolute()) if cell else ""


def _numbers(lines: list[int], shown: int = 10) -> str:
    """Line numbers in words: "line 4", "lines 4, 7", "lines 1, .., 10 and 3 more"."""
    text = ", ".join(map(str, lines[:shown]))
    more = f" and {len(lines) - shown} more" if len(lines) > shown else ""
    return f"line{'s' if len(lines) > 1 else ''} {text}{more}"
