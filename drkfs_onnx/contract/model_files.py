"""The shipped model files (``models/``, installed as ``drkfs_onnx.models``): the manifest, the
weights entry trained for a config, the feature graphs' names and the metadata keys they carry
(shared by the torch path, export and runtime)."""

from __future__ import annotations

import hashlib
import json
from importlib import resources
from pathlib import Path

from .config import PipelineConfig

MATCH_FILE = "match.onnx"
CONFIG_KEY = "drkfs_config"
VERSION_KEY = "drkfs_model_version"
WEIGHTS_KEY = "drkfs_weights_sha256"
# the metric versions a feature graph serves at its export, comma-separated ("custom" for none);
# a reader of the file learns them there, a scorer from the graph's config against its own
SERVES_KEY = "drkfs_serves"


def features_file(config: PipelineConfig) -> str:
    """File name of the feature graph for a config's nets, descriptor width and image size (the
    graph takes any number of views)."""
    return f"{nets_prefix(config)}{config.image_size}px.onnx"


def nets_prefix(config: PipelineConfig) -> str:
    """What the names of every feature graph of a config's nets begin with, whatever its
    image size."""
    return f"features_{config.nets}_w{config.descriptor_width:g}_"


MANIFEST = "manifest.json"


def sha256(path: Path) -> str:
    """A file's sha256, as the manifest records it."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def models_dir():
    """The installed ``models/`` folder (a Traversable)."""
    return resources.files("drkfs_onnx.models")


def held_graphs(nets: str) -> dict[float, list[int]]:
    """The installed models/' feature graphs of ``nets``: each descriptor width's view sizes."""
    sizes: dict[float, list[int]] = {}
    prefix = f"features_{nets}_w"
    for item in models_dir().iterdir():
        width, _, size = item.name.removeprefix(prefix).removesuffix("px.onnx").partition("_")
        if item.name.startswith(prefix) and item.name.endswith("px.onnx") and size.isdigit():
            sizes.setdefault(float(width), []).append(int(size))
    return {width: sorted(sizes[width]) for width in sorted(sizes)}


def shipped_weights() -> list[dict]:
    """The manifest's weights entries: file, sha256 and the config each was trained for."""
    manifest_file = models_dir() / MANIFEST
    if not manifest_file.is_file():
        return []
    return json.loads(manifest_file.read_text()).get("weights", [])


def shipped_entry(config: PipelineConfig, any_rendering: bool = False) -> dict | None:
    """The manifest's weights entry trained for ``config``, or None when none is shipped.

    any_rendering: also accept weights trained at other RENDER_FIELDS values
    (``shaping("weights")``). The match settings never matter: they do not touch the nets.
    """
    return entry_for(shipped_weights(), config, any_rendering)


def entry_for(entries: list[dict], config: PipelineConfig, any_rendering: bool) -> dict | None:
    """The first of a manifest's weights ``entries`` trained for ``config`` (as
    ``shipped_entry``), or None."""
    shaping = "weights" if any_rendering else "features"
    wanted = config.shaping(shaping)
    return next(
        (e for e in entries if PipelineConfig.from_dict(e["config"]).shaping(shaping) == wanted),
        None,
    )
