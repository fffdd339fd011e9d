"""bench/records/matching.md's tables: the second match study's rows
(bench/results/match_study.json), the first study's feature configs (its match_study.json, kept
under bench/earlier since the second replaced it) and the reductions of one set of best-match
distances (bench/results/reductions.json).
"""

from __future__ import annotations

from pathlib import Path

from drkfs_lab.benchmark.human import SETTINGS as PEOPLE
from drkfs_lab.record_tables import Table, bold, committed, grid, minus

MATCH_STUDY = "bench/results/match_study.json"
# the tier pairs in this record's column order (as docs/benchmark.md's)
TIER_PAIRS = ("invisible_vs_structural", "invisible_vs_surface", "surface_vs_structural")
# the first study's run: bench/results/match_study.json at this commit
FIRST_STUDY = "3de5b75"
# the first study's names of the paper's match (global, forward, sum)
PAPER_MATCH = "global forward sum"
# the second study's rows: row -> (feature config, match) of match_study.json
SECOND_CHOICE_ROWS = {
    "metric nets / window r0 softmax 0.1 (the default)":
        ("6 views 128 px w0.5 metric", "window r0 softmax 0.1"),
    "metric nets / global power 8 (the structure preset)":
        ("6 views 128 px w0.5 metric", "global power 8"),
    "correspondence nets / global power 8 (the previous default)":
        ("6 views 128 px w0.5 correspondence", "global power 8"),
    "correspondence nets / window r0 softmax 0.1":
        ("6 views 128 px w0.5 correspondence", "window r0 softmax 0.1"),
    "metric nets / window r0 softmax 0.03":
        ("6 views 128 px w0.5 metric", "window r0 softmax 0.03"),
    "metric nets / window r0 mean": ("6 views 128 px w0.5 metric", "window r0 mean"),
    "12 views, 256 px, correspondence / window r0 softmax 0.2":
        ("12 views 256 px w0.5 correspondence", "window r0 softmax 0.2"),
    "the paper's features / window r0 softmax 0.2":
        ("25 views 256 px w1 correspondence", "window r0 softmax 0.2"),
}  # fmt: skip
CHAMFER_ROW = "Chamfer-L1 (100k samples)"
REDUCTIONS = "bench/results/reductions.json"


def _tier_cells(tiers: dict) -> list[str]:
    """Invisible < structural, its synthetic / shared halves, invisible < surface and
    surface < structural."""
    pair = "invisible_vs_structural"
    halves = f"{tiers['synthetic'][pair]:.2f} / {tiers['shared'][pair]:.2f}"
    return [f"{tiers[pair]:.3f}", halves, *(f"{tiers[p]:.3f}" for p in TIER_PAIRS if p != pair)]


def second_choice(root: Path) -> str:
    """The table of "The second choice": each named candidate's tiers, people's Spearman,
    retrieval and bars (match_study.json), the chosen one in bold, and Chamfer-L1's tiers."""
    study = committed(root, MATCH_STUDY)
    chosen = (study["chosen"]["feature_config"], study["chosen"]["variant"])
    rows = []
    for label, (config, match) in SECOND_CHOICE_ROWS.items():
        row = study["feature_configs"][config]["variants"][match]
        people = " / ".join(minus(row["human"][s], 2) for s in PEOPLE)
        cells = [label, *_tier_cells(row["tiers"]), people,
                 f"{row['retrieval']:.2f}", f"{row['bars']:.2f}"]  # fmt: skip
        rows.append(bold(cells) if (config, match) == chosen else cells)
    rows.append([CHAMFER_ROW, *_tier_cells(study["chamfer"]), "", "", ""])
    header = ("feature config / match", "inv < str", "synthetic / shared", "inv < surf",
              "surf < str", "human (close fl. / close n. / far fl. / far n.)", "retrieval",
              "bars")  # fmt: skip
    return grid(header, rows, right=7)


def _best_match(variants: dict) -> str:
    """A feature config's most accurate match; ties to the better bars ratio, then retrieval,
    then the sweep's order."""
    return max(variants, key=lambda name: (
        variants[name]["accuracy"], variants[name]["bars_ratio"], variants[name]["retrieval"]
    ))  # fmt: skip


def first_choice(root: Path) -> str:
    """The table of "The first choice": per feature config of the first study, its seconds a
    new mesh and the accuracy of the paper's match, the chosen match and its best, the chosen
    config in bold."""
    study = committed(root, MATCH_STUDY, FIRST_STUDY)
    chosen = study["chosen"]
    rows = []
    for name, entry in study["feature_configs"].items():
        config, variants = entry["config"], entry["variants"]
        best = _best_match(variants)
        cells = [str(config["num_views"]), str(config["image_size"]),
                 f"{config['descriptor_width']:g}", f"{entry['seconds_per_mesh']:.3f}",
                 f"{variants[PAPER_MATCH]['accuracy']:.3f}",
                 f"{variants[chosen['variant']]['accuracy']:.3f}",
                 f"{best} ({variants[best]['accuracy']:.3f})"]  # fmt: skip
        rows.append(bold(cells) if name == chosen["feature_config"] else cells)
    header = ("views", "px", "width", "s / new mesh", "paper's match", "default's match",
              "best match (its accuracy)")  # fmt: skip
    return grid(header, rows, right=4)


def reductions(root: Path) -> str:
    """The table of "A second component from the same descriptors": each reduction's tier
    shares and people's Spearman (reductions.json)."""
    rows = [[name, *(f"{row['tiers'][p]:.3f}" for p in TIER_PAIRS),
             " / ".join(minus(row["human"][s], 3) for s in PEOPLE)]
            for name, row in committed(root, REDUCTIONS)["rows"].items()]  # fmt: skip
    header = ("reduction", "invisible < structural", "invisible < surface",
              "surface < structural",
              "Spearman: close fl. / close n. / far fl. / far n.")  # fmt: skip
    return grid(header, rows, right=4)


TABLES: list[Table] = [second_choice, first_choice, reductions]
