"""``drkfs-score``: the server command runs without torch, scores pairs and resumable batches,
and names what went wrong."""

import csv
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh
from conftest import ROOT, without
from typer.testing import CliRunner

from drkfs_onnx import PipelineConfig, load_mesh
from drkfs_onnx.contract.model_files import features_file
from drkfs_onnx.contract.versions import LATEST, metric_config
from drkfs_onnx.runtime.cli import app
from drkfs_onnx.runtime.output_lock import lock_path

EXAMPLES = ROOT / "examples"
CHAIR = EXAMPLES / "chair.obj"
NO_LEG = EXAMPLES / "chair_no_leg.obj"
NO_BACK = EXAMPLES / "chair_no_back.obj"
FAST = ["--nets", "metric", "--width", "0.25"]  # the smallest shipped nets keep these tests quick
PAPER_FAST = ["--width", "0.25"]  # the paper preset's own nets (256 px) at that width


def _run(*args: str):
    return CliRunner().invoke(app, [*map(str, args)])


def test_drkfs_score_runs_where_torch_and_matplotlib_cannot_be_imported(tmp_path):
    pair = ("pair", str(NO_LEG), str(CHAIR), "--json", *FAST)
    result = without(tmp_path, ("torch", "matplotlib"), "drkfs-score", *pair)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["score"] > 0
    assert PipelineConfig.from_dict(report["config"]) == PipelineConfig(
        nets="metric", descriptor_width=0.25
    )
    assert report["model_version"].startswith("drkfs-onnx")


def test_precomputed_reference_gives_the_same_score(tmp_path):
    assert _run("features", CHAIR, "--out", tmp_path / "chair.npz", *FAST).exit_code == 0
    direct = _run("pair", NO_LEG, CHAIR, *FAST)
    cached = _run("pair", NO_LEG, tmp_path / "chair.npz", *FAST)
    assert direct.exit_code == cached.exit_code == 0
    assert float(direct.stdout) == float(cached.stdout) > 0


def test_openings_show_dark_by_default_and_two_sided_lights_them_as_before(tmp_path):
    """By default faces seen from behind lie in the shell's shadow, pushed behind the outlines:
    the chair's seat cut open (its inside showing) scores otherwise than under --two-sided, a
    whole chair the same, and a reference described under one light is refused under the
    other, with the flag that fits it named."""
    chair = load_mesh(CHAIR)
    seat = chair.vertices[chair.faces].mean(1)
    top = np.argmax(seat[:, 1] * (np.abs(seat[:, 0]) < 0.1) * (np.abs(seat[:, 2]) < 0.1))
    cut = tmp_path / "cut.obj"
    cut.write_text(
        "".join(f"v {x} {y} {z}\n" for x, y, z in chair.vertices)
        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in np.delete(chair.faces, top, 0))
    )
    dark = _run("pair", cut, CHAIR, "--json", *FAST)
    lit = _run("pair", cut, CHAIR, "--json", "--two-sided", *FAST)
    assert lit.exit_code == dark.exit_code == 0
    config = json.loads(dark.stdout)["config"]
    assert (config["back_light"], config["back_push"]) == (0.0, 0.05)
    assert json.loads(lit.stdout)["config"]["back_light"] == 1.0
    assert json.loads(dark.stdout)["score"] != json.loads(lit.stdout)["score"]
    assert float(_run("pair", NO_LEG, CHAIR, "--two-sided", *FAST).stdout) == float(
        _run("pair", NO_LEG, CHAIR, *FAST).stdout
    )
    described = _run("features", CHAIR, "--out", tmp_path / "lit.npz", "--two-sided", *FAST)
    assert described.exit_code == 0
    refused = _run("pair", NO_LEG, tmp_path / "lit.npz", *FAST)
    assert refused.exit_code == 2 and "back_light" in refused.output
    assert "--two-sided" in refused.output


def test_a_features_file_remembers_its_normalisation_and_refuses_another(tmp_path):
    reference = tmp_path / "chair.npz"
    assert _run("features", CHAIR, "--out", reference, *FAST).exit_code == 0  # joint
    refused = _run("pair", CHAIR, reference, "--normalize", "none", *FAST)
    assert refused.exit_code != 0
    assert f"{reference}: features made with normalisation 'joint'" in refused.output
    assert "--normalize none" in refused.output
    assert float(_run("pair", CHAIR, reference, *FAST).stdout) == 0.0  # itself, as made
    # an old-format file is named and refused, not misread
    old = tmp_path / "old.npz"
    np.savez(old, format="drkfs-features-3")
    result = _run("pair", CHAIR, old, *FAST)
    assert result.exit_code != 0 and f"{old}: not a drkfs-score features file" in result.output


