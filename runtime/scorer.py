"""Evaluation-only DR-KFS: mesh -> numpy views -> ONNX features (onnxruntime) -> numpy match.

Scores equal the torch path's (``drkfs_onnx.DRKFS`` in evaluation mode) to float rounding.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import warnings
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from drkfs_onnx.contract.alignment import SurfaceSamples, reference_surface, turned
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import (
    Mesh,
    MeshError,
    check_normalization,
    declared_faces,
    frame_of,
    load_mesh,
    place,
)
from drkfs_onnx.contract.patch_grid import nonempty_patches
from drkfs_onnx.contract.render_equations import opposed_edges
from drkfs_onnx.contract.versions import LATEST, metric_config, metric_name

from .features import MeshFeatures
from .match import check_features, match
from .render import NumpyRenderer
from .sessions import open_features

MeshLike = Mesh | str | Path
# drkfs-score's default bound on a mesh's faces: one file's memory stays under about 4 GB
# (docs/design_notes.md, bench/large_mesh.py)
MAX_FACES = 5_000_000
# meshes with more faces than this say what they are doing before the long part starts
PROGRESS_FACES = 1_000_000


# what to try when a mesh placed in the reference's frame is out of every camera's view
JOINT_HINT = (
    "; joint is for a prediction and its ground truth in one frame: for two shapes of unknown "
    "scale or units use normalisation each (--normalize each)"
)


def reference_of(path: str | Path) -> Path | MeshFeatures:
    """A mesh path, or the features file written by ``drkfs-score features`` (a .npz), loaded."""
    path = Path(path)
    return MeshFeatures.load(path) if path.suffix == ".npz" else path


class WindingWarning(UserWarning):
    """A mesh whose file winds neighbouring faces against each other, scored by a config that
    reads a face's outside from the file."""


