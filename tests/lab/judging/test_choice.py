"""``drkfs choose-loss``: the network study's rule for a loss, run on reconstructions a user
lists in a CSV (a target column, then one column per loss)."""

import csv
import json
import subprocess
from pathlib import Path

import pytest
import trimesh
from conftest import ROOT
from typer.testing import CliRunner

from drkfs_lab.judging.choice import JUDGE_CONFIG, judge_and_choose, read_reconstructions
from drkfs_lab.judging.judges import VISUAL, Judge
from drkfs_lab.judging.rule import choose
from drkfs_onnx.cli import app
from drkfs_onnx.synthetic.examples import write_examples

QUICK_JUDGE = JUDGE_CONFIG.replace(num_views=2, image_size=64)


@pytest.fixture(scope="module")
def meshes(tmp_path_factory) -> Path:
    """The example chairs, and the reference chair 1.5 x larger about its centre."""
    folder = tmp_path_factory.mktemp("reconstructions")
    write_examples(folder)
    chair = trimesh.load(folder / "chair.obj", process=False)
    centre = chair.bounds.mean(0)
    larger = (chair.vertices - centre) * 1.5 + centre
    trimesh.Trimesh(larger, chair.faces, process=False).export(folder / "larger.ply")
    return folder


@pytest.fixture(scope="module")
def quick_judge():
    judge = Judge(QUICK_JUDGE, unseen_views=2, lfd=False)
    yield judge
    judge.close()


