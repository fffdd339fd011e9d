"""One mesh's descriptors as the runtime keeps them: the non-empty patches' descriptors and a
count of background patches (which share one descriptor)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from .nearest import row_hashes

FORMAT = "drkfs-features-1"


@dataclass(frozen=True)
class MeshFeatures:
    """descriptors: (N, D) float32 of the patches that see the mesh; empty: how many of the
    K * P patches see only background; centre (3,) and scale: the frame the mesh was placed in
    (v' = (v - centre) / scale), which joint normalisation applies to meshes scored against it;
    model: sha256 of the feature graph that computed them."""

    descriptors: np.ndarray
    empty: int
    centre: np.ndarray
    scale: float
    model: str

    @cached_property
    def row_hashes(self) -> np.ndarray:
        """(N,) uint64 hashes of the descriptor rows, to find exact copies (once per mesh)."""
        return row_hashes(self.descriptors)

    def save(self, path: str | Path) -> None:
        np.savez_compressed(
            path,
            format=FORMAT,
            descriptors=self.descriptors,
            empty=self.empty,
            centre=self.centre,
            scale=self.scale,
            model=self.model,
        )

    @classmethod
    def load(cls, path: str | Path) -> MeshFeatures:
        with np.load(path, allow_pickle=False) as data:
            if "format" not in data or str(data["format"]) != FORMAT:
                raise ValueError(f"{path}: not a drkfs-score features file ({FORMAT})")
            return cls(
                descriptors=data["descriptors"],
                empty=int(data["empty"]),
                centre=data["centre"],
                scale=float(data["scale"]),
                model=str(data["model"]),
            )
