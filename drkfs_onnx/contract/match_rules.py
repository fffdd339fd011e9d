"""The match contract, written once for torch and numpy: which patches a query may match
(``window_table``), which directions are searched (``directions``), which rings of cameras are
compared (``ring_pairings``) and how each pairing's parts make its score (``pairing_part``,
``pairing_solid``), and how the best-match squared distances become one score (``reduce``).

Torch-free: ``reduce`` runs on numpy arrays, or on torch tensors with ``ops=TORCH_OPS``
(``array_ops``' convention). A row stands for ``weight`` patches: the torch path gives
every patch a row of weight 1, the runtime one row for all background patches weighted by their
count; ``reduce`` is the same number either way.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from typing import Any, TypeVar

import numpy as np

from .array_ops import NUMPY_OPS, ArrayOps
from .config import PipelineConfig

T = TypeVar("T")


@lru_cache(maxsize=8)
def window_table(config: PipelineConfig) -> np.ndarray:
    """(K * P, W) int64, read-only and cached per config: the patches each patch may match under
    'window' matching, as rows of the row-major (K * P) patch list; W = (2 * window + 1)^2.

    Same view, row and column each within ``window`` grid steps. At the image border a
    neighbour is clamped into the grid, which gives a patch that is also within the window, so
    border rows repeat entries instead of needing a mask (a repeat does not change a minimum).
    """
    side, per_view = config.patches_per_side, config.patches_per_view
    rows, cols = np.divmod(np.arange(per_view), side)
    steps = np.arange(-config.window, config.window + 1)
    near_rows = np.clip(rows[:, None, None] + steps[None, :, None], 0, side - 1)
    near_cols = np.clip(cols[:, None, None] + steps[None, None, :], 0, side - 1)
    one_view = (near_rows * side + near_cols).reshape(per_view, -1)
    views = np.arange(config.num_views)[:, None, None] * per_view
    table = (views + one_view[None]).reshape(config.num_views * per_view, -1)
    table.setflags(write=False)
    return table


def query_sides(config: PipelineConfig) -> tuple[str, ...]:
    """Whose patches search the other mesh: 'a' (forward, the paper), 'b' (backward) or both."""
    return {"forward": ("a",), "backward": ("b",), "both": ("a", "b")}[config.direction]


def directions(a: T, b: T, config: PipelineConfig) -> list[tuple[T, T]]:
    """(queries, targets) pairs searched for the score of A against B, one per side of
    ``query_sides``: A -> B, B -> A, or the two (their reductions are averaged)."""
    pairs = {"a": (a, b), "b": (b, a)}
    return [pairs[side] for side in query_sides(config)]


def ring_pairings(config: PipelineConfig) -> tuple[tuple[int, int], ...]:
    """(A's ring, B's ring) of each comparison whose least score is the score: own ring against
    own ring, and with a turned ring each mesh's own ring against the other's turned one (a
    turn either way). Both turned is a turn of 0 again, and is left out."""
    return ((0, 0), (0, 1), (1, 0)) if len(config.rings) == 2 else ((0, 0),)


def _own_rings(i: int, j: int, config: PipelineConfig) -> bool:
    """Whether A's ring ``i`` against B's ring ``j`` is own ring against own ring with a turned
    ring beside it: the pairing whose turned twin, ring 1 against ring 1, sees the same."""
    return (i, j) == (0, 0) and len(config.rings) == 2


def pairing_part(
    i: int, j: int, part: Callable[[int, int], Any], config: PipelineConfig,
    ops: ArrayOps = NUMPY_OPS,
) -> Any:  # fmt: skip
    """The descriptors' part of A's ring ``i`` against B's ring ``j``, ``part(i, j)`` of one
    ring's sets; in the own-ring pairing ``turned_part_share`` of it is the turned ring's own
    comparison's: the same cameras 2.5° on, a second look at the same surface. Moderated
    (``moderated_part``) by the config's window."""
    share = config.turned_part_share if _own_rings(i, j, config) else 0.0
    own = part(i, j)
    blended = (1.0 - share) * own + share * part(1, 1) if share else own
    window = (config.moderate_slope, config.moderate_from, config.moderate_to)
    return moderated_part(blended, *window, ops)


def moderated_part(part: T, slope: float, low: float, high: float, ops: ArrayOps = NUMPY_OPS) -> T:
    """A descriptors' part (a float or an array) counted at ``slope`` between ``low`` and
    ``high`` and in full elsewhere: a moderate part counts less against the solid change, a
    small one keeps its value and two above ``high`` keep their difference."""
    if slope == 1.0 or high <= low:
        return part
    return part - (1.0 - slope) * ops.clip(part - low, 0.0, high - low)


