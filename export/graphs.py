"""The torch modules that become the ONNX graphs: features (views -> descriptors) and match."""

from __future__ import annotations

import copy

import torch
from torch import nn

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
    """Squared distance of each descriptor of A to its best match in B.

    ``forward(a (N, D), b (M, D)) -> (N,)``, as |a|^2 + |b|^2 - 2 a.b (torch.cdist does not
    convert), clamped at 0.
    """

    def forward(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        squared = (a * a).sum(1, keepdim=True) + (b * b).sum(1)[None] - 2.0 * a @ b.t()
        return squared.amin(dim=1).clamp_min(0.0)
