"""The gallery PNG: one row per problem, one column per mesh (target, template, each loss's
result), every cell the same views from the same cameras."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..benchmark.chart import Canvas
from ..config import PipelineConfig
from ..runtime.render import NumpyRenderer

VIEWS = PipelineConfig(num_views=2, image_size=128)  # a side view and one from above
MARGIN = 6
LABEL = 14  # pixels of text above each row


def write_gallery(path: Path, columns: list[str], rows: list[tuple[str, list[tuple]]]) -> None:
    """rows: (problem name, [(verts, faces) per column]); cells stack the VIEWS vertically."""
    renderer = NumpyRenderer(VIEWS)
    size = VIEWS.image_size
    cell_w, cell_h = size + MARGIN, VIEWS.num_views * size + LABEL + MARGIN
    canvas = Canvas(MARGIN + cell_w * len(columns), LABEL + cell_h * len(rows))
    for c, name in enumerate(columns):
        canvas.text(MARGIN + c * cell_w, 3, name, (0, 0, 0))
    for r, (name, meshes) in enumerate(rows):
        top = LABEL + r * cell_h
        canvas.text(MARGIN, top + 3, name, (90, 90, 90))
        for c, (verts, faces) in enumerate(meshes):
            images = renderer.render(verts, faces).reshape(-1, size)  # views stacked
            grey = np.clip(images * 255.0, 0, 255).astype(np.uint8)
            x, y = MARGIN + c * cell_w, top + LABEL
            canvas.pixels[y : y + len(grey), x : x + size] = grey[:, :, None]
    path.write_bytes(canvas.png())
