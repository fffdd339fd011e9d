"""What a user installs: a torch-free runtime, the examples, the command line."""

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
import typer.main
from conftest import ROOT
from typer.testing import CliRunner

from drkfs_lab.fit import app as fit_app
from drkfs_onnx import DRKFS, PipelineConfig, load_mesh
from drkfs_onnx.cli import RUNS, app
from drkfs_onnx.contract.versions import LATEST
from drkfs_onnx.synthetic.examples import example_meshes


def test_runtime_imports_where_torch_and_ray_cannot_be_imported():
    code = (
        "import sys; sys.modules['torch'] = sys.modules['ray'] = None\n"
        "import drkfs_onnx, drkfs_onnx.runtime, drkfs_onnx.runtime.cli, drkfs_onnx.contract.mesh\n"
        "import drkfs_onnx.runtime.batch\n"
        "from drkfs_onnx import PipelineConfig, load_mesh\n"
        "from drkfs_onnx.contract.cameras import make_cameras\n"
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


def test_bundled_examples_are_what_the_code_generates(tmp_path):
    for name, (_, mesh) in example_meshes().items():
        shipped = trimesh.load(ROOT / "examples" / name, force="mesh", process=False)
        assert np.allclose(shipped.vertices, mesh.vertices, atol=1e-7), name
        assert np.array_equal(shipped.faces, mesh.faces), name
    # drkfs examples DIR writes the pairs file too: the README's main job runs outside a clone
    written = CliRunner().invoke(app, ["examples", str(tmp_path)])
    assert written.exit_code == 0, written.output
    assert (tmp_path / "pairs.csv").read_text() == (ROOT / "examples" / "pairs.csv").read_text()


def test_demo_without_torch_says_so_before_it_writes_anything(tmp_path):
    code = (
        "import sys; sys.modules['torch'] = None\n"
        "from drkfs_onnx.cli import main; sys.argv = ['drkfs', 'demo', '--folder', 'ex']; main()"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            cwd=tmp_path)  # fmt: skip
    assert result.returncode == 2 and "needs torch" in result.stderr, result.stderr
    assert not (tmp_path / "ex").exists()


def test_cli_scores_a_pair_as_json_naming_what_drkfs_score_names():
    chair, no_leg = (str(ROOT / "examples" / name) for name in ("chair.obj", "chair_no_leg.obj"))
    reports = []
    for mesh in (chair, no_leg):
        result = CliRunner().invoke(app, ["score", mesh, chair, "--json"])
        assert result.exit_code == 0, result.output
        reports.append(json.loads(result.stdout.strip().splitlines()[-1]))
    assert reports[0]["score"] == 0.0 < reports[1]["score"]
    assert reports[1]["metric"] == LATEST and reports[1]["normalize"] == "joint"
    assert PipelineConfig.from_dict(reports[1]["config"]) == PipelineConfig()
    assert reports[1]["mesh_a"] == no_leg


def test_cli_names_the_bad_file(tmp_path):
    bad = tmp_path / "cloud.ply"
    trimesh.PointCloud(np.random.default_rng(0).random((10, 3))).export(bad)
    result = CliRunner().invoke(app, ["score", str(bad), str(ROOT / "examples" / "chair.obj")])
    assert result.exit_code == 2
    assert str(bad) in result.output and "no faces" in result.output


def test_no_command_writes_into_shipped_files_by_default(monkeypatch):
    """train, tune-tolerant, export, bench and bench/fit.py write under runs/ unless --out
    names models/ or bench/."""
    commands = typer.main.get_command(app).commands
    for name in ("train", "tune-tolerant", "export", "bench"):
        (out,) = [p for p in commands[name].params if p.name == "out"]
        assert Path(out.default).parts[0] == RUNS.name, name

    class Called(Exception):
        pass

    def record(out, *args):
        raise Called(out)

    for module, function, args in (
        ("study", "run_study", []),
        ("network", "run_network_study", ["--network"]),
    ):
        monkeypatch.setattr(f"drkfs_lab.studies.{module}.{function}", record)
        result = CliRunner().invoke(fit_app, args)
        assert isinstance(result.exception, Called), result.output
        assert Path(result.exception.args[0]).parts[0] == RUNS.name


def test_the_labs_commands_join_drkfs_once_and_a_broken_lab_leaves_the_librarys_own(tmp_path):
    from drkfs_onnx import cli

    names = [cli.command_name(command) for command in app.registered_commands]
    assert {"train", "tune-tolerant", "bench", "choose-loss"} <= set(names)
    cli.add_installed_commands()  # the lab's entry again: nothing is added twice
    assert [cli.command_name(command) for command in app.registered_commands] == names
    assert not cli.UNAVAILABLE
    code = (
        "import sys\n"
        "sys.modules['drkfs_lab'] = None\n"  # an install whose lab no longer imports
        "from drkfs_onnx import cli\n"
        "sys.argv = ['drkfs', 'score', '--help']\n"
        "cli.main()\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True
    )
    assert result.returncode == 0 and "Score MESH_A against" in result.stdout, result.stderr
    assert "warning: drkfs_onnx.commands entry 'lab' left out: drkfs_lab.cli:app did not load" in (
        result.stderr
    )


def test_the_runtime_imports_from_the_repository_root_without_the_editable_finder():
    """What a plain `pip install .` meets at the repository root: ./drkfs_onnx shadows the
    installed package, and no finder maps export/ and runtime/ into it."""
    code = (
        "import sys\n"
        "sys.meta_path[:] = [f for f in sys.meta_path if 'Editable' not in repr(f)]\n"
        "from drkfs_onnx.runtime import Scorer\n"
        "from drkfs_onnx.contract.model_files import shipped_weights\n"
        "assert shipped_weights(), 'models/ not found'\n"
        "assert 'torch' not in sys.modules\n"
        "import drkfs_onnx.export\n"
        "import importlib.util as u\n"
        "names = ('bench', 'docs', 'drkfs_onnx', 'tests', 'meshes', 'studies')\n"
        "print([u.find_spec(f'drkfs_onnx.{name}') for name in names])\n"
    )
    root = ROOT
    result = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    # nothing but the package's own modules imports as drkfs_onnx.*
    assert result.stdout.strip() == str([None] * 6)


# what the wheel's models/ holds: each preset's nets once, as the feature graphs it loads
PRESET_GRAPHS = {
    "features_tolerant_w0.5_144px.onnx", "features_correspondence_w1_256px.onnx",
    "features_correspondence_w0.5_128px.onnx",
}  # fmt: skip


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The package as `pip install .` installs it, into a folder of its own."""
    folder = tmp_path_factory.mktemp("wheel")
    source = folder / "source"  # what a clone holds: no build/ left from an earlier build
    source.mkdir()
    for name in ("pyproject.toml", "README.md", "drkfs_onnx", "export", "runtime", "models"):
        copy = shutil.copytree if (ROOT / name).is_dir() else shutil.copy
        kept = {"symlinks": True, "ignore": shutil.ignore_patterns("__pycache__")}
        copy(ROOT / name, source / name, **(kept if copy is shutil.copytree else {}))
    # this environment's setuptools where it has one (no index needed), else pip's isolated one
    isolation = [] if importlib.util.find_spec("setuptools") is None else ["--no-build-isolation"]
    build = [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", *isolation]
    subprocess.run([*build, str(source), "-w", str(folder / "dist")], check=True)
    (wheel,) = (folder / "dist").glob("*.whl")
    install = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-compile"]
    subprocess.run([*install, "--target", str(folder / "site"), str(wheel)], check=True)
    return folder / "site"


def test_the_installed_package_is_lean_and_ships_each_presets_nets_once(installed):
    package = installed / "drkfs_onnx"
    models = {path.name for path in (package / "models").iterdir() if path.is_file()}
    assert models == {"__init__.py", "manifest.json", "match.onnx", *PRESET_GRAPHS}
    size = sum(path.stat().st_size for path in package.rglob("*") if path.is_file())
    assert size <= 12e6, f"{size / 1e6:.1f} MB"
    # the package is the metric, the loss, the runtime and export; the lab (bench/: the
    # benchmark, the nets' training, judging and the studies) is a distribution of its own
    assert sorted(p.name for p in package.iterdir() if p.is_dir() and p.name != "__pycache__") == [
        "contract", "export", "models", "nets", "render", "runtime", "synthetic",
    ]  # fmt: skip


def test_every_preset_scores_from_the_installed_package(installed, tmp_path):
    """Server presets through onnxruntime, and the torch path's nets read from the graphs (no
    .pt installed), the training loss's included; run outside the checkout."""
    chair, no_leg = (str(ROOT / "examples" / name) for name in ("chair.obj", "chair_no_leg.obj"))
    code = (
        "import json, drkfs_onnx, torch\n"
        "from drkfs_onnx import DRKFS, PipelineConfig, load_mesh\n"
        "from drkfs_onnx.runtime import Scorer\n"
        f"a, b = load_mesh({no_leg!r}), load_mesh({chair!r})\n"
        "presets = {'default': PipelineConfig(), 'structure': PipelineConfig.structure(),\n"
        "           'paper': PipelineConfig.paper(num_views=6), 'loss': PipelineConfig.loss()}\n"
        "out = {'file': drkfs_onnx.__file__}\n"
        "for name, config in presets.items():\n"
        "    with torch.no_grad():\n"
        "        out[name] = float(DRKFS.pretrained(config).score_meshes(a, b))\n"
        "    if name != 'loss':\n"
        "        out[name + ' onnx'] = Scorer(config).score(a, b)\n"
        "print(json.dumps(out))\n"
    )
    env = {**os.environ, "PYTHONPATH": str(installed)}
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    scores = json.loads(result.stdout)
    assert scores.pop("file").startswith(str(installed))
    # the paper's own 256 px graph from 6 of its 25 cameras (all 25: the test took 21 s, not 11)
    presets = {
        "default": PipelineConfig(), "structure": PipelineConfig.structure(),
        "paper": PipelineConfig.paper(num_views=6), "loss": PipelineConfig.loss(),
    }  # fmt: skip
    a, b = load_mesh(no_leg), load_mesh(chair)
    for name, config in presets.items():
        with torch.no_grad():  # the checkout's .pt weights
            expected = float(DRKFS.pretrained(config).score_meshes(a, b))
        assert scores[name] == expected, name  # the graph's initializers, bit for bit
        if name != "loss":
            assert scores[f"{name} onnx"] == pytest.approx(expected, rel=1e-4), name
