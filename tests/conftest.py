from pathlib import Path

import numpy as np
import pytest
import trimesh

SHARED_MESHES = Path(__file__).resolve().parents[2] / "shared" / "meshes"


@pytest.fixture(scope="session")
def shared_meshes() -> Path:
    """The shared test meshes in ../shared/meshes (read in place, never copied)."""
    if not (SHARED_MESHES / "cow.obj").is_file():
        pytest.fail(f"shared test meshes not found at {SHARED_MESHES}; they sit beside the repo")
    return SHARED_MESHES


def icosphere(subdivisions: int = 1, radius: float = 0.8) -> tuple[np.ndarray, np.ndarray]:
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(sphere.vertices), np.asarray(sphere.faces)
