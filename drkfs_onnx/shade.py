"""Shaders for rasterised fragments (torch): grey Lambertian faces with SoftRas' soft blend, and
silhouettes. The equations are ``render_math``'s, shared with the numpy renderer."""

from __future__ import annotations

import torch

from . import render_math
from .config import PipelineConfig
from .rasterize import TORCH_OPS, Fragments

SATURATED = 1.0 - 1e-6


def face_shading(
    verts_cam: torch.Tensor, faces: torch.Tensor, config: PipelineConfig
) -> torch.Tensor:
    """(K, V, 3) camera-frame vertices, (F, 3) faces -> (K*F,) grey value per face
    (``render_math.face_shading``)."""
    return render_math.face_shading(verts_cam, faces, config, TORCH_OPS)


def soft_blend(
    fragments: Fragments, face_colors: torch.Tensor, num_views: int, config: PipelineConfig
) -> torch.Tensor:
    """SoftRas aggregation -> (K, S, S) grey images (``render_math.soft_blend``)."""
    size = config.image_size
    logit = render_math.pair_logit(fragments.coverage, fragments.depth, config, TORCH_OPS)
    image = render_math.soft_blend(
        fragments.pixel, fragments.face, logit, fragments.logit_max, face_colors, config, TORCH_OPS
    )
    return image.reshape(num_views, size, size)


def silhouette(fragments: Fragments, num_views: int, config: PipelineConfig) -> torch.Tensor:
    """alpha = 1 - prod_j (1 - D_j) -> (K, S, S); needs fragments rasterised without depth cull."""
    size = config.image_size
    log_clear = torch.log1p(-fragments.coverage.clamp_max(SATURATED))
    total = fragments.logit_max.new_zeros(num_views * size * size).index_add(
        0, fragments.pixel, log_clear
    )
    return (1.0 - torch.exp(total)).reshape(num_views, size, size)
