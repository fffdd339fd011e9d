"""Evaluation-only scoring with onnxruntime and numpy; never imports torch (installed as
``drkfs_onnx.runtime``)."""

from .features import MeshFeatures
from .scorer import Scorer
from .sessions import ModelMismatch

__all__ = ["MeshFeatures", "ModelMismatch", "Scorer"]
