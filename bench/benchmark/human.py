"""The human-judgment check: Geo-metric's simplification stimuli (Wolski et al., SIGGRAPH Asia
2022: 100 face scans, pairwise comparisons scaled to JOD per mesh and viewing setting).

The folder is a clone of github.com/facebookresearch/Geo-metric with the simplification stimuli
checked out from the commit that still holds them (its later history keeps only LFS pointers)::

    GIT_LFS_SKIP_SMUDGE=1 git clone https://github.com/facebookresearch/Geo-metric
    cd Geo-metric && git checkout b4f5cc9 -- $(git ls-tree -r --name-only b4f5cc9 stimuli \\
        | grep -E 'Simp_p(03.12|06.25|12.50)\\.obj$')

The true references are missing there, so each face's 12.5% simplification stands in for it:
the 3.125% and 6.25% ones are scored against it (200 pairs), and a metric agrees with people
when its score falls as the JOD difference JOD(prediction) - JOD(stand-in) rises (a negative
Spearman). Nothing of the dataset is committed.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from drkfs_onnx.contract.mesh import load_mesh

from .sets import BenchSet, Comparison

SETTINGS = ("close_flipped", "close_normal", "far_flipped", "far_normal")
REFERENCE = "p12.50"
LEVELS = ("p03.12", "p06.25")
JOD_FILE = Path("analysis/results/JODPerMesh.csv")


def stimulus(folder: Path, face: str, level: str) -> Path:
    return folder / "stimuli" / face / f"{face}-Simp_{level}.obj"


def faces_in(folder: Path) -> list[str]:
    """The faces whose stand-in and both scored levels are in ``folder``; a ValueError names
    what is missing when there are none."""
    if not (folder / JOD_FILE).is_file():
        raise ValueError(f"{folder}: no {JOD_FILE}; is it a Geo-metric clone? (see docs)")
    faces = sorted(
        path.name
        for path in (folder / "stimuli").glob("*")
        if all(stimulus(folder, path.name, level).is_file() for level in (REFERENCE, *LEVELS))
    )
    if not faces:
        raise ValueError(
            f"{folder}: no face has its Simp_p03.12, p06.25 and p12.50 stimuli; check them out "
            "from commit b4f5cc9 (see docs)"
        )
    return faces


# the dataset's own metrics, computed by its authors against the true references
DATASET_METRICS = ("MSDM2", "FMPD", "METRO", "RMS")


def _simplification_rows(folder: Path, column: str) -> dict[tuple[str, str, str], float]:
    """(face, level, setting) -> ``column`` of JODPerMesh.csv's simplification rows."""
    with open(folder / JOD_FILE, newline="") as handle:
        return {
            (row["basemesh"], row["magnitude"].removeprefix("Simp_"), row["setting"]): float(
                row[column]
            )
            for row in csv.DictReader(handle)
            if row["dst_type"] == "Simp"
        }


def jod_differences(folder: Path) -> dict[tuple[str, str, str], float]:
    """(face, level, setting) -> JOD(level) - JOD(stand-in) from the dataset's JODPerMesh.csv."""
    jod = _simplification_rows(folder, "JOD")
    return {
        (face, level, setting): value - jod[(face, REFERENCE, setting)]
        for (face, level, setting), value in jod.items()
        if level in LEVELS
    }


def add_human(bench: BenchSet, folder: Path) -> dict[tuple[str, str, str], float]:
    """Add the stimuli of ``folder`` as comparisons of group "human" (each level against its
    face's stand-in) and return their JOD differences."""
    for face in faces_in(folder):
        reference = f"human/{face}/{REFERENCE}"
        for key, level in ((reference, REFERENCE), *((f"human/{face}/{lv}", lv) for lv in LEVELS)):
            mesh = load_mesh(stimulus(folder, face, level))
            bench.shapes[key] = (mesh.vertices, mesh.faces)
            bench.sources[key] = stimulus(folder, face, level)
            if key != reference:
                bench.comparisons.append(Comparison("human", face, level, level, key, reference))
    return jod_differences(folder)


