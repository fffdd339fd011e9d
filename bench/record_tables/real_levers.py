"""real_levers.md's tables, printed from the lever runs' JSON (bench/results/real_levers*.json,
real_nets*.json, part_transforms.json, shift_tolerance.json).

A table names its columns (``COLUMNS``' keys) and its rows: each row the cells that name it and
the lever it prints, by its run and its place among the run's levers. The checks read training
side / held-out side; a mesh's cost is against the first lever of its run (the run's default).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from drkfs_lab.benchmark.run import REAL_CHECKS, REAL_SIDES, TIER_PAIRS
from drkfs_lab.benchmark.torch_checks import JUMP_LIMIT
from drkfs_lab.record_tables import Table, bold, committed, grid, minus, trio

# the checks' column names, in REAL_CHECKS' order
CHECKS = dict(zip(("2° turn", "every turn", "salient"), REAL_CHECKS, strict=True))


@dataclass(frozen=True)
class Row:
    """A row: the cells that name it, its run (bench/results/RUN.json) and the lever's place
    among the run's levers; ``torch`` False where the lever has no torch path, so that its slide
    check is not its own (shown "–")."""

    cells: tuple[str, ...]
    run: str
    index: int
    bold: bool = False
    torch: bool = True


def _levers(root: Path, run: str) -> list[dict]:
    """A run's levers in the order it scored them."""
    found = committed(root, f"bench/results/{run}.json")
    return list((found.get("levers") or found.get("rows") or found["shift_search"]).values())


def _check(lever: dict, check: str, sides: tuple[str, ...] = REAL_SIDES) -> str:
    """A check's share on each side, as "80% / 60%"."""
    return " / ".join(f"{lever['checks'][side][CHECKS[check]]['share']:.0%}" for side in sides)


def _checks(lever: dict) -> str:
    """Every check the lever's run made, on both sides; one phrase where all hold."""
    made = [c for c, key in CHECKS.items() if key in lever["checks"]["training"]]
    if all(lever["checks"][s][CHECKS[c]]["share"] == 1.0 for s in REAL_SIDES for c in made):
        return "100% on both sides"
    return ", ".join(f"{c} {_check(lever, c)}" for c in made)


def _slide(lever: dict, row: Row) -> str:
    """The slide check's largest over mean step; more digits where two would hide a miss."""
    if not row.torch:
        return "–"
    step = lever["slide"]["max_over_mean_step"]
    return f"{step:.4f}" if round(step, 2) <= JUMP_LIMIT < step else f"{step:.2f}"


def _people(lever: dict, far_digits: int = 3) -> str:
    """Geo-metric's close/flipped / far/normal Spearman, "–" where people were not asked."""
    human = lever.get("human")
    if not human:
        return "–"
    return f"{minus(human['close_flipped'], 3)} / {minus(human['far_normal'], far_digits)}"


def _bars_retrieval_slide(lever: dict, row: Row) -> str:
    """The bars ratio, retrieval and the slide check, as "1.62 / 0.848 / 2.79"."""
    bars, found = lever["bars"]["deletion_over_max_shift"], lever["retrieval"]
    return f"{bars:.2f} / {found['nearest_neighbour_accuracy']:.3f} / {_slide(lever, row)}"


def _cost(lever: dict, row: Row, run: list[dict]) -> str:
    """A new mesh's seconds against the run's first lever's."""
    return f"{lever['seconds_per_mesh'] / run[0]['seconds_per_mesh']:.2f}×"


