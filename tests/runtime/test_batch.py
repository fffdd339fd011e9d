"""``drkfs-score batch --ray``: Ray workers give the serial run's results, in input order, into
the same resumable CSV."""

import csv
import sys
from pathlib import Path

import pytest
from conftest import ROOT
from typer.testing import CliRunner

from drkfs_onnx.runtime.cli import app

EXAMPLES = ROOT / "examples"
BUNNY = ROOT / "meshes" / "stanford-bunny.obj"
FAST = ["--nets", "metric", "--width", "0.25"]


def _run(*args) -> object:
    return CliRunner().invoke(app, [*map(str, args)])


def _records(path: Path) -> list[dict]:
    return list(csv.DictReader(path.open()))


def test_ray_workers_give_the_serial_results_in_input_order_and_resume(tmp_path):
    pytest.importorskip("ray")
    chair = EXAMPLES / "chair.obj"
    reference = tmp_path / "chair.npz"
    assert _run("features", chair, "--out", reference, *FAST).exit_code == 0
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"")
    # The first row is the slowest (69k faces), so later rows finish before it; rows share
    # references (a mesh and a features file), and two fail.
    rows = [
        (BUNNY, chair),
        (EXAMPLES / "chair_no_leg.obj", chair),
        (tmp_path / "missing.obj", chair),
        (EXAMPLES / "chair_retessellated.obj", reference),
        (EXAMPLES / "chair_leg_shifted.obj", broken),
        (chair, reference),
    ]
    pairs = tmp_path / "pairs.csv"
    pairs.write_text("mesh_a,mesh_b\n" + "".join(f"{a},{b}\n" for a, b in rows))
    serial, parallel = tmp_path / "serial.csv", tmp_path / "ray.csv"
    assert _run("batch", pairs, "--out", serial, "--threads", "1", *FAST).exit_code == 1
    ray_run = _run("batch", pairs, "--out", parallel, "--ray", "local", "--workers", 2, *FAST)
    assert ray_run.exit_code == 1, ray_run.output
    assert "4 scored, 2 failed" in ray_run.output

    def results(path):
        columns = ("row", "mesh_a", "mesh_b", "score", "error")
        return [tuple(r[c] for c in columns) for r in _records(path)]

    assert results(parallel) == results(serial)  # the same scores and errors, in input order
    assert [r[0] for r in results(parallel)] == [str(i) for i in range(len(rows))]
    assert {r["settings"] for r in _records(parallel)} == {r["settings"] for r in _records(serial)}
    # a rerun retries only the failed rows
    rerun = _run("batch", pairs, "--out", parallel, "--ray", "local", "--workers", 2, *FAST)
    assert "0 scored, 2 failed, 4 already done" in rerun.output
    assert len(_records(parallel)) == len(rows)


def test_ray_options_name_what_is_missing(tmp_path, monkeypatch):
    pairs = tmp_path / "pairs.csv"
    pairs.write_text(f"mesh_a,mesh_b\n{EXAMPLES / 'chair.obj'},{EXAMPLES / 'chair.obj'}\n")
    out = tmp_path / "scores.csv"
    alone = _run("batch", pairs, "--out", out, "--workers", 2, *FAST)
    assert alone.exit_code == 2 and "--workers needs --ray" in alone.output
    monkeypatch.setitem(sys.modules, "ray", None)  # a base install: import ray fails
    result = _run("batch", pairs, "--out", out, "--ray", "local", *FAST)
    assert result.exit_code == 2 and 'pip install "drkfs-onnx[ray]"' in result.output


def test_ray_auto_without_a_cluster_is_one_line_and_writes_no_results_file(tmp_path):
    pairs = tmp_path / "pairs.csv"
    pairs.write_text(f"mesh_a,mesh_b\n{EXAMPLES / 'chair.obj'},{EXAMPLES / 'chair.obj'}\n")
    out = tmp_path / "scores.csv"
    result = _run("batch", pairs, "--out", out, "--ray", "auto", *FAST)
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert "--ray auto: this machine has joined no Ray cluster" in result.output
    assert "--address" not in result.output and not out.exists()


class _RayWhoseWorkersCannotImport:
    """Stands in for a Ray instance another program started: its workers lack the package."""

    @staticmethod
    def remote(**options):
        def wrap(function):
            class Remote:
                @staticmethod
                def remote():
                    return function

            return Remote

        return wrap

    @staticmethod
    def get(ref, timeout):
        raise RuntimeError("The actor never ran\nModuleNotFoundError: No module named 'drkfs_onnx'")


def test_a_ray_instance_whose_workers_cannot_import_the_package_is_refused_by_name():
    from drkfs_onnx.runtime.batch import check_workers

    with pytest.raises(ConnectionError) as error:
        check_workers(_RayWhoseWorkersCannotImport(), "auto")
    message = str(error.value)
    assert message.startswith("--ray auto: joined a Ray instance whose workers cannot run")
    assert "No module named 'drkfs_onnx'" in message and "--ray local" in message
