"""What a newcomer meets first: every mistake gets one line that names the file and says what
to do, the base install reads what the torch install reads, and a server can bound what one
file costs."""

import csv
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh
from conftest import ROOT, without
from typer.testing import CliRunner

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import load_mesh
from drkfs_onnx.runtime.cli import app
from drkfs_onnx.runtime.scorer import MAX_FACES, Scorer

EXAMPLES = ROOT / "examples"
CHAIR, NO_LEG = EXAMPLES / "chair.obj", EXAMPLES / "chair_no_leg.obj"
FAST = ["--nets", "metric", "--width", "0.25"]


def _run(*args) -> object:
    return CliRunner().invoke(app, [*map(str, args)])


def _error_line(result) -> str:
    """The one line a failed command printed (whitespace joined, as a terminal wraps it)."""
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    return " ".join(result.output.split())


def test_an_obj_with_a_latin1_comment_scores_without_charset_detection(tmp_path):
    latin1 = tmp_path / "latin1.obj"
    latin1.write_bytes(b"# mod\xe9le\n" + CHAIR.read_bytes())
    # the base install has no charset_normalizer; trimesh needs it for non-UTF-8 text
    args = ("pair", str(latin1), str(CHAIR), "--json", *FAST)
    result = without(tmp_path, ("torch", "charset_normalizer"), "drkfs-score", *args)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["score"] == 0.0
    assert np.array_equal(load_mesh(latin1).vertices, load_mesh(CHAIR).vertices)


def test_each_first_mistake_names_the_file_and_what_to_do(tmp_path):
    not_csv = tmp_path / "big.ply"
    not_csv.write_bytes(b"ply\n\x96\x97 binary")
    corrupt = tmp_path / "reference.npz"
    corrupt.write_bytes(b"garbage")
    features = tmp_path / "chair.npz"
    assert _run("features", CHAIR, "--out", features, *FAST).exit_code == 0
    out_of_range = tmp_path / "oob.obj"
    out_of_range.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    picture = tmp_path / "p.png"
    cases = [
        (("batch", not_csv, "--out", tmp_path / "o.csv"),
         f"{not_csv}: not a CSV of mesh pairs"),
        (("pair", NO_LEG, corrupt), f"{corrupt}: not a features file"),
        (("pair", features, CHAIR), f"{features}: a features file (drkfs-score features), not a "
         "mesh: it can only be the reference (mesh B)"),
        (("explain", NO_LEG, features, "--out", picture), f"{features}: a features file"),
        (("features", CHAIR, "--out", tmp_path / "none" / "x.npz"),
         f"--out {tmp_path / 'none' / 'x.npz'}: its folder {tmp_path / 'none'} does not exist"),
        (("pair", out_of_range, CHAIR),
         f"{out_of_range}: a face uses vertex 8 (counting from 0), but the file has 3 vertices"),
    ]  # fmt: skip
    for args, message in cases:
        line = _error_line(_run(*args, *FAST))
        assert message in line, (args, line)
        assert "allow_pickle" not in line and "Errno" not in line and "codec" not in line
    assert not picture.exists()


def test_two_meshes_of_unrelated_scale_fail_joint_with_the_advice_and_score_each(real_meshes):
    cow, bunny = real_meshes / "cow.obj", real_meshes / "stanford-bunny.obj"
    line = _error_line(_run("pair", cow, bunny, *FAST))
    assert f"{cow}: nothing visible from any camera" in line
    assert "for two shapes of unknown scale or units use normalisation each" in line
    each = _run("pair", cow, bunny, "--normalize", "each", *FAST)
    assert each.exit_code == 0 and float(each.stdout) > 0


@pytest.mark.parametrize(("command", "module"), [("export", "onnx"), ("bench", "scipy")])
def test_a_drkfs_command_without_its_extra_names_the_module_and_the_extra(
    tmp_path, command, module
):
    result = without(tmp_path, (module,), "drkfs", command, "--out", str(tmp_path / "o"))
    assert result.returncode == 2, result.stderr
    assert f"error: this drkfs command needs {module}" in result.stderr
    install = "pip install 'drkfs-onnx[torch]'" if module == "onnx" else "pip install -e ./bench"
    assert install in result.stderr
    assert "Traceback" not in result.stderr