# column -> (header, the cell of a lever (lever, row, its run's levers), aligned right)
Cell = Callable[[dict, Row, list[dict]], str]
COLUMNS: dict[str, tuple[str, Cell, bool]] = {
    "synthetic": ("synthetic tiers", lambda lever, row, run: trio(lever["tiers"]), False),
    "training": ("real, training side",
                 lambda lever, row, run: trio(lever["real"]["training"]), False),
    "held_out": ("real, held out", lambda lever, row, run: trio(lever["real"]["held_out"]),
                 False),
    "third": ("third side", lambda lever, row, run: trio(lever["real"]["other"]), False),
    "turn": ("2° turn", lambda lever, row, run: _check(lever, "2° turn"), False),
    "every_turn": ("every turn", lambda lever, row, run: _check(lever, "every turn"), False),
    "salient": ("salient", lambda lever, row, run: _check(lever, "salient"), False),
    "checks": ("checks", lambda lever, row, run: _checks(lever), False),
    "turns_held_out": ("2° turn / every turn, held out", lambda lever, row, run: " / ".join(
        _check(lever, c, ("held_out",)) for c in ("2° turn", "every turn")), False),
    "bars_retrieval_slide": ("bars / retrieval / slide",
                             lambda lever, row, run: _bars_retrieval_slide(lever, row), False),
    "bars_slide": ("bars / slide", lambda lever, row, run:
                   f"{lever['bars']['deletion_over_max_shift']:.2f} / {_slide(lever, row)}", False),
    "targets_people": ("bars / retrieval / slide / people", lambda lever, row, run:
                       f"{_bars_retrieval_slide(lever, row)} / "
                       f"{_people(lever).replace(' / ', ', ')}", False),
    "bars": ("bars", lambda lever, row, run: f"{lever['bars']['deletion_over_max_shift']:.2f}",
             True),
    "retrieval": ("retrieval", lambda lever, row, run:
                  f"{lever['retrieval']['nearest_neighbour_accuracy']:.3f}", True),
    "slide": ("slide", lambda lever, row, run: _slide(lever, row), True),
    "people": ("people", lambda lever, row, run: _people(lever), False),
    # far/normal to 4 digits, where levers part in the fourth
    "people4": ("people", lambda lever, row, run: _people(lever, 4), False),
    "cost": ("a new mesh", _cost, True),
    "seconds": ("s a mesh", lambda lever, row, run: f"{lever['seconds_per_mesh']:.3f}", True),
    "targets": ("every target", lambda lever, row, run: _targets(lever), False),
    # the default the transforms are counted against loses none
    "pairs_lost": ("synthetic pairs lost",
                   lambda lever, row, run: str(len(lever.get("synthetic_lost", ()))), True),
}  # fmt: skip


def _targets(lever: dict) -> str:
    """Whether the lever keeps every target the bench held a default to then (the bars at least
    1.6, the slide check, synthetic pairs at least 0.9, retrieval 0.83, people −0.60 / −0.43),
    and where not, which it misses."""
    tiers, human = lever["tiers"], lever["human"]
    missed = [
        *(["bars"] if lever["bars"]["deletion_over_max_shift"] < 1.6 else []),
        *(["slide"] if lever["slide"]["max_over_mean_step"] > JUMP_LIMIT else []),
        *(f"synthetic {pair.replace('_vs_', ' < ')} {tiers[pair]:.3f}"
          for pair in TIER_PAIRS if tiers[pair] < 0.9),
        *(["retrieval"] if lever["retrieval"]["nearest_neighbour_accuracy"] < 0.83 else []),
        *(["close/flipped"] if human["close_flipped"] > -0.60 else []),
        *(["far/normal"] if human["far_normal"] > -0.43 else []),
    ]  # fmt: skip
    return "no: " + ", ".join(missed) if missed else "yes"


# the columns most tables open with (the tiers on each side) and close with (the bench's own
# targets, then people's agreement)
TIERS = ("synthetic", "training", "held_out")
BENCH_TARGETS = ("bars_retrieval_slide", "people")


@dataclass(frozen=True)
class LeverTable:
    """A table of levers: the headers of the cells that name a row, the columns, the rows."""

    names: tuple[str, ...]
    columns: tuple[str, ...]
    rows: tuple[Row, ...]

    def __post_init__(self):
        printed = [(row.run, row.index) for row in self.rows]
        if len(set(printed)) != len(printed):
            raise ValueError(f"a lever printed twice in one table: {printed}")

    def __call__(self, root: Path) -> str:
        """The table's markdown, each row's lever read from its run under ``root``."""
        runs = {run: _levers(root, run) for run in {row.run for row in self.rows}}
        header = [*self.names, *(COLUMNS[c][0] for c in self.columns)]
        printed = []
        for row in self.rows:
            run = runs[row.run]
            lever = run[row.index]
            cells = [*row.cells, *(COLUMNS[c][1](lever, row, run) for c in self.columns)]
            printed.append(bold(cells) if row.bold else cells)
        right = {len(self.names) + n for n, c in enumerate(self.columns) if COLUMNS[c][2]}
        return grid(header, printed, right)


LEVERS_AT_FIRST = LeverTable(
    ("lever",),
    (*TIERS, "turn", "salient"),
    (
        Row(("default",), "real_levers", 0),
        Row(("window r1",), "real_levers", 1),
        Row(("softmax t = 0.03",), "real_levers", 2),
        Row(("tail 10%",), "real_levers", 3),
        Row(("12 cameras",), "real_levers", 4),
        Row(("12 cameras, window r1",), "real_levers", 5),
    ),
)


