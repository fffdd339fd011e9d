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
    """The torch state dict shipped for ``config`` (see ``shipped_entry``), or None.

    From the training's own file where it is there (a checkout, fresh weights), sha256-checked
    against the manifest; otherwise (an installed wheel, which ships each net once) from the
    initializers of a feature graph exported from that file, which names its sha256.
    """
    entry = shipped_entry(config, any_rendering)
    if entry is None:
        return None
    import torch

    path = models_dir() / entry["file"]
    if not path.is_file():
        return _state_from_graph(entry)
    data = path.read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    if digest != entry["sha256"]:
        raise ValueError(f"{path}: sha256 {digest} does not match the manifest")
    return torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)


def _state_from_graph(entry: dict):
    """The state dict of ``entry``'s weights, read from a shipped feature graph exported from
    them (any image size: the nets are the same)."""
    import onnx
    import torch
    from onnx import numpy_helper

    from .hardnet import state_from_folded
    from .model_files import WEIGHTS_KEY, nets_prefix

    trained = PipelineConfig.from_dict(entry["config"])
    prefix = nets_prefix(trained)
    for item in sorted(models_dir().iterdir(), key=lambda item: item.name):
        if not (item.name.startswith(prefix) and item.name.endswith("px.onnx")):
            continue
        graph = onnx.load_from_string(item.read_bytes())
        if {p.key: p.value for p in graph.metadata_props}.get(WEIGHTS_KEY) != entry["sha256"]:
            continue
        tensors = {
            init.name: torch.from_numpy(numpy_helper.to_array(init).copy())
            for init in graph.graph.initializer
        }
        # the metric's two nets: the detector as trained, HardNet with its BatchNorms folded
        state = {name: tensors[name] for name in ("detector.conv.weight", "detector.conv.bias")}
        descriptor = {
            name.removeprefix("descriptor."): tensor
            for name, tensor in tensors.items()
            if name.startswith("descriptor.")
        }
        for name, tensor in state_from_folded(descriptor, trained).items():
            state[f"descriptor.{name}"] = tensor
        return state
    raise ValueError(
        f"models/: neither {entry['file']} nor a feature graph exported from it (sha256 "
        f"{entry['sha256'][:12]}): an installed package carries the presets' nets only; the "
        "others are in a checkout's models/ (pip install -e .), or train them (drkfs train)"
    )
