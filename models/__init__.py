"""Shipped weights and ONNX graphs (data only), installed as ``drkfs_onnx.models``."""
