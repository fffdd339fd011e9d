import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from drkfs_onnx.benchmark.sets import real_mesh

# Tests run the rasteriser's equations eagerly, their subprocesses too: compiling them for each
# test's config would cost CI's 2 cores about 10 s a graph. The default, compiled where a
# training step or a GPU asks (rasterize._compiles), has its own tests in test_render.py, and
# test_cuda.py runs under it.
os.environ.setdefault("DRKFS_COMPILE", "0")


@pytest.fixture
def compile_setting(monkeypatch):
    """``compile_setting(value)`` sets DRKFS_COMPILE for one test; the rasteriser's cache of
    equations forgets what it made under another setting, before and after."""
    import drkfs_onnx.rasterize as rasterize

    def use(value: str) -> None:
        monkeypatch.setenv("DRKFS_COMPILE", value)
        rasterize._fused.cache_clear()

    yield use
    rasterize._fused.cache_clear()


@pytest.fixture(scope="session")
def real_meshes() -> Path:
    """The folder of the repository's real meshes (meshes/; read in place, never copied); a
    missing mesh fails the test that needs it with the reason."""
    try:
        return real_mesh("cow").parent
    except ValueError as exc:
        pytest.fail(str(exc))


def icosphere(subdivisions: int = 1, radius: float = 0.8) -> tuple[np.ndarray, np.ndarray]:
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(sphere.vertices), np.asarray(sphere.faces)


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
