"""Names of the shipped ONNX files and the metadata keys they carry (shared by export and
runtime; torch-free)."""

from __future__ import annotations

from .config import PipelineConfig

MATCH_FILE = "match.onnx"
CONFIG_KEY = "drkfs_config"
VERSION_KEY = "drkfs_model_version"
WEIGHTS_KEY = "drkfs_weights_sha256"


def features_file(config: PipelineConfig) -> str:
    """File name of the feature graph for a config's nets, descriptor width and image size (the
    graph takes any number of views)."""
    return f"{nets_prefix(config)}{config.image_size}px.onnx"


def nets_prefix(config: PipelineConfig) -> str:
    """What the names of every feature graph of a config's nets begin with, whatever its
    image size."""
    return f"features_{config.nets}_w{config.descriptor_width:g}_"
