"""Write the feature and match graphs as ONNX files with the metadata the runtime checks."""

from __future__ import annotations

import hashlib
import io
from importlib.metadata import version
from pathlib import Path

import onnx
import torch

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.model_files import (
    CONFIG_KEY,
    MATCH_FILE,
    SERVES_KEY,
    VERSION_KEY,
    WEIGHTS_KEY,
    features_file,
    shipped_weights,
)
from drkfs_onnx.contract.versions import CUSTOM, served_versions
from drkfs_onnx.metric import DRKFS

from .graphs import FeatureGraph, MatchGraph

OPSET = 18


def weights_digest(metric: DRKFS) -> str:
    """sha256 of the metric's state dict as torch.save writes it (for unshipped weights)."""
    buffer = io.BytesIO()
    torch.save(metric.state_dict(), buffer)
    return hashlib.sha256(buffer.getvalue()).hexdigest()


def _export(module: torch.nn.Module, args: tuple, names: list[str], dims: dict):
    program = torch.onnx.export(
        module.eval(),
        args,
        input_names=names[:-1],
        output_names=names[-1:],
        opset_version=OPSET,
        dynamic_shapes=dims,
        dynamo=True,
        optimize=True,
        verbose=False,
    )
    model = program.model_proto
    onnx.checker.check_model(model)
    return onnx.shape_inference.infer_shapes(model, strict_mode=True)


def _write(model: onnx.ModelProto, path: Path, metadata: dict[str, str]) -> Path:
    del model.metadata_props[:]
    for key, value in metadata.items():
        model.metadata_props.add(key=key, value=value)
    path.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(model, path)
    return path


def export_features(metric: DRKFS, path: Path, weights_sha256: str) -> Path:
    """views (B, 1, S, S), patch_index (N,) -> descriptors (N, D); B and N dynamic."""
    size = metric.config.image_size
    views = torch.zeros(2, 1, size, size)
    index = torch.arange(3)
    dims = {
        "views": {0: torch.export.Dim("views", min=1, max=4096)},
        "patch_index": {0: torch.export.Dim("patches", min=1, max=1 << 22)},
    }
    with torch.no_grad():
        model = _export(
            FeatureGraph(metric), (views, index), ["views", "patch_index", "descriptors"], dims
        )
    metadata = {
        CONFIG_KEY: metric.config.to_json(),
        VERSION_KEY: f"drkfs-onnx {version('drkfs-onnx')} weights {weights_sha256[:12]}",
        WEIGHTS_KEY: weights_sha256,
        SERVES_KEY: ", ".join(served_versions(metric.config, "graph") or [CUSTOM]),
    }
    return _write(model, path, metadata)


def export_match(path: Path, dim: int) -> Path:
    """a (N, D), b (M, D) -> index of each row's nearest row of b (N,); N and M dynamic."""
    a, b = torch.zeros(3, dim), torch.zeros(5, dim)
    dims = {
        "a": {0: torch.export.Dim("rows_a", min=1)},
        "b": {0: torch.export.Dim("rows_b", min=1)},
    }
    model = _export(MatchGraph(), (a, b), ["a", "b", "nearest"], dims)
    return _write(model, path, {VERSION_KEY: f"drkfs-onnx {version('drkfs-onnx')} match"})


def export_shipped(folder: Path) -> list[Path]:
    """Per weights file in the manifest, a feature graph at the image size it was trained at
    (the paper preset's), at the default config's and at the loss's, and the match graph, into
    folder."""
    written = []
    dims = set()
    sizes = {PipelineConfig().image_size, PipelineConfig.loss().image_size}
    for entry in shipped_weights():
        trained = PipelineConfig.from_dict(entry["config"])
        for size in sorted({trained.image_size, *sizes}):
            config = trained.replace(image_size=size)
            path = folder / features_file(config)
            written.append(export_features(DRKFS.pretrained(config), path, entry["sha256"]))
        dims.add(trained.descriptor_dim)
    if len(dims) > 1:
        raise ValueError(f"shipped descriptors differ in size ({sorted(dims)}); one match graph")
    written.append(export_match(folder / MATCH_FILE, dims.pop() if dims else 128))
    return written