TOLERANT_NETS_LEVERS = LeverTable(
    ("lever",),
    (*TIERS, "turn", "salient", "cost"),
    (
        Row(("default",), "real_levers_tolerant", 0),
        Row(("window r1",), "real_levers_tolerant", 1),
        Row(("softmax t = 0.03",), "real_levers_tolerant", 2),
        Row(("tail 10%",), "real_levers_tolerant", 3),
        Row(("12 cameras",), "real_levers_tolerant", 4),
        Row(("12 cameras, window r1",), "real_levers_tolerant", 5),
        Row(("160 px",), "real_levers_tolerant", 6),
        Row(("192 px",), "real_levers_tolerant", 7),
        Row(("256 px",), "real_levers_tolerant", 8),
        Row(("256 px, softmax t = 0.05",), "real_levers_tolerant", 9),
        Row(("4 cameras, 192 px",), "real_levers_tolerant", 10),
        Row(
            ("4 cameras, 192 px, softmax t = 0.05 (the default of one bench run)",),
            "real_levers_tolerant",
            11,
        ),
        Row(("softmax t = 0.05",), "real_levers_bars", 1),
        Row(("144 px, softmax t = 0.05",), "real_levers_bars", 2),
        Row(
            (
                "5 cameras, 144 px, softmax t = 0.05 (the default's cameras, "
                "with a turned ring since)",
            ),
            "real_levers_bars",
            3,
            bold=True,
        ),
        Row(("4 cameras, 144 px, softmax t = 0.05",), "real_levers_bars", 4),
        Row(("3 cameras, 256 px, softmax t = 0.05",), "real_levers_tolerant", 12),
        Row(("4 cameras, 256 px, softmax t = 0.05",), "real_levers_tolerant", 13),
    ),
)


TARGETS = LeverTable(
    ("lever",),
    ("bars", "retrieval", "slide", "people", "targets"),
    (
        Row(("default (6 views, 128 px, t = 0.1)",), "real_levers_bars", 0),
        Row(("softmax t = 0.05",), "real_levers_bars", 1),
        Row(("144 px, softmax t = 0.05",), "real_levers_bars", 2),
        Row(("5 cameras, 144 px, softmax t = 0.05",), "real_levers_bars", 3, bold=True),
        Row(("4 cameras, 144 px, softmax t = 0.05",), "real_levers_bars", 4),
        Row(("4 cameras, 192 px, softmax t = 0.05",), "real_levers_bars", 5),
    ),
)


NEIGHBOURS = LeverTable(
    ("5 cameras",),
    (*TIERS, "targets_people"),
    (
        Row(("144 px, t = 0.05",), "real_levers_neighbours", 1, bold=True),
        Row(("144 px, t = 0.1",), "real_levers_neighbours", 2),
        Row(("144 px, t = 0.07",), "real_levers_neighbours", 3),
        Row(("144 px, t = 0.04",), "real_levers_neighbours", 4),
        Row(("128 px, t = 0.05",), "real_levers_neighbours", 5),
        Row(("160 px, t = 0.05",), "real_levers_neighbours", 6),
    ),
)


SHIFT_SEARCHES = LeverTable(
    ("search",),
    (*TIERS, "turn", "salient"),
    (
        Row(("no search, patch",), "shift_tolerance", 0),
        Row(("no search, view",), "shift_tolerance", 1),
        Row(("+-1 px, patch",), "shift_tolerance", 2),
        Row(("+-1 px, view",), "shift_tolerance", 3),
        Row(("+-2 px, patch",), "shift_tolerance", 4),
        Row(("+-2 px, view",), "shift_tolerance", 5),
        Row(("+-2 px along x, patch",), "shift_tolerance", 6),
        Row(("+-2 px along x, view",), "shift_tolerance", 7),
        Row(("+-4 px along x, patch",), "shift_tolerance", 8),
        Row(("+-4 px along x, view",), "shift_tolerance", 9),
    ),
)