def test_a_broken_reference_file_is_its_rows_error_and_the_batch_goes_on(tmp_path):
    good = tmp_path / "chair.npz"
    assert _run("features", CHAIR, "--out", good, *FAST).exit_code == 0
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    corrupt = tmp_path / "corrupt.npz"
    corrupt.write_bytes(b"PK\x03\x04 not a zip at all")
    missing = tmp_path / "missing.npz"
    broken = (truncated, empty, corrupt, missing, tmp_path)  # the folder: not a file either
    pairs = tmp_path / "pairs.csv"
    rows = [f"{NO_LEG},{path}" for path in (*broken, good)]
    pairs.write_text("mesh_a,mesh_b\n" + "\n".join(rows) + "\n")
    out = tmp_path / "scores.csv"
    result = _run("batch", pairs, "--out", out, *FAST)
    assert result.exit_code == 1  # rows failed; the run itself did not crash
    records = list(csv.DictReader(out.open()))
    assert len(records) == len(broken) + 1
    for path, record in zip(broken, records[:-1], strict=True):
        assert record["error"].startswith(f"{path}:") and record["score"] == ""
    assert float(records[-1]["score"]) > 0  # the good row after five bad ones
    assert "Aborted" not in _run("pair", NO_LEG, empty, *FAST).output


def test_a_mesh_no_camera_sees_is_an_error_not_a_perfect_score(tmp_path):
    far = tmp_path / "far_triangle.obj"
    far.write_text("v 1e6 1e6 1e6\nv 1000001 1e6 1e6\nv 1e6 1000001 1e6\nf 1 2 3\n")
    result = _run("pair", far, CHAIR, "--normalize", "joint", *FAST)
    assert result.exit_code != 0
    assert "far_triangle.obj: nothing visible from any camera" in result.output
    assert "reference's frame" in result.output
    # its own frame makes it visible: a real (non-zero) score, not an error
    alone = _run("pair", far, CHAIR, "--normalize", "each", *FAST)
    assert alone.exit_code == 0 and float(alone.stdout) > 0
    pairs = tmp_path / "pairs.csv"
    pairs.write_text(f"mesh_a,mesh_b\n{far},{CHAIR}\n{NO_LEG},{CHAIR}\n")
    out = tmp_path / "scores.csv"
    _run("batch", pairs, "--out", out, *FAST)
    rows = list(csv.DictReader(out.open()))
    assert "nothing visible" in rows[0]["error"] and rows[0]["score"] == ""
    assert float(rows[1]["score"]) > 0  # the bad row costs no other row its result


def test_a_model_for_another_config_is_refused(tmp_path):
    asked = PipelineConfig().descriptor_width
    other = PipelineConfig(nets="metric", descriptor_width=0.5 if asked != 0.5 else 1.0)
    shipped = ROOT / "models" / features_file(other)
    result = _run("pair", NO_LEG, CHAIR, "--model", shipped)
    assert result.exit_code == 2
    assert f"descriptor_width {other.descriptor_width!r} (asked {asked!r})" in result.output


def _records(path: Path) -> dict[int, dict]:
    return {int(r["row"]): r for r in _record_list(path)}


def _record_list(path: Path) -> list[dict]:
    """OUT's records in the file's order."""
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_batch_records_errors_goes_on_and_resumes_after_a_kill(tmp_path):
    pairs = tmp_path / "pairs.csv"
    missing = tmp_path / "missing.obj"
    pairs.write_text(f"mesh_a,mesh_b\n{NO_LEG},{CHAIR}\n{missing},{CHAIR}\n{NO_BACK},{CHAIR}\n")
    out = tmp_path / "scores.csv"

    first = _run("batch", pairs, "--out", out, *FAST)
    assert first.exit_code == 1
    assert "2 scored, 1 failed" in first.output and "failed rows: 1" in first.output
    records = _records(out)
    assert float(records[0]["score"]) > 0 and float(records[2]["score"]) > 0
    assert records[1]["score"] == "" and str(missing) in records[1]["error"]

    # A kill while writing row 2 leaves a cut line; the rerun drops it and scores row 2 again.
    lines = out.read_text().splitlines(keepends=True)
    out.write_text("".join(lines[:3]) + lines[3][:10])
    second = _run("batch", pairs, "--out", out, *FAST)
    assert second.exit_code == 1
    assert "1 scored, 1 failed, 1 already done" in second.output
    assert _records(out)[2]["score"] == records[2]["score"]


