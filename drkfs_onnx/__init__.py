"""DR-KFS: a differentiable visual similarity metric for 3D shapes.

The package root imports no torch, so the server runtime (``drkfs_onnx.runtime``) stays
torch-free; ``drkfs_onnx.DRKFS`` and ``drkfs_onnx.MeshBatch`` load the torch path on first use.
"""

from .contract.config import PipelineConfig
from .contract.mesh import Mesh, MeshError, check_mesh, load_mesh

__version__ = "1.1.0"
__all__ = ["DRKFS", "Mesh", "MeshBatch", "MeshError", "PipelineConfig", "check_mesh", "load_mesh"]


def __getattr__(name: str):
    if name == "DRKFS":
        from .metric import DRKFS

        return DRKFS
    if name == "MeshBatch":
        from .render.mesh_batch import MeshBatch

        return MeshBatch
    raise AttributeError(f"module 'drkfs_onnx' has no attribute {name!r}")