def human_agreement(bench: BenchSet, values: dict[int, float | None], jod: dict) -> dict | None:
    """Spearman between a method's scores and the JOD differences, per viewing setting: over all
    pairs, and within each level (how well it orders the faces at one level of simplification).
    None when the method scored none of them."""
    rows = [(i, c) for i, c in enumerate(bench.comparisons) if c.group == "human"]
    rows = [(i, c) for i, c in rows if values.get(i) is not None]
    if not rows:
        return None

    def rho(chosen, setting: str) -> float:
        scores = [values[i] for i, _ in chosen]
        people = [jod[(c.base, c.kind, setting)] for _, c in chosen]
        return float(spearmanr(scores, people)[0])

    result = {setting: rho(rows, setting) for setting in SETTINGS}
    result["pairs"] = len(rows)
    result["within_level"] = {
        level: {
            setting: rho([r for r in rows if r[1].kind == level], setting) for setting in SETTINGS
        }
        for level in LEVELS
    }
    result["within_level_mean"] = {
        setting: float(np.mean([result["within_level"][lv][setting] for lv in LEVELS]))
        for setting in SETTINGS
    }
    return result


def dataset_agreement(bench: BenchSet, folder: Path, jod: dict) -> dict[str, dict]:
    """``human_agreement`` of the dataset's own metrics (DATASET_METRICS) on the same pairs,
    for reference: they were computed against the true references, which DR-KFS never sees
    (per setting, so each setting's value of a metric is its own row)."""
    rows = [c for c in bench.comparisons if c.group == "human"]
    found = {}
    for metric in DATASET_METRICS:
        values = _simplification_rows(folder, metric)
        found[metric] = {
            setting: float(
                spearmanr(
                    [values[(c.base, c.kind, setting)] for c in rows],
                    [jod[(c.base, c.kind, setting)] for c in rows],
                )[0]
            )
            for setting in SETTINGS
        }
    return found


CEILING_DRAWS = 2000  # random within-level orders drawn for ``agreement_ceiling``


def agreement_ceiling(bench: BenchSet, jod: dict, seed: int = 0) -> dict[str, dict]:
    """What this protocol lets any scorer reach, from the people's data alone, per setting.

    ``levels_only``: the mean Spearman of a scorer that ranks every 3.125% face above every
    6.25% one but orders the faces within a level at random, with ``levels_only_lucky``, the
    2.5th percentile over CEILING_DRAWS such orders (what luck alone may reach).
    ``people_within_level``: the Spearman, within one level, between this setting's JOD
    differences and another setting's, averaged over the other settings and both levels: how
    well people's own judgments in another viewing order the faces within a level, a bound on
    what any scorer can learn there.
    """
    rows = [c for c in bench.comparisons if c.group == "human"]
    level = np.array([LEVELS.index(c.kind) for c in rows])  # 0: the coarser level
    rng = np.random.default_rng(seed)
    orders = [rng.permutation(len(rows)) for _ in range(CEILING_DRAWS)]
    found = {}
    for setting in SETTINGS:
        people = np.array([jod[(c.base, c.kind, setting)] for c in rows])
        # coarser level first, ranks inside a level drawn at random: larger = further
        draws = [spearmanr((1 - level) * len(rows) + order, people)[0] for order in orders]
        within = [
            spearmanr(
                [jod[(c.base, c.kind, setting)] for c in rows if c.kind == lv],
                [jod[(c.base, c.kind, other)] for c in rows if c.kind == lv],
            )[0]
            for other in SETTINGS
            if other != setting
            for lv in LEVELS
        ]
        found[setting] = {
            "levels_only": float(np.mean(draws)),
            "levels_only_lucky": float(np.percentile(draws, 2.5)),
            "people_within_level": float(np.mean(within)),
        }
    return found
