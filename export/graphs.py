"""The torch modules that become the ONNX graphs: features (views -> descriptors) and match."""

from __future__ import annotations

import copy

import torch
from torch import nn

from drkfs_onnx.metric import DRKFS
from drkfs_onnx.nets.patches import select_patches


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
        return self.descriptor(select_patches(self.detector(views), patch_index, self.config))


class MatchGraph(nn.Module):
    """Each descriptor of A's nearest descriptor in B.

    ``forward(a (N, D), b (M, D)) -> (N,)`` int64, ranked by |b|^2 - 2 a.b in float32 (torch.cdist
    does not convert). A float32 near-tie can pick a neighbour whose distance exceeds the minimum
    by float32 rounding; the caller computes the distance to it exactly and matches rows with an
    exact copy in B at 0 itself.
    """

    def forward(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        return ((b * b).sum(1)[None] - 2.0 * a @ b.t()).argmin(1)
