"""The records' tables (bench/records/NAME.md), printed from the committed JSON they report:
module ``record_tables.NAME`` lists a record's tables in the order the record holds them
(``TABLES``, each ``table(root) -> markdown`` of one table or of several a study prints
together), and bench/check_results.py holds the record to them, every table of it, so none is
typed by hand.

    python -m drkfs_lab.record_tables [NAME ...] [--write]

Prints what differs, or with ``--write`` puts the printed tables in the records in place of
theirs (the record's n-th table is replaced by the n-th printed one).
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from drkfs_lab.benchmark.run import TIER_PAIRS

ROOT = Path(__file__).resolve().parents[2]
# the runs a later run of the same command replaced, where a record still quotes them: each file
# as commit C held it, at EARLIER/C/its path (`git show C:PATH`), so no table needs git's history
EARLIER = "bench/earlier"
# the records whose every table is printed here: all of them
RECORDS: tuple[str, ...] = (
    "fitting",
    "matching",
    "nets",
    "real_levers",
    "real_tiers",
    "single_view",
)

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


def grid(header: Sequence[str], rows: Sequence[Sequence[str]], right: int = 0) -> str:
    """A markdown table; its last ``right`` columns aligned right."""
    rule = "|" + "---|" * (len(header) - right) + "---:|" * right
    lines = ["| " + " | ".join(line) + " |" for line in (header, *rows)]
    return "\n".join([lines[0], rule, *lines[1:]])


def bold(cells: Sequence[str]) -> list[str]:
    """A row set in bold: the default of its time, or the row chosen."""
    return [f"**{cell}**" for cell in cells]


def minus(value: float, digits: int) -> str:
    """A signed figure with a typographic minus, as the records print them."""
    return f"{value:.{digits}f}".replace("-", "−")


def tables_in(text: str) -> list[str]:
    """The markdown tables of a text, each its run of lines that start with '|'."""
    found, run = [], []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            run.append(line)
        elif run:
            found.append("\n".join(run))
            run = []
    return found


def printed(name: str, root: Path = ROOT) -> list[str]:
    """Record ``name``'s tables, printed from the committed JSON under ``root``."""
    module = importlib.import_module(f"{__name__}.{name}")
    return [found for table in module.TABLES for found in tables_in(table(root))]


def differences(name: str, root: Path = ROOT) -> list[str]:
    """Where record ``name`` and its printed tables part: a count that differs, or the first
    line that does in each table; empty where the record holds them exactly."""
    held = tables_in((root / "bench" / "records" / f"{name}.md").read_text())
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
    """Put the printed tables in record ``name`` in place of the ones it holds, in order."""
    path = root / "bench" / "records" / f"{name}.md"
    text = path.read_text()
    held, tables = tables_in(text), printed(name, root)
    if len(held) != len(tables):
        raise SystemExit(f"{path}: holds {len(held)} tables, {len(tables)} are printed")
    start = 0
    for old, new in zip(held, tables, strict=True):
        at = text.index(old, start)
        text = text[:at] + new + text[at + len(old) :]
        start = at + len(new)
    path.write_text(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="records to print (default: every one)")
    parser.add_argument("--write", action="store_true", help="put the tables in the records")
    args = parser.parse_args()
    failed = False
    for name in args.names or RECORDS:
        if args.write:
            write(name)
        for line in differences(name):
            failed = True
            print(line)
    sys.exit(1 if failed else 0)
