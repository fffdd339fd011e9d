"""The match of two described meshes in numpy: best-match distances per row, reduced into a
score by the shared contract (``drkfs_onnx.contract.match_rules``)."""

from __future__ import annotations

import numpy as np

from drkfs_onnx.contract import match_rules
from drkfs_onnx.contract.array_ops import NUMPY_OPS
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.solid_change import solid_change

from .features import MeshFeatures
from .nearest import exact_copies, nearest_lifted

# Query rows per block of window matching: (rows, W, D) float64 differences stay ~10 MiB at W = 9.
WINDOW_ROWS = 1024


def global_distances(queries: MeshFeatures, targets: MeshFeatures) -> np.ndarray:
    """(R,) squared distance from each of the queries' rows to its nearest target row.

    A row with an exact copy among the targets matches at 0 (most rows, for small changes); the
    others' nearest rows are found in float32 (``nearest_lifted``) and the distances to them
    computed in float64.
    """
    rows = queries.rows
    best = np.zeros(len(rows))
    rest = np.flatnonzero(~exact_copies(rows, queries.row_hashes, targets.rows, targets.row_hashes))
    if len(rest):
        searched = rows if len(rest) == len(rows) else rows[rest]
        nearest = targets.rows[nearest_lifted(searched, targets.lifted)]
        diff = np.subtract(searched, nearest, dtype=np.float64)
        best[rest] = np.einsum("ij,ij->i", diff, diff)
    return best


def window_distances(queries: np.ndarray, targets: np.ndarray, table: np.ndarray) -> np.ndarray:
    """(N, D), (N, D) every patch's descriptor at the same grid positions, (N, W)
    ``match_rules.window_table`` -> (N,) squared distance to the best match in each window.

    A patch equal to the target patch at its own position matches at 0 without a search: every
    background patch seen as background on both sides, and unchanged patches.
    """
    best = np.zeros(len(queries))
    rest = np.flatnonzero((queries != targets).any(1))
    for start in range(0, len(rest), WINDOW_ROWS):
        rows = rest[start : start + WINDOW_ROWS]
        diff = np.subtract(queries[rows, None, :], targets[table[rows]], dtype=np.float64)
        best[rows] = np.einsum("nwd,nwd->nw", diff, diff).min(1)
    return best


def best_matches(
    queries: MeshFeatures, targets: MeshFeatures, config: PipelineConfig
) -> tuple[np.ndarray, np.ndarray]:
    """(R,) squared distance from each of the queries' rows to its best match under the config's
    matching, and (R,) how many patches each row stands for (``match_rules.reduce``'s input)."""
    if config.matching == "global":
        return global_distances(queries, targets), queries.weights
    distances = window_distances(queries.dense, targets.dense, match_rules.window_table(config))
    return distances, np.ones(len(distances))


def patch_distances(
    queries: MeshFeatures, targets: MeshFeatures, config: PipelineConfig
) -> tuple[np.ndarray, np.ndarray]:
    """(K * P,) each query patch's best-match squared distance and (K * P,) its share of this
    direction's reduced score (``match_rules.shares``; the background row's share is split
    evenly over the empty patches it stands for)."""
    distances, weights = best_matches(queries, targets, config)
    share = match_rules.shares(distances, weights, config) / weights
    if config.matching == "window":
        return distances, share
    return queries.per_patch(distances), queries.per_patch(share)


def check_features(
    features: MeshFeatures, config: PipelineConfig, model: str, normalization: str
) -> None:
    """Refuse features computed for another config (naming the settings that differ), by
    another feature graph than ``model`` (a sha256) or under another normalisation."""
    made, asked = features.config.features_part(), config.features_part()
    if made != asked:
        raise ValueError(
            f"{features.source}: features computed for another config: {made.differences(asked)}"
        )
    if features.model != model:
        raise ValueError(
            f"{features.source}: features from different feature graphs "
            f"({features.model[:12]}, expected {model[:12]})"
        )
    if features.normalization != normalization:
        raise ValueError(
            f"{features.source}: features made with normalisation "
            f"{features.normalization!r}, scoring asked {normalization!r}; describe "
            f"the reference again with --normalize {normalization}"
        )
    if config.solid_weight and features.views is None:
        raise ValueError(
            f"{features.source}: features without their views, which the config's solid change "
            f"(solid_weight {config.solid_weight:g}) compares; describe the mesh again with this "
            "version's drkfs-score features"
        )


def match(a: MeshFeatures, b: MeshFeatures, config: PipelineConfig) -> float:
    """DR-KFS of A against B from their features: each direction the config searches, its
    best-match distances reduced (``match_rules.reduce``), averaged over the directions, plus
    the views' solid change times ``solid_weight`` (``contract.solid_change``); with a turned
    ring of cameras, the least such score over ``match_rules.ring_pairings``."""
    for features in (a, b):
        check_features(features, config, a.model, a.normalization)
    if len(config.rings) > 1:  # the least score over the rings compared (match_rules)
        one = config.one_ring()
        return min(match(a.ring(i), b.ring(j), one) for i, j in match_rules.ring_pairings(config))
    scores = [
        float(match_rules.reduce(*best_matches(queries, targets, config), config))
        for queries, targets in match_rules.directions(a, b, config)
    ]
    score = float(np.mean(scores))
    if config.solid_weight:
        ranges = a.view_range(config), b.view_range(config)
        change = solid_change(a.views, b.views, config, NUMPY_OPS, *ranges)
        score += config.solid_weight * float(change)
    return score
