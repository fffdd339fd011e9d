"""bench/records/real_tiers.md's tables: every method on the real tiers' two sides
(bench/results/real_tiers.json), the default with noises left out (real_tiers_without_*.json),
every method on the third side (real_tiers_other.json) and the speed of server scoring
(score.json). Earlier defaults' rows are the same command's runs that the file has replaced
since, kept as the commit that made each held it (``record_tables.EARLIER``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from drkfs_lab.benchmark import sets
from drkfs_lab.benchmark.methods import DEFAULT_NAME
from drkfs_lab.benchmark.run import OTHER_SIDE, REAL_CHECKS, REAL_SIDES, real_checks, tier_accuracy
from drkfs_lab.record_tables import Table, bold, committed, grid, italic, trio

REAL_TIERS = "bench/results/real_tiers.json"
OTHER_TIERS = "bench/results/real_tiers_other.json"
# the commits whose real_tiers.json and real_tiers_other.json hold an earlier default's run
TWO_SIDED_LIGHT = "aca8f98"
PARTS_IN_FULL = "9d1ea5b"
OWN_RING_ALONE = "c7674db"
ONE_REACH = "bb03b89"
NO_SOLID_CHANGE = "ca1235a"
ONE_RING = "43cc20c"
FOUR_VIEWS_192 = "9e56d92"
SIX_VIEWS_128 = "57108d5"
METRIC_NETS = "e4594b6"
THIRD_SIDE_FIRST = "b70958e"
# a table's row: (row, commit of the run or None for the file's own, method of that run)
RunRow = tuple[str, str | None, str]
EVERY_METHOD_ROWS: tuple[RunRow, ...] = (
    ("DR-KFS", None, "DR-KFS"),
    ("DR-KFS, two-sided light (the default before openings seen dark)", TWO_SIDED_LIGHT, "DR-KFS"),
    ("DR-KFS paper", None, "DR-KFS paper"),
    ("DR-KFS structure", None, "DR-KFS structure"),
    ("DR-KFS structure, two-sided light", TWO_SIDED_LIGHT, "DR-KFS structure"),
    ("DR-KFS, parts in full", PARTS_IN_FULL, "DR-KFS"),
    ("DR-KFS, own ring alone (×0.7)", OWN_RING_ALONE, "DR-KFS"),
    ("DR-KFS structure, own ring alone (×0.7)", OWN_RING_ALONE, "DR-KFS structure"),
    ("DR-KFS, one reach of 2 (×0.5)", ONE_REACH, "DR-KFS"),
    ("DR-KFS structure, one reach of 2 (×0.5)", ONE_REACH, "DR-KFS structure"),
    ("DR-KFS, no solid change", NO_SOLID_CHANGE, "DR-KFS"),
    ("DR-KFS structure, no solid change", NO_SOLID_CHANGE, "DR-KFS structure"),
    ("DR-KFS, one ring", ONE_RING, "DR-KFS"),
    ("DR-KFS structure, one ring", ONE_RING, "DR-KFS structure"),
    ("DR-KFS, 4 views of 192 px", FOUR_VIEWS_192, "DR-KFS"),
    ("DR-KFS structure, 4 views of 192 px", FOUR_VIEWS_192, "DR-KFS structure"),
    ("DR-KFS, 6 views of 128 px, t = 0.1", SIX_VIEWS_128, "DR-KFS"),
    ("DR-KFS structure, 6 views of 128 px", SIX_VIEWS_128, "DR-KFS structure"),
    ("DR-KFS, metric nets", METRIC_NETS, "DR-KFS"),
    ("DR-KFS structure, metric nets", METRIC_NETS, "DR-KFS structure"),
    ("pixel MSE", None, "pixel MSE"),
    ("Chamfer-L1", None, "Chamfer-L1"),
    ("F-score 1%", None, "F-score 1%"),
    ("LFD", None, "LFD"),
)
THIRD_SIDE_ROWS: tuple[RunRow, ...] = (
    ("DR-KFS", None, "DR-KFS"),
    ("DR-KFS, two-sided light (the default before openings seen dark)", TWO_SIDED_LIGHT, "DR-KFS"),
    ("DR-KFS paper", None, "DR-KFS paper"),
    ("DR-KFS structure", None, "DR-KFS structure"),
    ("DR-KFS structure, two-sided light", TWO_SIDED_LIGHT, "DR-KFS structure"),
    ("DR-KFS, parts in full, two-sided light", THIRD_SIDE_FIRST, "DR-KFS"),
    ("pixel MSE", None, "pixel MSE"),
    ("Chamfer-L1", None, "Chamfer-L1"),
    ("F-score 1%", None, "F-score 1%"),
    ("LFD", None, "LFD"),
)
# what "Left open" leaves out: row -> the file of the shares without it
LEFT_OUT_ROWS = {
    "nothing (the default)": REAL_TIERS,
    "the four plainest crumpled noises": "bench/results/real_tiers_without_crumpled_noise.json",
    "every mesh's noise": "bench/results/real_tiers_without_noise.json",
}
# the tier pair whose held-out misses "Left open" counts: the one the bar lets a few miss
MISSED_PAIR = "surface_vs_structural"
SCORE = "bench/results/score.json"
# bench/score.py's goals per case ("goal_met"), set in bold where met
NEW_MESH_GOAL, MATCH_GOAL, TORCH_GOAL = "new_mesh_le_0.2s", "match_le_1ms", "torch_step_le_1s"


def _scored(run: dict, method: str) -> tuple[sets.BenchSet, dict[int, float | None]]:
    """A real-tiers run's comparisons, from its labels alone, and ``method``'s values by
    comparison: what its shares and checks recompute from."""
    bench = sets.BenchSet(comparisons=[
        sets.Comparison("real", *key.rsplit("/", 1), kind, key, "")
        for key, kind in run["labels"].items()
    ])  # fmt: skip
    values = run["values"][method]
    return bench, {i: values.get(c.shape) for i, c in enumerate(bench.comparisons)}


def _checks(run: dict, method: str) -> dict:
    """Per side, ``method``'s real checks in ``run``: the run's own, a check it came before
    (the every-turn check) recomputed from its values."""
    checks = run["methods"][method]["checks"]
    if all(name in side for side in checks.values() for name in REAL_CHECKS):
        return checks
    again = real_checks(*_scored(run, method))
    return {side: {**again[side], **made} for side, made in checks.items()}


def _method_cells(run: dict, method: str, sides: Sequence[str]) -> list[str]:
    """``method``'s cells of a real-tiers table: each side's shares, each check's share of
    meshes on the sides (as 'training / held out'), seconds a pair."""
    row, checks = run["methods"][method], _checks(run, method)
    shares = [trio(row[side]) for side in sides]
    passed = [" / ".join(f"{checks[side][name]['share']:.0%}" for side in sides)
              for name in REAL_CHECKS]  # fmt: skip
    return [*shares, *passed, f"{row['seconds_per_pair']:.2f}"]


def _method_rows(
    root: Path, path: str, rows: Sequence[RunRow], sides: Sequence[str]
) -> list[list[str]]:
    """A real-tiers table's rows: the default's in bold (its seconds a pair aside, a cost and
    not a result), earlier defaults' runs in italics."""
    runs = {commit: committed(root, path, commit) for commit in {row[1] for row in rows}}
    printed = []
    for label, commit, method in rows:
        cells = [label, *_method_cells(runs[commit], method, sides)]
        if commit is not None:
            cells = italic(cells)
        elif method == DEFAULT_NAME:
            cells = [*bold(cells[:-1]), cells[-1]]
        printed.append(cells)
    return printed


