"""HardNet descriptor in the L2-Net layout, with a width multiplier."""

from __future__ import annotations

import torch
from torch import nn

from ..contract.config import PipelineConfig
from . import precision

L2NET_CHANNELS = (32, 32, 64, 64, 128, 128)
L2NET_STRIDES = (1, 1, 2, 1, 2, 1)


def l2_normalize(x: torch.Tensor, eps: float = 1e-10) -> torch.Tensor:
    """x / |x| along dim 1, written as ONNX-friendly primitives (no expand in the graph)."""
    return x / torch.sqrt(torch.clamp_min((x * x).sum(dim=1, keepdim=True), eps))


def _whole_map_matrix(weight: torch.Tensor) -> torch.Tensor:
    """(D, C, h, w) weight of a conv that covers its whole h x w input -> (h * w * C, D): the
    conv as a matrix on the channels-last input's rows."""
    return weight.permute(2, 3, 1, 0).reshape(-1, weight.shape[0])


def _patches_in_layout(x: torch.Tensor) -> torch.Tensor:
    """(N, 1, H, W) patches -> the same values in ``precision.conv_layout``'s layout.
    Channels-last (a CPU's) sets the strides by hand: for one channel
    ``contiguous(memory_format=torch.channels_last)`` keeps the other layout's strides (both
    describe the same memory), and mkldnn then runs the first conv on that layout, slowly, and
    returns its output in it (docs/design_notes.md)."""
    _, _, height, width = x.shape
    if precision.conv_layout(x.device) != torch.channels_last:
        return x.contiguous()
    return x.contiguous().as_strided(x.shape, (height * width, 1, width, 1))


def conv_stack(x: torch.Tensor, layers: list, passed: list | None = None) -> torch.Tensor:
    """HardNet's folded convs (``layers``: (weight, bias, stride, padding) each) in order, a ReLU
    after all but the last. The activations are in ``precision.conv_layout``'s layout from the
    first conv on (its one-channel input can leave its output in the other): a gradient and a
    mask in different layouts multiply slowly on a CPU.

    ``passed``, where given (the fixed nets' training step), collects where each ReLU passed
    (0 or 1, int8: a byte an activation), and the last conv, which covers its whole input map,
    runs as one matmul, faster than mkldnn's conv on a CPU (docs/design_notes.md). Elsewhere
    the last layer stays the conv the exported graphs hold, so that scores do not move by a
    rounding."""
    if passed is not None:
        x = _patches_in_layout(x)
    for k, (weight, bias, stride, padding) in enumerate(layers):
        if passed is not None and k + 1 == len(layers):
            rows = x.permute(0, 2, 3, 1).reshape(len(x), -1)
            return torch.addmm(bias, rows, _whole_map_matrix(weight))[:, :, None, None]
        x = nn.functional.conv2d(x, weight, bias, stride, padding)
        if k == 0:
            x = x.contiguous(memory_format=precision.conv_layout(x.device))
        if k + 1 < len(layers):  # in place: the conv's output is not needed for its backward
            x = torch.relu_(x)
            if passed is not None:
                # nonzero after the ReLU: where it passed (faster than x > 0 on a CPU)
                passed.append(x.bool().view(torch.int8))
    return x


def _stack_input_grad(
    grad: torch.Tensor, layers: list, passed: list, floats: torch.Tensor, size
) -> torch.Tensor:
    """The gradient of ``conv_stack``'s output ``grad`` with respect to its input of spatial
    ``size``, from where each ReLU passed (``passed``): through the last conv as a matmul (it
    covers its whole input map), then through each ReLU and conv as a mask and a transposed conv.
    ``floats``: a flat float tensor at least the size of the largest mask, which this
    overwrites."""
    n, channels, height, width = passed[-1].shape
    grad = grad.flatten(1) @ _whole_map_matrix(layers[-1][0]).t()
    grad = grad.view(n, height, width, channels).permute(0, 3, 1, 2)  # channels-last
    grad = grad.contiguous(memory_format=precision.conv_layout(grad.device))  # the masks' layout
    # each conv's input size: the patches', then each ReLU's output but the last
    sizes = [size, *(mask.shape[-2:] for mask in passed[:-1])]
    steps = zip(layers[:-1], passed, sizes, strict=True)
    for (weight, _, stride, padding), mask, size in reversed(list(steps)):
        # the mask as floats first: a float32 by int8 product is slower than the conversion and
        # a float32 product together
        grad = grad.mul_(floats.as_strided(mask.shape, mask.stride()).copy_(mask))
        # a stride-2 conv maps input sizes n and n + 1 to one output size: the output
        # padding tells the transposed conv which of them it had
        kernel, out = weight.shape[-2:], grad.shape[-2:]
        lost = [n - ((o - 1) * s - 2 * p + k) for n, o, s, p, k in
                zip(size, out, stride, padding, kernel, strict=True)]  # fmt: skip
        grad = nn.functional.conv_transpose2d(grad, weight, None, stride, padding, lost)
    return grad


