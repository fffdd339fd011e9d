"""The torch modules that become the ONNX graphs: features (views -> descriptors) and match."""

from __future__ import annotations

import torch
from torch import nn

from drkfs_onnx.metric import DRKFS
from drkfs_onnx.nets.hardnet import HardNet, conv_stack, l2_normalize
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
        self.descriptor = FoldedHardNet(metric.descriptor)

    def forward(self, views: torch.Tensor, patch_index: torch.Tensor) -> torch.Tensor:
        return self.descriptor(select_patches(self.detector(views), patch_index, self.config))


class _FoldedConv(nn.Module):
    def __init__(self, weight: torch.Tensor, bias: torch.Tensor, stride, padding):
        super().__init__()
        self.weight = nn.Parameter(weight.detach().clone(), requires_grad=False)
        self.weight_bias = nn.Parameter(bias.detach().clone(), requires_grad=False)
        self.stride, self.padding = stride, padding


class FoldedHardNet(nn.Module):
    """HardNet in evaluation mode with each BatchNorm folded into its conv ahead of the export,
    so that the graph holds the folded weights as initializers named ``features.{k}.weight`` and
    ``features.{k}.weight_bias`` (which ``nets.hardnet.state_from_folded`` reads back where a
    wheel ships no .pt), whatever the exporter's constant folding does.

    ``forward(patches (N, 1, P, P)) -> (N, D)``, HardNet's evaluation forward.
    """

    def __init__(self, net: HardNet):
        super().__init__()
        self.patch_norm_eps = net.patch_norm_eps
        self.features = nn.ModuleDict(
            {str(k): _FoldedConv(*layer) for k, layer in net.folded_layers().items()}
        )

    def forward(self, patches: torch.Tensor) -> torch.Tensor:
        x = nn.functional.instance_norm(patches, eps=self.patch_norm_eps)
        layers = [(c.weight, c.weight_bias, c.stride, c.padding) for c in self.features.values()]
        return l2_normalize(conv_stack(x, layers).flatten(1))


class MatchGraph(nn.Module):
    """Each descriptor of A's nearest descriptor in B.

    ``forward(a (N, D), b (M, D)) -> (N,)`` int64, ranked by |b|^2 - 2 a.b in float32 (torch.cdist
    does not convert). A float32 near-tie can pick a neighbour whose distance exceeds the minimum
    by float32 rounding; the caller computes the distance to it exactly and matches rows with an
    exact copy in B at 0 itself.
    """

    def forward(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        return ((b * b).sum(1)[None] - 2.0 * a @ b.t()).argmin(1)
