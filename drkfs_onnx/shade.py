"""Shaders for rasterised fragments: grey Lambertian faces, SoftRas' soft blend, silhouettes."""

from __future__ import annotations

import torch

from .config import PipelineConfig
from .rasterize import Fragments

SATURATED = 1.0 - 1e-6


def face_shading(
    verts_cam: torch.Tensor, faces: torch.Tensor, config: PipelineConfig
) -> torch.Tensor:
    """(K, V, 3) camera-frame vertices, (F, 3) faces -> (K*F,) grey value per face.

    Flat two-sided Lambertian shading: a face seen from behind is lit as if its normal faced the
    camera, so open and non-watertight meshes show their inner side instead of a black hole.
    """
    v0, v1, v2 = (verts_cam[:, faces[:, i]] for i in range(3))
    normal = torch.cross(v1 - v0, v2 - v0, dim=-1)
    normal = normal / torch.sqrt((normal * normal).sum(-1, keepdim=True) + 1e-20)
    centroid = (v0 + v1 + v2) / 3.0
    towards_camera = torch.where((normal * centroid).sum(-1, keepdim=True) > 0, -1.0, 1.0)
    light = torch.tensor(config.light_direction, dtype=verts_cam.dtype, device=verts_cam.device)
    light = light / light.norm()
    lambert = ((normal * towards_camera) @ light).clamp_min(0.0)
    return (config.ambient + config.diffuse * lambert).reshape(-1)


def soft_blend(
    fragments: Fragments, face_colors: torch.Tensor, num_views: int, config: PipelineConfig
) -> torch.Tensor:
    """SoftRas aggregation -> (K, S, S) grey images.

    I = (sum_j w_j C_j + w_b C_b) / (sum_j w_j + w_b), w_j = D_j exp(z_j / gamma),
    w_b = exp(background_eps / gamma), computed with the per-pixel shift from the rasteriser.
    """
    size = config.image_size
    shift = fragments.logit_max
    weight = torch.exp(
        torch.log(fragments.coverage) + fragments.depth / config.gamma - shift[fragments.pixel]
    )
    numerator = shift.new_zeros(shift.shape).index_add(
        0, fragments.pixel, weight * face_colors[fragments.face]
    )
    denominator = shift.new_zeros(shift.shape).index_add(0, fragments.pixel, weight)
    background = torch.exp(config.background_eps / config.gamma - shift)
    image = (numerator + background * config.background) / (denominator + background)
    return image.reshape(num_views, size, size)


def silhouette(fragments: Fragments, num_views: int, config: PipelineConfig) -> torch.Tensor:
    """alpha = 1 - prod_j (1 - D_j) -> (K, S, S); needs fragments rasterised without depth cull."""
    size = config.image_size
    log_clear = torch.log1p(-fragments.coverage.clamp_max(SATURATED))
    total = fragments.logit_max.new_zeros(num_views * size * size).index_add(
        0, fragments.pixel, log_clear
    )
    return (1.0 - torch.exp(total)).reshape(num_views, size, size)
