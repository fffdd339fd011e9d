"""Best-match distances between descriptor sets and their reduction to a score, plus the views'
solid change (torch)."""

from __future__ import annotations

import torch

from .contract import match_rules
from .contract.config import FULL_PARTS, PipelineConfig
from .contract.solid_change import view_solid_changes
from .render.torch_ops import TORCH_OPS

CHUNK_ROWS = 2048
# Best-match candidates ranked by the fast matmul form, then re-ranked by exact distance.
MATCH_CANDIDATES = 4


def nearest_indices(queries: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """(..., N, D), (..., M, D) -> (..., N) index of each query's nearest target (squared
    Euclidean), per leading index (a batch's meshes).

    Ranks by |t|^2 - 2 q.t (|q|^2 is constant per row) on CHUNK_ROWS rows at a time, so the
    distance matrix never exceeds CHUNK_ROWS x M, then re-ranks the best MATCH_CANDIDATES
    exactly. The ranking runs in float64: trained descriptors of flat patches nearly coincide,
    and in float32 dozens of near-duplicates can outrank an exact duplicate.
    """
    queries, targets = queries.double(), targets.double()
    target_sq = (targets * targets).sum(-1)[..., None, :]
    k = min(MATCH_CANDIDATES, targets.shape[-2])
    parts = []
    for chunk in queries.split(CHUNK_ROWS, dim=-2):
        ranking = target_sq - 2.0 * chunk @ targets.transpose(-1, -2)
        candidates = ranking.topk(k, dim=-1, largest=False).indices  # (..., n, k)
        near = torch.take_along_dim(targets[..., None, :, :], candidates[..., None], dim=-2)
        exact = ((chunk[..., None, :] - near) ** 2).sum(-1)
        parts.append(candidates.gather(-1, exact.argmin(-1, keepdim=True)).squeeze(-1))
    return torch.cat(parts, dim=-1) if parts else queries.new_zeros(0, dtype=torch.long)


def window_nearest(queries: torch.Tensor, targets: torch.Tensor, table: torch.Tensor):
    """(..., N, D), (..., N, D) patch descriptors at the same grid positions, (N, W)
    ``window_table`` -> (..., N) index of each query's nearest target among its window
    (float64, exact)."""
    queries, targets = queries.double(), targets.double()
    parts = []
    for rows in torch.arange(queries.shape[-2], device=table.device).split(CHUNK_ROWS):
        near = table.index_select(0, rows)  # (n, W)
        found = targets[..., near, :]  # (..., n, W, D)
        distance = ((queries[..., rows, None, :] - found) ** 2).sum(-1)
        index = near.expand(*distance.shape).gather(-1, distance.argmin(-1, keepdim=True))
        parts.append(index.squeeze(-1))
    return torch.cat(parts, dim=-1) if parts else queries.new_zeros(0, dtype=torch.long)


def window_index(config: PipelineConfig, device: torch.device) -> torch.Tensor:
    """``match_rules.window_table`` as a tensor on ``device``."""
    return torch.as_tensor(match_rules.window_table(config).copy(), device=device)


def _batched(queries: torch.Tensor, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """A set without the other's batch axis expanded (not copied) to it."""
    lead = max(queries.shape[:-2], targets.shape[:-2], key=len)
    return queries.expand(*lead, *queries.shape[-2:]), targets.expand(*lead, *targets.shape[-2:])


def best_match_distances(
    queries: torch.Tensor,
    targets: torch.Tensor,
    config: PipelineConfig,
    table: torch.Tensor | None = None,
) -> torch.Tensor:
    """(..., N, D), (..., M, D) -> (..., N) squared distance from each query to its best match,
    per leading index (a batch's meshes; a set without one is shared by all).

    'global' searches all targets; 'window' needs both sets as the full row-major (K * P)
    patch lists of the same cameras, and takes its ``table`` (``window_index``; made from the
    config when None). The match is found without autograd; the distance to it is then
    differentiable with respect to both sets (the gradient of a min is the gradient at the
    argmin).
    """
    queries, targets = _batched(queries, targets)
    with torch.no_grad():
        if config.matching == "global":
            index = nearest_indices(queries.detach(), targets.detach())
        else:
            table = window_index(config, queries.device) if table is None else table
            if queries.shape[-2] != len(table) or targets.shape[-2] != len(table):
                raise ValueError(
                    f"window matching needs all {len(table)} patches of both meshes "
                    f"({config.num_views} views x {config.patches_per_view}); got "
                    f"{queries.shape[-2]} and {targets.shape[-2]}"
                )
            index = window_nearest(queries.detach(), targets.detach(), table)
    matched = torch.take_along_dim(targets, index[..., None], dim=-2)
    return ((queries - matched) ** 2).sum(-1)


def match_score(
    desc_a: torch.Tensor,
    desc_b: torch.Tensor,
    config: PipelineConfig,
    temperature: float | None = None,
    table: torch.Tensor | None = None,
    views_a: torch.Tensor | None = None,
    views_b: torch.Tensor | None = None,
) -> torch.Tensor:
    """DR-KFS score from the (K * P, D) descriptor sets of A and B -> (), or of a batch's
    (B, K * P, D) (either side may be one set shared by the batch) -> (B,): the reduced
    best-match distances of each direction the config searches, averaged (``match_rules``);
    with a ``temperature``, soft best matches (``soft_match_distances``) in place of the hard
    ones. A config with a solid change (``solid_weight`` > 0) adds that of the (K, S, S) or
    (B, K, S, S) views of A and B (``contract.solid_change``), which it then needs. With a
    turned ring of cameras (``config.rings``), (K * T * P, D) sets and (K * T, S, S) views, and
    the least score over ``match_rules.ring_pairings``."""
    return pairing_scores(desc_a, desc_b, config, temperature, table, views_a, views_b).amin(0)


def pairing_scores(
    desc_a: torch.Tensor,
    desc_b: torch.Tensor,
    config: PipelineConfig,
    temperature: float | None = None,
    table: torch.Tensor | None = None,
    views_a: torch.Tensor | None = None,
    views_b: torch.Tensor | None = None,
) -> torch.Tensor:
    """``match_score``'s sets and views -> (P, ...) the score of each pairing of
    ``match_rules.ring_pairings`` (one with a single ring of cameras), its parts as
    ``match_rules.pairing_part`` and ``pairing_solid`` make them."""
    one, rows = config.one_ring(), match_rules.ring_rows

    def part(i: int, j: int) -> torch.Tensor:
        a, b = desc_a[..., rows(i, config), :], desc_b[..., rows(j, config), :]
        return _descriptor_score(a, b, one, temperature, table)

    def solid(i: int, j: int) -> torch.Tensor:
        a, b = ring_views(views_a, i, config), ring_views(views_b, j, config)
        return view_solid_changes(a, b, one, TORCH_OPS)

    if config.solid_weight:
        _check_views(views_a, views_b, config)
    scores = []
    for i, j in match_rules.ring_pairings(config):
        score = match_rules.pairing_part(i, j, part, config, TORCH_OPS)
        if config.solid_weight:
            score = score + match_rules.pairing_solid(i, j, solid, config, TORCH_OPS)
        scores.append(score)
    return torch.stack(scores)


def _check_views(views_a: torch.Tensor | None, views_b: torch.Tensor | None, config) -> None:
    if views_a is None or views_b is None:
        raise ValueError(
            f"a config with a solid change (solid_weight {config.solid_weight:g}) compares the "
            "two meshes' views: pass views_a and views_b"
        )


def descriptor_score(
    desc_a: torch.Tensor,
    desc_b: torch.Tensor,
    config: PipelineConfig,
    temperature: float | None = None,
    table: torch.Tensor | None = None,
) -> torch.Tensor:
    """``match_score`` of the descriptors alone, without the views' solid change and with their
    part in full (``FULL_PARTS``): what the nets are trained to order (the solid change has no
    weights to train, and the window is a reading of the nets' distances, not a target)."""
    alone = config.replace(solid_weight=0.0, **FULL_PARTS)
    return match_score(desc_a, desc_b, alone, temperature, table)


def ring_views(views: torch.Tensor | None, ring: int, config: PipelineConfig):
    """The (..., K, S, S) views of one ring of cameras of (..., K * T, S, S)
    (``match_rules.ring_views``), or None."""
    return None if views is None else views[..., match_rules.ring_views(ring, config), :, :]


def _descriptor_score(
    desc_a: torch.Tensor,
    desc_b: torch.Tensor,
    config: PipelineConfig,
    temperature: float | None,
    table: torch.Tensor | None,
) -> torch.Tensor:
    """One ring's score from the descriptors alone: each direction's reduced best-match
    distances, averaged."""
    scores = []
    for queries, targets in match_rules.directions(desc_a, desc_b, config):
        if temperature is None:
            distances = best_match_distances(queries, targets, config, table)
        else:
            distances = soft_match_distances(queries, targets, config, temperature, table)
        scores.append(match_rules.reduce(distances, torch.ones_like(distances), config, TORCH_OPS))
    return torch.stack(scores).mean(0)


# a soft match over a global search differences every query with every target: (..., N, M, D)
SOFT_GLOBAL_BYTES = 2**31


def check_soft_global_size(queries: torch.Tensor, targets: torch.Tensor) -> None:
    """Refuse a global soft match whose (..., N, M, D) differences pass SOFT_GLOBAL_BYTES (the
    paper preset's would take about 16 GB a mesh) before it is built."""
    count = queries[..., :1].numel() * targets.shape[-2] * queries.shape[-1]
    size = count * queries.element_size()
    if size > SOFT_GLOBAL_BYTES:
        raise ValueError(
            f"a soft match over a global search would build {size / 2**30:.1f} GiB of "
            f"differences ({tuple(queries.shape[:-1])} queries x {targets.shape[-2]} targets x "
            f"{queries.shape[-1]} dims): use matching='window' for a soft match, or no soft match"
        )


def soft_match_distances(
    queries: torch.Tensor,
    targets: torch.Tensor,
    config: PipelineConfig,
    temperature: float,
    table: torch.Tensor | None = None,
) -> torch.Tensor:
    """(..., N, D), (..., M, D) -> (..., N) soft best-match squared distances: each query's
    candidates (all targets under 'global', its window under 'window') weighted by
    softmax(-d / temperature), so the match moves smoothly from one candidate to the next
    instead of jumping. Tends to the hard best match as the temperature falls; a loss form with
    no runtime counterpart."""
    if config.matching == "window":
        table = window_index(config, queries.device) if table is None else table
        squared = ((queries[..., None, :] - targets[..., table, :]) ** 2).sum(-1)  # (..., N, W)
    else:
        check_soft_global_size(queries, targets)
        squared = (queries[..., :, None, :] - targets[..., None, :, :]).pow(2).sum(-1)
    weights = torch.softmax(-squared / temperature, dim=-1)
    return (weights * squared).sum(-1)
