"""Differentiable multi-view renderer: cameras + soft rasteriser + grey shader."""

from __future__ import annotations

from typing import Literal

import torch

from .cameras import Cameras, make_cameras
from .config import PipelineConfig
from .rasterize import Fragments, SoftRasterizer, to_screen
from .shade import face_shading, silhouette, soft_blend

RenderMode = Literal["shaded", "silhouette"]


class Renderer:
    """Renders a mesh from the config's cameras.

    ``render(verts (V, 3), faces (F, 3)) -> (K, S, S)`` grey images in [0, 1], differentiable
    with respect to ``verts``. Faces with a vertex in front of the near plane are dropped.
    """

    def __init__(self, config: PipelineConfig, cameras: Cameras | None = None):
        self.config = config
        self.cameras = cameras if cameras is not None else make_cameras(config)
        self.rasterizer = SoftRasterizer(config)

    def render(
        self, verts: torch.Tensor, faces: torch.Tensor, mode: RenderMode = "shaded"
    ) -> torch.Tensor:
        num_views = len(self.cameras)
        if mode == "silhouette":
            _, fragments = self.rasterize(verts, faces, depth_cull=False)
            return silhouette(fragments, num_views, self.config)
        if mode != "shaded":
            raise ValueError(f"unknown render mode {mode!r}; use 'shaded' or 'silhouette'")
        verts_cam, fragments = self.rasterize(verts, faces, depth_cull=True)
        colors = face_shading(verts_cam, faces, self.config)
        return soft_blend(fragments, colors, num_views, self.config)

    def rasterize(
        self, verts: torch.Tensor, faces: torch.Tensor, depth_cull: bool
    ) -> tuple[torch.Tensor, Fragments]:
        """(V, 3), (F, 3) -> (K, V, 3) camera-frame vertices and the views' fragments."""
        verts_cam, screen = to_screen(verts, faces, self.cameras, self.config)
        return verts_cam, self.rasterizer(screen, depth_cull=depth_cull)
