"""Differentiable geometry of a mesh fit: surface samples, Chamfer distance, smoothness."""

from __future__ import annotations

import torch


def surface_points(
    verts: torch.Tensor, faces: torch.Tensor, count: int, generator: torch.Generator
) -> torch.Tensor:
    """(V, 3), (F, 3) -> (count, 3) points drawn uniformly by area.

    Differentiable with respect to ``verts`` through the barycentric combination; which face a
    point lands on is a draw, not a function of the vertices.
    """
    corners = verts[faces]
    area = torch.linalg.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]).norm(
        dim=1
    )
    face = torch.multinomial(area.detach(), count, replacement=True, generator=generator)
    u, v = torch.rand(2, count, 1, generator=generator, dtype=verts.dtype)
    fold = u + v > 1  # fold the square onto the triangle
    u, v = torch.where(fold, 1 - u, u), torch.where(fold, 1 - v, v)
    c = corners[face]
    return c[:, 0] + u * (c[:, 1] - c[:, 0]) + v * (c[:, 2] - c[:, 0])


def chamfer(points: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """(N, 3), (M, 3) -> (): mean squared distance to the nearest point, both ways, summed
    (the squared Chamfer loss of mesh-fitting work, e.g. Pixel2Mesh and PyTorch3D)."""
    # the |a|^2 + |b|^2 - 2ab form: cdist's sqrt has no finite gradient at coincident points
    squared = (points * points).sum(1)[:, None] + (targets * targets).sum(1)[None]
    squared = (squared - 2 * points @ targets.T).clamp_min(0.0)
    return squared.min(1).values.mean() + squared.min(0).values.mean()


class Smoothness:
    """How far a deformed template's offsets are from smooth: mean squared uniform Laplacian
    of (verts - template), so sharp edges the template already has cost nothing.

    ``Smoothness(template (V, 3), faces (F, 3))(verts (V, 3)) -> ()``.
    """

    def __init__(self, template: torch.Tensor, faces: torch.Tensor):
        edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        self.edges = torch.unique(torch.sort(edges, dim=1).values, dim=0)
        degree = torch.zeros(len(template)).index_add(
            0, self.edges.reshape(-1), torch.ones(self.edges.numel())
        )
        self.degree = degree.clamp_min(1.0)[:, None].to(template.dtype)
        self.template = template.detach()

    def laplacian(self, verts: torch.Tensor) -> torch.Tensor:
        """(V, 3) -> (V, 3): each vertex minus the mean of its neighbours."""
        i, j = self.edges.T
        neighbours = torch.zeros_like(verts).index_add(0, i, verts[j]).index_add(0, j, verts[i])
        return verts - neighbours / self.degree

    def __call__(self, verts: torch.Tensor) -> torch.Tensor:
        return (self.laplacian(verts - self.template) ** 2).sum(1).mean()