TOLERANT_NETS = LeverTable(
    ("nets", "softmax"),
    (*TIERS, "turn", "salient", "people"),
    (
        Row(("metric (shipped)", "t = 0.1"), "real_nets", 0),
        Row(("tolerant, trained at t = 0.03", "t = 0.1"), "real_nets", 1),
        Row(("metric (shipped)", "t = 0.05"), "real_nets", 2),
        Row(("tolerant, trained at t = 0.03", "t = 0.05"), "real_nets", 3),
        Row(("metric (shipped)", "t = 0.03"), "real_nets", 4),
        Row(("tolerant, trained at t = 0.03", "t = 0.03"), "real_nets", 5),
        Row(("tolerant, trained at t = 0.05", "t = 0.1"), "real_nets_t0.05", 1),
        Row(("tolerant, trained at t = 0.05", "t = 0.05"), "real_nets_t0.05", 3),
        Row(("tolerant, trained at t = 0.05", "t = 0.03"), "real_nets_t0.05", 5),
        Row(("tolerant, trained at t = 0.05, 200 steps", "t = 0.1"), "real_nets_t0.05_200", 1),
        Row(("tolerant, trained at t = 0.05, 200 steps", "t = 0.05"), "real_nets_t0.05_200", 3),
        Row(("tolerant, trained at t = 0.05, 200 steps", "t = 0.03"), "real_nets_t0.05_200", 5),
        Row(
            ("tolerant + simplification, trained at t = 0.05 (the default's nets)", "t = 0.1"),
            "real_nets_t0.05_simplification",
            1,
            bold=True,
        ),
        Row(
            ("tolerant + simplification, trained at t = 0.05", "t = 0.05"),
            "real_nets_t0.05_simplification",
            3,
        ),
        Row(
            ("tolerant + simplification, trained at t = 0.05", "t = 0.03"),
            "real_nets_t0.05_simplification",
            5,
        ),
        Row(
            ("tolerant + simplification + salient, trained at t = 0.05", "t = 0.1"),
            "real_nets_t0.05_simplification_salient",
            1,
        ),
        Row(
            ("tolerant + simplification + salient, trained at t = 0.05", "t = 0.05"),
            "real_nets_t0.05_simplification_salient",
            3,
        ),
        Row(
            ("tolerant + simplification + salient, trained at t = 0.05", "t = 0.03"),
            "real_nets_t0.05_simplification_salient",
            5,
        ),
        Row(
            ("tolerant + simplification ×3 + salient, trained at t = 0.05", "t = 0.1"),
            "real_nets_t0.05_simplification_x3_salient",
            1,
        ),
        Row(
            ("tolerant + simplification ×3 + salient, trained at t = 0.05", "t = 0.05"),
            "real_nets_t0.05_simplification_x3_salient",
            3,
        ),
        Row(
            ("tolerant + simplification ×3 + salient, trained at t = 0.05", "t = 0.03"),
            "real_nets_t0.05_simplification_x3_salient",
            5,
        ),
    ),
)


NETS_AT_THE_DEFAULTS_VIEWS = LeverTable(
    ("nets at 5 views of 144 px", "softmax"),
    (*TIERS, "turn", "salient", "people", "bars", "slide"),
    (
        Row(("shipped tolerant (the default)", "t = 0.05"), "real_levers_bars", 3, bold=True),
        Row(("shipped tolerant", "t = 0.1"), "real_levers_neighbours", 2),
        Row(
            ("fine-tuned at these views", "t = 0.1"),
            "real_nets_t0.05_simplification_144px_5views",
            1,
        ),
        Row(
            ("fine-tuned at these views", "t = 0.05"),
            "real_nets_t0.05_simplification_144px_5views",
            3,
        ),
        Row(
            ("fine-tuned at these views", "t = 0.03"),
            "real_nets_t0.05_simplification_144px_5views",
            5,
        ),
        Row(
            ("metric, not fine-tuned", "t = 0.05"), "real_nets_t0.05_simplification_144px_5views", 2
        ),
        Row(
            ("fine-tuned there, simplification ×3", "t = 0.1"),
            "real_nets_t0.05_simplification_x3_144px_5views",
            1,
        ),
        Row(
            ("fine-tuned there, simplification ×3", "t = 0.05"),
            "real_nets_t0.05_simplification_x3_144px_5views",
            3,
        ),
        Row(
            ("fine-tuned there, simplification ×3", "t = 0.03"),
            "real_nets_t0.05_simplification_x3_144px_5views",
            5,
        ),
    ),
)


