"""Where the shipped detector and HardNet weights live (``models/``, installed as
``drkfs_onnx.models``), and how they are matched to a pipeline config."""

from __future__ import annotations

import hashlib
import io
import json
from importlib import resources
from pathlib import Path

from .config import PipelineConfig

RANDOM_SEED = 0
MANIFEST = "manifest.json"


def sha256(path: Path) -> str:
    """A file's sha256, as the manifest records it."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def models_dir():
    """The installed ``models/`` folder (a Traversable)."""
    return resources.files("drkfs_onnx.models")


def shipped_weights() -> list[dict]:
    """The manifest's weights entries: file, sha256 and the config each was trained for."""
    manifest_file = models_dir() / MANIFEST
    if not manifest_file.is_file():
        return []
    return json.loads(manifest_file.read_text()).get("weights", [])


# Settings that change what the nets are shown but not the nets: a reduced config (fitting, a
# quick run) or the softer training renderer (``PipelineConfig.training()``) reuses the weights.
RENDER_FIELDS = ("num_views", "image_size", "sigma", "gamma")


def shipped_entry(config: PipelineConfig, any_rendering: bool = False) -> dict | None:
    """The manifest's weights entry trained for ``config``, or None when none is shipped.

    any_rendering: also accept weights trained at other RENDER_FIELDS values. The match
    settings never matter: they do not touch the nets.
    """
    for entry in shipped_weights():
        trained = PipelineConfig.from_dict(entry["config"])
        if any_rendering:
            trained = trained.replace(**{name: getattr(config, name) for name in RENDER_FIELDS})
        if trained.features_part() == config.features_part():
            return entry
    return None


def load_shipped_state(config: PipelineConfig, any_rendering: bool = False):
    """The torch state dict shipped for ``config`` (see ``shipped_entry``), or None."""
    entry = shipped_entry(config, any_rendering)
    if entry is None:
        return None
    import torch

    path = models_dir() / entry["file"]
    if not path.is_file():
        raise ValueError(f"{path}: listed in the manifest but missing")
    data = path.read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    if digest != entry["sha256"]:
        raise ValueError(f"{path}: sha256 {digest} does not match the manifest")
    return torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
