"""The gallery PNG (matplotlib): one row per problem, one column per mesh (target, template,
each loss's result), every cell the same views from the same cameras."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.runtime.render import NumpyRenderer

VIEWS = PipelineConfig(num_views=2, turn_degrees=0.0, image_size=128)  # a side view, one from above
CELL_INCHES = 1.3  # per view


def write_gallery(path: Path, columns: list[str], rows: list[tuple[str, list[tuple]]]) -> None:
    """rows: (problem name, [(verts, faces) or an image (H, W) in [0, 1], per column]); a
    mesh's cell stacks the VIEWS vertically."""
    renderer = NumpyRenderer(VIEWS)
    size = VIEWS.image_size
    figure = Figure(
        figsize=(CELL_INCHES * len(columns), CELL_INCHES * VIEWS.num_views * len(rows)),
        layout="constrained",
    )
    grid = figure.subplots(len(rows), len(columns), squeeze=False)
    for r, (name, meshes) in enumerate(rows):
        for c, cell in enumerate(meshes):
            axes = grid[r, c]
            if isinstance(cell, np.ndarray):
                images = cell
            else:
                images = renderer.render(*cell).reshape(-1, size)  # views stacked
            axes.imshow(images, cmap="gray", vmin=0.0, vmax=1.0)
            axes.set_xticks([])
            axes.set_yticks([])
            if r == 0:
                axes.set_title(columns[c], fontsize=8)
            if c == 0:
                axes.set_ylabel(name, fontsize=7)
    figure.savefig(path, dpi=100)
