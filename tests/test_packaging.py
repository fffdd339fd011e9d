"""What a user installs: a torch-free runtime, the examples, the command line."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import trimesh
import typer.main
from typer.testing import CliRunner

from drkfs_onnx.cli import RUNS, app
from drkfs_onnx.synthetic.examples import example_meshes

ROOT = Path(__file__).resolve().parents[1]


def test_runtime_imports_where_torch_and_ray_cannot_be_imported():
    code = (
        "import sys; sys.modules['torch'] = sys.modules['ray'] = None\n"
        "import drkfs_onnx, drkfs_onnx.runtime, drkfs_onnx.runtime.cli, drkfs_onnx.mesh\n"
        "import drkfs_onnx.runtime.batch\n"
        "from drkfs_onnx import PipelineConfig, load_mesh\n"
        "from drkfs_onnx.cameras import make_cameras\n"
        f"mesh = load_mesh({str(ROOT / 'examples' / 'chair.obj')!r})\n"
        "assert len(make_cameras(PipelineConfig.paper())) == 25 and len(mesh.faces) > 0\n"
        "try:\n    drkfs_onnx.DRKFS\nexcept ImportError:\n    print('torch-free')\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "torch-free"


def test_no_bare_export_or_runtime_module_is_installed(tmp_path):
    """Outside the checkout, only drkfs_onnx.export and drkfs_onnx.runtime exist."""
    code = (
        "import importlib.util as u\n"
        "print([u.find_spec(n) is None for n in ('export', 'runtime')],"
        " [u.find_spec(n) is None for n in ('drkfs_onnx.export', 'drkfs_onnx.runtime')])"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path
    )
    assert result.stdout.strip() == "[True, True] [False, False]", result.stderr


def test_bundled_examples_are_what_the_code_generates():
    for name, (_, mesh) in example_meshes().items():
        shipped = trimesh.load(ROOT / "examples" / name, force="mesh", process=False)
        assert np.allclose(shipped.vertices, mesh.vertices, atol=1e-7), name
        assert np.array_equal(shipped.faces, mesh.faces), name


def test_cli_scores_a_pair_as_json():
    chair, no_leg = (str(ROOT / "examples" / name) for name in ("chair.obj", "chair_no_leg.obj"))
    scores = []
    for mesh in (chair, no_leg):
        result = CliRunner().invoke(app, ["score", mesh, chair, "--json"])
        assert result.exit_code == 0, result.output
        scores.append(json.loads(result.stdout.strip().splitlines()[-1])["score"])
    assert scores[0] == 0.0 < scores[1]


def test_cli_names_the_bad_file(tmp_path):
    bad = tmp_path / "cloud.ply"
    trimesh.PointCloud(np.random.default_rng(0).random((10, 3))).export(bad)
    result = CliRunner().invoke(app, ["score", str(bad), str(ROOT / "examples" / "chair.obj")])
    assert result.exit_code == 2
    assert str(bad) in result.output and "no faces" in result.output


def test_no_command_writes_into_shipped_files_by_default(monkeypatch):
    """train, export, bench and fit write under runs/ unless --out names models/ or bench/."""
    commands = typer.main.get_command(app).commands
    for name in ("train", "export", "bench"):
        (out,) = [p for p in commands[name].params if p.name == "out"]
        assert Path(out.default).parts[0] == RUNS.name, name

    class Called(Exception):
        pass

    def record(out, *args):
        raise Called(out)

    for module, function, args in (
        ("study", "run_study", ["fit"]),
        ("network", "run_network_study", ["fit", "--network"]),
    ):
        monkeypatch.setattr(f"drkfs_onnx.fitting.{module}.{function}", record)
        result = CliRunner().invoke(app, args)
        assert isinstance(result.exception, Called), result.output
        assert Path(result.exception.args[0]).parts[0] == RUNS.name


def test_the_runtime_imports_from_the_repository_root_without_the_editable_finder():
    """What a plain `pip install .` meets at the repository root: ./drkfs_onnx shadows the
    installed package, and no finder maps export/ and runtime/ into it."""
    code = (
        "import sys\n"
        "sys.meta_path[:] = [f for f in sys.meta_path if 'Editable' not in repr(f)]\n"
        "from drkfs_onnx.runtime import Scorer\n"
        "from drkfs_onnx.weights import shipped_weights\n"
        "assert shipped_weights(), 'models/ not found'\n"
        "assert 'torch' not in sys.modules\n"
        "import drkfs_onnx.export\n"
    )
    root = Path(__file__).resolve().parents[1]
    result = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