def every_method(root: Path) -> str:
    """The table of "Real-mesh tiers: every method": each method's shares on both sides, its
    checks and seconds a pair (real_tiers.json), with earlier defaults' runs."""
    header = ("method", "real, training side", "real, held out",
              "2° turn below every surface variant", "every turn below every surface variant",
              "salient part above every invisible", "s a pair")  # fmt: skip
    return grid(header, _method_rows(root, REAL_TIERS, EVERY_METHOD_ROWS, REAL_SIDES), right=1)


def _without(run: dict, left_out: Sequence[str], bases: Sequence[str] | None = None) -> dict:
    """The default's real-tier accuracy (``tier_accuracy``) from ``run``'s scores with the
    variants ``left_out`` ("mesh/variant") taken out, over the meshes ``bases`` (all where
    None)."""
    bench, values = _scored(run, DEFAULT_NAME)
    dropped = {sets.REAL_PREFIX + name for name in left_out}
    kept_bases = None if bases is None else {sets.REAL_PREFIX + name for name in bases}
    comparisons = bench.comparisons
    kept = {i: value for i, value in values.items()
            if comparisons[i].shape not in dropped
            and (kept_bases is None or comparisons[i].base in kept_bases)}  # fmt: skip
    return tier_accuracy(bench, kept, "real")


