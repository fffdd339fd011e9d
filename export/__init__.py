"""ONNX export of the feature and match graphs (installed as ``drkfs_onnx.export``)."""
