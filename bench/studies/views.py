"""The single-view study's images: each shape seen as SoftRas' data sees it, from AZIMUTHS
azimuths at a fixed elevation and distance, rendered by the project's soft rasteriser (grey
shading and the silhouette, the study's RGBA).

One camera renders every view: a view from azimuth a is the mesh turned by -a about the vertical
seen from azimuth 0 (the light is fixed in the camera's frame, so the two images are the same),
which lets one batched render call draw each sample of a batch from its own azimuth.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from drkfs_onnx.contract.cameras import Cameras, look_at
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.render.renderer import Renderer

AZIMUTHS = 24  # SoftRas' ShapeNet renders: 24 azimuths, 15 degrees apart
ELEVATION = 30.0  # degrees
DISTANCE = 2.732  # SoftRas' camera distance
IMAGE_SIZE = 64
# the views' renderer, the data's and the image losses': the project's training renderer
# (SoftRas' reconstruction sigma 1e-4, and a depth blend of gamma 0.1: at SoftRas' 1e-4 the
# nearest face takes a pixel outright, and pixel MSE trained the generator into a plate that
# covered the view, its objective rising to 2.7x its start in 100 steps), the project's light
# and field of view, which frames a shape of radius 1 at this distance
VIEW_CONFIG = PipelineConfig.training(num_views=1, image_size=IMAGE_SIZE, camera_distance=DISTANCE)
CHANNELS = 2  # grey, alpha: the project's renderer is grey, so RGBA's three colours are one


def azimuth_camera(config: PipelineConfig = VIEW_CONFIG) -> Cameras:
    """The one camera at azimuth 0 and ELEVATION, looking at the origin."""
    e = math.radians(ELEVATION)
    eye = config.camera_distance * np.array([[0.0, math.sin(e), math.cos(e)]])
    focal = 1.0 / math.tan(math.radians(config.fov_degrees) / 2.0)
    return Cameras(rotations=look_at(eye), eyes=eye, focal=focal)


def turned(verts: torch.Tensor, azimuths: torch.Tensor) -> torch.Tensor:
    """(B, V, 3) vertices and (B,) azimuth indices -> each mesh turned so that the camera at
    azimuth 0 sees it as the camera at its azimuth would."""
    angle = azimuths.to(verts.dtype) * (2 * math.pi / AZIMUTHS)
    c, s = torch.cos(angle), torch.sin(angle)
    x, y, z = verts.unbind(-1)
    # rotation by -angle about y: the camera at +angle sees what this one sees
    return torch.stack([c[:, None] * x - s[:, None] * z, y, s[:, None] * x + c[:, None] * z], -1)


class ViewRenderer(torch.nn.Module):
    """``forward(verts (B, V, 3), faces (F, 3), azimuths (B,), mode) -> (B, S, S)``: each mesh
    seen from its azimuth, grey ('shaded') or its coverage ('silhouette'), differentiable."""

    def __init__(self, config: PipelineConfig = VIEW_CONFIG):
        super().__init__()
        self.renderer = Renderer(config, azimuth_camera(config))

    def forward(self, verts, faces, azimuths, mode: str = "shaded") -> torch.Tensor:
        return self.renderer.render(turned(verts, azimuths), faces, mode)


@torch.no_grad()
def render_views(views: ViewRenderer, verts: np.ndarray, faces: np.ndarray) -> torch.Tensor:
    """A shape's data: (AZIMUTHS, CHANNELS, S, S) float32, grey then alpha."""
    v = torch.as_tensor(verts, dtype=torch.float32)[None].expand(AZIMUTHS, -1, -1)
    f = torch.as_tensor(faces)
    azimuths = torch.arange(AZIMUTHS)
    return torch.stack([views(v, f, azimuths, mode) for mode in ("shaded", "silhouette")], 1)