def noise_left_out(root: Path) -> str:
    """The table of "Left open": the default's shares on both sides and its held-out
    surface < structural misses, from real_tiers.json's scores with nothing, the plainest
    crumpled noises or every noise left out (the variants real_tiers_without_*.json name)."""
    run = committed(root, REAL_TIERS)
    rows = []
    for label, path in LEFT_OUT_ROWS.items():
        left_out = committed(root, path).get("left_out", [])  # the run itself leaves none out
        shares = _without(run, left_out)
        held_out = _without(run, left_out, sets.HELDOUT_MESHES)
        misses = sum(held_out["misses"][MISSED_PAIR].values())
        rows.append([label, *(trio(shares[side]) for side in REAL_SIDES),
                     f"{misses} of {held_out['pairs'][MISSED_PAIR]}"])  # fmt: skip
    return grid(("left out", "real, training side", "real, held out", "held-out misses"), rows)


def third_side(root: Path) -> str:
    """The table of "A third side": each method's shares on the outside meshes, its checks and
    seconds a pair (real_tiers_other.json), with the runs before openings were seen dark."""
    header = ("method", "third side", "2° turn below every surface variant", "every turn",
              "salient part above every invisible", "s a pair")  # fmt: skip
    return grid(header, _method_rows(root, OTHER_TIERS, THIRD_SIDE_ROWS, (OTHER_SIDE,)), right=4)


def _met(text: str, case: dict, goal: str) -> str:
    """``text``, in bold where the case met ``goal``."""
    return bold([text])[0] if case["goal_met"][goal] else text


def _speed_cells(case: dict) -> list[str]:
    """One case of bench/score.py: the runtime's new mesh, render and match, the torch step,
    torch against the runtime, Chamfer-L1's costs, the peak memory and a reference's."""
    runtime, torch = case["runtime"], case["torch_eager"]
    ratios, chamfer = case["torch_over_runtime"], case["chamfer_l1"]
    return [
        f"{Path(case['mesh']).stem} ({case['faces']:,})",
        case["preset"],
        _met(f"{runtime['new_mesh_s']:.3f} s", case, NEW_MESH_GOAL),
        f"{runtime['render_s']:.3f} s",
        _met(f"{runtime['match_s'] * 1e3:.2f} ms", case, MATCH_GOAL),
        _met(f"{torch['forward_backward_to_target_s']:.2f} s", case, TORCH_GOAL),
        f"{ratios['new_mesh']:.1f}×",
        f"{ratios['match']:.1f}×",
        f"{chamfer['new_mesh_s'] * 1e3:.0f} ms / {chamfer['match_s'] * 1e3:.0f} ms",
        f"{runtime['peak_rss_mb'] / 1024:.2f} GB",
        f"{runtime['described_mb']:.1f} / {runtime['held_after_match_mb']:.1f} MB",
    ]


def speed(root: Path) -> str:
    """The table of "Speed of server scoring": every case of score.json, its goals met in
    bold."""
    header = ("mesh (faces)", "config", "new mesh", "of which render", "match",
              "torch fwd+bwd to a target", "torch / runtime, new", "torch / runtime, match",
              "Chamfer-L1 new / match", "peak RSS",
              "a reference held, described / matched")  # fmt: skip
    rows = [_speed_cells(case) for case in committed(root, SCORE)["cases"]]
    return grid(header, rows, right=9)


TABLES: list[Table] = [every_method, noise_left_out, third_side, speed]
