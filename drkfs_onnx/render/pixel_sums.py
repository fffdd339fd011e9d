"""Per pixel, a shader's terms summed over its kept pairs, and the backward that sends the
pixels' gradients to the faces by the written-out ``pair_terms_grad`` (no autograd graph of
every pair)."""

from __future__ import annotations

import torch

from ..contract.render_equations import (
    PAIR_GRAD_PARTS,
    face_params_grad,
    pair_terms_grad,
    pixel_centre,
)
from .compile_policy import fused
from .kept_pairs import KeptPairs
from .torch_ops import TORCH_OPS


def _terms_grad_at(params, face, pixel, coverage, grad_coverage, grad_depth, config, ops):
    """``pair_terms_grad`` of a chunk of kept pairs from the screen's params, the pairs' faces
    and flat pixel indices: the gather and the pixel centres fused with it where compiled."""
    size = config.image_size
    px = pixel_centre((pixel % size).to(params.dtype), size)
    py = pixel_centre((pixel // size % size).to(params.dtype), size)
    tri = params.index_select(1, face)
    return pair_terms_grad(tri, px, py, coverage, grad_coverage, grad_depth, config, ops)


class Shader:
    """Per-pair terms summed per pixel (``pixel_sums``), and their slopes for the backward:
    ``values(pairs, colors) -> (C, P)``; ``slopes(pairs, colors, grad (C, P)) -> (d/d coverage,
    d/d depth, d/d each pair's colour or None)`` of sum(grad * values), for a chunk of pairs."""

    channels: int

    def values(self, pairs: KeptPairs, colors: torch.Tensor) -> torch.Tensor:
        raise NotImplementedError

    def slopes(self, pairs: KeptPairs, colors: torch.Tensor, grad: torch.Tensor):
        raise NotImplementedError


class _PixelSums(torch.autograd.Function):
    """Per pixel, the sum over its kept pairs of a shader's terms. Backward recomputes each
    chunk's pair terms and sends the gradient to the faces by ``pair_terms_grad``."""

    @staticmethod
    def forward(ctx, pairs: KeptPairs, shader: Shader, params, colors):
        sums = params.new_zeros(shader.channels, pairs.plan.num_pixels)
        for chunk in pairs.chunks():
            sums.index_add_(1, chunk.pixel, shader.values(chunk, colors))
        ctx.pairs, ctx.shader = pairs, shader
        ctx.save_for_backward(params, colors)
        return sums

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        params, colors = ctx.saved_tensors
        pairs, shader, config = ctx.pairs, ctx.shader, ctx.pairs.plan.config
        grad_parts = params.new_zeros(PAIR_GRAD_PARTS, params.shape[1])
        grad_colors = torch.zeros_like(colors)
        terms_grad = fused(_terms_grad_at, config, params.device.type, True)
        for chunk in pairs.chunks():
            pair_grad = grad.index_select(1, chunk.pixel)
            grad_coverage, grad_depth, grad_color = shader.slopes(chunk, colors, pair_grad)
            face = chunk.face.long()
            parts = terms_grad(params, chunk.face, chunk.pixel, chunk.coverage, grad_coverage,
                               grad_depth)  # fmt: skip
            grad_parts.index_add_(1, face, parts)
            if grad_color is not None:
                grad_colors.index_add_(0, face, grad_color)
        return None, None, face_params_grad(params, grad_parts, TORCH_OPS), grad_colors


def pixel_sums(
    pairs: KeptPairs, shader: Shader, params: torch.Tensor, colors: torch.Tensor
) -> torch.Tensor:
    """(C, views * S * S): per pixel, the sum of the shader's terms over its kept pairs;
    differentiable with respect to the faces' ``params`` (9, N) and ``colors`` (N,)."""
    return _PixelSums.apply(pairs, shader, params, colors)
