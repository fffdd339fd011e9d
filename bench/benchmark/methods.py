"""The compared methods. Each prepares one mesh (already placed in its frame) and compares two
prepared meshes into distances: lower is closer, so similarities enter as 1 - value.

A method's seconds per mesh include the renders and descriptors it uses even when another
method made them first (``Placed.shared`` keeps each and remembers what it cost).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from drkfs_onnx.contract.alignment import reference_surface, turned
from drkfs_onnx.contract.config import (
    MATCH_FIELDS,
    VIEW_FIELDS,
    AlignmentSettings,
    PipelineConfig,
)
from drkfs_onnx.contract.model_files import features_file, models_dir
from drkfs_onnx.match import match_score
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.runtime.render import NumpyRenderer
from drkfs_onnx.runtime.scorer import Scorer

from .point_metrics import iou, is_watertight, occupancy, sample_surface, surface_distances

SURFACE_SAMPLES = 100_000  # per mesh, as OccNet
QUICK_SURFACE_SAMPLES = 20_000  # in the quick run (the tests' set), where 100,000 took 14 of 46 s
# retrieval's all-pairs search: 100k samples take ~1 s per pair of different shapes, so the
# 5,460 pairs of 105 shapes would take hours
RETRIEVAL_SAMPLES = 10_000
DEFAULT_NAME = "DR-KFS"  # the shipped default config, marked "default": true in results.json
PAPER_NAME = "DR-KFS paper"  # PipelineConfig.paper(), marked "preset": "paper"
STRUCTURE_NAME = "DR-KFS structure"  # PipelineConfig.structure(), marked "preset": "structure"
# the first match choice's default: correspondence nets, global power 8
PREVIOUS_NAME = "DR-KFS previous default"


@dataclass
class Placed:
    """A mesh in the frame it is compared in, with what methods made of it so far."""

    key: str
    verts: np.ndarray
    faces: np.ndarray
    _made: dict = field(default_factory=dict)

    def shared(self, key: tuple, make) -> tuple[object, float]:
        """``make()``'s value for this mesh and the seconds it took, made once per ``key``."""
        if key not in self._made:
            self._made[key] = timed_call(make)
        return self._made[key]

    def views(self, renderer: NumpyRenderer) -> tuple[np.ndarray, float]:
        """(K * T, S, S) images from the renderer's cameras (T rings of K), and the seconds they
        took to render."""
        config = renderer.config
        key = ("views", *(getattr(config, name) for name in VIEW_FIELDS))
        return self.shared(key, lambda: renderer.render(self.verts, self.faces))


class Method:
    """outputs: the names of the distances ``compare`` returns (one row each in the results)."""

    outputs: tuple[str, ...]
    symmetric = False  # compare(a, b) == compare(b, a): retrieval scores each pair once

    def prepare(self, placed: Placed) -> tuple[object, float]:
        """-> (prepared mesh, seconds it cost)."""
        raise NotImplementedError

    def compare(self, a, b) -> tuple[float | None, ...]:
        raise NotImplementedError

    def for_retrieval(self) -> Method:
        """The method retrieval's all-pairs search runs (itself, unless that costs too much)."""
        return self


def timed_call(fn, *args):
    start = time.perf_counter()
    value = fn(*args)
    return value, time.perf_counter() - start


def sampled_surface(placed: Placed, config: PipelineConfig) -> tuple[object, float]:
    """The surface samples a mesh compared with ``placed`` is turned onto, and the seconds they
    took; (None, 0) where the config turns no mesh."""
    if not config.align_degrees:
        return None, 0.0
    return timed_call(reference_surface, placed.verts, placed.faces, config)


