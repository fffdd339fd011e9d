"""Point-of-interest detector with TILDE's piecewise-linear activation."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from ..contract.config import PipelineConfig
from . import precision


class _FrozenConv(torch.autograd.Function):
    """conv2d(x, weight, bias) for fixed weights, differentiable with respect to ``x`` only;
    its backward a transposed conv of the channels-last gradient (on a CPU faster than the
    conv's own input gradient; docs/design_notes.md), at the forward's ``precision``."""

    @staticmethod
    def forward(ctx, x, weight, bias):
        ctx.save_for_backward(weight)
        ctx.precision = precision.current()
        return F.conv2d(x, weight, bias)

    @staticmethod
    def backward(ctx, grad):
        (weight,) = ctx.saved_tensors
        grad = grad.contiguous(memory_format=precision.conv_layout(grad.device))
        with precision.conv_precision(ctx.precision):
            return F.conv_transpose2d(grad, weight).contiguous(), None, None


# A training step's detector on a CPU runs its conv in the 4 x 4 space-to-depth form
# (``unshuffled_weight``): mkldnn runs a one-channel 9 x 9 conv far below its speed on many
# channels, and the form's 3 x 3 conv of 16 into 64 channels halves the detector's step there
# (docs/design_notes.md). A GPU keeps the plain conv: the form is untried there
UNSHUFFLE = 4


def unshuffled_weight(weight: torch.Tensor, r: int) -> torch.Tensor:
    """(C, 1, k, k) conv weight -> (C * r * r, r * r, m, m), m = (k + r - 2) // r + 1: the conv
    on ``pixel_unshuffle(image, r)`` whose output, ``pixel_shuffle``d, is the conv's on the
    image. Output phase (u, v) of channel c reads input phase (s, t) at block offset (A, B)
    through the original tap (r A + s - u, r B + t - v), where that lies in the kernel."""
    channels, _, k, _ = weight.shape
    m = (k + r - 2) // r + 1
    phase = torch.arange(r, device=weight.device)
    tap = r * torch.arange(m, device=weight.device) + phase[None, :, None] - phase[:, None, None]
    inside = (tap >= 0) & (tap < k)  # (u, s, A)
    tap = tap.clamp(0, k - 1)
    rows, columns = tap[:, None, :, None, :, None], tap[None, :, None, :, None, :]
    mask = inside[:, None, :, None, :, None] & inside[None, :, None, :, None, :]
    taps = weight[:, 0][:, rows, columns] * mask  # (C, u, v, s, t, A, B)
    return taps.reshape(channels * r * r, r * r, m, m)


class PoIDetector(nn.Module):
    """Grey image -> per-pixel keypoint probability.

    score(p) = sum_n delta_n max_m (W_mn * I + b_mn)(p), with N x M filters of size k x k and
    fixed signs delta_n (+1 for the first half of n, -1 for the rest, as in TILDE); the map is
    sigmoid(score). The image is padded with the background value, so a region of pure
    background gives one constant probability wherever it lies, borders included.

    Shapes: (B, 1, S, S) -> (B, 1, S, S).
    """

    def __init__(self, config: PipelineConfig):
        super().__init__()
        self.n, self.m, self.kernel = config.detector_n, config.detector_m, config.detector_kernel
        self.background = config.background
        self.conv = nn.Conv2d(1, self.n * self.m, self.kernel)
        signs = torch.ones(self.n)
        signs[self.n // 2 :] = -1.0 if self.n > 1 else 1.0
        self.register_buffer("delta", signs.view(1, self.n, 1, 1), persistent=False)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        frozen = images.requires_grad and not self.conv.weight.requires_grad
        if frozen and images.device.type == "cpu":
            return self._unshuffled(images, UNSHUFFLE)
        pad = self.kernel // 2
        padded = F.pad(images, (pad, pad, pad, pad), value=self.background)
        response = (
            _FrozenConv.apply(padded, self.conv.weight, self.conv.bias)
            if frozen
            else self.conv(padded)
        )
        return self._probability(response)

    def _probability(self, response: torch.Tensor) -> torch.Tensor:
        """(B, N * M, ...) filter responses -> (B, 1, ...) sigmoid(sum_n delta_n max_m)."""
        b, _, *rest = response.shape
        maxout = response.view(b, self.n, self.m, *rest).amax(dim=2)
        delta = self.delta.view(1, self.n, *[1] * len(rest))
        return torch.sigmoid((maxout * delta).sum(dim=1, keepdim=True))

    def _unshuffled(self, images: torch.Tensor, r: int) -> torch.Tensor:
        """``forward`` for fixed weights with the conv in its r x r space-to-depth form; the
        PoI map is computed per phase and shuffled back once."""
        b, _, height, width = images.shape
        weight = unshuffled_weight(self.conv.weight, r).contiguous(
            memory_format=torch.channels_last
        )
        pad, m = self.kernel // 2, weight.shape[-1]
        rows, columns = -(-height // r), -(-width // r)  # the output's r x r blocks
        # the background pad, then as many rows and columns as the blocks read: beyond the
        # plain pad they reach only outputs the crop below drops
        bottom, right = (rows + m - 1) * r - height - pad, (columns + m - 1) * r - width - pad
        padded = F.pad(images, (pad, right, pad, bottom), value=self.background)
        phases = F.pixel_unshuffle(padded, r).contiguous(memory_format=torch.channels_last)
        response = _FrozenConv.apply(phases, weight, self.conv.bias.repeat_interleave(r * r))
        maps = self._probability(response.view(b, -1, r * r, rows, columns))[:, 0]
        return F.pixel_shuffle(maps, r)[:, :, :height, :width]
