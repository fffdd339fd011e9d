"""onnxruntime sessions for the shipped graphs, and the check that a model fits the config."""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

import onnxruntime as ort

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.model_files import (
    CONFIG_KEY,
    VERSION_KEY,
    features_file,
    models_dir,
)
from drkfs_onnx.contract.versions import serving_version


class ModelMismatch(ValueError):
    """A feature graph built for another pipeline config than the one asked for."""


def session_options(threads: int | None) -> ort.SessionOptions:
    """Graph optimisation ALL (NCHWc convs, faster than BASIC: docs/design_notes.md);
    threads=None lets onnxruntime use every core."""
    options = ort.SessionOptions()
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.intra_op_num_threads = threads or 0
    options.inter_op_num_threads = 1
    options.log_severity_level = 3
    return options


@dataclass
class Graph:
    """An onnxruntime session with its file's name, sha256 and metadata."""

    session: ort.InferenceSession
    source: str
    sha256: str
    metadata: dict[str, str]

    @classmethod
    def open(cls, data: bytes, source: str, threads: int | None) -> Graph:
        try:
            session = ort.InferenceSession(
                data, session_options(threads), providers=["CPUExecutionProvider"]
            )
        except Exception as exc:  # onnxruntime raises its own types for a file it cannot read
            raise ModelMismatch(f"{source}: not a readable ONNX model ({exc})") from exc
        metadata = dict(session.get_modelmeta().custom_metadata_map)
        return cls(session, source, hashlib.sha256(data).hexdigest(), metadata)

    @property
    def version(self) -> str:
        return self.metadata.get(VERSION_KEY, "unknown")


def _read(path: str | Path | None, default: str) -> tuple[bytes, str]:
    if path is not None:
        if not Path(path).is_file():
            raise ModelMismatch(f"{path}: no such model file")
        return Path(path).read_bytes(), str(path)
    shipped = models_dir() / default
    if not shipped.is_file():
        nets = default.removeprefix("features_").split("_w")[0]
        raise FileNotFoundError(
            f"no {default} in the installed models/: {_graphs_of(nets)}; for another width or "
            "view size, make a graph with drkfs export (torch extra) and pass it with --model"
        )
    return shipped.read_bytes(), f"models/{default}"


def _graphs_of(nets: str) -> str:
    """What the installed models/ hold of ``nets``: each width's view sizes, in words."""
    sizes: dict[str, list[int]] = {}
    for item in models_dir().iterdir():
        found = re.fullmatch(rf"features_{re.escape(nets)}_w([\d.]+)_(\d+)px\.onnx", item.name)
        if found:
            sizes.setdefault(found[1], []).append(int(found[2]))
    if not sizes:
        return (
            f"it holds no {nets} nets (an installed package carries the presets' graphs, a "
            "checkout's models/ every shipped net: --nets)"
        )
    held = [f"{w} ({', '.join(map(str, sorted(px)))} px)" for w, px in sorted(sizes.items())]
    return f"the {nets} nets come at width {', '.join(held)} (--width, --nets)"


def open_features(
    config: PipelineConfig, path: str | Path | None = None, threads: int | None = None
) -> Graph:
    """The feature graph for ``config`` (the shipped one unless ``path``), refused with a
    ModelMismatch naming the version it was built for, the one asked and the differing settings
    when it was built for another config (the match settings, the cameras' count and turn and
    the light on faces seen from behind aside: the graph describes any views, however lit)."""
    graph = Graph.open(*_read(path, features_file(config)), threads)
    if CONFIG_KEY not in graph.metadata:
        raise ModelMismatch(f"{graph.source}: no {CONFIG_KEY} metadata; not a DR-KFS feature graph")
    exported = PipelineConfig.from_json(graph.metadata[CONFIG_KEY])
    built, wanted = exported.shaping("graph"), config.shaping("graph")
    if built != wanted:
        made, asked = serving_version(exported, "graph"), serving_version(config, "graph")
        raise ModelMismatch(
            f"{graph.source} was built for {made}'s feature graph, scoring asks {asked}'s: "
            f"{built.differences(wanted)}; export a model for this config or score with the "
            "model's config"
        )
    return graph
