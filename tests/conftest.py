import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from drkfs_lab.benchmark.sets import real_mesh

# the repository's root, for tests at any depth of tests/
ROOT = Path(__file__).resolve().parents[1]

# Tests run the rasteriser's equations eagerly, their subprocesses too: compiling them for each
# test's config would cost CI's 2 cores about 10 s a graph. The default, compiled where a
# training step or a GPU asks (render.compile_policy.compiles), has its own tests in
# render/test_renderer.py, and test_cuda.py runs under it.
os.environ.setdefault("DRKFS_COMPILE", "0")


@pytest.fixture
def compile_setting(monkeypatch):
    """``compile_setting(value)`` sets DRKFS_COMPILE for one test; the rasteriser's cache of
    equations forgets what it made under another setting, before and after."""
    from drkfs_onnx.render.compile_policy import fused

    def use(value: str) -> None:
        monkeypatch.setenv("DRKFS_COMPILE", value)
        fused.cache_clear()

    yield use
    fused.cache_clear()


@pytest.fixture(scope="session")
def real_meshes() -> Path:
    """The folder of the repository's real meshes (meshes/; read in place, never copied); a
    missing mesh fails the test that needs it with the reason."""
    try:
        return real_mesh("cow").parent
    except ValueError as exc:
        pytest.fail(str(exc))


def unit_rows(rng, n: int, dim: int = 128) -> np.ndarray:
    """(n, dim) float32 rows of unit length, drawn by ``rng``: descriptor-like search rows."""
    rows = rng.normal(size=(n, dim))
    return (rows / np.linalg.norm(rows, axis=1, keepdims=True)).astype(np.float32)


def icosphere(subdivisions: int = 1, radius: float = 0.8) -> tuple[np.ndarray, np.ndarray]:
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(sphere.vertices), np.asarray(sphere.faces)


def loss_case():
    """The case the batched loss is checked on: a prediction as a fresh reconstruction network
    makes one (a sphere of 1,280 faces, nudged off it) and the example chair it is fit to ->
    (prediction (V, 3), its faces (F, 3), the chair's (verts (V', 3), faces (F', 3))), float32
    and int64 tensors in the chair's frame."""
    import torch

    from drkfs_onnx.contract.mesh import frame_of, place
    from drkfs_onnx.synthetic.examples import REFERENCE, example_meshes

    chair = example_meshes()[REFERENCE][1]
    frame = frame_of(np.asarray(chair.vertices))
    verts, faces = icosphere(3, radius=0.6)
    generator = torch.Generator().manual_seed(0)
    prediction = torch.tensor(verts, dtype=torch.float32)
    prediction += 0.02 * torch.randn(prediction.shape, generator=generator)
    truth_verts = torch.tensor(place(np.asarray(chair.vertices), frame), dtype=torch.float32)
    return prediction, torch.as_tensor(faces), (truth_verts, torch.as_tensor(chair.faces))


def without(
    tmp_path: Path, modules: tuple[str, ...], command: str, *args: str
) -> subprocess.CompletedProcess:
    """Run an installed command where importing ``modules`` fails, as on a base install."""
    for module in modules:
        blocker = tmp_path / module
        blocker.mkdir()
        (blocker / "__init__.py").write_text(
            f"raise ModuleNotFoundError('no {module}', name='{module}')\n"
        )
    script = shutil.which(command)
    assert script, f"{command} is not installed (pip install -e .)"
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    return subprocess.run([script, *args], capture_output=True, text=True, env=env)
