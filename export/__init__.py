"""ONNX export of the feature and match graphs (installed as ``drkfs_onnx.export``; torch extra)."""

from .onnx_files import export_features, export_match, export_shipped, weights_digest

__all__ = ["export_features", "export_match", "export_shipped", "weights_digest"]
