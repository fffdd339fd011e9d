"""Best-match distances between descriptor sets, chunked so memory stays bounded."""

from __future__ import annotations

import torch

from .config import REDUCTIONS

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


def best_match_distances(queries: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """(N, D), (M, D) -> (N,) squared distance from each query to its nearest target.

    The nearest index is found without autograd; the distance to it is then differentiable with
    respect to both sets (the gradient of a min is the gradient at the argmin).
    """
    with torch.no_grad():
        index = nearest_indices(queries.detach(), targets.detach())
    return ((queries - targets[index]) ** 2).sum(1)


def match_score(
    desc_a: torch.Tensor, desc_b: torch.Tensor, reduction: str = "sum", symmetric: bool = False
) -> torch.Tensor:
    """DR-KFS score from descriptor sets: reduce A's best-match distances into B.

    reduction: 'sum' (the paper) or 'mean'; symmetric averages the A->B and B->A scores.
    """
    if reduction not in REDUCTIONS:
        raise ValueError(f"unknown reduction {reduction!r}; use one of {', '.join(REDUCTIONS)}")
    directions = [(desc_a, desc_b), (desc_b, desc_a)] if symmetric else [(desc_a, desc_b)]
    scores = [getattr(best_match_distances(q, t), reduction)() for q, t in directions]
    return torch.stack(scores).mean()
