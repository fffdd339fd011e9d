"""The records' tables (bench/records/NAME.md), printed from the committed JSON they report:
module ``record_tables.NAME`` lists a record's tables in the order the record holds them
(``TABLES``, each ``table(root) -> markdown`` of one table or of several a study prints
together), and bench/check_results.py holds the record to them, every table of it, so none is
typed by hand.

    python -m drkfs_lab.record_tables [NAME ...] [--write | --print]

Prints where each record and its printed tables differ (exit 1 where any do); ``--write`` then
puts the printed tables in the records in place of theirs (a record's n-th table replaced by
the n-th printed one: a new table needs a placeholder table where it goes), ``--print`` prints
the tables instead. Every record in bench/records but its README (an index, no results) has a
printer.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from collections.abc import Callable, Collection, Sequence
from pathlib import Path

from drkfs_lab.benchmark.run import TIER_PAIRS

ROOT = Path(__file__).resolve().parents[2]
# the runs a later run of the same command replaced, where a record still quotes them: each file
# as commit C held it, at EARLIER/C/its path (`git show C:PATH`), so no table needs git's history
EARLIER = "bench/earlier"
RECORDS = "bench/records"

Table = Callable[[Path], str]


def committed(root: Path, path: str, commit: str | None = None) -> dict:
    """The committed JSON file ``path`` under ``root``; with ``commit`` (7 hex digits), the run
    the file held at that commit, kept under ``EARLIER``."""
    where = root / EARLIER / commit / path if commit else root / path
    return json.loads(where.read_text())


def trio(shares: dict) -> str:
    """The three tier shares as the records print them: invisible < structural / surface <
    structural / invisible < surface."""
    return " / ".join(f"{shares[pair]:.3f}" for pair in TIER_PAIRS)


def grid(
    header: Sequence[str], rows: Sequence[Sequence[str]], right: int | Collection[int] = 0
) -> str:
    """A markdown table; aligned right: its last ``right`` columns, or the columns at the
    indices ``right`` holds."""
    if isinstance(right, int):
        right = range(len(header) - right, len(header))
    rule = "|" + "".join("---:|" if n in right else "---|" for n in range(len(header)))
    lines = ["| " + " | ".join(line) + " |" for line in (header, *rows)]
    return "\n".join([lines[0], rule, *lines[1:]])


def bold(cells: Sequence[str]) -> list[str]:
    """A row set in bold: the default of its time, or the row chosen."""
    return [f"**{cell}**" for cell in cells]


def italic(cells: Sequence[str]) -> list[str]:
    """A row set in italics: an earlier default's run."""
    return [f"*{cell}*" for cell in cells]


def minus(value: float, digits: int) -> str:
    """A signed figure with a typographic minus, as the records print them."""
    return f"{value:.{digits}f}".replace("-", "−")


def records(root: Path = ROOT) -> list[str]:
    """The names of the records under ``root`` (bench/records/NAME.md, its README aside)."""
    return sorted(p.stem for p in (root / RECORDS).glob("*.md") if p.stem != "README")


def tables_in(text: str) -> list[str]:
    """The markdown tables of a text, each its run of lines that start with '|', indented ones
    too (so that a table under a bullet is held as well)."""
    found, run = [], []
    for line in [*text.splitlines(), ""]:
        if line.lstrip().startswith("|"):
            run.append(line)
        elif run:
            found.append("\n".join(run))
            run = []
    return found


def printed(name: str, root: Path = ROOT) -> list[str]:
    """Record ``name``'s tables, printed from the committed JSON under ``root``."""
    try:
        module = importlib.import_module(f"{__name__}.{name}")
    except ModuleNotFoundError as missing:
        raise ValueError(f"{RECORDS}/{name}.md has no printer, {__name__}.{name}") from missing
    return [found for table in module.TABLES for found in tables_in(table(root))]


def differences(name: str, root: Path = ROOT) -> list[str]:
    """Where record ``name`` and its printed tables part: a count that differs, or the first
    line that does in each table; empty where the record holds them exactly."""
    held = tables_in((root / RECORDS / f"{name}.md").read_text())
    tables = printed(name, root)
    if len(held) != len(tables):
        return [f"{name}.md holds {len(held)} tables, {len(tables)} are printed"]
    found = []
    for n, (mine, theirs) in enumerate(zip(tables, held, strict=True), 1):
        for a, b in zip(mine.splitlines() + [""], theirs.splitlines() + [""], strict=False):
            if a != b:
                found.append(f"{name}.md table {n}: printed {a!r}, typed {b!r}")
                break
    return found


def write(name: str, root: Path = ROOT) -> None:
    """Put the printed tables in record ``name`` in place of the ones it holds, in order;
    ValueError, the record untouched, where their counts differ."""
    path = root / RECORDS / f"{name}.md"
    text = path.read_text()
    held, tables = tables_in(text), printed(name, root)
    if len(held) != len(tables):
        raise ValueError(f"{path}: holds {len(held)} tables, {len(tables)} are printed")
    start = 0
    for old, new in zip(held, tables, strict=True):
        at = text.index(old, start)
        text = text[:at] + new + text[at + len(old) :]
        start = at + len(new)
    path.write_text(text)


def main() -> None:
    """The command line: hold, write or print the named records' tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "names",
        nargs="*",
        metavar="NAME",
        help=f"records to hold (default: every one: {', '.join(records())})",
    )
    act = parser.add_mutually_exclusive_group()
    act.add_argument("--write", action="store_true", help="put the tables in the records")
    act.add_argument("--print", action="store_true", help="print the tables")
    args = parser.parse_args()
    unknown = sorted(set(args.names) - set(records()))
    if unknown:
        parser.error(f"no record {', '.join(unknown)}; the records: {', '.join(records())}")
    names = args.names or records()
    if args.print:
        for name in names:
            print(f"{name}.md\n\n" + "\n\n".join(printed(name)) + "\n")
        return
    found = [line for name in names for line in differences(name)]
    print("\n".join(found) if found else "every table as printed")
    if args.write and found:
        counts = [line for line in found if " tables, " in line]
        if counts:  # a count that differs writes nothing, in any record
            sys.exit("nothing written: " + "; ".join(counts))
        for name in names:
            write(name)
        print("written: read the prose beside each changed table")
    sys.exit(1 if found and not args.write else 0)
