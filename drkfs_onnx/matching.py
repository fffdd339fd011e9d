"""Best-match distances between descriptor sets and their reduction to a score (torch)."""

from __future__ import annotations

import torch

from . import match_rules
from .config import PipelineConfig

CHUNK_ROWS = 2048
# Best-match candidates ranked by the fast matmul form, then re-ranked by exact distance.
MATCH_CANDIDATES = 4


def nearest_indices(queries: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """(N, D), (M, D) -> (N,) index of each query's nearest target (squared Euclidean).

    Ranks by |t|^2 - 2 q.t (|q|^2 is constant per row) on CHUNK_ROWS rows at a time, so the
    distance matrix never exceeds CHUNK_ROWS x M, then re-ranks the best MATCH_CANDIDATES
    exactly. The ranking runs in float64: trained descriptors of flat patches nearly coincide,
    and in float32 dozens of near-duplicates can outrank an exact duplicate.
    """
    queries, targets = queries.double(), targets.double()
    target_sq = (targets * targets).sum(1)
    k = min(MATCH_CANDIDATES, len(targets))
    parts = []
    for chunk in queries.split(CHUNK_ROWS):
        candidates = (target_sq - 2.0 * chunk @ targets.T).topk(k, dim=1, largest=False).indices
        exact = ((chunk[:, None, :] - targets[candidates]) ** 2).sum(-1)
        parts.append(candidates.gather(1, exact.argmin(1, keepdim=True)).squeeze(1))
    return torch.cat(parts) if parts else queries.new_zeros(0, dtype=torch.long)


def window_nearest(queries: torch.Tensor, targets: torch.Tensor, table: torch.Tensor):
    """(N, D), (N, D) patch descriptors at the same grid positions, (N, W) ``window_table`` ->
    (N,) index of each query's nearest target among its window (float64, exact)."""
    queries, targets = queries.double(), targets.double()
    parts = []
    for rows in torch.arange(len(queries)).split(CHUNK_ROWS):
        near = table[rows]
        distance = ((queries[rows, None, :] - targets[near]) ** 2).sum(-1)
        parts.append(near.gather(1, distance.argmin(1, keepdim=True)).squeeze(1))
    return torch.cat(parts) if parts else queries.new_zeros(0, dtype=torch.long)


def best_match_distances(
    queries: torch.Tensor, targets: torch.Tensor, config: PipelineConfig
) -> torch.Tensor:
    """(N, D), (M, D) -> (N,) squared distance from each query to its best match.

    'global' searches all targets; 'window' needs both sets as the full row-major (K * P)
    patch lists of the same cameras. The match is found without autograd; the distance to it is
    then differentiable with respect to both sets (the gradient of a min is the gradient at the
    argmin).
    """
    with torch.no_grad():
        if config.matching == "global":
            index = nearest_indices(queries.detach(), targets.detach())
        else:
            table = torch.as_tensor(match_rules.window_table(config).copy(), device=queries.device)
            if len(queries) != len(table) or len(targets) != len(table):
                raise ValueError(
                    f"window matching needs all {len(table)} patches of both meshes "
                    f"({config.num_views} views x {config.patches_per_view}); got "
                    f"{len(queries)} and {len(targets)}"
                )
            index = window_nearest(queries.detach(), targets.detach(), table)
    return ((queries - targets[index]) ** 2).sum(1)


def match_score(
    desc_a: torch.Tensor,
    desc_b: torch.Tensor,
    config: PipelineConfig,
    temperature: float | None = None,
) -> torch.Tensor:
    """DR-KFS score from the (K * P, D) descriptor sets of A and B: the reduced best-match
    distances of each direction the config searches, averaged (``match_rules``); with a
    ``temperature``, soft best matches (``soft_match_distances``) in place of the hard ones."""
    scores = []
    for queries, targets in match_rules.directions(desc_a, desc_b, config):
        if temperature is None:
            distances = best_match_distances(queries, targets, config)
        else:
            distances = soft_match_distances(queries, targets, config, temperature)
        scores.append(match_rules.reduce(distances, torch.ones_like(distances), config, torch))
    return torch.stack(scores).mean()


def soft_match_distances(
    queries: torch.Tensor, targets: torch.Tensor, config: PipelineConfig, temperature: float
) -> torch.Tensor:
    """(N, D), (M, D) -> (N,) soft best-match squared distances: each query's candidates (all
    targets under 'global', its window under 'window') weighted by softmax(-d / temperature),
    so the match moves smoothly from one candidate to the next instead of jumping. Tends to the
    hard best match as the temperature falls; a loss form with no runtime counterpart."""
    if config.matching == "window":
        table = torch.as_tensor(match_rules.window_table(config).copy(), device=queries.device)
        squared = ((queries[:, None, :] - targets[table]) ** 2).sum(-1)  # (N, W)
    else:
        squared = (queries[:, None, :] - targets[None]).pow(2).sum(-1)  # (N, M)
    weights = torch.softmax(-squared / temperature, dim=1)
    return (weights * squared).sum(1)