TURNS = LeverTable(
    ("lever",),
    (
        *TIERS,
        "turn",
        "salient",
        *BENCH_TARGETS,
        "cost",
    ),
    (
        Row(("one ring (the default before)",), "real_levers_turns", 0),
        Row(("the cameras turned by 1°, no search",), "real_levers_turns", 1, torch=False),
        Row(("search: B turned by 0, ±1°",), "real_levers_turns", 2, torch=False),
        Row(("search: B turned by 0, ±1.5°",), "real_levers_turns", 3, torch=False),
        Row(("search: B turned by 0, ±2°",), "real_levers_turns", 4, torch=False),
        Row(("search: B turned by 0, ±2°, t = 0.04",), "real_levers_turns", 5, torch=False),
        Row(("search: B turned by 0, ±1°, ±2°",), "real_levers_turns", 6, torch=False),
        Row(("two rings at ±1°, every pairing",), "real_levers_turns", 7, torch=False),
        Row(("two rings at ±1°, t = 0.04",), "real_levers_turns", 8, torch=False),
        Row(("two rings at ±1°, t = 0.03",), "real_levers_turns", 9, torch=False),
        Row(("two rings at ±1°, each against its own only",), "real_levers_turns", 10, torch=False),
        Row(("rings at 0° and 2° (`turn_degrees = 2`)",), "real_levers_turns", 11),
        Row(("rings at 0° and 2°, t = 0.04",), "real_levers_turns", 12),
        Row(("rings at 0° and 2°, t = 0.03",), "real_levers_turns", 13),
    ),
)


RING_ANGLES = LeverTable(
    ("ring",),
    (
        *TIERS,
        "turn",
        "every_turn",
        "salient",
        *BENCH_TARGETS,
    ),
    (
        Row(("2°",), "real_levers_ring_angles", 0),
        Row(("1.5°",), "real_levers_ring_angles", 1),
        Row(("2.5° (the default)",), "real_levers_ring_angles", 2, bold=True),
        Row(("3°",), "real_levers_ring_angles", 3),
    ),
)


SOLID_CHANGE = LeverTable(
    ("lever",),
    (*TIERS, "turn", "salient", *BENCH_TARGETS),
    (
        Row(("no solid change (the default before)",), "real_levers_solid", 0),
        Row(("×0.3, reach 1, block 3",), "real_levers_solid", 1),
        Row(("×0.5, reach 1, block 3",), "real_levers_solid", 2),
        Row(("×1, reach 1, block 3",), "real_levers_solid", 3),
        Row(("×0.3, reach 2, block 3",), "real_levers_solid", 4),
        Row(("×0.5, reach 2, block 3 (the default then)",), "real_levers_solid", 5, bold=True),
        Row(("×0.7, reach 2, block 3",), "real_levers_solid", 6),
        Row(("×1, reach 2, block 3",), "real_levers_solid", 7),
        Row(("×0.5, reach 3, block 3",), "real_levers_solid", 8),
        Row(("×1, reach 3, block 3",), "real_levers_solid", 9),
        Row(("×0.5, reach 1, block 5",), "real_levers_solid", 10),
        Row(("×1, reach 1, block 5",), "real_levers_solid", 11),
        Row(("×1, reach 2, block 5",), "real_levers_solid", 12),
    ),
)


CAMERAS = LeverTable(
    ("lever",),
    (
        *TIERS,
        "turn",
        "salient",
        *BENCH_TARGETS,
        "seconds",
    ),
    (
        Row(("the default: 5 cameras of 144 px",), "real_levers_cameras", 0, bold=True),
        Row(("the default on the runtime path",), "real_levers_cameras", 1),
        Row(("6 cameras of 128 px, ×0.5, reach 2",), "real_levers_cameras", 2),
        Row(("6 cameras of 128 px, ×0.7, reach 2",), "real_levers_cameras", 3),
        Row(("6 cameras of 128 px, ×0.5, reach 1",), "real_levers_cameras", 4),
        Row(("6 cameras of 128 px, ×0.7, reach 1",), "real_levers_cameras", 5),
        Row(("6 cameras of 128 px, ×0.5, reach 1, t = 0.07",), "real_levers_cameras", 6),
        Row(("7 cameras of 128 px, ×0.5, reach 2",), "real_levers_cameras", 7),
        Row(("6 cameras of 144 px, ×0.5, reach 2",), "real_levers_cameras", 8),
        Row(("6 cameras of 144 px, ×0.5, reach 1, t = 0.07",), "real_levers_cameras", 9),
        Row(("solid change ×0.5 from 6 more cameras of 128 px",), "real_levers_cameras", 10),
        Row(("solid change ×0.7 from 6 more cameras of 128 px",), "real_levers_cameras", 11),
        Row(("descriptors' part at most 0.1",), "real_levers_cameras", 12),
        Row(("descriptors' part at most 0.05",), "real_levers_cameras", 13),
        Row(("solid change ×0.5, power mean p = 4 over the views",), "real_levers_cameras", 14),
        Row(("solid change ×0.3, the largest view's",), "real_levers_cameras", 15),
        Row(("solid change ×0.5, reach 1 inside the mesh",), "real_levers_cameras", 16),
        Row(("solid change ×0.7, reach 1 inside the mesh",), "real_levers_cameras", 17),
        Row(
            ("solid change ×0.5, reach 1 and power 1.5 inside the mesh",), "real_levers_cameras", 18
        ),
        Row(
            ("solid change ×0.7, reach 1 and power 1.5 inside the mesh",), "real_levers_cameras", 19
        ),
        Row(("solid change ×0.5, reach 1 and power 2 inside the mesh",), "real_levers_cameras", 20),
        Row(("solid change ×0.7, reach 1 and power 2 inside the mesh",), "real_levers_cameras", 21),
    ),
)


