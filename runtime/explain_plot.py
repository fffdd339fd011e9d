"""The ``drkfs-score explain`` picture (matplotlib: ``pip install "drkfs-onnx[plot]"``): for A and
then B, a row of its plain views and below it the same views with each patch's best-match
distance as a heat overlay on the patch grid, and the spots that carry most of the score
outlined. The overlay fades out towards 0, so a patch that matches well keeps its shading."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from .explain import SIDES, Explanation

CELL_INCHES = 2.2
HEAT = "plasma"
HEAT_ALPHA = 0.8  # a patch's overlay opacity: this times its distance over the largest
OUTLINE = "#00e5ff"


def write_explanation(path: Path, explanation: Explanation, top: int = 5) -> None:
    explanation_figure(explanation, top).savefig(path, dpi=100)


def explanation_figure(explanation: Explanation, top: int = 5) -> Figure:
    """The picture: rows A's views, A's overlay, B's views, B's overlay; a column a view."""
    config = explanation.config
    size, stride, side = config.image_size, config.patch_stride, config.patches_per_side
    # each patch's value fills the stride-sized cell around its centre
    first = (config.patch_size - stride) / 2
    extent = (first, first + side * stride, first + side * stride, first)
    peak = max(float(d.max()) for d in explanation.distances.values()) or 1.0
    heat = ScalarMappable(Normalize(0.0, peak), colormaps[HEAT])
    outlined = explanation.top_patches(top)
    figure = Figure(
        figsize=(CELL_INCHES * config.num_views + 1.2, 4 * CELL_INCHES + 0.6),
        layout="constrained",
    )
    grid = figure.subplots(4, config.num_views, squeeze=False)
    for side_index, mesh in enumerate(SIDES):
        plain, overlaid = 2 * side_index, 2 * side_index + 1
        for view in range(config.num_views):
            for row in (plain, overlaid):
                axes = grid[row, view]
                axes.imshow(explanation.views[mesh][view], cmap="gray", vmin=0.0, vmax=1.0)
                axes.set_xlim(-0.5, size - 0.5)
                axes.set_ylim(size - 0.5, -0.5)
                axes.set_xticks([])
                axes.set_yticks([])
            axes = grid[overlaid, view]
            if mesh in explanation.distances:
                distances = explanation.distances[mesh][view]
                colours = heat.to_rgba(distances)
                colours[..., 3] = HEAT_ALPHA * np.clip(distances / peak, 0.0, 1.0)
                axes.imshow(colours, extent=extent, interpolation="nearest")
            for rank, patch in enumerate(outlined, 1):
                if mesh in patch["sides"] and patch["view"] == view:
                    corner = (patch["column"] * stride - 0.5, patch["row"] * stride - 0.5)
                    axes.add_patch(
                        Rectangle(corner, config.patch_size, config.patch_size, fill=False,
                                  edgecolor=OUTLINE, linewidth=1.5)
                    )  # fmt: skip
                    axes.text(corner[0] + 1, corner[1] + 5, f"{rank}", color=OUTLINE, fontsize=7)
            if side_index == 0:
                grid[0, view].set_title(f"view {view}", fontsize=8)
        searched = "" if mesh in explanation.distances else "\n(does not search)"
        role = "A" if mesh == "a" else "B (reference)"
        name = Path(explanation.names[mesh]).name
        grid[plain, 0].set_ylabel(f"{role}\n{name}", fontsize=8)
        grid[overlaid, 0].set_ylabel(f"{role}: where it differs{searched}", fontsize=8)
    figure.suptitle(
        f"DR-KFS {explanation.score:.4g}; top {len(outlined)} spots outlined "
        f"({sum(p['share'] for p in outlined):.0%} of the score"
        + (
            f"; the views' solid change {explanation.solid_change:.3g}"
            if explanation.solid_change
            else ""
        )
        + ")",
        fontsize=9,
    )
    if explanation.distances:
        figure.colorbar(heat, ax=grid, shrink=0.3, label="best-match squared distance")
    return figure
