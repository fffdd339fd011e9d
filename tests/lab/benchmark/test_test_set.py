"""The frozen test set: built by the benchmark's recipes at seeds nothing else uses, unchanged
since it was made, imported by its release script and the results' check alone, and scored once
per released version."""

import ast
import json
import subprocess
import sys

import pytest
from conftest import ROOT
from test_layout import every_module

from drkfs_lab.benchmark import as_they_come, sets, test_set
from drkfs_lab.studies import network, single_view
from drkfs_lab.test_set import kept_from
from drkfs_lab.training import graded, tolerance
from drkfs_lab.training.run import TrainPlan
from drkfs_onnx.contract.versions import LATEST, VERSIONS

RELEASE = ROOT / "bench" / "test_set.py"


@pytest.fixture(scope="module")
def built():
    return test_set.build()


def test_the_set_is_what_it_was_when_it_was_frozen(built):
    assert test_set.digest(built) == test_set.DIGEST


def test_it_holds_every_tier_and_the_assets_checks(built):
    kinds = {(c.group, c.kind) for c in built.comparisons}
    for group in (test_set.TIERS_GROUP, test_set.ASSETS_GROUP):
        assert {kind for g, kind in kinds if g == group} == {"invisible", "surface", "structural"}
    labels = {c.label for c in built.comparisons if c.group == test_set.ASSETS_GROUP}
    assert {*as_they_come.FILES, "turned_x_2", "small_hole", "part_removed"} <= labels


def test_its_seeds_are_no_other_sets_or_trainings():
    used = {
        sets.SEED, sets.SEED + 1, sets.SEED + 2, *sets.HOLDOUT_SEEDS, as_they_come.SEED,
        *(s for side in as_they_come.ASSET_SEEDS.values() for s in side),
        graded.TRAIN_SEED, graded.HELDOUT_SEED, tolerance.TRAIN_SEED, tolerance.SIMPLIFY_SEED,
        tolerance.SLIDE_SEED, TrainPlan().seed, network.TRAIN_SEED, network.VALIDATION_SEED,
        network.TEST_SEED, single_view.TRAIN_SEED, single_view.VALIDATION_SEED,
        single_view.TEST_SEED,
    }  # fmt: skip
    assert not used & {*test_set.TIER_SEEDS, *test_set.ASSET_SEEDS}


def test_only_the_release_script_and_the_results_check_import_it():
    importers = []
    for path in every_module():
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            if any(n.endswith("benchmark.test_set") for n in names):
                importers.append(path.relative_to(ROOT).as_posix())
    assert importers == ["bench/check_results.py", "bench/test_set.py"]


def _release(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(RELEASE), *args], capture_output=True, text=True, cwd=ROOT
    )


def test_a_release_scores_the_newest_version_only(tmp_path):
    older = next(name for name in VERSIONS if name != LATEST)
    result = _release("--release", older, "--out", str(tmp_path / "t.json"))
    assert result.returncode != 0
    assert f"only the newest version ({LATEST}) is released" in result.stderr


def test_a_version_is_scored_once(tmp_path):
    out = tmp_path / "t.json"
    out.write_text(json.dumps({"releases": {LATEST: {}}}))
    result = _release("--release", LATEST, "--out", str(out))
    assert result.returncode != 0
    assert f"{LATEST} was scored at its release; its test figures are kept" in result.stderr
    assert json.loads(out.read_text()) == {"releases": {LATEST: {}}}


def test_a_release_keeps_what_earlier_releases_scored_but_the_last_ones_own_version():
    # frozen set, frozen configs: an earlier release's rows stand; the last release's version
    # is scored again beside the new one, so that the seconds compare within one run
    releases = {
        "drkfs-1.1": {"methods": {"drkfs-1.0": {}, "drkfs-1.1": {}, "LFD": {}}},
        "drkfs-1.2": {"methods": {"drkfs-1.1": {}, "drkfs-1.2": {}}},
    }
    assert kept_from(releases) == {
        "drkfs-1.0": "drkfs-1.1",
        "LFD": "drkfs-1.1",
        "drkfs-1.1": "drkfs-1.2",
    }
    assert kept_from({}) == {}
