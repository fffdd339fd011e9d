"""bench/records/nets.md's tables: the metric stage of ``drkfs train`` (models/manifest.json),
each fine-tuning objective and each width and detector under the chosen one.
"""

from __future__ import annotations

from pathlib import Path

from drkfs_lab.record_tables import Table, bold, committed, grid

MANIFEST = "models/manifest.json"
# a metric-stage row's figures (models/manifest.json) and their digits, in the tables' order
FIGURES = (("accuracy", 3), ("accuracy_synthetic", 3), ("accuracy_real", 3), ("heldout", 3),
           ("training", 3), ("bars", 2), ("retrieval", 2))  # fmt: skip
# the training bases are what the objectives fit, so their best marks no objective
UNMARKED = "training"
OBJECTIVE_NAMES = {
    "correspondence triplet (paper-style)": "correspondence triplet (paper-style, the baseline)"
}
CHAMFER_ROW = "Chamfer-L1 (no training)"
COLUMNS = ("benchmark", "synthetic half", "shared-mesh half", "held out", "training bases",
           "bars", "retrieval")  # fmt: skip


def _cells(row: dict) -> list[str]:
    """A metric-stage row's figures, each at its digits."""
    return [f"{row[key]:.{digits}f}" for key, digits in FIGURES]


def objectives(root: Path) -> str:
    """The table of "Objectives, measured against each other": each objective's benchmark,
    halves, held-out, training-bases, bars and retrieval figures, the best of each column but
    the training bases in bold, and Chamfer-L1's benchmark and halves."""
    metric = committed(root, MANIFEST)["metric"]
    rows = {OBJECTIVE_NAMES.get(name, name): _cells(row)
            for name, row in metric["objectives"].items()}  # fmt: skip
    for column, (key, _) in enumerate(FIGURES):
        best = max(float(cells[column]) for cells in rows.values())
        for cells in rows.values():
            if key != UNMARKED and float(cells[column]) == best:
                cells[column] = bold([cells[column]])[0]
    chamfer = [f"{metric['chamfer_l1'][key]:.3f}" for key, _ in FIGURES[:3]]
    printed = [[name, *cells] for name, cells in rows.items()]
    printed.append([CHAMFER_ROW, *chamfer, *[""] * (len(FIGURES) - len(chamfer))])
    return grid(("objective (width 0.5, detector n2m2k9)", *COLUMNS), printed, right=7)


def _sized_rows(sized: list[tuple[str, str, dict, bool]]) -> list[list[str]]:
    """Rows of one kind of size (widths, detectors): each named with its parameter count, the
    first naming the unit, its figures, the chosen one in bold."""
    rows = []
    for n, (label, count, row, chosen) in enumerate(sized):
        cells = [f"{label} ({count}{'' if n else ' params'})", *_cells(row)]
        rows.append(bold(cells) if chosen else cells)
    return rows


def _width_count(count: int) -> str:
    """A HardNet width's parameter count, in M or k."""
    return f"{count / 1e6:.2f} M" if count >= 1e6 else f"{count / 1e3:.0f} k"


def sizes(root: Path) -> str:
    """The table of "Width and detector size under the chosen objective": each HardNet
    width's and each detector's figures under the ranking objective, with its parameters (the
    widths' from the correspondence stage, the same nets), the chosen ones in bold."""
    manifest = committed(root, MANIFEST)
    metric = manifest["metric"]
    widths = [(f"width {d['width']:g}", _width_count(d["params"]),
               metric["widths"][f"{d['width']:g}"], d["width"] == metric["width"])
              for d in manifest["descriptors"]]  # fmt: skip
    detectors = [(f"detector {name}", f"{row['params']:,}", row, name == metric["detector"])
                 for name, row in metric["detectors"].items()]  # fmt: skip
    rows = _sized_rows(widths) + _sized_rows(detectors)
    return grid(("ranking objective", *COLUMNS), rows, right=7)


TABLES: list[Table] = [objectives, sizes]
