"""Shaders of a screen's kept pixel-face pairs (torch): grey Lambertian faces with SoftRas' soft
blend, and silhouettes. The equations are ``contract.render_equations``', shared with the numpy
renderer; the pairs' sums and their backward are ``pixel_sums``'."""

from __future__ import annotations

import numpy as np
import torch

from ..contract import render_equations
from ..contract.config import PipelineConfig
from .kept_pairs import KeptPairs
from .pixel_sums import Shader, pixel_sums
from .torch_ops import TORCH_OPS

SATURATED = 1.0 - 1e-6


def face_light(
    verts: torch.Tensor,
    verts_cam: torch.Tensor,
    faces: torch.Tensor,
    eyes: np.ndarray,
    config: PipelineConfig,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(B, V, 3) world and (B, K, V, 3) camera-frame vertices, (B, F, 3) faces and the cameras'
    (K, 3) world positions -> (lit, shadow, behind), (B*K*F,) each
    (``render_equations.face_light``, the faces oriented by ``outward_signs``: a sign, no
    gradient)."""
    world = verts.detach().cpu().numpy()
    found = render_equations.outward_signs(world, faces.cpu().numpy(), eyes, config)
    signs = torch.as_tensor(found, dtype=verts_cam.dtype, device=verts_cam.device)
    return render_equations.face_light(verts_cam, faces, signs, config, TORCH_OPS)


class Blend(Shader):
    """A pair's blend weight w = exp(logit - logit_max) times its face's colour, and w: the
    numerator and denominator of ``render_equations.blend_image``."""

    channels = 2

    def _weight(self, pairs: KeptPairs) -> torch.Tensor:
        shift = pairs.logit_max.index_select(0, pairs.pixel)
        return render_equations.blend_weight(pairs.logit, shift, TORCH_OPS)

    def values(self, pairs: KeptPairs, colors: torch.Tensor) -> torch.Tensor:
        weight = self._weight(pairs)
        return torch.stack([weight * colors.index_select(0, pairs.face), weight])

    def slopes(self, pairs: KeptPairs, colors: torch.Tensor, grad: torch.Tensor):
        weight, color = self._weight(pairs), colors.index_select(0, pairs.face)
        # d/d logit of grad_n * w * C + grad_d * w, with logit = log D' + depth / gamma
        grad_logit = weight * (grad[0] * color + grad[1])
        gamma = pairs.plan.config.gamma
        return grad_logit / pairs.coverage, grad_logit / gamma, grad[0] * weight


class Silhouette(Shader):
    """log(1 - D') of each pair: summed per pixel, the log of its share left uncovered."""

    channels = 1

    def values(self, pairs: KeptPairs, colors: torch.Tensor) -> torch.Tensor:
        return torch.log1p(-pairs.coverage.clamp_max(SATURATED))[None]

    def slopes(self, pairs: KeptPairs, colors: torch.Tensor, grad: torch.Tensor):
        coverage = pairs.coverage
        slope = torch.where(coverage < SATURATED, -1.0 / (1.0 - coverage), 0.0)
        return grad[0] * slope, torch.zeros_like(coverage), None


def shaded_images(
    pairs: KeptPairs, params: torch.Tensor, face_colors: torch.Tensor, background=None
) -> torch.Tensor:
    """SoftRas aggregation of the kept pairs -> (views, S, S) grey images
    (``render_equations.blend_image``; the config's background unless ``background``)."""
    config, size = pairs.plan.config, pairs.plan.config.image_size
    numerator, denominator = pixel_sums(pairs, Blend(), params, face_colors)
    image = render_equations.blend_image(
        numerator, denominator, pairs.logit_max, config, TORCH_OPS, background
    )
    return image.reshape(pairs.plan.num_views, size, size)


def silhouette(pairs: KeptPairs, params: torch.Tensor) -> torch.Tensor:
    """alpha = 1 - prod_j (1 - D_j) over every covered pair (kept without depth cull) ->
    (views, S, S)."""
    size = pairs.plan.config.image_size
    (total,) = pixel_sums(pairs, Silhouette(), params, params.new_zeros(0))
    return (1.0 - torch.exp(total)).reshape(pairs.plan.num_views, size, size)
