"""The geometry terms a training loop puts beside DR-KFS: surface samples, Chamfer distance and
smoothness, batched like the loss (``render.mesh_batch.MeshBatch``) and made on the input's
device.

    points = surface_points(pred_verts, faces, 2000, generator)  # (B, 2000, 3)
    value = chamfer(points, truth_points)  # mean over the batch; batch_reduction="none" -> (B,)
"""

from __future__ import annotations

import torch

from .render.mesh_batch import MeshBatch, over_batch

NORMS = (1, 2)


def surface_points(
    verts, faces, count: int, generator: torch.Generator | None = None
) -> torch.Tensor:
    """Points drawn uniformly by area on a mesh's surface.

    Args:
        verts, faces: one mesh, (V, 3) and (F, 3), or a batch (any form ``MeshBatch.of``
            takes).
        count: points per mesh.
        generator: the draws' source, on whatever device it lives; torch's default on the
            vertices' device when None.

    Returns:
        (count, 3) for one mesh, (B, count, 3) for a batch, on the vertices' device.
        Differentiable with respect to the vertices through the barycentric combination;
        which face a point lands on is a draw, not a function of the vertices (every face
        alike on a mesh with no area: a prediction collapsed to a point).
    """
    meshes = MeshBatch.of(verts, faces)
    corners = torch.take_along_dim(meshes.verts[:, :, None], meshes.faces[..., None], dim=1)
    edges = corners[:, :, 1:] - corners[:, :, :1]  # (B, F, 2, 3)
    area = torch.linalg.cross(edges[:, :, 0], edges[:, :, 1]).norm(dim=-1)  # padding: area 0
    draw_on = generator.device if generator is not None else meshes.verts.device
    weights = area.detach()
    # a mesh collapsed to a point or a line has no area to weigh by: every face alike (its
    # points are then where the mesh is), where multinomial would refuse all-zero weights
    weights = torch.where(weights.sum(-1, keepdim=True) > 0, weights, 1.0)
    face = torch.multinomial(weights.to(draw_on), count, replacement=True,
                             generator=generator).to(meshes.verts.device)  # fmt: skip
    u, v = torch.rand(2, len(meshes), count, 1, generator=generator, dtype=meshes.verts.dtype,
                      device=draw_on).to(meshes.verts.device)  # fmt: skip
    fold = u + v > 1  # fold the square onto the triangle
    u, v = torch.where(fold, 1 - u, u), torch.where(fold, 1 - v, v)
    c = torch.take_along_dim(corners, face[..., None, None], dim=1)  # (B, count, 3, 3)
    points = c[:, :, 0] + u * (c[:, :, 1] - c[:, :, 0]) + v * (c[:, :, 2] - c[:, :, 0])
    return meshes.unbatch(points)


def chamfer(
    points: torch.Tensor, targets: torch.Tensor, norm: int = 2, batch_reduction: str = "mean"
) -> torch.Tensor:
    """Chamfer distance: the mean distance to the nearest point, both ways, summed. Builds the
    (N, M) distance matrix of each mesh, as ``torch.cdist`` does.

    Args:
        points: (N, 3), or a batch's (B, N, 3).
        targets: (M, 3), shared by a batch, or one each (B, M, 3); on the points' device.
        norm: 2 takes squared distances (Chamfer-L2, the loss of Pixel2Mesh and PyTorch3D),
            1 Euclidean ones (Chamfer-L1).
        batch_reduction: a batch's values' 'mean', 'sum', or 'none'.

    Returns:
        () for one cloud; a batch's () mean or sum, or its (B,) values.
    """
    if norm not in NORMS:
        raise ValueError(f"unknown norm {norm!r}; use 1 (Euclidean) or 2 (squared)")
    for name, cloud in (("points", points), ("targets", targets)):
        if cloud.ndim not in (2, 3) or cloud.shape[-1] != 3 or not cloud.is_floating_point():
            raise ValueError(
                f"{name}: expected a float tensor (N, 3) or (B, N, 3); got {cloud.dtype} "
                f"{tuple(cloud.shape)}"
            )
    if targets.device != points.device:
        raise ValueError(f"targets: expected a tensor on {points.device}; got {targets.device}")
    single = points.ndim == 2
    # float32 at least, autocast off: under a caller's mixed precision the product below would
    # run in float16 or bfloat16, whose 8-11 bits cancel away the distances between near points
    dtype = torch.promote_types(torch.promote_types(points.dtype, targets.dtype), torch.float32)
    points, targets = (points if not single else points[None]).to(dtype), targets.to(dtype)
    with torch.autocast(points.device.type, enabled=False):
        # the |a|^2 + |b|^2 - 2ab form: cdist's sqrt has no finite gradient at coincident points
        squared = (points * points).sum(-1)[..., :, None]
        squared = squared + (targets * targets).sum(-1)[..., None, :]
        squared = (squared - 2 * points @ targets.transpose(-1, -2)).clamp_min(0.0)
    near_a, near_b = squared.min(-1).values, squared.min(-2).values
    if norm == 1:  # sqrt kept off 0, where its slope is infinite
        near_a, near_b = near_a.clamp_min(1e-12).sqrt(), near_b.clamp_min(1e-12).sqrt()
    values = near_a.mean(-1) + near_b.mean(-1)
    return over_batch(values, single, batch_reduction)


class Smoothness:
    """How far a deformed template's offsets are from smooth: mean squared uniform Laplacian
    of (verts - template), so sharp edges the template already has cost nothing.

    Args:
        template: (V, 3) the undeformed vertices; the tables live on its device
            (``to(device)`` moves them).
        faces: (F, 3) the template's faces.

    Shape:
        - call: verts (V, 3) or a batch's (B, V, 3) -> (), the mean over the batch.
    """

    def __init__(self, template: torch.Tensor, faces: torch.Tensor):
        edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        self.edges = torch.unique(torch.sort(edges, dim=1).values, dim=0).to(template.device)
        ones = torch.ones(self.edges.numel(), dtype=template.dtype, device=template.device)
        degree = ones.new_zeros(len(template)).index_add(0, self.edges.reshape(-1), ones)
        self.degree = degree.clamp_min(1.0)[:, None]
        self.template = template.detach()

    def to(self, device: torch.device | str) -> Smoothness:
        self.edges, self.degree = self.edges.to(device), self.degree.to(device)
        self.template = self.template.to(device)
        return self

    def laplacian(self, verts: torch.Tensor) -> torch.Tensor:
        """(..., V, 3) -> (..., V, 3): each vertex minus the mean of its neighbours."""
        i, j = self.edges.T
        neighbours = torch.zeros_like(verts).index_add(-2, i, verts.index_select(-2, j))
        neighbours = neighbours.index_add(-2, j, verts.index_select(-2, i))
        return verts - neighbours / self.degree

    def __call__(self, verts: torch.Tensor) -> torch.Tensor:
        return (self.laplacian(verts - self.template) ** 2).sum(-1).mean()
