"""SoftRas' shape generator (Liu et al. 2019, after NMR), scaled to the single-view study, and
the regularisers its authors trained it with.

An encoder of one 64 px image (three 5 x 5 stride-2 convolutions with batch norm, three fully
connected layers) gives a code; the decoder maps it to a centroid and a displacement of every
vertex of a 642-vertex icosphere. NMR's parametrisation keeps each vertex inside the unit box
and the sphere's topology: a vertex's coordinate is sigmoid(logit(|base|) + bias) * sign(base),
then squeezed towards the predicted centroid. SoftRas' widths (64-128-256 channels, 1024-wide
layers, a 25M-parameter network) are scaled down to ``Widths`` so that a network trains in
minutes on 2 CPU cores and its weights are a small file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import trimesh
from torch import nn
from torch.nn import functional as F

from drkfs_onnx.geometry import Smoothness

SPHERE_LEVEL = 3  # 642 vertices, 1,280 faces: SoftRas' sphere_642
SPHERE_RADIUS = 0.5  # SoftRas' obj_scale: the template's radius in the unit box
CENTROID_SCALE = 0.1  # SoftRas' decoder: the centroid's and the displacements' scales
BIAS_SCALE = 1.0
# SoftRas' regularisers' weights (examples/recon/train.py): the uniform Laplacian's summed
# squares and the flatten loss's summed (1 + cos)^2 over edges
LAPLACIAN_WEIGHT = 5e-3
FLATTEN_WEIGHT = 5e-4


@dataclass(frozen=True)
class Widths:
    """The generator's sizes. SoftRas' own: channels (64, 128, 256), hidden 1024, code 512,
    decoder (1024, 2048)."""

    channels: tuple[int, int, int] = (16, 32, 64)
    hidden: int = 256
    code: int = 256
    decoder: tuple[int, int] = (256, 256)


def template_sphere() -> tuple[torch.Tensor, torch.Tensor]:
    """The (642, 3) unit icosphere turned by a fixed rotation, and its (1280, 3) faces.

    Why turned: trimesh's icosphere has coordinates that are exactly 0, where sign(base) is 0
    and NMR's parametrisation could never move them."""
    sphere = trimesh.creation.icosphere(SPHERE_LEVEL)
    turn = trimesh.transformations.euler_matrix(0.3, 0.5, 0.7)[:3, :3]
    verts = np.asarray(sphere.vertices) @ turn.T
    return torch.as_tensor(verts, dtype=torch.float32), torch.as_tensor(sphere.faces)


class ShapeGenerator(nn.Module):
    """Image -> mesh.

    ``forward(images (B, C, S, S)) -> (B, 642, 3)`` vertices in [-1, 1]^3 (the study's shapes
    fit the unit sphere); ``faces`` (1280, 3) is fixed. S must be a multiple of 8.
    """

    def __init__(self, in_channels: int, image_size: int, widths: Widths = Widths()):
        super().__init__()
        c1, c2, c3 = widths.channels
        layers = []
        for a, b in ((in_channels, c1), (c1, c2), (c2, c3)):
            layers += [nn.Conv2d(a, b, 5, stride=2, padding=2), nn.BatchNorm2d(b), nn.ReLU()]
        self.encoder = nn.Sequential(
            *layers,
            nn.Flatten(),
            nn.Linear(c3 * (image_size // 8) ** 2, widths.hidden),
            nn.ReLU(),
            nn.Linear(widths.hidden, widths.hidden),
            nn.ReLU(),
            nn.Linear(widths.hidden, widths.code),
            nn.ReLU(),
        )
        d1, d2 = widths.decoder
        self.decoder = nn.Sequential(
            nn.Linear(widths.code, d1), nn.ReLU(), nn.Linear(d1, d2), nn.ReLU()
        )
        unit, faces = template_sphere()
        self.centroid = nn.Linear(d2, 3)
        self.bias = nn.Linear(d2, unit.numel())
        base = SPHERE_RADIUS * unit
        self.register_buffer("sign", torch.sign(base), persistent=False)
        self.register_buffer("base_logit", torch.logit(base.abs()), persistent=False)
        self.register_buffer("faces", faces, persistent=False)

    def template(self) -> torch.Tensor:
        """(642, 3): the sphere every prediction deforms."""
        return torch.sigmoid(self.base_logit) * self.sign

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        hidden = self.decoder(self.encoder(images))
        centroid = torch.tanh(CENTROID_SCALE * self.centroid(hidden))[:, None]  # (B, 1, 3)
        bias = BIAS_SCALE * self.bias(hidden).reshape(len(images), -1, 3)
        verts = torch.sigmoid(self.base_logit + bias) * self.sign  # in (-1, 1)
        # squeezed towards the centroid so that every vertex stays in the unit box
        return F.relu(verts) * (1 - centroid) - F.relu(-verts) * (1 + centroid) + centroid


class Regularisers:
    """SoftRas' Laplacian and flatten losses of a batch of predictions (B, V, 3) on the
    generator's faces -> () each, their sums over a mesh averaged over the batch."""

    def __init__(self, template: torch.Tensor, faces: torch.Tensor):
        self.smooth = Smoothness(template, faces)
        edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        opposite = faces[:, [2, 0, 1]].reshape(-1)
        key = torch.sort(edges, dim=1).values
        order = torch.argsort(key[:, 0] * len(template) + key[:, 1])
        # a closed mesh's edges come in pairs: each sorted pair is one edge's two faces
        first, second = order[0::2], order[1::2]
        if not torch.equal(key[first], key[second]):
            raise ValueError("the template must be a closed manifold mesh")
        self.edge = key[first]  # (E, 2)
        self.across = torch.stack([opposite[first], opposite[second]], dim=1)  # (E, 2)

    def to(self, device: torch.device | str) -> Regularisers:
        self.smooth = self.smooth.to(device)
        self.edge, self.across = self.edge.to(device), self.across.to(device)
        return self

    def laplacian(self, verts: torch.Tensor) -> torch.Tensor:
        return (self.smooth.laplacian(verts) ** 2).sum((-1, -2)).mean()

    def flatten(self, verts: torch.Tensor) -> torch.Tensor:
        """sum over edges of (1 + cos)^2, cos the angle between the two faces' heights over
        the edge: 0 where the faces are coplanar."""
        start, end = verts[:, self.edge[:, 0]], verts[:, self.edge[:, 1]]
        along = end - start
        along = along / along.norm(dim=-1, keepdim=True).clamp_min(1e-12)
        heights = []
        for k in range(2):
            out = verts[:, self.across[:, k]] - start
            height = out - (out * along).sum(-1, keepdim=True) * along
            heights.append(height / height.norm(dim=-1, keepdim=True).clamp_min(1e-12))
        cos = (heights[0] * heights[1]).sum(-1)
        return ((1 + cos) ** 2).sum(-1).mean()

    def __call__(self, verts: torch.Tensor) -> torch.Tensor:
        return LAPLACIAN_WEIGHT * self.laplacian(verts) + FLATTEN_WEIGHT * self.flatten(verts)
