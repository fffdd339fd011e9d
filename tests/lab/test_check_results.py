"""bench/check_results.py: the committed results recompute from their own rows, and a number
changed in one of them is caught."""

import json
import shutil
import subprocess
import sys

import pytest
from conftest import ROOT

from drkfs_lab import check_results


@pytest.mark.slow  # .ci/run runs the script itself too; 17 s of the default run's 5 minutes
def test_the_script_runs_every_check_on_the_committed_results():
    script = ROOT / "bench" / "check_results.py"
    result = subprocess.run([sys.executable, script], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    lines = result.stdout.splitlines()
    assert len(lines) == len(check_results.CHECKS)
    assert all(line.startswith("ok ") for line in lines), result.stdout


def test_a_share_that_does_not_follow_from_its_table_fails_its_check(tmp_path):
    study = tmp_path / "bench" / "fit-network"
    study.mkdir(parents=True)
    results = json.loads((ROOT / "bench/fit-network/results.json").read_text())
    results["summary"]["share_beats_chamfer"] = 0.99
    (study / "results.json").write_text(json.dumps(results))
    with pytest.raises(AssertionError):
        check_results.network_studies_shares_recompute(tmp_path)
    shutil.copy(ROOT / "bench/fit-network/results.json", study / "results.json")
    check_results.network_studies_shares_recompute(tmp_path)  # the committed file passes


def test_a_readme_that_drops_a_version_or_retypes_a_batch_figure_fails_its_check(tmp_path):
    shutil.copytree(ROOT / "bench" / "results", tmp_path / "bench" / "results")
    readme = (ROOT / "README.md").read_text()
    check_results.readme_versions_table_names_every_version(ROOT)
    paper = next(line for line in readme.splitlines() if line.startswith("| `drkfs-paper` |"))
    (tmp_path / "README.md").write_text(readme.replace(paper + "\n", ""))
    with pytest.raises(AssertionError, match="versions"):
        check_results.readme_versions_table_names_every_version(tmp_path)
    swapped = paper.replace("PipelineConfig.paper()", "PipelineConfig.structure()")
    (tmp_path / "README.md").write_text(readme.replace(paper, swapped))
    with pytest.raises(AssertionError, match="is not drkfs-paper"):
        check_results.readme_versions_table_names_every_version(tmp_path)
    check_results.readme_batch_table_is_torch_batchs(ROOT)
    (tmp_path / "README.md").write_text(readme.replace("| 0.14 s |", "| 0.15 s |"))
    with pytest.raises(AssertionError, match="batch table"):
        check_results.readme_batch_table_is_torch_batchs(tmp_path)


def test_a_readme_that_retypes_a_figure_of_the_loss_study_fails_its_check(tmp_path):
    shutil.copytree(ROOT / "bench" / "single_view", tmp_path / "bench" / "single_view",
                    ignore=shutil.ignore_patterns("networks*", "data"))  # fmt: skip
    readme = (ROOT / "README.md").read_text()
    check_results.readme_as_a_loss_is_the_single_view_studys(ROOT)
    curve = json.loads((ROOT / "bench/single_view/curve.json").read_text())["points"]
    lfd = f"{curve['2000']['means']['DR-KFS']['LFD']:,.0f}"
    (tmp_path / "README.md").write_text(readme.replace(f"(LFD {lfd}", "(LFD 1,234"))
    with pytest.raises(AssertionError, match="As a loss"):
        check_results.readme_as_a_loss_is_the_single_view_studys(tmp_path)


def test_an_architecture_page_with_a_stale_setting_fails_its_check(tmp_path):
    check_results.architecture_numbers_are_the_configs(ROOT)
    page = (ROOT / "docs" / "architecture.md").read_text()
    (tmp_path / "docs").mkdir()
    for stale in ("t = 0.1", "t = 0.055"):  # another value, or one that starts as the true one
        (tmp_path / "docs" / "architecture.md").write_text(page.replace("t = 0.05", stale))
        with pytest.raises(AssertionError, match="architecture"):
            check_results.architecture_numbers_are_the_configs(tmp_path)


def test_a_committed_score_that_its_version_no_longer_gives_fails_the_sample_check(tmp_path):
    """drkfs-1.0 is held to the lever runs that scored it, not to the benchmark alone."""
    shutil.copytree(ROOT / "bench" / "results", tmp_path / "bench" / "results")
    assert "drkfs-1.0 in" in check_results.each_version_scores_as_its_committed_runs(tmp_path)
    path = tmp_path / "bench" / "results" / "real_levers_winding.json"
    run = json.loads(path.read_text())
    first = next(iter(run["levers"]))  # the run's default: drkfs-1.0
    key = next(k for k in json.loads((ROOT / "bench/results/version_sample.json").read_text())[
        "versions"]["drkfs-1.0"] if k in run["values"][first])  # fmt: skip
    run["values"][first][key] *= 1.001
    path.write_text(json.dumps(run))
    with pytest.raises(AssertionError, match=f"drkfs-1.0 {key}.*real_levers_winding"):
        check_results.each_version_scores_as_its_committed_runs(tmp_path)
