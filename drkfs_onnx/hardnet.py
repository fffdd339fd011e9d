"""HardNet descriptor in the L2-Net layout, with a width multiplier."""

from __future__ import annotations

import torch
from torch import nn

from .config import PipelineConfig

L2NET_CHANNELS = (32, 32, 64, 64, 128, 128)
L2NET_STRIDES = (1, 1, 2, 1, 2, 1)


def l2_normalize(x: torch.Tensor, eps: float = 1e-10) -> torch.Tensor:
    """x / |x| along dim 1, written as ONNX-friendly primitives (no expand in the graph)."""
    return x / torch.sqrt(torch.clamp_min((x * x).sum(dim=1, keepdim=True), eps))


class _FrozenConvReLU(torch.autograd.Function):
    """relu(conv(x)) for fixed weights, keeping for its backward only where the ReLU passed (a
    bool an activation) and the weights, where autograd keeps the conv's input and the ReLU's
    output (floats): a batch's HardNet activations were most of a training step's memory.
    The gradient reaches ``x`` only."""

    @staticmethod
    def forward(ctx, x, weight, bias, stride, padding):
        out = torch.relu_(nn.functional.conv2d(x, weight, bias, stride, padding))
        ctx.save_for_backward(out > 0, weight)
        ctx.geometry = (x.shape, stride, padding)
        return out

    @staticmethod
    def backward(ctx, grad):
        passed, weight = ctx.saved_tensors
        shape, stride, padding = ctx.geometry
        grad_x = nn.grad.conv2d_input(shape, weight, grad * passed, stride, padding)
        return grad_x, None, None, None, None


class HardNet(nn.Module):
    """Patch -> unit-length descriptor.

    Per-patch mean/std normalisation, six 3x3 convs (two with stride 2) each followed by
    BatchNorm without affine parameters and ReLU, dropout, a final conv covering the whole
    remaining map, BatchNorm, L2 normalisation. width=1 is L2-Net's 1.33M parameters.

    Shapes: (N, 1, p, p) -> (N, D).
    """

    def __init__(self, config: PipelineConfig):
        super().__init__()
        self.patch_norm_eps = config.patch_norm_eps
        channels = [max(1, round(c * config.descriptor_width)) for c in L2NET_CHANNELS]
        layers: list[nn.Module] = []
        previous = 1
        for out, stride in zip(channels, L2NET_STRIDES, strict=True):
            layers += [
                nn.Conv2d(previous, out, 3, stride=stride, padding=1, bias=False),
                nn.BatchNorm2d(out, affine=False),
                nn.ReLU(),
            ]
            previous = out
        final = config.patch_size // 4
        layers += [
            nn.Dropout(0.3),
            nn.Conv2d(previous, config.descriptor_dim, final, bias=False),
            nn.BatchNorm2d(config.descriptor_dim, affine=False),
        ]
        self.features = nn.Sequential(*layers)

    def forward(self, patches: torch.Tensor) -> torch.Tensor:
        x = nn.functional.instance_norm(patches, eps=self.patch_norm_eps)
        features = self.features(x) if self.training else self._folded(x)
        return l2_normalize(features.flatten(1))

    def _folded(self, x: torch.Tensor) -> torch.Tensor:
        """The evaluation-mode layers with each BatchNorm folded into the conv before it:
        (x - mean) / sqrt(var + eps) of W * x is (W / sqrt(var + eps)) * x - mean / sqrt(var +
        eps). One conv per layer instead of a conv and a normalisation, forward and backward.
        Dropout is the identity in evaluation mode."""
        layers = [m for m in self.features if not isinstance(m, nn.Dropout)]
        # fixed nets on an input that needs a gradient (a training loss): the lean backward
        lean = x.requires_grad and not any(p.requires_grad for p in self.parameters())
        for i, layer in enumerate(layers):
            if isinstance(layer, nn.Conv2d):
                norm = layers[i + 1]
                scale = torch.rsqrt(norm.running_var + norm.eps)
                folded = (layer.weight * scale[:, None, None, None], -norm.running_mean * scale)
                relu = i + 2 < len(layers) and isinstance(layers[i + 2], nn.ReLU)
                if lean and relu:
                    x = _FrozenConvReLU.apply(x, *folded, layer.stride, layer.padding)
                    continue
                x = nn.functional.conv2d(x, *folded, layer.stride, layer.padding)
                if relu:  # in place: the conv's output is not needed for its backward
                    x = torch.relu_(x)
        return x


def state_from_folded(folded: dict[str, torch.Tensor], config: PipelineConfig) -> dict:
    """A HardNet state dict from its evaluation form with each BatchNorm folded into the conv
    before it, as an exported graph's initializers hold it (``features.{k}.weight``: W / sqrt(var
    + eps); ``features.{k}.weight_bias``: -mean / sqrt(var + eps)). The convs take the folded
    weights and each BatchNorm becomes the identity (mean -b, var 1 - eps, whose 1 / sqrt(var +
    eps) is exactly 1), so ``_folded`` computes the graph's numbers bit for bit."""
    state = {}
    for k, layer in enumerate(HardNet(config).features):
        if isinstance(layer, nn.Conv2d):
            state[f"features.{k}.weight"] = folded[f"features.{k}.weight"]
        elif isinstance(layer, nn.BatchNorm2d):
            bias = folded[f"features.{k - 1}.weight_bias"]
            var = torch.ones_like(bias) - layer.eps
            if not bool((torch.rsqrt(var + layer.eps) == 1).all()):
                raise ValueError(f"BatchNorm eps {layer.eps} does not fold exactly")
            state[f"features.{k}.running_mean"] = -bias
            state[f"features.{k}.running_var"] = var
            state[f"features.{k}.num_batches_tracked"] = torch.tensor(0)
    return state
