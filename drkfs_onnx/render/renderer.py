"""Differentiable multi-view renderer: cameras + soft rasteriser + grey shader."""

from __future__ import annotations

from typing import Literal

import torch
from torch import nn

from ..contract.cameras import Cameras, make_cameras
from ..contract.config import PipelineConfig
from ..contract.render_equations import (
    ScreenFaces,
    project_faces,
    pushed_back,
    pushes_back,
    to_camera,
)
from .kept_pairs import KeptPairs, kept_pairs
from .mesh_batch import MeshBatch
from .pair_plan import PairPlan
from .shading import face_light, shaded_images, silhouette
from .torch_ops import TORCH_OPS

RenderMode = Literal["shaded", "silhouette"]


def to_screen(
    verts: torch.Tensor,
    faces: torch.Tensor,
    rotations: torch.Tensor,
    eyes: torch.Tensor,
    focal: float,
    config: PipelineConfig,
) -> tuple[torch.Tensor, ScreenFaces]:
    """(B, V, 3) world vertices, (B, F, 3) faces, K cameras ((K, 3, 3) rotations, (K, 3) eyes)
    -> (B, K, V, 3) camera-frame vertices and the faces projected into the B*K views."""
    verts_cam = to_camera(verts, rotations.to(verts.dtype), eyes.to(verts.dtype), TORCH_OPS)
    return verts_cam, project_faces(verts_cam, faces, focal, config, TORCH_OPS)


class Renderer(nn.Module):
    """Renders meshes from the config's K cameras, which it holds as buffers (``.to()`` moves
    them).

    ``render(verts (V, 3), faces (F, 3)) -> (K, S, S)`` grey images in [0, 1], differentiable
    with respect to ``verts``; a batch of B meshes (any form ``MeshBatch.of`` takes) -> (B * K,
    S, S), mesh b's views at b * K .. (b + 1) * K. Faces with a vertex in front of the near
    plane are dropped.
    """

    def __init__(self, config: PipelineConfig, cameras: Cameras | None = None):
        super().__init__()
        self.config = config
        self.cameras = cameras if cameras is not None else make_cameras(config)
        for name in ("rotations", "eyes"):
            value = torch.as_tensor(getattr(self.cameras, name), dtype=torch.float64)
            self.register_buffer(name, value, persistent=False)

    def render(self, verts, faces=None, mode: RenderMode = "shaded") -> torch.Tensor:
        if mode not in ("shaded", "silhouette"):
            raise ValueError(f"unknown render mode {mode!r}; use 'shaded' or 'silhouette'")
        meshes = MeshBatch.of(verts, faces)
        # on a CPU mesh by mesh, so that a mesh's pairs stay in cache (a batch's do not); on a
        # GPU the whole batch at once (docs/design_notes.md)
        size = len(meshes) if meshes.verts.is_cuda else 1
        return torch.cat([self._render(group, mode) for group in meshes.split(size)])

    def _render(self, meshes: MeshBatch, mode: RenderMode) -> torch.Tensor:
        verts_cam, screen = self.screen(meshes)
        plan = PairPlan(screen, self.config)
        pairs = kept_pairs(plan, screen.params, mode == "shaded")
        if mode == "silhouette":
            return silhouette(pairs, screen.params)
        eyes = self.cameras.eyes
        lit, shadow, behind = face_light(meshes.verts, verts_cam, meshes.faces, eyes, self.config)
        if not pushes_back(self.config):
            return shaded_images(pairs, screen.params, lit - shadow)
        # lit from both sides, less the shadow where faces seen from behind still show pushed
        # back: an opening's inside, not an outline. The push moves depths alone, so the plan
        # of pixel-face pairs (screen boxes and spans) serves both blends.
        pushed = pushed_back(screen, behind, self.config, TORCH_OPS)
        shade_pairs = kept_pairs(plan, pushed.params, True)
        shade = shaded_images(shade_pairs, pushed.params, shadow, background=0.0)
        return shaded_images(pairs, screen.params, lit) - shade

    @torch.no_grad()
    def rasterize(self, verts, faces=None, depth_cull: bool = True) -> KeptPairs:
        """The pixel-face pairs the views are made of (no autograd), for analysis."""
        meshes = MeshBatch.of(verts, faces)
        _, screen = self.screen(meshes)
        plan = PairPlan(screen, self.config)
        return kept_pairs(plan, screen.params, depth_cull, with_depth=True)

    def screen(self, meshes: MeshBatch) -> tuple[torch.Tensor, ScreenFaces]:
        """-> (B, K, V, 3) camera-frame vertices and the faces projected into the B * K views,
        padding faces and faces of no area hidden."""
        verts_cam, screen = to_screen(
            meshes.verts, meshes.faces, self.rotations, self.eyes, self.cameras.focal, self.config
        )
        # padding, and faces of no area (as the runtime drops them), cover no pixel
        valid = meshes.faces_with_area()[:, None].expand(-1, len(self.cameras), -1).reshape(-1)
        screen.visible = screen.visible & valid
        return verts_cam, screen
