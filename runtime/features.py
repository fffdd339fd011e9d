"""One mesh's descriptors as the runtime keeps them: the non-empty patches' descriptors with their
positions, and the one descriptor the background patches share."""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from drkfs_onnx.contract import match_rules
from drkfs_onnx.contract.alignment import SurfaceSamples
from drkfs_onnx.contract.array_ops import NUMPY_OPS
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.nearest import lift
from drkfs_onnx.contract.solid_change import view_range
from drkfs_onnx.contract.versions import CUSTOM, served_versions

from .nearest import row_hashes

FORMAT = "drkfs-features-4"  # 4: records the normalisation
SURFACE_KEYS = ("surface_points", "surface_normals")


@dataclass(frozen=True)
class MeshFeatures:
    """descriptors: (N, D) float32 of the patches that see the mesh, at patch_index (N,) sorted
    rows of the row-major (K * T * P) patch list (T rings of K views); the other patches see
    only background and share empty_descriptor (D,); centre (3,) and scale: the frame the mesh
    was placed in (v' = (v - centre) / scale), which joint normalisation applies to meshes
    scored against it;
    normalization: the scorer's normalisation when they were made (it decides the frame, and a
    scorer with another one would place the meshes scored against them differently); model:
    sha256 of the feature graph that computed them; config: the pipeline config they were
    computed for (its match settings do not matter); views: (K * T, S, S) float32 grey views
    they were made from, which a solid change of the views compares (``contract.solid_change``;
    None in a file written before they were kept); surface: points sampled on the mesh as
    placed, with their faces' normals, that a mesh compared with it is turned onto
    (``contract.alignment``; None where the config turns no mesh); source: where they were
    read from, for error messages (not saved). The match's forms of the rows, and of the views,
    are computed once per mesh."""

    descriptors: np.ndarray
    patch_index: np.ndarray
    empty_descriptor: np.ndarray
    centre: np.ndarray
    scale: float
    normalization: str
    model: str
    config: PipelineConfig
    views: np.ndarray | None = None
    surface: SurfaceSamples | None = None
    source: str = "<features>"

    @property
    def frame(self) -> tuple[np.ndarray, float]:
        """(centre, scale): the frame the mesh was placed in (``mesh.place``)."""
        return self.centre, self.scale

    @property
    def patches(self) -> int:
        """K * T * P: every patch of every view of every ring."""
        return self.config.views_per_mesh * self.config.patches_per_view

    def ring(self, ring: int) -> MeshFeatures:
        """The features of one ring of cameras (``config.rings``), as a one-ring config's; made
        once per mesh, so their match forms are too."""
        return self._rings[ring]

    @cached_property
    def _rings(self) -> tuple[MeshFeatures, ...]:
        if len(self.config.rings) == 1:
            return (self,)
        found = []
        for ring in range(len(self.config.rings)):
            rows = match_rules.ring_rows(ring, self.config)
            seen_from = match_rules.ring_views(ring, self.config)
            chosen = (self.patch_index >= rows.start) & (self.patch_index < rows.stop)
            found.append(
                replace(
                    self,
                    descriptors=self.descriptors[chosen],
                    patch_index=self.patch_index[chosen] - rows.start,
                    config=self.config.one_ring(),
                    views=None if self.views is None else self.views[seen_from],
                )
            )
        return tuple(found)

    def view_range(self, reach: int) -> tuple[np.ndarray, np.ndarray]:
        """The views' lowest and highest greys within ``reach`` pixels
        (``solid_change.view_range``), for a one-ring mesh's solid change; made once per mesh
        and reach."""
        if reach not in self._view_ranges:
            self._view_ranges[reach] = view_range(self.views, reach, NUMPY_OPS)
        return self._view_ranges[reach]

    @cached_property
    def _view_ranges(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        return {}

    @cached_property
    def seen_lines(self) -> tuple[np.ndarray, np.ndarray]:
        """(S,) bool rows and (S,) bool columns where any view shows anything but background."""
        seen = (self.views != self.config.background).any(axis=0)
        return seen.any(axis=1), seen.any(axis=0)

    @property
    def empty(self) -> int:
        """How many patches see only background."""
        return self.patches - len(self.patch_index)

    @cached_property
    def dense(self) -> np.ndarray:
        """(K * T * P, D) every patch's descriptor, background patches included (window
        matching)."""
        rows = np.tile(self.empty_descriptor, (self.patches, 1))
        rows[self.patch_index] = self.descriptors
        return rows

    @cached_property
    def rows(self) -> np.ndarray:
        """(R, D) the rows a match uses: one per non-empty patch, then the shared empty
        descriptor once if a patch is empty (identical non-empty rows are kept apart)."""
        if not self.empty:
            return self.descriptors
        return np.concatenate([self.descriptors, self.empty_descriptor[None]])

    @cached_property
    def weights(self) -> np.ndarray:
        """(R,) how many patches each row stands for."""
        return np.append(np.ones(len(self.descriptors)), [self.empty] if self.empty else [])

    @cached_property
    def row_hashes(self) -> np.ndarray:
        """(R,) uint64 hashes of the rows, to find exact copies."""
        return row_hashes(self.rows)

    def per_patch(self, values: np.ndarray) -> np.ndarray:
        """(R,) one value per row of ``rows`` -> (K * T * P,) the value of every patch (the empty
        patches all take the background row's)."""
        dense = np.full(self.patches, values[-1] if self.empty else 0.0, dtype=np.float64)
        dense[self.patch_index] = values[: len(self.descriptors)]
        return dense

    @cached_property
    def lifted(self) -> np.ndarray:
        """(R, D + 1) the rows as search targets (``nearest.lift``)."""
        return lift(self.rows)

    def save(self, path: str | Path) -> None:
        np.savez_compressed(
            path,
            format=FORMAT,
            descriptors=self.descriptors,
            patch_index=self.patch_index,
            empty_descriptor=self.empty_descriptor,
            centre=self.centre,
            scale=self.scale,
            normalization=self.normalization,
            model=self.model,
            config=self.config.shaping("features").to_json(),
            # for a reader: the versions it serves (loading derives them from the config)
            serves=np.array(served_versions(self.config) or [CUSTOM]),
            **({} if self.views is None else {"views": self.views}),
            **({} if self.surface is None else dict(zip(SURFACE_KEYS, self.surface, strict=True))),
        )

    @classmethod
    def load(cls, path: str | Path) -> MeshFeatures:
        """Read a features file; anything wrong with it is a ValueError naming the file."""
        if not Path(path).is_file():
            raise ValueError(f"{path}: no such features file")
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {name: data[name] for name in data.files}
        except Exception as exc:  # numpy and zipfile raise many types for a broken file
            # numpy's own words (allow_pickle advice for a file that is no zip) mislead here
            raise ValueError(
                f"{path}: not a features file (not a readable .npz archive: "
                f"{type(exc).__name__}); write it again with drkfs-score features"
            ) from exc
        if str(arrays.get("format", "")) != FORMAT:
            raise ValueError(
                f"{path}: not a drkfs-score features file of this version ({FORMAT}); "
                "describe the reference again with drkfs-score features"
            )
        try:
            return cls(
                descriptors=arrays["descriptors"],
                patch_index=arrays["patch_index"],
                empty_descriptor=arrays["empty_descriptor"],
                centre=arrays["centre"],
                scale=float(arrays["scale"]),
                normalization=str(arrays["normalization"]),
                model=str(arrays["model"]),
                config=PipelineConfig.from_json(str(arrays["config"])),
                views=arrays.get("views"),
                surface=_surface(arrays),
                source=str(path),
            )
        except (KeyError, ValueError) as exc:
            raise ValueError(f"{path}: incomplete features file ({exc})") from exc


def _surface(arrays: dict[str, np.ndarray]) -> SurfaceSamples | None:
    """A file's surface samples; None in a file without them; ValueError where they are not
    (N, 3) points and (N, 3) normals."""
    if not all(key in arrays for key in SURFACE_KEYS):
        return None
    points, normals = (np.asarray(arrays[key], dtype=np.float64) for key in SURFACE_KEYS)
    if points.ndim != 2 or points.shape[1:] != (3,) or normals.shape != points.shape:
        raise ValueError(f"surface samples of shapes {points.shape} and {normals.shape}")
    return SurfaceSamples(points, normals)