def turned_onto(a, b, config: PipelineConfig, describe):
    """A's prepared (placed, described) turned onto B's (placed, described, surface) as the
    config turns a compared mesh (``contract.alignment``): A's description, made again by
    ``describe`` (a ``Placed`` -> its description) where a turn is applied."""
    (placed, described, _), surface = a, b[2]
    verts = turned(placed.verts, placed.faces, surface, config)
    if verts is placed.verts:
        return described
    return describe(Placed(f"{placed.key}@turned", verts, placed.faces))


class DrkfsOnnx(Method):
    """The runtime scorer (numpy renderer + onnxruntime), for one config and feature graph; a
    config that turns a compared mesh onto its reference turns A onto B (as ``Scorer.score``)."""

    def __init__(self, name: str, config: PipelineConfig, model: Path | None, threads: int):
        self.outputs = (name,)
        self.scorer = Scorer(config, model, threads=threads)
        # match(a, b) == match(b, a), unless A is turned onto B
        self.symmetric = config.direction == "both" and not config.align_degrees
        # configs that differ only in their match or their turn describe a mesh alike
        unturned = config.replace(**dataclasses.asdict(AlignmentSettings()))
        self.features_key = ("features", unturned.shaping("features"), model)

    def _describe(self, placed: Placed):
        images, render_s = placed.views(self.scorer.renderer)
        features, seconds = placed.shared(self.features_key, lambda: self.scorer.describe(images))
        own = self.scorer.config.shaping("features")
        if features.config != own:  # described alike for another turn: this config's, relabelled
            features = dataclasses.replace(features, config=own)
        return features, render_s + seconds

    def prepare(self, placed):
        features, seconds = self._describe(placed)
        surface, sampling = sampled_surface(placed, self.scorer.config)
        return (placed, features, surface), seconds + sampling

    def compare(self, a, b):
        features = turned_onto(a, b, self.scorer.config, lambda p: self._describe(p)[0])
        return (self.scorer.match(features, b[1]),)


class DrkfsTorch(Method):
    """``DRKFS`` in evaluation mode, torch eager, its own torch renderer; A turned onto B as
    ``DrkfsOnnx`` turns it."""

    def __init__(self, name: str, metric: DRKFS):
        self.outputs = (name,)
        self.metric = metric

    def _described(self, placed: Placed) -> tuple[torch.Tensor, torch.Tensor | None]:
        verts = torch.as_tensor(placed.verts, dtype=torch.float32)
        with torch.no_grad():
            return self.metric.described(verts, torch.as_tensor(placed.faces))

    def prepare(self, placed):
        described, seconds = timed_call(self._described, placed)
        surface, sampling = sampled_surface(placed, self.metric.config)
        return (placed, described, surface), seconds + sampling

    def compare(self, a, b):
        desc_a, views_a = turned_onto(a, b, self.metric.config, self._described)
        desc_b, views_b = b[1]
        config = self.metric.config
        return (float(match_score(desc_a, desc_b, config, None, None, views_a, views_b)),)


