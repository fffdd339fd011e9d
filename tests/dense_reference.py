"""A dense, slow transcription of the soft rasteriser's definition: every pixel against every
face, no culling, float64. Only for tests on tiny meshes and images."""

from __future__ import annotations

import torch

from drkfs_onnx.contract.cameras import Cameras
from drkfs_onnx.contract.config import PipelineConfig


def _segment_distance2(p: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Squared distance from points p (N, 1, 2) to segments a-b (1, F, 2) -> (N, F)."""
    ab = b - a
    t = (((p - a) * ab).sum(-1) / (ab * ab).sum(-1).clamp_min(1e-300)).clamp(0, 1)
    closest = a + t[..., None] * ab
    return ((p - closest) ** 2).sum(-1)


def dense_render(
    verts: torch.Tensor, faces: torch.Tensor, cameras: Cameras, config: PipelineConfig, mode: str
) -> torch.Tensor:
    size = config.image_size
    rot = torch.as_tensor(cameras.rotations, dtype=verts.dtype)
    eyes = torch.as_tensor(cameras.eyes, dtype=verts.dtype)
    centres = (2 * torch.arange(size, dtype=verts.dtype) + 1) / size - 1
    py, px = torch.meshgrid(centres, centres, indexing="ij")
    pixels = torch.stack([px.reshape(-1), py.reshape(-1)], -1)[:, None]  # (N, 1, 2)
    light = torch.tensor(config.light_direction, dtype=verts.dtype)
    light = light / light.norm()
    images = []
    for k in range(len(cameras)):
        cam = (verts - eyes[k]) @ rot[k].T
        tri_cam = cam[faces]  # (F, 3, 3)
        z = tri_cam[..., 2]
        usable = (z > config.near).all(1)
        screen = cameras.focal * tri_cam[..., :2] / z[..., None]
        inv = (1 / z - 1 / config.far) / (1 / config.near - 1 / config.far)
        a, b, c = screen[:, 0][None], screen[:, 1][None], screen[:, 2][None]
        dist2 = torch.minimum(
            torch.minimum(_segment_distance2(pixels, a, b), _segment_distance2(pixels, b, c)),
            _segment_distance2(pixels, c, a),
        )
        # Barycentrics by Cramer's rule.
        v0, v1, v2 = b - a, c - a, pixels - a
        den = v0[..., 0] * v1[..., 1] - v1[..., 0] * v0[..., 1]
        den = torch.where(den.abs() > 1e-12, den, torch.full_like(den, 1e-12))
        l1 = (v2[..., 0] * v1[..., 1] - v1[..., 0] * v2[..., 1]) / den
        l2 = (v0[..., 0] * v2[..., 1] - v2[..., 0] * v0[..., 1]) / den
        l0 = 1 - l1 - l2
        inside = (l0 > 0) & (l1 > 0) & (l2 > 0)
        prob = torch.sigmoid(torch.where(inside, dist2, -dist2) / config.sigma)
        eps = config.coverage_eps
        cover = ((prob - eps) / (1 - eps)).clamp_min(0) * usable
        depth = l0 * inv[:, 0] + l1 * inv[:, 1] + l2 * inv[:, 2]
        depth = torch.minimum(torch.maximum(depth, inv.min(1).values), inv.max(1).values)
        if mode == "silhouette":
            alpha = 1 - torch.prod(1 - cover.clamp_max(1 - 1e-6), dim=1)
            images.append(alpha.reshape(size, size))
            continue
        normal = torch.linalg.cross(tri_cam[:, 1] - tri_cam[:, 0], tri_cam[:, 2] - tri_cam[:, 0])
        normal = normal / normal.norm(dim=1, keepdim=True).clamp_min(1e-10)
        if_back = (normal * tri_cam.mean(1)).sum(1) > 0
        normal = torch.where(if_back[:, None], -normal, normal)
        color = config.ambient + config.diffuse * (normal @ light).clamp_min(0)
        logits = torch.log(cover) + depth / config.gamma  # -inf where uncovered
        background = torch.full((len(pixels), 1), config.background_eps / config.gamma)
        weights = torch.softmax(torch.cat([logits, background.to(verts.dtype)], 1), dim=1)
        image = weights[:, :-1] @ color + weights[:, -1] * config.background
        images.append(image.reshape(size, size))
    return torch.stack(images)