RAMP = LeverTable(
    ("lever",),
    (
        *TIERS,
        "turn",
        "every_turn",
        "salient",
        *BENCH_TARGETS,
    ),
    (
        Row(("the default before: ×0.5, reach 2",), "real_levers_ramp", 0),
        Row(
            ("the default then: ×0.7, reaches 2-3, 1-2 inside at power 1.5",),
            "real_levers_ramp",
            1,
            bold=True,
        ),
        Row(("×0.5, reaches 1-2-3 everywhere",), "real_levers_ramp", 2),
        Row(("×0.7, reaches 1-2-3 everywhere",), "real_levers_ramp", 3),
        Row(("×0.5, reaches 1-2 everywhere",), "real_levers_ramp", 4),
        Row(("×0.7, reaches 1-2 everywhere",), "real_levers_ramp", 5),
        Row(("×0.5, reaches 2-3 everywhere",), "real_levers_ramp", 6),
        Row(("×0.7, reaches 1-2-3-4 everywhere",), "real_levers_ramp", 7),
        Row(("×0.5, reaches 2-3, 1-2-3 inside",), "real_levers_ramp", 8),
        Row(("×0.7, reaches 2-3, 1-2-3 inside",), "real_levers_ramp", 9),
        Row(("×0.5, reaches 2-3, 1-2 inside",), "real_levers_ramp", 10),
        Row(("×0.7, reaches 2-3, 1-2 inside",), "real_levers_ramp", 11),
        Row(("×0.7, reaches 2-3, 1 inside at power 1.5",), "real_levers_ramp", 12),
        Row(("×0.7, reaches 2-3, 1-2-3 inside at power 1.5",), "real_levers_ramp", 13),
        Row(("×0.7, reaches 2-3, 1-2 inside at power 1.5",), "real_levers_ramp", 14),
        Row(("×0.5, reaches 2-3, 1-2 inside at power 1.5",), "real_levers_ramp", 15),
        Row(("×0.6, reaches 2-3, 1-2 inside at power 1.5",), "real_levers_ramp", 16),
        Row(("×0.7, reaches 2-3, 1-2 inside at power 2",), "real_levers_ramp", 17),
        Row(("×0.7, reaches 2-3, 1-2-3 inside at power 2",), "real_levers_ramp", 18),
    ),
)


WEIGHT_FLOOR = LeverTable(
    ("lever",),
    (*TIERS, "checks", *BENCH_TARGETS),
    (
        Row(("the default: ×0.7",), "real_levers_weight_floor", 0, bold=True),
        Row(("×0.85",), "real_levers_weight_floor", 1),
        Row(("×0.87",), "real_levers_weight_floor", 2),
        Row(("×1",), "real_levers_weight_floor", 3),
        Row(("×1.2",), "real_levers_weight_floor", 4),
        Row(("×1.5",), "real_levers_weight_floor", 5),
        Row(("floor 0.5 × the median",), "real_levers_weight_floor", 6),
        Row(("floor 1 × the median",), "real_levers_weight_floor", 7),
        Row(("floor 1 × the lower quartile",), "real_levers_weight_floor", 8),
        Row(("floor 0.5 × the upper quartile",), "real_levers_weight_floor", 9),
    ),
)


NETS_FROM_THE_DEFAULT = LeverTable(
    ("nets at the default",),
    (*TIERS, "checks", "bars_slide", "people"),
    (
        Row(("the default's",), "real_nets_from_default_salient", 0, bold=True),
        Row(("fine-tuned from them",), "real_nets_from_default_salient", 1),
        Row(("the same, 200 steps",), "real_nets_from_default_salient_200", 1),
        Row(("the same, 100 steps",), "real_nets_from_default_salient_100", 1),
    ),
)