class _FrozenHardNet(torch.autograd.Function):
    """HardNet's evaluation layers (``HardNet._folded``) for fixed weights, differentiable with
    respect to the patches only, in groups of ``group`` patches. The forward is ``conv_stack``, as
    ``_folded``'s; the backward keeps only where each ReLU passed (a byte an activation, where
    autograd keeps every conv's input: most of a batch's training-step memory) and sends the
    gradient back through each conv as a transposed conv and through the last as a matmul, faster on
    a CPU than the convs' own input gradients (docs/design_notes.md). One node for every group, so
    that their backwards share buffers. The backward runs at the forward's ``precision``.

    ``layers``: (weight, bias, stride, padding) of each folded conv, in order; a ReLU follows
    all but the last."""

    @staticmethod
    def forward(ctx, x, layers, group):
        parts, passed = [], []
        for part in x.split(group):
            passed.append([])
            parts.append(conv_stack(part, layers, passed[-1]))
        ctx.layers, ctx.passed, ctx.group, ctx.input_size = layers, passed, group, x.shape[-2:]
        ctx.precision = precision.current()
        return torch.cat(parts)

    @staticmethod
    def backward(ctx, grad):
        # the masks as floats in one buffer, the largest mask's size, that every layer and
        # group reuses in turn: fresh memory for each took its pages from the system one fault
        # at a time (the fine stage's 9,251 patches: 760-780k faults, a backward of 3.9 s on 2
        # cores; with one buffer a layer 90-310k, 2.4-3.4 s), and a buffer for every layer at
        # once would hold all of a GPU's patches' masks as floats (one group there)
        largest = max(mask.numel() for mask in ctx.passed[0])
        floats = grad.new_empty(largest)
        with precision.conv_precision(ctx.precision):
            grads = [
                _stack_input_grad(part, ctx.layers, masks, floats, ctx.input_size)
                for part, masks in zip(grad.split(ctx.group), ctx.passed, strict=True)
            ]
        return torch.cat(grads), None, None


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

    def forward(
        self, patches: torch.Tensor, group: int | None = None, dtype: torch.dtype | None = None
    ) -> torch.Tensor:
        """``group``: in evaluation mode, the convs run on that many patches at a time (on a CPU
        a group's activations can stay in cache); None: all at once. ``dtype``: in evaluation
        mode, the convs run in it (``precision.conv_dtype``), the descriptors come back in the
        patches' dtype; None: the patches' dtype throughout."""
        x = nn.functional.instance_norm(patches, eps=self.patch_norm_eps)
        features = self.features(x) if self.training else self._folded(x, group, dtype)
        return l2_normalize(features.flatten(1).to(patches.dtype))

    def folded_layers(self) -> dict[int, tuple]:
        """Each conv's index in ``features`` -> (W / sqrt(var + eps), -mean / sqrt(var + eps),
        stride, padding): the conv with the BatchNorm after it folded in (evaluation mode)."""
        modules = list(self.features)
        layers = {}
        for k, conv in enumerate(modules):
            if isinstance(conv, nn.Conv2d):
                norm = modules[k + 1]
                scale = torch.rsqrt(norm.running_var + norm.eps)
                weight, bias = conv.weight * scale[:, None, None, None], -norm.running_mean * scale
                layers[k] = (weight, bias, conv.stride, conv.padding)
        return layers

    def _folded(
        self, x: torch.Tensor, group: int | None, dtype: torch.dtype | None = None
    ) -> torch.Tensor:
        """The evaluation-mode layers with each BatchNorm folded into the conv before it:
        (x - mean) / sqrt(var + eps) of W * x is (W / sqrt(var + eps)) * x - mean / sqrt(var +
        eps). One conv per layer instead of a conv and a normalisation, forward and backward.
        Dropout is the identity in evaluation mode. ``dtype``: the convs' (None: x's)."""
        dtype = dtype or x.dtype
        x = x.to(dtype)
        layout = precision.conv_layout(x.device)
        layers = [
            (weight.to(dtype).contiguous(memory_format=layout), bias.to(dtype), *rest)
            for weight, bias, *rest in self.folded_layers().values()
        ]
        # fixed nets on an input that needs a gradient (a training loss): the lean backward
        if x.requires_grad and not any(p.requires_grad for p in self.parameters()):
            return _FrozenHardNet.apply(x, layers, group or max(len(x), 1))
        if group is None:  # one pass (and a graph an exporter can trace for any batch size)
            return conv_stack(x, layers)
        return torch.cat([conv_stack(part, layers) for part in x.split(group)])


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
