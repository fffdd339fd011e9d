"""Where a score comes from: every patch's best-match distance and its share of the score.

Torch- and matplotlib-free; ``explain_plot`` draws the picture (the ``plot`` extra).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drkfs_onnx.contract import match_rules
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import Mesh

from .match import best_pairing, check_features, patch_distances
from .scorer import Scorer

SIDES = ("a", "b")


@dataclass(frozen=True)
class Explanation:
    """A scored pair, patch by patch. views: side -> (K, S, S) the views it was described from;
    distances, shares: side -> (K, n, n) best-match squared distance of each of that mesh's
    patches and its share of the whole score, for the sides whose patches search the other mesh
    (``match_rules.query_sides``); solid_change: the part of the score the views' solid change
    adds (``contract.solid_change``; 0 without one), so the patches' shares sum to 1 less its
    share; rings: side -> the ring of cameras (``config.rings``) these views and patches come
    from, those of the comparison whose score counts (where that is own ring against own ring,
    the turned ring's own comparison has a part in the score too, ``match_rules.pairing_part``
    and ``pairing_solid``, and these patches stand for it)."""

    score: float
    config: PipelineConfig
    names: dict[str, str]
    views: dict[str, np.ndarray]
    distances: dict[str, np.ndarray]
    shares: dict[str, np.ndarray]
    solid_change: float
    rings: dict[str, int]

    def top_patches(self, count: int = 5) -> list[dict]:
        """The ``count`` spots that carry the largest shares of the score, one entry a spot:
        view, grid row and column (the patch covers pixels [stride * row, stride * row + size)
        of the view), share (both meshes' patches there together), and the mesh whose patch
        there carries more (``mesh``) with its distance; ``sides``: the meshes whose patch
        there carries any. Patches that carry nothing are never listed (a score of 0 lists
        none)."""
        spots: dict[tuple, dict[str, float]] = {}
        for side, grid in self.shares.items():
            for index, share in np.ndenumerate(grid):
                if share > 0:
                    spots.setdefault(index, {})[side] = float(share)
        ranked = sorted(spots.items(), key=lambda spot: -sum(spot[1].values()))
        top = []
        for (view, row, column), shares in ranked[:count]:
            side = max(shares, key=shares.get)
            top.append({
                "mesh": side,
                "view": int(view),
                "row": int(row),
                "column": int(column),
                "distance": float(self.distances[side][view, row, column]),
                "share": sum(shares.values()),
                "sides": sorted(shares),
            })  # fmt: skip
        return top


def explain(scorer: Scorer, mesh_a: Mesh | str | Path, mesh_b: Mesh | str | Path) -> Explanation:
    """A against the reference B, placed and described as ``Scorer.score`` does."""
    a = scorer.load(mesh_a)
    b = scorer.load(mesh_b)
    reference = scorer.features(b)
    check_features(reference, scorer.config, scorer.features_graph.sha256, scorer.normalization)
    features = {
        "a": scorer.compared(a, reference),
        "b": reference,
    }
    config, one = scorer.config, scorer.config.one_ring()
    best = best_pairing(features["a"], features["b"], config)  # its rings are explained
    ring = {side: features[side].ring(r) for side, r in zip(SIDES, best.rings, strict=True)}
    grid = (config.num_views, config.patches_per_side, config.patches_per_side)
    found = {}  # side -> its patches' distances, their shares of its direction, its score
    pairs = match_rules.directions(ring["a"], ring["b"], one)
    for side, (queries, targets) in zip(match_rules.query_sides(one), pairs, strict=True):
        distances, shares = patch_distances(queries, targets, one)
        score = float(match_rules.reduce(distances, np.ones_like(distances), one))
        found[side] = (distances.reshape(grid), shares.reshape(grid), score)
    total = sum(score for _, _, score in found.values())  # each direction's part of the mean
    patches_part = 1.0 - best.solid / best.score if best.score else 1.0
    return Explanation(
        score=best.score,
        config=config,
        names={"a": a.source, "b": b.source},
        views={side: ring[side].views for side in SIDES},  # the views the features were made of
        rings=dict(zip(SIDES, best.rings, strict=True)),
        distances={side: d for side, (d, _, _) in found.items()},
        shares={
            side: s * patches_part * score / total if total else s
            for side, (_, s, score) in found.items()
        },
        solid_change=best.solid,
    )