MOVES = LeverTable(
    ("lever",),
    (*TIERS, "checks", *BENCH_TARGETS),
    (
        Row(("the default",), "real_levers_moves", 0, bold=True),
        Row(("netted ×0.7",), "real_levers_moves", 1),
        Row(("netted ×1",), "real_levers_moves", 2),
        Row(("netted ×1.5",), "real_levers_moves", 3),
        Row(("netted ×0.7, outline 1-2",), "real_levers_moves", 4),
        Row(("netted ×1, outline 1-2",), "real_levers_moves", 5),
        Row(("added ×0.3",), "real_levers_moves", 6),
        Row(("added ×0.7",), "real_levers_moves", 7),
        Row(("added ×1.5",), "real_levers_moves", 8),
        Row(("added by area ×0.7",), "real_levers_moves", 9),
        Row(("added by area ×1.5",), "real_levers_moves", 10),
        Row(("added ×0.7, local below 0.1",), "real_levers_moves", 11),
        Row(("added ×0.7, local below 0.2",), "real_levers_moves", 12),
        Row(("added ×1.5, local below 0.1",), "real_levers_moves", 13),
    ),
)


MOVES_BOUNDED = LeverTable(
    ("lever",),
    (*TIERS, "every_turn", *BENCH_TARGETS),
    (
        Row(("6 cameras of 128 px, at most 0.3",), "real_levers_moves_bounded", 0),
        Row(("6 cameras of 128 px, at most 0.5",), "real_levers_moves_bounded", 1),
        Row(("5 cameras of 144 px, at most 0.5",), "real_levers_moves_bounded", 2),
    ),
)


BOTH_RINGS = LeverTable(
    ("lever",),
    (*TIERS, "checks", *BENCH_TARGETS),
    (
        Row(("the default",), "real_levers_both_rings", 0, bold=True),
        Row(("both rings (mean)",), "real_levers_both_rings", 2),
        Row(("both rings (max)",), "real_levers_both_rings", 3),
        Row(("both rings (mean), ×1",), "real_levers_both_rings", 4),
        Row(("both rings (max), ×1",), "real_levers_both_rings", 5),
        Row(("both rings (max), ×1.2",), "real_levers_both_rings_netted", 0),
        Row(("both rings (mean), ×1.5",), "real_levers_both_rings", 6),
        Row(("both rings (max), ×1.5",), "real_levers_both_rings", 7),
        Row(("both rings (max), added ×0.7",), "real_levers_both_rings_netted", 6),
        Row(("both rings (max), added ×0.7, at most 0.75",), "real_levers_both_rings_netted", 5),
        Row(("both rings (max), netted ×3",), "real_levers_both_rings_netted", 4),
        Row(("both rings (max), netted ×4",), "real_levers_both_rings_netted", 3),
        Row(("both rings (max), netted ×4, at most 1",), "real_levers_both_rings_netted", 2),
        Row(("both rings (max), netted ×4, at most 0.5",), "real_levers_both_rings_netted", 1),
    ),
)


BOTH_PARTS = LeverTable(
    ("lever",),
    (*TIERS, "bars_retrieval_slide", "people4"),
    (
        Row(("the default before (×0.7, own ring alone)",), "real_levers_both_rings", 0, bold=True),
        Row(("×1.2, s = 0 (the table above)",), "real_levers_both_rings_netted", 0),
        Row(("×0.7, s = 0.5",), "real_levers_both_parts", 0),
        Row(("×1, s = 0.5",), "real_levers_both_parts", 1),
        Row(("×1.2, s = 0.5",), "real_levers_both_parts", 2),
        Row(("×1, s = 0.5, both rings' mean",), "real_levers_both_parts", 3),
        Row(("×0.7, s = 0.5, solid change from ring 0 alone",), "real_levers_both_parts", 4),
        Row(("×1, s = 0.25",), "real_levers_both_parts_weighted", 0),
        Row(("×1.2, s = 0.25",), "real_levers_both_parts_weighted", 1),
        Row(("×1.2, s = 0.35",), "real_levers_both_parts_weighted", 2),
        Row(("×1.5, s = 0.25",), "real_levers_both_parts_weighted", 3),
        Row(("×1.2, s = 0.1",), "real_levers_both_parts_light", 0),
        Row(("×1.2, s = 0.15",), "real_levers_both_parts_light", 1),
        Row(
            ("×1.2, s = 0.2 (the default until the window)",),
            "real_levers_both_parts_light",
            2,
            bold=True,
        ),
        Row(("×1, s = 0.15",), "real_levers_both_parts_light", 3),
    ),
)