def pairing_solid(
    i: int, j: int, solid: Callable[[int, int], Any], config: PipelineConfig, ops: ArrayOps
) -> Any:
    """``solid_weight`` times the mean of ``pairing_views``: the views' solid change of A's ring
    ``i`` against B's ring ``j``."""
    return config.solid_weight * pairing_views(i, j, solid, config, ops).mean(-1)


def pairing_views(
    i: int, j: int, solid: Callable[[int, int], Any], config: PipelineConfig, ops: ArrayOps
) -> Any:
    """(..., K) each camera's solid change of A's ring ``i`` against B's ring ``j``, from
    ``solid(i, j)``, the ``solid_change.view_solid_changes`` of one ring's views; in the
    own-ring pairing with ``solid_both_rings``, each camera's larger change of its two rings
    (the turned ring sees a sliver the own ring misses)."""
    views = solid(i, j)
    if config.solid_both_rings and _own_rings(i, j, config):
        views = ops.maximum(views, solid(1, 1))
    return views


def ring_rows(ring: int, config: PipelineConfig) -> slice:
    """The rows of ``ring``'s patches in a mesh's row-major (K * T * P) patch list."""
    per_ring = config.num_views * config.patches_per_view
    return slice(ring * per_ring, (ring + 1) * per_ring)


def ring_views(ring: int, config: PipelineConfig) -> slice:
    """The views of ``ring``'s cameras in a mesh's (K * T) views, ring after ring."""
    return slice(ring * config.num_views, (ring + 1) * config.num_views)


def reduce(distances, weights, config: PipelineConfig, ops: ArrayOps = NUMPY_OPS):
    """(..., R) best-match squared distances, (..., R) patch counts -> (...) score: one per
    leading index (a batch's meshes), reduced along the last axis.

    sum: Σ w·d (the paper). mean: Σ w·d / Σ w. tail: the mean over the k = tail_fraction · Σ w
    largest distances (at least one patch; the boundary row counts with the fraction of its
    weight that fits). power: (Σ w·d^p / Σ w)^(1/p), p = ``power``. softmax: t·log(Σ w·e^(d/t) /
    Σ w), t = ``temperature``, a smooth maximum that tends to the mean as t grows. Every one is
    0 when all distances are 0 and differentiable in the distances.
    """
    total = weights.sum(-1)
    if config.reduction == "sum":
        return (weights * distances).sum(-1)
    if config.reduction == "mean":
        return (weights * distances).sum(-1) / total
    if config.reduction == "tail":
        k = ops.minimum(total, ops.clip(config.tail_fraction * total, 1.0, None))
        order = ops.argsort(-distances, -1)
        ranked, counts = ops.take(distances, order), ops.take(weights, order)
        before = ops.cumsum(counts, -1) - counts  # patches ranked above each row
        taken = ops.minimum(ops.clip(k[..., None] - before, 0.0, None), counts)
        return (taken * ranked).sum(-1) / k
    if config.reduction == "power":
        mean = (weights * distances**config.power).sum(-1) / total
        # the root's slope is infinite at 0: take it only where the mean is positive
        positive = mean > 0
        return ops.where(positive, ops.where(positive, mean, 1.0) ** (1.0 / config.power), 0.0)
    top = ops.amax(distances, -1)  # log-mean-exp shifted by the maximum: exp never overflows
    t = config.temperature
    spread = (weights * ops.exp((distances - top[..., None]) / t)).sum(-1)
    return top + t * ops.log(spread / total)


def shares(distances: np.ndarray, weights: np.ndarray, config: PipelineConfig) -> np.ndarray:
    """(R,) best-match squared distances, (R,) patch counts -> (R,) each row's share of the
    reduced score (numpy; they sum to 1, or are all 0 for a score of 0).

    A row's share is its distance times the score's slope in it, d_i * dS/dd_i, over the sum of
    these: for the sum, the mean and the tail it is the row's part of the (weighted) sum, for
    the power mean w * d^p, for softmax w * d * e^(d / t). A row of weight w holds w patches.
    """
    distances = np.asarray(distances, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    if config.reduction in ("sum", "mean"):
        part = weights * distances
    elif config.reduction == "tail":
        k = min(weights.sum(), max(config.tail_fraction * weights.sum(), 1.0))
        order = np.argsort(-distances, kind="stable")
        before = np.cumsum(weights[order]) - weights[order]
        part = np.empty_like(distances)
        part[order] = np.minimum(np.clip(k - before, 0.0, None), weights[order])
        part *= distances
    elif config.reduction == "power":
        top = distances.max(initial=0.0)  # d^p relative to the largest, so p = 8 cannot overflow
        part = weights * (distances / top) ** config.power if top > 0 else 0.0 * distances
    else:
        top = distances.max(initial=0.0)
        part = weights * distances * np.exp((distances - top) / config.temperature)
    total = part.sum()
    return part / total if total > 0 else np.zeros_like(part)