class Scorer:
    """DR-KFS between meshes, scored with onnxruntime; torch is never imported.

    Args:
        config: the score's settings; the feature graph must have been exported for them
            (``ModelMismatch`` otherwise). None: ``metric``'s.
        metric: a named version (``contract.versions``: ``drkfs-1.0``, ``drkfs-paper``, ...)
            whose frozen config to score with, when ``config`` is None; None: the newest.
        model: a feature graph's path; None for the shipped one of ``config``.
        threads: onnxruntime intra-op threads and renderer threads (None: all cores); the
            match's BLAS threads follow OPENBLAS_NUM_THREADS.
        normalization: 'joint' (both meshes by the reference's bounding box), 'each', 'none'.
        view_batch: views per feature-graph run. Memory grows with it, speed does not; the
            score does not depend on it.
        cache_size: how many meshes' descriptors are kept, keyed by the placed mesh's content
            and the model's hash: a ground truth scored against many predictions is described
            once.
        max_faces: a mesh with more faces is refused (``MeshError``) before it is rendered;
            None: no bound.
        progress: called with a line before and after the work on a mesh of over
            ``PROGRESS_FACES`` faces.

    Methods:
        - ``score(a, b) -> float``: A (a ``Mesh`` or a mesh's path) against the reference B (a
          mesh, a mesh's path, a features file's path, or ``MeshFeatures``).
        - ``features(mesh) -> MeshFeatures``: a reference described once; ``save`` it, and
          score against it later.
    """

    def __init__(
        self,
        config: PipelineConfig | None = None,
        model: str | Path | None = None,
        metric: str | None = None,
        threads: int | None = None,
        normalization: str = "joint",
        view_batch: int = 1,
        cache_size: int = 32,
        max_faces: int | None = None,
        progress: Callable[[str], None] | None = None,
    ):
        if config is not None and metric is not None:
            raise ValueError("give a config or a metric version, not both")
        self.config = config or metric_config(metric or LATEST)
        self.normalization = check_normalization(normalization)
        self.view_batch = view_batch
        self.features_graph = open_features(self.config, model, threads)
        self.renderer = NumpyRenderer(self.config, threads=threads or os.cpu_count() or 1)
        self.cache: OrderedDict[str, MeshFeatures] = OrderedDict()
        self.cache_size = cache_size
        self.max_faces, self.progress = max_faces, progress
        self._empty = self._describe_views(
            np.full((1, self.config.image_size, self.config.image_size), self.config.background),
            np.array([0]),
        )[0]

    @property
    def metric(self) -> str:
        """The named version this scorer's config is (``CUSTOM`` where a setting differs)."""
        return metric_name(self.config)

    @property
    def model_version(self) -> str:
        return self.features_graph.version

    @property
    def settings(self) -> str:
        """A digest of everything that shapes this scorer's scores: the config, the
        normalisation and the feature graph (batch resume keys on it)."""
        shaping = {
            "config": self.config.to_dict(),
            "normalization": self.normalization,
            "model": self.features_graph.sha256,
        }
        return hashlib.sha256(json.dumps(shaping, sort_keys=True).encode()).hexdigest()[:16]

    def features(
        self,
        mesh: MeshLike,
        frame: tuple[np.ndarray, float] | None = None,
        onto: SurfaceSamples | None = None,
    ) -> MeshFeatures:
        """Descriptors of a mesh placed in ``frame`` (default: its own normalisation frame) and
        turned onto the reference surface ``onto`` where the config turns meshes
        (``contract.alignment``); without ``onto``, not turned and with its own surface samples,
        as a reference."""
        mesh = self.load(mesh)
        placement = "its own frame" if frame is None else "the reference's frame"
        hint = JOINT_HINT if frame is not None else ""
        if frame is None:
            frame = self._own_frame(mesh.vertices)
        placed = turned(place(mesh.vertices, frame), mesh.faces, onto, self.config)
        key = self._key(placed, mesh.faces)
        if key in self.cache:
            self.cache.move_to_end(key)
            if onto is None and self.config.align_degrees and self.cache[key].surface is None:
                # described before as a compared mesh, now wanted as a reference
                self.cache[key] = self._as_reference(self.cache[key], placed, mesh.faces)
            return self.cache[key]
        start, long = time.perf_counter(), len(mesh.faces) > PROGRESS_FACES and self.progress
        if long:
            self.progress(
                f"{mesh.source}: {len(mesh.faces):,} faces; rendering and describing "
                f"{self.config.views_per_mesh} views"
            )
        result = self.describe(self.renderer.render(placed, mesh.faces), frame)
        if onto is None:
            result = self._as_reference(result, placed, mesh.faces)
        if long:
            self.progress(f"{mesh.source}: done in {time.perf_counter() - start:.0f} s")
        if len(result.patch_index) == 0:
            # every patch would match every other as empty: a silent perfect score
            raise MeshError(
                mesh.source,
                f"nothing visible from any camera after normalisation "
                f"({self.normalization}: placed in {placement}){hint}",
            )
        self.cache[key] = result
        if len(self.cache) > self.cache_size:
            self.cache.popitem(last=False)
        return result

    def _as_reference(self, features: MeshFeatures, placed, faces) -> MeshFeatures:
        """``features`` with the surface samples a mesh compared with them is turned onto (none
        where the config turns no mesh)."""
        return replace(features, surface=reference_surface(placed, faces, self.config))

    def load(self, mesh: MeshLike) -> Mesh:
        """A checked mesh within ``max_faces``; a MeshError naming the file otherwise. A PLY or
        OFF file's header is checked before its geometry is read."""
        if not isinstance(mesh, Mesh):
            if self.max_faces is not None:
                self._check_faces(str(mesh), declared_faces(mesh))
            mesh = load_mesh(mesh)
        self._check_faces(mesh.source, len(mesh.faces))
        self._check_winding(mesh)
        return mesh

    def _check_winding(self, mesh: Mesh) -> None:
        """A warning (``WindingWarning``) where the config reads a face's outside from the file
        and the file winds faces that share an edge against each other."""
        if self.config.winding != "file" or self.config.back_light >= 1.0:
            return  # read from the surface, or lit alike from both sides: the winding is moot
        opposed = opposed_edges(mesh.vertices, mesh.faces)
        if opposed:
            warnings.warn(
                f"{mesh.source}: {opposed:,} of its edges are run the same way by two faces "
                "(faces wound against their neighbours), which "
                "shade as a shell's inside here; --winding geometry (winding='geometry') reads "
                "each face's outside from the surface",
                WindingWarning,
                stacklevel=2,  # one place: each file's warning is shown once
            )

    def _check_faces(self, source: str, faces: int | None) -> None:
        if self.max_faces is not None and faces is not None and faces > self.max_faces:
            raise MeshError(
                source,
                f"{faces:,} faces, over the bound of {self.max_faces:,} "
                "(--max-faces; raise it to score this mesh)",
            )

    def views(self, mesh: Mesh, frame: tuple[np.ndarray, float]) -> np.ndarray:
        """(K, S, S) grey views of ``mesh`` placed in ``frame`` (as ``features`` sees it,
        turned onto no reference)."""
        return self.renderer.render(place(mesh.vertices, frame), mesh.faces)

    def describe(
        self, images: np.ndarray, frame: tuple[np.ndarray, float] | None = None
    ) -> MeshFeatures:
        """Features of rendered views (K, S, S), e.g. ``self.renderer``'s, of a mesh placed in
        ``frame`` (default: where it is, centre 0 and scale 1)."""
        frame = (np.zeros(3), 1.0) if frame is None else frame
        index = np.flatnonzero(nonempty_patches(images, self.config))
        return MeshFeatures(
            descriptors=self._describe_views(images, index),
            patch_index=index,
            empty_descriptor=self._empty,
            centre=np.asarray(frame[0], dtype=np.float64),
            scale=float(frame[1]),
            normalization=self.normalization,
            model=self.features_graph.sha256,
            config=self.config.shaping("features"),
            views=images.astype(np.float32),
        )

    def score(self, a: MeshLike, b: MeshLike | MeshFeatures) -> float:
        """DR-KFS of A against the reference B (0 for identical meshes)."""
        a = self.load(a)  # a bad A fails before B's work
        if isinstance(b, (str, Path)):
            b = reference_of(b)
        reference = b if isinstance(b, MeshFeatures) else self.features(b)
        # before A's work
        check_features(reference, self.config, self.features_graph.sha256, self.normalization)
        return self.match(self.compared(a, reference), reference)

    def compared(self, a: Mesh, reference: MeshFeatures) -> MeshFeatures:
        """A's descriptors as they are matched against the checked ``reference``: placed in
        its frame (joint normalisation) or A's own, and turned onto its surface."""

        if self.config.align_degrees and reference.surface is None:
            raise ValueError(
                f"{reference.source}: features of views alone, without the surface samples a "
                "mesh is turned onto before it is compared (align_degrees "
                f"{self.config.align_degrees:g}): describe the reference from its mesh"
            )
        frame = reference.frame if self.normalization == "joint" else None
        return self.features(a, frame, reference.surface)

    def match(self, a: MeshFeatures, b: MeshFeatures) -> float:
        """The score of described A against described B under the scorer's config."""
        return match(a, b, self.config)

    def _own_frame(self, vertices: np.ndarray) -> tuple[np.ndarray, float]:
        if self.normalization == "none":
            return np.zeros(3), 1.0
        centre, scale = frame_of(vertices)
        return centre, float(scale)

    def _key(self, vertices: np.ndarray, faces: np.ndarray) -> str:
        digest = hashlib.sha256(self.features_graph.sha256.encode())
        digest.update(np.ascontiguousarray(vertices, dtype=np.float64).tobytes())
        digest.update(np.ascontiguousarray(faces, dtype=np.int64).tobytes())
        return digest.hexdigest()

    def _describe_views(self, images: np.ndarray, index: np.ndarray) -> np.ndarray:
        """(K, S, S) views and sorted flat patch indices -> (len(index), D) descriptors, run
        ``view_batch`` views at a time."""
        per_view = self.config.patches_per_view
        parts = [np.zeros((0, self.config.descriptor_dim), np.float32)]
        for start in range(0, len(images), self.view_batch):
            stop = min(start + self.view_batch, len(images))
            chosen = index[(index >= start * per_view) & (index < stop * per_view)]
            if len(chosen):
                views = images[start:stop, None].astype(np.float32)
                inputs = {"views": views, "patch_index": chosen - start * per_view}
                parts.append(self.features_graph.session.run(None, inputs)[0])
        return np.concatenate(parts)