PART_POWER = LeverTable(
    ("lever",),
    (*TIERS, "checks", *BENCH_TARGETS),
    (
        Row(("the default",), "real_levers_part_power", 0, bold=True),
        Row(("part², c = 1",), "real_levers_part_power", 1),
        Row(("part^1.5, c = 1",), "real_levers_part_power", 2),
        Row(("part², c = 0.5",), "real_levers_part_power", 3),
    ),
)


PART_KNEE = LeverTable(
    ("lever",),
    (*TIERS, "third", *BENCH_TARGETS),
    (
        Row(("the default",), "part_transforms", 0, bold=True),
        Row(("part², no knee",), "real_levers_other", 1),
        Row(("part², knee 0.005 (the rule's choice)",), "real_levers_part_knee", 0),
        Row(("part², knee 0.01",), "real_levers_part_knee", 1),
        Row(("part², knee 0.02",), "real_levers_part_knee", 2),
        Row(("part^1.25, knee 0.01",), "real_levers_part_knee_milder", 0),
        Row(("part^1.5, knee 0.01",), "real_levers_part_knee_milder", 1),
        Row(("part^1.5, knee 0.02",), "real_levers_part_knee_milder", 2),
        Row(("part^1.75, knee 0.01",), "real_levers_part_knee_milder", 3),
        Row(("netted ×4, bounded at 1, both rings",), "real_levers_other", 3),
        Row(("netted ×4, 6 cameras of 128 px",), "real_levers_other", 4),
    ),
)


PART_TRANSFORMS = LeverTable(
    ("lever",),
    (*TIERS, "third", *BENCH_TARGETS, "pairs_lost"),
    (
        Row(("the default before the window",), "part_transforms", 0),
        Row(("solid term ×1.5",), "part_transforms", 3),
        Row(("solid term ×3",), "part_transforms", 5),
        Row(("part^1.5 above 0.01",), "part_transforms", 11),
        Row(("part² above 0.01",), "part_transforms", 17),
        Row(
            ("slope 0.6 between 0.04 and 0.18 (the rule's choice, in the default since)",),
            "part_transforms",
            117,
            bold=True,
        ),
        Row(("slope 0.4 between 0.01 and 0.15",), "part_transforms", 66),
        Row(("slope 0.2 between 0.04 and 0.18",), "part_transforms", 37),
        Row(("slope 0.2 between 0.04 and 0.3",), "part_transforms", 38),
    ),
)


BACK_LIGHT = LeverTable(
    ("faces seen from behind",),
    (
        *TIERS,
        "third",
        "turns_held_out",
        *BENCH_TARGETS,
    ),
    (
        Row(("lit as their front, 1 (the default)",), "real_levers_back_light", 0, bold=True),
        Row(("0.75 of the light",), "real_levers_back_light", 4),
        Row(("0.5 of the light",), "real_levers_back_light", 3),
        Row(("0.25 of the light",), "real_levers_back_light", 2),
        Row(("ambient alone, 0",), "real_levers_back_light", 1),
    ),
)


OPENINGS = LeverTable(
    ("faces seen from behind",),
    (
        *TIERS,
        "third",
        "turns_held_out",
        *BENCH_TARGETS,
        "cost",
    ),
    (
        Row(("lit as their front (the default then)",), "real_levers_openings", 0),
        Row(("0 of the light, pushed back 0.02",), "real_levers_openings", 1),
        Row(
            ("0 of the light, pushed back 0.05 (the default now)",),
            "real_levers_openings",
            2,
            bold=True,
        ),
        Row(("0 of the light, pushed back 0.1",), "real_levers_openings", 3),
        Row(("0.5 of the light, pushed back 0.05",), "real_levers_openings", 4),
    ),
)

TABLES: list[Table] = [
    LEVERS_AT_FIRST,
    TOLERANT_NETS_LEVERS,
    TARGETS,
    NEIGHBOURS,
    SHIFT_SEARCHES,
    TOLERANT_NETS,
    NETS_AT_THE_DEFAULTS_VIEWS,
    TURNS,
    RING_ANGLES,
    SOLID_CHANGE,
    CAMERAS,
    RAMP,
    WEIGHT_FLOOR,
    NETS_FROM_THE_DEFAULT,
    MOVES,
    MOVES_BOUNDED,
    BOTH_RINGS,
    BOTH_PARTS,
    PART_POWER,
    PART_KNEE,
    PART_TRANSFORMS,
    BACK_LIGHT,
    OPENINGS,
]
