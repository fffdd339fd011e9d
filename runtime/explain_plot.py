"""The ``drkfs-score explain`` picture (matplotlib: ``pip install "drkfs-onnx[plot]"``): A's views
in the top row and B's below them, each patch's best-match distance as a heat overlay on the
patch grid, and the patches that carry most of the score outlined."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from .explain import SIDES, Explanation

CELL_INCHES = 2.2
HEAT = "inferno"
OUTLINE = "#00e5ff"


def write_explanation(path: Path, explanation: Explanation, top: int = 5) -> None:
    config = explanation.config
    size, stride, side = config.image_size, config.patch_stride, config.patches_per_side
    # each patch's value fills the stride-sized cell around its centre
    first = (config.patch_size - stride) / 2
    extent = (first, first + side * stride, first + side * stride, first)
    peak = max(float(d.max()) for d in explanation.distances.values())
    outlined = explanation.top_patches(top)
    figure = Figure(
        figsize=(CELL_INCHES * config.num_views + 1.2, 2 * CELL_INCHES + 0.6),
        layout="constrained",
    )
    grid = figure.subplots(2, config.num_views, squeeze=False)
    heat = None
    for row, mesh in enumerate(SIDES):
        for view in range(config.num_views):
            axes = grid[row, view]
            axes.imshow(explanation.views[mesh][view], cmap="gray", vmin=0.0, vmax=1.0)
            if mesh in explanation.distances:
                distances = explanation.distances[mesh][view]
                heat = axes.imshow(
                    np.ma.masked_equal(distances, 0.0),  # exact matches stay clear
                    cmap=HEAT,
                    vmin=0.0,
                    vmax=peak or 1.0,
                    alpha=0.55,
                    extent=extent,
                    interpolation="nearest",
                )
            for rank, patch in enumerate(outlined, 1):
                if patch["mesh"] == mesh and patch["view"] == view:
                    corner = (patch["column"] * stride - 0.5, patch["row"] * stride - 0.5)
                    axes.add_patch(
                        Rectangle(corner, config.patch_size, config.patch_size, fill=False,
                                  edgecolor=OUTLINE, linewidth=1.5)
                    )  # fmt: skip
                    axes.text(corner[0] + 1, corner[1] + 5, f"{rank}", color=OUTLINE, fontsize=7)
            axes.set_xlim(-0.5, size - 0.5)
            axes.set_ylim(size - 0.5, -0.5)
            axes.set_xticks([])
            axes.set_yticks([])
            if row == 0:
                axes.set_title(f"view {view}", fontsize=8)
        searched = "" if mesh in explanation.distances else "\n(does not search)"
        role = "A" if mesh == "a" else "B (reference)"
        grid[row, 0].set_ylabel(
            f"{role}\n{Path(explanation.names[mesh]).name}{searched}", fontsize=8
        )
    figure.suptitle(
        f"DR-KFS {explanation.score:.4g}; top {len(outlined)} patches outlined "
        f"({sum(p['share'] for p in outlined):.0%} of the score"
        + (
            f"; the views' solid change {explanation.solid_change:.3g}"
            if explanation.solid_change
            else ""
        )
        + ")",
        fontsize=9,
    )
    if heat is not None:
        figure.colorbar(heat, ax=grid, shrink=0.4, label="best-match squared distance")
    figure.savefig(path, dpi=100)
