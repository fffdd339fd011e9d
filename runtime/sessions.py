"""onnxruntime sessions for the shipped graphs, and the check that a model fits the config."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import onnxruntime as ort

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.model_files import (
    CONFIG_KEY,
    VERSION_KEY,
    features_file,
    held_graphs,
    models_dir,
)
from drkfs_onnx.contract.versions import in_words, serving_version


class ModelMismatch(ValueError):
    """A feature graph built for another pipeline config than the one asked for."""


def session_options(threads: int | None, spinning: bool = False) -> ort.SessionOptions:
    """Graph optimisation ALL (NCHWc convs, faster than BASIC: docs/design_notes.md);
    threads=None lets onnxruntime use every core. ``spinning``: the idle intra-op threads
    busy-wait for the next run, as onnxruntime's default; off, they sleep, and the renderer's
    threads and numpy's BLAS that run between descriptions get the cores (bench/score.py,
    "spinning")."""
    options = ort.SessionOptions()
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.intra_op_num_threads = threads or 0
    options.inter_op_num_threads = 1
    options.log_severity_level = 3
    options.add_session_config_entry("session.intra_op.allow_spinning", "1" if spinning else "0")
    return options


@dataclass
class Graph:
    """An onnxruntime session with its file's name, sha256 and metadata."""

    session: ort.InferenceSession
    source: str
    sha256: str
    metadata: dict[str, str]

    @classmethod
    def open(cls, data: bytes, source: str, threads: int | None, spinning: bool = False) -> Graph:
        try:
            session = ort.InferenceSession(
                data, session_options(threads, spinning), providers=["CPUExecutionProvider"]
            )
        except Exception as exc:  # onnxruntime raises its own types for a file it cannot read
            raise ModelMismatch(f"{source}: not a readable ONNX model ({exc})") from exc
        metadata = dict(session.get_modelmeta().custom_metadata_map)
        return cls(session, source, hashlib.sha256(data).hexdigest(), metadata)

    @property
    def version(self) -> str:
        return self.metadata.get(VERSION_KEY, "unknown")


def _read(path: str | Path | None, config: PipelineConfig) -> tuple[bytes, str]:
    """The bytes of the graph file ``path``, else of the shipped graph for ``config``, and its
    name; an error that says what the installed models/ hold where it has no such graph."""
    if path is not None:
        if not Path(path).is_file():
            raise ModelMismatch(f"{path}: no such model file")
        return Path(path).read_bytes(), str(path)
    default = features_file(config)
    shipped = models_dir() / default
    if not shipped.is_file():
        raise FileNotFoundError(
            f"no {default} in the installed models/: {_held_in_words(config.nets)}; for another "
            "width or view size, make a graph with drkfs export (torch extra) and pass it with "
            "--model"
        )
    return shipped.read_bytes(), f"models/{default}"


def _held_in_words(nets: str) -> str:
    """What the installed models/ hold of ``nets`` (``held_graphs``), in words."""
    held = held_graphs(nets)
    if not held:
        return (
            f"it holds no {nets} nets (an installed package carries the presets' graphs, a "
            "checkout's models/ every shipped net: --nets)"
        )
    widths = [f"{w:g} ({', '.join(map(str, px))} px)" for w, px in held.items()]
    return f"the {nets} nets come at width {', '.join(widths)} (--width, --nets)"


def open_features(
    config: PipelineConfig, path: str | Path | None = None, threads: int | None = None
) -> Graph:
    """The feature graph for ``config`` (the shipped one unless ``path``), refused with a
    ModelMismatch naming the version it was built for, the one asked and the differing settings
    when it was built for another config (the match settings, the cameras' count and turn and
    the light on faces seen from behind aside: the graph describes any views, however lit)."""
    graph = Graph.open(*_read(path, config), threads)
    if CONFIG_KEY not in graph.metadata:
        raise ModelMismatch(f"{graph.source}: no {CONFIG_KEY} metadata; not a DR-KFS feature graph")
    exported = PipelineConfig.from_json(graph.metadata[CONFIG_KEY])
    built, wanted = exported.shaping("graph"), config.shaping("graph")
    if built != wanted:
        made, asked = (in_words(serving_version(c, "graph")) for c in (exported, config))
        raise ModelMismatch(
            f"{graph.source} was built for {made} feature graph, scoring asks {asked}: "
            f"{built.differences(wanted)}; export a model for this config or score with the "
            "model's config"
        )
    return graph