def write_csv(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(
    ("header", "reason"),
    [
        ("pred,chamfer,ours", "must name a 'target' column"),
        ("target,chamfer", "at least one candidate"),
        ("target,chamfer,chamfer", "each once"),
        ("target,chamfer,,ours", "each once"),
    ],
)
def test_a_header_that_does_not_list_a_target_and_two_losses_is_refused_naming_the_file(
    tmp_path, header, reason
):
    path = write_csv(tmp_path / "val.csv", [header, "a.obj,b.obj,c.obj"])
    with pytest.raises(ValueError, match=reason) as error:
        read_reconstructions(path)
    assert str(path) in str(error.value)


def test_the_baseline_is_the_first_loss_unless_named_and_must_be_a_column(tmp_path):
    path = write_csv(tmp_path / "val.csv", ["target,chamfer,ours,theirs", "t.obj,c.obj,o.obj"])
    listed = read_reconstructions(path)
    assert (listed.baseline, listed.candidates) == ("chamfer", ["ours", "theirs"])
    assert listed.rows[0].reconstructions == {"chamfer": "c.obj", "ours": "o.obj", "theirs": ""}
    named = read_reconstructions(path, "ours")
    assert (named.baseline, named.candidates) == ("ours", ["chamfer", "theirs"])
    with pytest.raises(ValueError, match="no column named 'mse'"):
        read_reconstructions(path, "mse")


def test_the_loss_that_beats_the_baseline_most_often_is_chosen_judged_in_the_targets_frame(
    tmp_path, meshes, quick_judge
):
    """The larger chair would equal the target in a frame of its own; in the target's frame it
    loses to the exact copy, which wins every visual cell. A row with a missing file is skipped
    with its reason, and the other row still counts."""
    m = meshes
    path = write_csv(
        tmp_path / "val.csv",
        [
            "target,chamfer,larger,copy",
            f"{m / 'chair.obj'},{m / 'chair_no_leg.obj'},{m / 'larger.ply'},{m / 'chair.obj'}",
            f"{m / 'chair.obj'},{m / 'absent.obj'},{m / 'larger.ply'},{m / 'chair.obj'}",
        ],
    )
    result = judge_and_choose(read_reconstructions(path), quick_judge, lambda _: None)
    assert result["chosen"] == "copy"
    assert result["shares"]["copy"] == {"wins": 4, "cells": 4, "share": 1.0}  # VISUAL less LFD
    assert result["shares"]["larger"]["wins"] < 4
    assert result["chamfer_l1_ratio"]["copy"] == 0.0
    assert list(result["table"]) == [str(m / "chair.obj")]
    assert result["skipped"] == [{"line": 3, "reason": f"{m / 'absent.obj'}: no such file"}]
    # against an exact baseline no ratio can be formed, and no candidate wins a cell
    exact = choose(result["table"], ["chamfer", "larger"], "copy")
    assert exact["chamfer_l1_ratio"] == {"chamfer": None, "larger": None}
    assert all(won["wins"] == 0 for won in exact["shares"].values())
    assert set(result["table"][str(m / "chair.obj")]["copy"]) >= set(VISUAL)


def test_a_file_where_no_row_can_be_judged_is_an_error(tmp_path, meshes, quick_judge):
    path = write_csv(
        tmp_path / "val.csv",
        ["target,chamfer,ours", f"{meshes / 'chair.obj'},{meshes / 'chair.obj'},"],
    )
    with pytest.raises(ValueError, match="no row could be judged"):
        judge_and_choose(read_reconstructions(path), quick_judge, lambda _: None)


def test_the_command_prints_each_candidates_cells_and_the_choice_and_writes_json(tmp_path, meshes):
    m = meshes
    path = write_csv(
        tmp_path / "val.csv",
        [
            "target,chamfer,no back,retessellated",
            f"{m / 'chair.obj'},{m / 'chair_no_leg.obj'},{m / 'chair_no_back.obj'},"
            f"{m / 'chair_retessellated.obj'}",
        ],
    )
    out = tmp_path / "choice.json"
    command = ["choose-loss", str(path), "--no-lfd", "--out", str(out)]
    result = CliRunner().invoke(app, command)
    assert result.exit_code == 0, result.output
    assert "chosen: retessellated (1 shapes; LFD not asked for)" in result.output
    assert "retessellated beats chamfer on 4/4 visual cells" in result.output
    assert json.loads(out.read_text())["chosen"] == "retessellated"


def test_the_command_refuses_a_bad_file_before_judging(tmp_path):
    result = CliRunner().invoke(app, ["choose-loss", str(tmp_path / "val.csv")])
    assert result.exit_code == 2
    assert "no such reconstructions file" in result.output


class FailingLightField:
    """A judge whose LFD program fails on one mesh file and judges the others alike."""

    lfd_note, config = "LFD by a stub", QUICK_JUDGE

    def __init__(self, failing_faces: int):
        self.failing_faces = failing_faces

    def prepare(self, verts, faces):
        if len(faces) == self.failing_faces:
            raise subprocess.CalledProcessError(139, ["./3DAlignment", "mesh3"])
        return len(faces)

    def compare(self, prediction, target):
        return {"Chamfer-L1": 1.0, **{metric: float(prediction) for metric in VISUAL}}


def test_a_line_whose_mesh_lfd_cannot_describe_is_skipped_and_the_others_still_count(
    tmp_path, meshes
):
    m = meshes
    retessellated = trimesh.load(m / "chair_retessellated.obj", process=False)
    path = write_csv(
        tmp_path / "val.csv",
        [
            "target,chamfer,ours",
            f"{m / 'chair.obj'},{m / 'chair_retessellated.obj'},{m / 'chair_no_leg.obj'}",
            f"{m / 'chair_no_back.obj'},{m / 'chair.obj'},{m / 'chair_no_leg.obj'}",
        ],
    )
    judge = FailingLightField(len(retessellated.faces))
    result = judge_and_choose(read_reconstructions(path), judge, lambda _: None)
    assert list(result["table"]) == [str(m / "chair_no_back.obj")]
    assert result["skipped"][0]["line"] == 2
    assert result["skipped"][0]["reason"].startswith("LFD failed (Command '['./3DAlignment'")


@pytest.mark.slow  # a study's end to end check
def test_the_committed_study_reconstructions_judge_as_the_study_judged_them(tmp_path):
    """One test shape of bench/fit-network: its saved target and reconstructions, listed in a
    CSV and judged by the study's judge (LFD aside), give the study's committed values."""
    study_folder = ROOT / "bench" / "fit-network"
    study = json.loads((study_folder / "results.json").read_text())
    shape, losses = "table 4500", study["plan"]["losses"]
    saved = study["meshes"][shape]
    files = [str(study_folder / saved[name]) for name in ("target", *losses)]
    path = tmp_path / "val.csv"
    with open(path, "w", newline="") as handle:  # the loss names hold commas
        csv.writer(handle).writerows([["target", *losses], files])
    judge = Judge(JUDGE_CONFIG, lfd=False)
    try:
        result = judge_and_choose(read_reconstructions(path), judge, lambda _: None)
    finally:
        judge.close()
    (judged,) = result["table"].values()
    for name in losses:
        committed = {m: v for m, v in study["table"][shape][name].items() if m != "LFD"}
        assert judged[name].pop("LFD") is None  # judged without LFD here
        assert judged[name] == pytest.approx(committed, rel=1e-4), name