def test_batch_resume_is_keyed_by_the_pair_and_the_settings_not_the_row(tmp_path):
    pairs, out = tmp_path / "pairs.csv", tmp_path / "scores.csv"
    missing = tmp_path / "later.obj"
    pairs.write_text(f"mesh_a,mesh_b\n{NO_LEG},{CHAIR}\n{missing},{CHAIR}\n")
    assert _run("batch", pairs, "--out", out, *FAST).exit_code == 1
    # a pair inserted at the top is scored; the scored one is found though its row moved; the
    # failed one is tried again (its mesh now exists) and replaces its old record
    shutil.copy(NO_BACK, missing)
    pairs.write_text(f"mesh_a,mesh_b\n{CHAIR},{CHAIR}\n{NO_LEG},{CHAIR}\n{missing},{CHAIR}\n")
    rerun = _run("batch", pairs, "--out", out, *FAST)
    assert rerun.exit_code == 0, rerun.output
    assert "2 scored, 0 failed, 1 already done" in rerun.output
    records = list(csv.DictReader(out.open()))
    assert sorted((r["mesh_a"], r["error"]) for r in records) == sorted(
        [(str(NO_LEG), ""), (str(CHAIR), ""), (str(missing), "")]
    )  # one record per pair: no duplicates, no stale error
    done = _run("batch", pairs, "--out", out, *FAST)
    assert done.exit_code == 0 and "0 scored, 0 failed, 3 already done" in done.output
    assert "scoring 0 pairs" in done.output
    assert {r["model_version"] for r in records} != {""}
    # other settings are other results: nothing is "already done"
    wider = _run("batch", pairs, "--out", out, "--width", "0.5")
    assert "3 scored, 0 failed, 0 already done" in wider.output
    settings = {r["settings"] for r in csv.DictReader(out.open())}
    assert len(settings) == 2


def test_batch_records_the_metric_version_and_resumes_a_file_from_before_it_named_one(tmp_path):
    pairs, out = tmp_path / "pairs.csv", tmp_path / "scores.csv"
    pairs.write_text(f"mesh_a,mesh_b\n{NO_LEG},{CHAIR}\n")
    assert _run("batch", pairs, "--out", out).exit_code == 0
    (record,) = _record_list(out)
    assert record["metric"] == LATEST
    unnamed = [{k: v for k, v in record.items() if k != "metric"}]
    with open(out, "w", newline="") as handle:  # as a results file without the column
        writer = csv.DictWriter(handle, list(unnamed[0]))
        writer.writeheader()
        writer.writerows(unnamed)
    again = _run("batch", pairs, "--out", out)
    assert "0 scored, 0 failed, 1 already done" in again.output
    assert _record_list(out) == [record]


def test_batch_names_meshes_as_its_csv_wrote_them_from_any_folder(tmp_path, monkeypatch):
    folder = tmp_path / "data"
    folder.mkdir()
    shutil.copy(CHAIR, folder / "chair.obj")
    (folder / "pairs.csv").write_text("mesh_a,mesh_b\nchair.obj,chair.obj\n~/no.obj,chair.obj\n")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.chdir(tmp_path)
    result = subprocess.run(
        ["drkfs-score", "batch", "data/pairs.csv", "--out", "scores.csv", *FAST],
        capture_output=True, text=True,
    )  # fmt: skip
    assert result.returncode == 1 and result.stdout == ""  # the progress bar is on stderr
    rows = _record_list(tmp_path / "scores.csv")
    assert [(r["mesh_a"], r["mesh_b"]) for r in rows] == [
        ("chair.obj", "chair.obj"), ("~/no.obj", "chair.obj")
    ]  # fmt: skip
    assert f"{tmp_path / 'home' / 'no.obj'}: no such file" in rows[1]["error"]