class ImageMSE(Method):
    """Mean squared difference of the same renders (pixels), or of their PoI maps."""

    symmetric = True

    def __init__(self, name: str, renderer: NumpyRenderer, detector: torch.nn.Module | None):
        self.outputs = (name,)
        self.renderer, self.detector = renderer, detector

    def _maps(self, images: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return self.detector(torch.from_numpy(images[:, None].astype(np.float32))).numpy()

    def prepare(self, placed):
        images, render_s = placed.views(self.renderer)
        if self.detector is None:
            return images, render_s
        maps, seconds = timed_call(self._maps, images)
        return maps, render_s + seconds

    def compare(self, a, b):
        return (float(np.mean((a - b) ** 2)),)


class Surface(Method):
    """Chamfer-L1, 1 - F-score at 1%, 1 - normal consistency from one nearest-neighbour pass."""

    outputs = ("Chamfer-L1", "F-score 1%", "normal consistency")
    symmetric = True

    def __init__(self, samples: int = SURFACE_SAMPLES):
        self.samples = samples

    @classmethod
    def of_bench(cls, quick: bool) -> Surface:
        """At the benchmark's samples a mesh, or its quick run's."""
        return cls(QUICK_SURFACE_SAMPLES if quick else SURFACE_SAMPLES)

    def prepare(self, placed):
        return timed_call(sample_surface, placed.verts, placed.faces, self.samples)

    def compare(self, a, b):
        d = surface_distances(a, b)
        return d["chamfer_l1"], 1.0 - d["fscore"], 1.0 - d["normal_consistency"]

    def for_retrieval(self) -> Surface:
        return Surface(RETRIEVAL_SAMPLES)


class VolumeIoU(Method):
    """1 - IoU of 64^3 occupancy grids; None (not applicable) unless both are watertight."""

    outputs = ("volumetric IoU",)
    symmetric = True

    def _occupancy(self, placed: Placed):
        if not is_watertight(placed.verts, placed.faces):
            return None
        return occupancy(placed.verts, placed.faces)

    def prepare(self, placed):
        return timed_call(self._occupancy, placed)

    def compare(self, a, b):
        return (None if a is None or b is None else 1.0 - iou(a, b),)


def _match_of(config: PipelineConfig) -> dict:
    return {name: getattr(config, name) for name in MATCH_FIELDS}


# The quick run (the tests' set) caps every DR-KFS config at 6 cameras of 144 px: the paper's
# 25 views of 256 px took half of its time; the default runs as shipped
QUICK_CAP = {"num_views": 6, "image_size": 144}


def drkfs_configs(quick: bool = False) -> dict[str, PipelineConfig]:
    """The DR-KFS rows of the benchmark by name: the default, the paper and structure presets,
    the previous default (the structure preset's match with the correspondence nets), and the
    default and paper each with the other's match (what the cameras and what the match
    contribute); ``quick``: each within ``QUICK_CAP``."""
    default, paper = PipelineConfig(), PipelineConfig.paper()
    configs = {
        DEFAULT_NAME: default,
        PAPER_NAME: paper,
        STRUCTURE_NAME: PipelineConfig.structure(),
        PREVIOUS_NAME: PipelineConfig.structure(nets="correspondence"),
        "DR-KFS default cameras, paper match": default.replace(**_match_of(paper)),
        "DR-KFS paper cameras, default match": paper.replace(**_match_of(default)),
    }
    if not quick:
        return configs
    return {
        name: c.replace(**{key: min(getattr(c, key), cap) for key, cap in QUICK_CAP.items()})
        for name, c in configs.items()
    }


def build_methods(models: Path, threads: int, quick: bool = False) -> list[Method]:
    """Every method; DR-KFS in the configs of ``drkfs_configs(quick)``, the surface metrics at
    ``Surface.of_bench(quick)``'s samples. When a config's feature graph is not shipped
    (weights retrained but not exported), ``drkfs export``'s function runs once, before any
    scoring, and writes every graph of the current weights into ``models``."""
    from drkfs_onnx.export.onnx_files import export_shipped

    configs = drkfs_configs(quick)
    shipped = models_dir()
    exported = any(not (shipped / features_file(c)).is_file() for c in configs.values())
    if exported:
        export_shipped(models)
    methods: list[Method] = [
        DrkfsOnnx(name, config, models / features_file(config) if exported else None, threads)
        for name, config in configs.items()
    ]
    default = configs[DEFAULT_NAME]
    paper = configs[PAPER_NAME]
    cameras = {"num_views": paper.num_views, "image_size": paper.image_size}
    renderer = NumpyRenderer(PipelineConfig.paper(**cameras), threads=threads)
    metric = DRKFS.pretrained(default)
    return [
        *methods,
        DrkfsTorch("DR-KFS torch", metric),
        ImageMSE("pixel MSE", renderer, None),
        ImageMSE("PoI-map MSE", renderer, metric.detector),
        Surface.of_bench(quick),
        VolumeIoU(),
    ]
