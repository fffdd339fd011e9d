"""DR-KFS: a differentiable visual similarity metric for 3D shapes.

The package root imports no torch, so the server runtime (``drkfs_onnx.runtime``) stays
torch-free; ``drkfs_onnx.DRKFS`` loads the torch path on first use.
"""

from pathlib import Path

from .config import PipelineConfig
from .mesh import Mesh, MeshError, check_mesh, load_mesh

# Installed, export/, runtime/ and models/ sit inside this package. In the source tree they sit
# beside it, and a plain `pip install .` run from the repository root imports this folder, not
# the installed copy: look beside it too, so drkfs_onnx.runtime imports from there as well.
_SOURCE_ROOT = Path(__file__).resolve().parent.parent
if (_SOURCE_ROOT / "pyproject.toml").is_file() and (_SOURCE_ROOT / "runtime").is_dir():
    __path__.append(str(_SOURCE_ROOT))

__version__ = "0.1.0"
__all__ = ["DRKFS", "Mesh", "MeshError", "PipelineConfig", "check_mesh", "load_mesh"]


def __getattr__(name: str):
    if name == "DRKFS":
        from .metric import DRKFS

        return DRKFS
    raise AttributeError(f"module 'drkfs_onnx' has no attribute {name!r}")