def _big_chair(folder: Path, copies: int) -> Path:
    """The chair repeated ``copies`` times side by side: one mesh of copies x 288 faces."""
    chair = load_mesh(CHAIR)
    parts = [trimesh.Trimesh(chair.vertices + [i * 2.0, 0, 0], chair.faces) for i in range(copies)]
    path = folder / "big.obj"
    trimesh.util.concatenate(parts).export(path)
    return path


def test_max_faces_refuses_a_larger_mesh_before_rendering_and_fails_only_its_row(
    tmp_path, monkeypatch
):
    big = _big_chair(tmp_path, 4)  # 1,152 faces
    rendered = []
    monkeypatch.setattr(Scorer, "views", lambda *args: rendered.append(args) or 1 / 0)
    line = _error_line(_run("pair", big, CHAIR, "--max-faces", "1000", *FAST))
    assert f"{big}: 1,152 faces, over the bound of 1,000 (--max-faces" in line
    assert rendered == []  # refused before any rendering
    monkeypatch.undo()
    pairs = tmp_path / "pairs.csv"
    pairs.write_text(f"mesh_a,mesh_b\n{big},{CHAIR}\n{NO_LEG},{CHAIR}\n")
    out = tmp_path / "scores.csv"
    assert _run("batch", pairs, "--out", out, "--max-faces", "1000", *FAST).exit_code == 1
    first, second = csv.DictReader(out.open())
    assert "over the bound of 1,000" in first["error"] and float(second["score"]) > 0
    assert f"0: no bound. [default: {MAX_FACES}]" in " ".join(_run("pair", "--help").output.split())
    unbounded = _run("features", big, "--out", tmp_path / "b.npz", "--max-faces", "0", *FAST)
    assert unbounded.exit_code == 0


def test_a_ply_or_off_header_over_the_bound_is_refused_before_the_geometry_is_read(
    tmp_path, monkeypatch
):
    chair = trimesh.load(_big_chair(tmp_path, 4), process=False)
    paths = [tmp_path / "big.ply", tmp_path / "big.off"]
    chair.export(paths[0])
    chair.export(paths[1])
    monkeypatch.setattr("drkfs_onnx.runtime.scorer.load_mesh", lambda path: 1 / 0)
    for path in paths:
        line = _error_line(_run("pair", path, CHAIR, "--max-faces", "1000", *FAST))
        assert f"{path}: 1,152 faces, over the bound of 1,000" in line


def test_a_large_mesh_says_what_it_is_doing_before_and_after(tmp_path, monkeypatch):
    monkeypatch.setattr("drkfs_onnx.runtime.scorer.PROGRESS_FACES", 1000)
    lines = []
    scorer = Scorer(PipelineConfig(descriptor_width=0.25, nets="metric"), progress=lines.append)
    scorer.score(NO_LEG, _big_chair(tmp_path, 4))
    views = PipelineConfig().views_per_mesh
    assert lines[0].endswith(f"big.obj: 1,152 faces; rendering and describing {views} views")
    assert lines[1].startswith(f"{tmp_path / 'big.obj'}: done in ")
    assert len(lines) == 2  # the 288-face mesh is not reported


def test_the_readme_examples_csv_runs_from_any_directory(tmp_path):
    out = tmp_path / "scores.csv"
    result = subprocess.run(
        ["drkfs-score", "batch", str(EXAMPLES / "pairs.csv"), "--out", str(out), *FAST],
        cwd=tmp_path, capture_output=True, text=True,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    records = list(csv.DictReader(out.open()))
    assert len(records) == 5 and all(r["error"] == "" for r in records)


def test_the_batch_command_prints_the_csvs_warnings_and_refuses_an_empty_one(tmp_path):
    pairs = tmp_path / "pairs.csv"
    pairs.write_text(f"mesh_a,mesh_b,note\n{NO_LEG},{CHAIR},x\n,\n")
    result = _run("batch", pairs, "--out", tmp_path / "o.csv", *FAST)
    assert result.exit_code == 0, result.output
    assert f"warning: {pairs}: blank rows skipped (line 3)" in result.output
    assert f"warning: {pairs}: columns ignored: note" in result.output
    pairs.write_text("")
    line = _error_line(_run("batch", pairs, "--out", tmp_path / "p.csv", *FAST))
    assert f"{pairs}: no pairs (the file is empty)" in line