def test_batch_refuses_to_write_over_its_input_or_an_old_results_file(tmp_path):
    pairs = tmp_path / "pairs.csv"
    pairs.write_text(f"mesh_a,mesh_b\n{CHAIR},{CHAIR}\n")
    result = _run("batch", pairs, "--out", pairs, *FAST)
    assert result.exit_code == 2 and "is the pairs file" in result.output
    assert pairs.read_text() == f"mesh_a,mesh_b\n{CHAIR},{CHAIR}\n"
    old = tmp_path / "old.csv"
    old.write_text("row,mesh_a,mesh_b,score,seconds,error\n0,a,b,0.1,0.2,\n")
    result = _run("batch", pairs, "--out", old, *FAST)
    assert result.exit_code == 2 and f"{old}: not a results file" in result.output


def test_a_batch_without_failures_exits_zero(tmp_path):
    pairs = tmp_path / "pairs.csv"
    pairs.write_text(f"{CHAIR},{CHAIR}\n")  # no header: the first two columns
    result = _run("batch", pairs, "--out", tmp_path / "scores.csv", *FAST)
    assert result.exit_code == 0, result.output
    assert float(_records(tmp_path / "scores.csv")[0]["score"]) == 0.0


def test_two_batches_on_one_out_at_once_score_each_pair_once(tmp_path):
    meshes = []
    for i in range(24):  # 48 distinct pairs
        meshes.append(tmp_path / f"leg_{i}.obj")
        shutil.copy(NO_LEG, meshes[-1])
    pairs, out = tmp_path / "pairs.csv", tmp_path / "scores.csv"
    rows = [f"{m},{reference}" for m in meshes for reference in (CHAIR, NO_BACK)]
    pairs.write_text("mesh_a,mesh_b\n" + "\n".join(rows) + "\n")
    script = shutil.which("drkfs-score")
    command = [script, "batch", str(pairs), "--out", str(out), "--threads", "1", *FAST]
    runs = [subprocess.Popen(command, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    errors = [run.communicate()[1] for run in runs]
    records = list(csv.DictReader(out.open()))
    assert len(records) == 48 and all(r["error"] == "" for r in records)
    assert len({(r["mesh_a"], r["mesh_b"]) for r in records}) == 48
    # the later run either found the file locked (naming the holder once it has written its
    # record, "another process" in the instant before) or every pair already done
    assert any("is being written by" in e or "0 scored, 0 failed, 48 already done" in e
               for e in errors), errors  # fmt: skip
    assert not lock_path(out).exists()


def test_a_batch_refuses_a_locked_out_naming_the_holder_and_takes_it_after_a_crash(tmp_path):
    pairs, out = tmp_path / "pairs.csv", tmp_path / "scores.csv"
    pairs.write_text(f"mesh_a,mesh_b\n{NO_LEG},{CHAIR}\n")
    holder = subprocess.Popen(
        ["python", "-c", "import sys, time; from drkfs_onnx.runtime.output_lock import "
         "output_lock; from pathlib import Path\nwith output_lock(Path(sys.argv[1])):\n"
         "    print('held', flush=True); time.sleep(60)", str(out)],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout.readline().strip() == "held"
        refused = _run("batch", pairs, "--out", out, *FAST)
        assert refused.exit_code == 2
        assert f"{out} is being written by pid {holder.pid} on" in refused.output
        assert len(refused.output.strip().splitlines()) == 1 and not out.exists()
    finally:
        holder.kill()  # a crash: the kernel releases the lock, the lock file stays
        holder.wait()
    assert lock_path(out).exists()
    taken = _run("batch", pairs, "--out", out, *FAST)
    assert taken.exit_code == 0, taken.output
    assert len(_records(out)) == 1 and not lock_path(out).exists()


def _write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    """An OBJ with every float64 digit (trimesh's exporter keeps 8 decimals, which rounds a
    chair of size 1e-8 to a point)."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
    lines += [f"f {a} {b} {c}" for a, b, c in (faces + 1).tolist()]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("scale", [1e-6, 1e-8, 1e-300, 1e300])
def test_a_mesh_in_other_units_scores_zero_against_itself_under_each(tmp_path, scale):
    chair = load_mesh(CHAIR)
    scaled = _write_obj(tmp_path / "scaled.obj", chair.vertices * scale, chair.faces)
    result = _run("pair", scaled, CHAIR, "--normalize", "each", *FAST)
    assert result.exit_code == 0, result.output
    assert float(result.stdout) == 0.0


def test_symmetric_is_order_free_under_each_but_not_under_joint():
    def swapped(normalize: str) -> tuple[float, float]:
        args = ("--symmetric", "--normalize", normalize, *FAST)
        return float(_run("pair", NO_BACK, CHAIR, *args).stdout), float(
            _run("pair", CHAIR, NO_BACK, *args).stdout
        )

    forward, backward = swapped("each")
    assert forward == pytest.approx(backward, rel=1e-6)
    forward, backward = swapped("joint")  # the frame is the second mesh's
    assert forward != pytest.approx(backward, rel=1e-3)


@pytest.mark.parametrize(
    "option",
    ["--symmetric", "--threads=1", "--normalize=each", "--preset=paper", "--reduction=mean",
     "--matching=window", "--window=2", "--direction=backward", "--solid-weight=0"],
)  # fmt: skip
def test_options_are_accepted_and_a_mesh_scores_zero_against_itself(option):
    result = _run("pair", CHAIR, CHAIR, option, *(PAPER_FAST if "paper" in option else FAST))
    assert result.exit_code == 0, result.output
    assert float(result.stdout) == 0.0


@pytest.mark.parametrize(
    ("options", "message"),
    [(["--reduction", "max"], "unknown reduction 'max'"),
     (["--preset", "fast"], "unknown preset 'fast'"),
     (["--symmetric", "--direction", "forward"], "--symmetric searches both directions"),
     (["--preset", "paper", "--window", "1"], "the paper preset matches globally: add "
      "--matching window"),
     (["--matching", "global", "--window", "2"], "--matching global has none: drop --window"),
     (["--metric", "drkfs-0.9"], "unknown metric 'drkfs-0.9'; use one of drkfs-1.0"),
     (["--metric", "drkfs-1.0", "--preset", "paper"], "both name a metric: give one"),
     (["--no-symmetric"], "No such option: --no-symmetric"),
     (["--nets", "mystery"], "unknown nets 'mystery'")],
)  # fmt: skip
def test_bad_match_options_are_named(options, message):
    result = _run("pair", NO_LEG, CHAIR, *FAST, *options)  # the options last: they win
    assert result.exit_code == 2
    assert message in result.output


def test_a_width_the_presets_nets_lack_is_refused_with_the_graphs_there_are():
    result = _run("pair", NO_LEG, CHAIR, "--width", "0.25")  # the tolerant nets come at 0.5
    assert result.exit_code == 2 and "Traceback" not in result.output
    said = " ".join(result.output.split())
    size = PipelineConfig().image_size
    assert f"no features_tolerant_w0.25_{size}px.onnx" in said
    assert "the tolerant nets come at width 0.5 (128, 144 px)" in said and "--nets" in said


def test_symmetric_changes_the_paper_preset_alone_and_features_help_speaks_of_one_mesh():
    scores = {
        preset: [float(_run("pair", NO_LEG, CHAIR, "--preset", preset, *extra, *fast).stdout)
                 for extra in ((), ("--symmetric",))]
        for preset, fast in (("default", FAST), ("paper", PAPER_FAST))
    }  # fmt: skip
    assert scores["default"][0] == scores["default"][1]  # it already searches both ways
    assert scores["paper"][0] != scores["paper"][1]
    boxed = _run("features", "--help").output  # rich draws the options in a box
    help_text = " ".join(re.sub("[│╭╮╰╯─]", " ", boxed).split())
    assert "the two meshes" not in help_text and "this reference will be scored in" in help_text


def test_solid_weight_sets_the_views_part_and_zero_leaves_the_descriptors_alone():
    scores = {
        weight: json.loads(_run("pair", NO_LEG, CHAIR, *FAST, "--json", "--solid-weight",
                                weight).stdout)
        for weight in ("0", "0.5", "1")
    }  # fmt: skip
    assert [scores[w]["config"]["solid_weight"] for w in ("0", "0.5", "1")] == [0.0, 0.5, 1.0]
    no_views, half, whole = (scores[w]["score"] for w in ("0", "0.5", "1"))
    assert whole - half == pytest.approx(half - no_views, rel=1e-6) and half > no_views
    assert _run("pair", NO_LEG, CHAIR, "--solid-weight", "-1").exit_code == 2


def test_json_report_carries_the_config_it_scored_with():
    result = _run("pair", NO_LEG, CHAIR, "--json", "--preset", "paper", *PAPER_FAST)
    config = PipelineConfig.from_dict(json.loads(result.stdout)["config"])
    assert config == PipelineConfig.paper(descriptor_width=0.25)


def test_a_score_names_its_metric_version_and_an_older_one_is_reproduced_by_name():
    latest = json.loads(_run("pair", NO_LEG, CHAIR, "--json").stdout)
    assert latest["metric"] == LATEST
    paper = json.loads(_run("pair", NO_LEG, CHAIR, "--json", "--metric", "drkfs-paper").stdout)
    assert paper["metric"] == "drkfs-paper"
    assert PipelineConfig.from_dict(paper["config"]) == metric_config("drkfs-paper")
    preset = json.loads(_run("pair", NO_LEG, CHAIR, "--json", "--preset", "paper").stdout)
    assert paper["score"] == preset["score"]
    overridden = json.loads(_run("pair", NO_LEG, CHAIR, "--json", *FAST).stdout)
    assert overridden["metric"] == "custom"  # a setting changed: no named version


def test_a_features_file_for_another_preset_is_refused_naming_the_settings(tmp_path):
    assert _run("features", CHAIR, "--out", tmp_path / "chair.npz").exit_code == 0
    result = _run("pair", NO_LEG, tmp_path / "chair.npz", "--preset", "paper")
    assert result.exit_code == 2
    said = " ".join(result.output.split())
    assert f"described for {LATEST}'s views, scoring asks drkfs-paper's" in said
    default = PipelineConfig()
    assert f"num_views {default.num_views} (asked 25)" in result.output
    assert f"image_size {default.image_size} (asked 256)" in result.output


def test_bad_command_lines_get_one_clear_error_line_each(tmp_path):
    folder = tmp_path / "folder"
    folder.mkdir()
    not_onnx = tmp_path / "model.onnx"
    not_onnx.write_text("not a graph")
    good = _csv(tmp_path, f"{CHAIR},{CHAIR}", "good.csv")
    cases = [
        (("pair", folder, CHAIR), f"{folder}: a folder, not a mesh file"),
        (("pair", NO_LEG, CHAIR, "--model", not_onnx), f"{not_onnx}: not a readable ONNX model"),
        (("pair", NO_LEG, CHAIR, "--model", tmp_path / "none.onnx"), "none.onnx: no such model"),
        (("pair", NO_LEG, CHAIR, "--threads", "-1"), "error: --threads must be at least 1, not -1"),
        (("pair", NO_LEG, CHAIR, "--solid-weight", "-0.5"),
         "error: --solid-weight must be at least 0, not -0.5"),
        (("pair", NO_LEG, CHAIR, "--solid-weight", "nan"),
         "error: --solid-weight must be at least 0, not nan"),
        (("batch", good, "--out", tmp_path / "o.csv", "--workers", "0"),
         "error: --workers must be at least 1, not 0"),
        (("batch", tmp_path / "none.csv", "--out", tmp_path / "o.csv"), "no such pairs file"),
        (("batch", folder, "--out", tmp_path / "o.csv"), "no such pairs file (a folder)"),
        (("batch", good, "--out", folder), f"--out {folder}: is a folder; give a file name"),
        (("batch", good, "--out", tmp_path / "no" / "o.csv"),
         f"its folder {tmp_path / 'no'} does not exist"),
        (("batch", _csv(tmp_path, f"pred,gt\n{CHAIR},{CHAIR}", "named.csv"), "--out",
          tmp_path / "o.csv"), "the first row pred,gt is neither the header mesh_a,mesh_b"),
    ]  # fmt: skip
    for args, message in cases:
        result = _run(*args, *FAST)
        assert result.exit_code == 2, (args, result.output)
        assert message in " ".join(result.output.split()), (args, result.output)
        assert result.output.count("\n") == 1, (args, result.output)
    at_the_bounds = ("--threads", "1", "--top", "1", "--solid-weight", "0")
    explained = _run("explain", NO_LEG, CHAIR, "--out", tmp_path / "p.png", *at_the_bounds, *FAST)
    assert explained.exit_code == 0, explained.output


def _csv(folder: Path, text: str, name: str = "pairs.csv") -> Path:
    path = folder / name
    path.write_text(text + "\n")
    return path


def test_a_one_column_row_is_its_rows_error(tmp_path):
    pairs = _csv(tmp_path, f"mesh_a,mesh_b\n{NO_LEG}\n{NO_LEG},{CHAIR}")
    out = tmp_path / "scores.csv"
    assert _run("batch", pairs, "--out", out, *FAST).exit_code == 1
    first, second = csv.DictReader(out.open())
    assert "needs two meshes" in first["error"] and float(second["score"]) > 0


def test_features_out_names_the_file_it_wrote(tmp_path):
    result = _run("features", CHAIR, "--out", tmp_path / "chair", *FAST)
    assert result.exit_code == 0
    assert result.output.startswith(f"{tmp_path / 'chair.npz'}:")
    assert (tmp_path / "chair.npz").is_file()


def test_the_torch_command_without_torch_names_the_extra_to_install(tmp_path):
    result = without(tmp_path, ("torch",), "drkfs", "score", str(NO_LEG), str(CHAIR))
    assert result.returncode == 2
    assert "pip install 'drkfs-onnx[torch]'" in result.stderr
    assert "Traceback" not in result.stderr


def test_explain_draws_the_picture_and_lists_the_top_patches(tmp_path):
    picture = tmp_path / "d.png"
    result = _run("explain", NO_LEG, CHAIR, "--out", picture, "--json", "--top", "3")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["score"] == pytest.approx(float(_run("pair", NO_LEG, CHAIR).stdout), rel=1e-5)
    top = report["top_patches"]
    assert len(top) == 3 and [p["share"] for p in top] == sorted(
        (p["share"] for p in top), reverse=True
    )
    assert {"mesh", "view", "row", "column", "distance", "share"} <= set(top[0])
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_explain_without_matplotlib_names_the_extra(tmp_path):
    args = ("explain", str(NO_LEG), str(CHAIR), "--out", str(tmp_path / "d.png"))
    result = without(tmp_path, ("torch", "matplotlib"), "drkfs-score", *args)
    assert result.returncode == 2
    assert result.stderr.strip() == (
        'error: explain draws with matplotlib: pip install "drkfs-onnx[plot]"'
    )


def test_a_resumed_batch_scores_again_a_file_overwritten_since(tmp_path):
    pred, pairs, out = tmp_path / "pred.obj", tmp_path / "pairs.csv", tmp_path / "scores.csv"
    shutil.copy(NO_LEG, pred)
    pairs.write_text("mesh_a,mesh_b\npred.obj,chair.obj\n")
    shutil.copy(CHAIR, tmp_path / "chair.obj")
    assert _run("batch", pairs, "--out", out, *FAST).exit_code == 0
    first = float(_records(out)[0]["score"])
    shutil.copy(NO_BACK, pred)  # the same path now holds another mesh
    rerun = _run("batch", pairs, "--out", out, *FAST)
    assert "1 scored, 0 failed, 0 already done" in rerun.output, rerun.output
    (record,) = _record_list(out)
    fresh = float(_run("pair", pred, tmp_path / "chair.obj", *FAST).stdout)  # 5 digits
    assert float(record["score"]) == pytest.approx(fresh, rel=1e-4)
    assert abs(fresh - first) > 0.01  # no leg 0.81, no back 0.89 at this width


def test_the_same_csv_run_from_another_folder_is_already_done_and_written_once(
    tmp_path, monkeypatch
):
    (tmp_path / "data").mkdir()
    for mesh in (NO_LEG, CHAIR):
        shutil.copy(mesh, tmp_path / "data" / mesh.name)
    pairs, out = tmp_path / "data" / "pairs.csv", tmp_path / "scores.csv"
    pairs.write_text(f"mesh_a,mesh_b\n{NO_LEG.name},{CHAIR.name}\n")
    monkeypatch.chdir(tmp_path)
    assert _run("batch", "data/pairs.csv", "--out", out, *FAST).exit_code == 0
    monkeypatch.chdir(tmp_path / "data")
    again = _run("batch", "pairs.csv", "--out", out, *FAST)
    assert "0 scored, 0 failed, 1 already done" in again.output, again.output
    assert len(_record_list(out)) == 1


def test_after_a_resume_with_retried_rows_the_results_are_in_input_order(tmp_path):
    pairs, out, late = tmp_path / "pairs.csv", tmp_path / "scores.csv", tmp_path / "late.obj"
    pairs.write_text(f"mesh_a,mesh_b\n{late},{CHAIR}\n{NO_LEG},{CHAIR}\n{NO_BACK},{CHAIR}\n")
    assert _run("batch", pairs, "--out", out, *FAST).exit_code == 1  # row 0 fails
    shutil.copy(NO_LEG, late)
    assert _run("batch", pairs, "--out", out, *FAST).exit_code == 0
    records = _record_list(out)
    assert [r["row"] for r in records] == ["0", "1", "2"]
    assert [r["mesh_a"] for r in records] == [str(late), str(NO_LEG), str(NO_BACK)]
    assert all(r["error"] == "" for r in records)


@pytest.mark.parametrize("command", ["pair", "explain", "features", "batch"])
def test_help_shows_flags_without_a_value_and_the_values_a_choice_takes(command):
    said = _run(command, "--help").output
    assert "<bool>" not in said and "<str>" not in said.split("Options:")[1]
    assert "--normalize [joint|each|none]" in said
    assert (
        "[drkfs-1.0|drkfs-1.1|drkfs-1.2|drkfs-structure-1.0|drkfs-structure-1.1|drkfs-paper]"
        in said
    )


def test_every_scoring_command_takes_the_config_options_of_one_definition():
    from typer.main import get_command

    from drkfs_onnx.cli import app as torch_app
    from drkfs_onnx.contract.cli_options import CONFIG_OPTIONS, DESCRIBING_OPTIONS

    def options(typer_app, name: str) -> set[str]:
        return {p.name for p in get_command(typer_app).commands[name].params}

    for name in ("pair", "explain", "batch"):
        assert set(CONFIG_OPTIONS) | {"width", "nets", "model", "max_faces"} <= options(app, name)
    assert set(CONFIG_OPTIONS) <= options(torch_app, "score")
    described = options(app, "features")
    assert set(DESCRIBING_OPTIONS) <= described and "matching" not in described


def test_a_file_wound_against_itself_scores_as_itself_and_gets_a_warning_where_read(tmp_path):
    chair = trimesh.load(CHAIR, force="mesh", process=False)
    flips = np.random.default_rng(0).random(len(chair.faces)) < 0.5
    chair.faces = np.where(flips[:, None], chair.faces[:, ::-1], chair.faces)
    rewound = tmp_path / "rewound.obj"
    chair.export(rewound)
    default = _run("pair", rewound, CHAIR)
    assert default.exit_code == 0 and float(default.stdout) < 1e-6
    assert "warning" not in default.stderr
    read = _run("pair", rewound, CHAIR, "--winding", "file")
    warned = [line for line in read.stderr.splitlines() if line.startswith("warning:")]
    assert read.exit_code == 0 and float(read.stdout) > 0.5  # it reads as a missing part
    assert len(warned) == 1 and str(rewound) in warned[0] and "--winding geometry" in warned[0]


def test_drkfs_1_2_scores_a_tilted_mesh_alike_through_a_features_file_and_a_batch(tmp_path):
    chair = load_mesh(CHAIR)
    centre = (chair.vertices.max(0) + chair.vertices.min(0)) / 2
    turn = trimesh.transformations.rotation_matrix(np.radians(2.0), [1, 0, 0], centre)
    tilted = tmp_path / "tilted.obj"
    trimesh.Trimesh(chair.vertices, chair.faces, process=False).apply_transform(turn).export(tilted)
    turning = ["--metric", "drkfs-1.2"]
    assert _run("features", CHAIR, "--out", tmp_path / "chair.npz", *turning).exit_code == 0
    direct = float(_run("pair", tilted, CHAIR, *turning).stdout)
    cached = float(_run("pair", tilted, tmp_path / "chair.npz", *turning).stdout)
    unturned = float(_run("pair", tilted, CHAIR).stdout)
    assert direct == cached < 0.2 * unturned
    pairs, out = tmp_path / "pairs.csv", tmp_path / "scores.csv"
    pairs.write_text(f"mesh_a,mesh_b\n{tilted},{tmp_path / 'chair.npz'}\n")
    assert _run("batch", pairs, "--out", out, *turning).exit_code == 0
    (record,) = _record_list(out)
    assert record["metric"] == "drkfs-1.2" and float(record["score"]) == pytest.approx(
        direct, rel=1e-5
    )
