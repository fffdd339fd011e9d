"""Evaluation-only scoring with onnxruntime and numpy; never imports torch (installed as
``drkfs_onnx.runtime``)."""
