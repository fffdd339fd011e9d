"""The match of two described meshes in numpy: best-match distances per row, reduced into a
score by the shared contract (``drkfs_onnx.contract.match_rules``), plus the views' solid change
(``drkfs_onnx.contract.solid_change``)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from drkfs_onnx.contract import match_rules
from drkfs_onnx.contract.array_ops import NUMPY_OPS
from drkfs_onnx.contract.config import TWO_SIDED, PipelineConfig
from drkfs_onnx.contract.nearest import nearest_lifted
from drkfs_onnx.contract.solid_change import solid_reaches, view_solid_changes
from drkfs_onnx.contract.versions import in_words, serving_version

from .features import MeshFeatures
from .nearest import exact_copies

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


def _two_sided(config: PipelineConfig) -> bool:
    return all(getattr(config, name) == value for name, value in TWO_SIDED.items())


def _light_alone(made: PipelineConfig, asked: PipelineConfig) -> bool:
    """Whether two configs (``shaping`` keys, not configs to run) differ in light alone."""
    a, b = made.to_dict(), asked.to_dict()
    return all(a[name] == b[name] for name in a if name not in TWO_SIDED)


def check_features(
    features: MeshFeatures, config: PipelineConfig, model: str, normalization: str
) -> None:
    """Refuse features computed for another config (naming the settings that differ), by
    another feature graph than ``model`` (a sha256) or under another normalisation."""
    made, asked = features.config.shaping("features"), config.shaping("features")
    if made != asked:
        hint = ""
        if _light_alone(made, asked):
            if _two_sided(made):
                hint = "; it was described under two-sided light: score with --two-sided, or "
                hint += "describe it again"
            elif _two_sided(asked):
                hint = "; scoring asks two-sided light (--two-sided): score without it, or "
                hint += "describe the reference again with it"
        raise ValueError(
            f"{features.source}: features described for {in_words(serving_version(made))} "
            f"views, scoring asks {in_words(serving_version(asked))}: "
            f"{made.differences(asked)}{hint}"
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


class Pairing(NamedTuple):
    """The ring pairing whose score counts: score = part + solid, rings = (A's, B's)."""

    score: float
    rings: tuple[int, int]
    solid: float


def match(a: MeshFeatures, b: MeshFeatures, config: PipelineConfig) -> float:
    """DR-KFS of A against B from their features (``best_pairing``'s score), each checked to
    have been described for ``config``."""
    for features in (a, b):
        check_features(features, config, a.model, a.normalization)
    return best_pairing(a, b, config).score


def best_pairing(a: MeshFeatures, b: MeshFeatures, config: PipelineConfig) -> Pairing:
    """The one assembly of the score: for each ring pairing (``match_rules.ring_pairings``) the
    descriptors' part (each direction the config searches, its best-match distances reduced by
    ``match_rules.reduce``, averaged over the directions; ``match_rules.pairing_part``) plus
    ``solid_weight`` times the views' solid change (``match_rules.pairing_solid``); the least
    such sum is the score."""
    parts = sorted(
        (pairing_part(a, b, i, j, config), (i, j)) for i, j in match_rules.ring_pairings(config)
    )
    best = Pairing(math.inf, parts[0][1], 0.0)
    for part, rings in parts:
        if part >= best.score:  # the solid change only adds: this pairing cannot score less
            break
        solid = pairing_solid(a, b, *rings, config)
        if part + solid < best.score:
            best = Pairing(part + solid, rings, solid)
    return best


def pairing_part(a: MeshFeatures, b: MeshFeatures, i: int, j: int, config: PipelineConfig):
    """The descriptors' part of A's ring ``i`` against B's ring ``j`` (``match_rules.
    pairing_part``) of two meshes' features."""
    one = config.one_ring()
    return float(
        match_rules.pairing_part(
            i, j, lambda k, m: descriptor_part(a.ring(k), b.ring(m), one), config
        )
    )


def descriptor_part(a: MeshFeatures, b: MeshFeatures, config: PipelineConfig) -> float:
    """The descriptors' score of two one-ring meshes: each direction's best-match distances
    reduced, averaged over the directions."""
    scores = [
        float(match_rules.reduce(*best_matches(queries, targets, config), config))
        for queries, targets in match_rules.directions(a, b, config)
    ]
    return float(np.mean(scores))


def pairing_solid(a: MeshFeatures, b: MeshFeatures, i: int, j: int, config: PipelineConfig):
    """``solid_weight`` times the views' solid change of A's ring ``i`` against B's ring ``j``
    (``match_rules.pairing_solid``); 0 without a solid change."""
    if not config.solid_weight:
        return 0.0
    one = config.one_ring()
    return float(
        match_rules.pairing_solid(
            i, j, lambda k, m: solid_views(a.ring(k), b.ring(m), one), config, NUMPY_OPS
        )
    )


def solid_views(a: MeshFeatures, b: MeshFeatures, config: PipelineConfig) -> np.ndarray:
    """(K,) each view's solid change of two one-ring meshes (``contract.solid_change.
    view_solid_changes``), computed in the window of the views where either mesh shows
    anything, grown by the reach: a pixel further than ``solid_shift`` from everything shown is
    background in both views and in the other's range, so it changes by nothing, and each
    view's change is the whole views' to the bit."""
    shift, size = config.solid_shift, config.image_size
    nothing = np.zeros(config.num_views)
    box = []  # per axis: the inner pixels (whose range is taken) of the window, [start, stop)
    for seen_a, seen_b in zip(a.seen_lines, b.seen_lines, strict=True):
        seen = np.flatnonzero(seen_a | seen_b)
        if len(seen) == 0:
            return nothing
        box.append((max(seen[0] - shift, shift), min(seen[-1] + 1 + shift, size - shift)))
    (top, bottom), (left, right) = box
    if min(bottom - top, right - left) < config.solid_block:
        return nothing  # every block of the whole views holds an unchanged pixel outside it
    views = np.s_[..., top - shift : bottom + shift, left - shift : right + shift]
    ranges_a, ranges_b = {}, {}
    for reach in set().union(*solid_reaches(config)):
        # the window's views' range at this reach: its pixels from ``reach`` in
        window = np.s_[..., top - shift : bottom + shift - 2 * reach,
                       left - shift : right + shift - 2 * reach]  # fmt: skip
        ranges_a[reach] = tuple(r[window] for r in a.view_range(reach))
        ranges_b[reach] = tuple(r[window] for r in b.view_range(reach))
    return view_solid_changes(a.views[views], b.views[views], config, NUMPY_OPS, ranges_a, ranges_b)
