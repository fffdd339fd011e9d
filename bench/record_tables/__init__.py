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
from dataclasses import dataclass
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
    """The names of the records under ``root`` (bench/records/NAME.md, its README aside);
    FileNotFoundError where there are none."""
    found = sorted(p.stem for p in (root / RECORDS).glob("*.md") if p.stem != "README")
    if not found:
        raise FileNotFoundError(f"no records in {root / RECORDS}")
    return found


def tables_in(text: str) -> list[str]:
    """The markdown tables of a text, each its run of lines that start with '|', indented ones
    too (a table under a bullet), as the text holds them."""
    found, run = [], []
    for line in [*text.splitlines(), ""]:
        if line.lstrip().startswith("|"):
            run.append(line)
        elif run:
            found.append("\n".join(run))
            run = []
    return found


def _indent(table: str) -> str:
    """The indent a held table's lines share."""
    return table[: len(table) - len(table.lstrip(" "))]


def printed(name: str, root: Path = ROOT) -> list[str]:
    """Record ``name``'s tables, printed from the committed JSON under ``root``; ValueError
    where the record has no printer."""
    module_name = f"{__name__}.{name}"
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as missing:
        if missing.name != module_name:  # the printer is there; an import of its own failed
            raise
        raise ValueError(f"{RECORDS}/{name}.md has no printer, {module_name}") from missing
    return [found for table in module.TABLES for found in tables_in(table(root))]


@dataclass
class Held:
    """A record's text, the tables it holds and those printed for it."""

    path: Path
    text: str
    held: list[str]
    printed: list[str]

    @classmethod
    def read(cls, name: str, root: Path = ROOT) -> Held:
        path = root / RECORDS / f"{name}.md"
        text = path.read_text()
        return cls(path, text, tables_in(text), printed(name, root))

    def differences(self) -> list[str]:
        """A count that differs, or the first line that does in each table (an indented
        table compared without its indent); empty where the record holds them exactly."""
        name = self.path.name
        if len(self.held) != len(self.printed):
            return [f"{name} holds {len(self.held)} tables, {len(self.printed)} are printed"]
        found = []
        for n, (mine, theirs) in enumerate(zip(self.printed, self.held, strict=True), 1):
            indent = _indent(theirs)
            lines = [line.removeprefix(indent) for line in theirs.splitlines()]
            for a, b in zip(mine.splitlines() + [""], lines + [""], strict=False):
                if a != b:
                    found.append(f"{name} table {n}: printed {a!r}, typed {b!r}")
                    break
        return found

    def write(self) -> None:
        """Put the printed tables in place of the held ones, in order, each at its held
        table's indent; ValueError, the record untouched, where their counts differ."""
        if len(self.held) != len(self.printed):
            raise ValueError(self.differences()[0])
        text, start = self.text, 0
        for old, new in zip(self.held, self.printed, strict=True):
            indent = _indent(old)
            new = "\n".join(indent + line for line in new.splitlines())
            at = text.index(old, start)
            text = text[:at] + new + text[at + len(old) :]
            start = at + len(new)
        self.path.write_text(text)


def differences(name: str, root: Path = ROOT) -> list[str]:
    """Where record ``name`` and its printed tables part (``Held.differences``)."""
    return Held.read(name, root).differences()


def write(name: str, root: Path = ROOT) -> None:
    """Put the printed tables in record ``name`` in place of the ones it holds (``Held.write``)."""
    Held.read(name, root).write()


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
    try:
        found = {name: Held.read(name) for name in args.names or records()}
    except ValueError as refused:
        sys.exit(f"error: {refused}")
    if args.print:
        for name, record in found.items():
            print(f"{name}.md\n\n" + "\n\n".join(record.printed) + "\n")
        return
    differ = {name: record.differences() for name, record in found.items()}
    lines = [line for said in differ.values() for line in said]
    print("\n".join(lines) if lines else "every table as printed")
    if not (args.write and lines):
        sys.exit(1 if lines else 0)
    counts = [differ[n][0] for n, r in found.items() if len(r.held) != len(r.printed)]
    if counts:  # a count that differs writes nothing, in any record
        sys.exit("nothing written: " + "; ".join(counts))
    for name, record in found.items():
        if differ[name]:
            record.write()
    print("written: read the prose beside each changed table")
