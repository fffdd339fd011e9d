"""The shipped detector and HardNet weights as torch state dicts, matched to a pipeline config
(``contract.model_files`` finds the manifest's entry)."""

from __future__ import annotations

import hashlib
import io

import torch

from ..contract import model_files
from ..contract.config import PipelineConfig
from .hardnet import state_from_folded

# the seed of the nets' weights where no trained ones are shipped for a config
RANDOM_SEED = 0


def load_shipped_state(config: PipelineConfig, any_rendering: bool = False):
    """The torch state dict shipped for ``config`` (see ``shipped_entry``), or None.

    From the training's own file where it is there (a checkout, fresh weights), sha256-checked
    against the manifest; otherwise (an installed wheel, which ships each net once) from the
    initializers of a feature graph exported from that file, which names its sha256.
    """
    entry = model_files.shipped_entry(config, any_rendering)
    if entry is None:
        return None
    path = model_files.models_dir() / entry["file"]
    if not path.is_file():
        return _state_from_graph(entry)
    return load_checked(path, entry)


def load_checked(path, entry: dict) -> dict:
    """The torch state dict in ``path``, read once; ValueError unless the file is there with
    the sha256 its manifest ``entry`` records."""
    if not path.is_file():
        raise ValueError(f"{path}: missing, though the manifest names it")
    data = path.read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    if digest != entry["sha256"]:
        raise ValueError(f"{path}: sha256 does not match the manifest (it is {digest[:12]})")
    return torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)


def _state_from_graph(entry: dict):
    """The state dict of ``entry``'s weights, read from a shipped feature graph exported from
    them (any image size: the nets are the same)."""
    import onnx  # only where the wheel lacks the .pt
    from onnx import numpy_helper

    trained = PipelineConfig.from_dict(entry["config"])
    prefix = model_files.nets_prefix(trained)
    for item in sorted(model_files.models_dir().iterdir(), key=lambda item: item.name):
        if not (item.name.startswith(prefix) and item.name.endswith("px.onnx")):
            continue
        graph = onnx.load_from_string(item.read_bytes())
        carried = {p.key: p.value for p in graph.metadata_props}
        if carried.get(model_files.WEIGHTS_KEY) != entry["sha256"]:
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
