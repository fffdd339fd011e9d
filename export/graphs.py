"""The torch modules that become the ONNX graphs: features (views -> descriptors) and match."""

from __future__ import annotations

import copy

import torch
from torch import nn

from drkfs_onnx.config import MATCH_CANDIDATES
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.patches import extract_patches


class FeatureGraph(nn.Module):
    """Rendered views -> PoI maps -> patches -> descriptors of the chosen patches.

    ``forward(views (B, 1, S, S) float32, patch_index (N,) int64) -> (N, D)``; patch_index
    selects rows of the (B * P) row-major patch list, so the caller can skip empty patches (they
    share one descriptor: the graph's output for a blank view).
    """

    def __init__(self, metric: DRKFS):
        super().__init__()
        self.config = metric.config
        self.detector = metric.detector
        # a copy: changing the memory format must not slow the caller's metric
        self.descriptor = copy.deepcopy(metric.descriptor).to(memory_format=torch.contiguous_format)

    def forward(self, views: torch.Tensor, patch_index: torch.Tensor) -> torch.Tensor:
        patches = extract_patches(self.detector(views), self.config)
        return self.descriptor(patches.index_select(0, patch_index))


class MatchGraph(nn.Module):
    """Each descriptor of A's MATCH_CANDIDATES nearest candidates in B.

    ``forward(a (N, D), b (M, D)) -> (N, MATCH_CANDIDATES)`` int64, ranked by |b|^2 - 2 a.b in
    float32 (torch.cdist does not convert); needs M >= MATCH_CANDIDATES. The caller re-ranks the
    candidates by exact distance, as ``drkfs_onnx.matching`` does: near-duplicate descriptors
    round to the same matmul distance.
    """

    def forward(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        ranking = (b * b).sum(1)[None] - 2.0 * a @ b.t()
        return ranking.topk(MATCH_CANDIDATES, dim=1, largest=False).indices
