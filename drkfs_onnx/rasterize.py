"""Sparse soft rasteriser (SoftRas' formulation) in plain torch.

Each face covers pixel p with probability D = sigmoid(+-d^2 / sigma), d the screen distance from
p to the triangle (+ inside, - outside). Like SoftRas' kernel we cut D where it falls below
``coverage_eps``; we shift and rescale it there, D' = max(D - eps, 0) / (1 - eps), so the cut is
continuous and the function stays smooth for gradients.

Cost grows with the covered pixel-face pairs, not pixels x faces:

1. every face lists the pixels of its bounding box grown by the cut-off radius;
2. a no-grad pass computes coverage and depth of those pairs, drops the uncovered ones and, for
   shaded images, the ones hidden behind a nearer face by more than ``DEPTH_CULL`` softmax
   logits (their weight is below exp(-DEPTH_CULL) of the front face's);
3. only the surviving pairs are recomputed with autograd.

Output is a list of pixel-face pairs (``Fragments``); shading and blending live in ``shade.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from .cameras import Cameras
from .config import PipelineConfig
from .coverage import pair_terms

DEPTH_CULL = 30.0
# Pairs per chunk of the candidate pass: small enough for elementwise work to stay in cache.
PAIR_CHUNK = 1 << 17


@dataclass
class ScreenFaces:
    """Faces projected into K views.

    params: (9, K*F) per face: x0, y0, x1, y1, x2, y2 in NDC, then the three vertices' normalised
        inverse depths (1 at the near plane, 0 at the far plane). Coordinate-major, so that
        gathering pairs gives nine contiguous rows for fast elementwise work.
    visible: (K*F,) bool, False for faces with a vertex in front of the near plane.
    """

    params: torch.Tensor
    visible: torch.Tensor
    num_views: int
    num_faces: int


@dataclass
class Fragments:
    """Pixel-face pairs of K views of size S x S.

    pixel: (P,) flat index into (K, S, S); face: (P,) flat index into (K, F);
    coverage: (P,) D' in (0, 1]; depth: (P,) normalised inverse depth (larger is nearer);
    logit_max: (K*S*S,) the softmax shift per pixel (max of log D' + depth / gamma, background
    included), a constant for autograd.
    """

    pixel: torch.Tensor
    face: torch.Tensor
    coverage: torch.Tensor
    depth: torch.Tensor
    logit_max: torch.Tensor


def camera_tensors(cameras: Cameras, like: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    rot = torch.as_tensor(cameras.rotations, dtype=like.dtype, device=like.device)
    eyes = torch.as_tensor(cameras.eyes, dtype=like.dtype, device=like.device)
    return rot, eyes


def to_camera(verts: torch.Tensor, cameras: Cameras) -> torch.Tensor:
    """(V, 3) world vertices -> (K, V, 3) camera-frame vertices."""
    rot, eyes = camera_tensors(cameras, verts)
    return torch.einsum("kij,knj->kni", rot, verts[None] - eyes[:, None])


def project_faces(
    verts_cam: torch.Tensor, faces: torch.Tensor, focal: float, config: PipelineConfig
) -> ScreenFaces:
    """(K, V, 3) camera-frame vertices and (F, 3) faces -> ScreenFaces."""
    k, f = verts_cam.shape[0], faces.shape[0]
    z = verts_cam[..., 2]
    visible_vert = z > config.near
    z_safe = torch.where(visible_vert, z, torch.full_like(z, config.near))
    xy = focal * verts_cam[..., :2] / z_safe[..., None]
    inv_near, inv_far = 1.0 / config.near, 1.0 / config.far
    inv_depth = (1.0 / z_safe - inv_far) / (inv_near - inv_far)
    tri_xy = xy[:, faces].reshape(k * f, 6)
    tri_w = inv_depth[:, faces].reshape(k * f, 3)
    params = torch.cat([tri_xy, tri_w], dim=1).t().contiguous()
    visible = visible_vert[:, faces].all(dim=2).reshape(k * f)
    return ScreenFaces(params=params, visible=visible, num_views=k, num_faces=f)


class SoftRasterizer:
    """Lists the pixel-face pairs of K views with coverage and depth, differentiably."""

    def __init__(self, config: PipelineConfig):
        self.config = config

    def __call__(self, screen: ScreenFaces, depth_cull: bool = True) -> Fragments:
        with torch.no_grad():
            pixel, face, logit_max = self._candidates(screen, depth_cull)
        size = self.config.image_size
        tri = screen.params.index_select(1, face)
        px, py = self._pixel_ndc(pixel % size, pixel // size, tri.dtype)
        coverage, depth = pair_terms(tri, px, py, self.config, torch)
        return Fragments(pixel, face, coverage, depth, logit_max)

    def _pixel_ndc(
        self, col: torch.Tensor, row: torch.Tensor, dtype: torch.dtype
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Pixel centres in NDC: pixel i sits at (2i + 1) / size - 1; rows wrap across views."""
        size = self.config.image_size
        return (
            (2 * col + 1).to(dtype) / size - 1.0,
            (2 * (row % size) + 1).to(dtype) / size - 1.0,
        )

    def _pixel_boxes(self, params: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Per face: first pixel (flat index), width and height of its bounding box grown by the
        cut-off radius, clipped to the image."""
        size = self.config.image_size
        radius = self.config.coverage_radius
        xs, ys = params[0:6:2], params[1:6:2]

        def to_index(lo: torch.Tensor, hi: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
            first = torch.ceil((lo - radius + 1.0) * size / 2.0 - 0.5).clamp(0, size)
            last = torch.floor((hi + radius + 1.0) * size / 2.0 - 0.5).clamp(-1, size - 1)
            return first.long(), (last.long() - first.long() + 1).clamp_min(0)

        i0, width = to_index(xs.amin(0), xs.amax(0))
        j0, height = to_index(ys.amin(0), ys.amax(0))
        return i0, j0, width, height

    def _candidates(
        self, screen: ScreenFaces, depth_cull: bool
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        cfg = self.config
        size = cfg.image_size
        params = screen.params.detach()
        device = params.device
        logit_max = torch.full(
            (screen.num_views * size * size,),
            cfg.background_eps / cfg.gamma,
            dtype=params.dtype,
            device=device,
        )
        i0, j0, width, height = self._pixel_boxes(params)
        counts = width * height * screen.visible
        view = torch.arange(screen.num_views, device=device).repeat_interleave(screen.num_faces)
        # Global row (view * size + row) of each face's first pixel row, and its first column.
        first_row = view * size + j0
        empty = torch.zeros(0, dtype=torch.long, device=device)
        pixels, faces, logits = [empty], [empty], [params.new_zeros(0)]
        for face_ids in self._face_chunks(counts):
            n = counts[face_ids]
            pair_face = face_ids.repeat_interleave(n)
            start = torch.cumsum(n, 0) - n
            local = torch.arange(int(n.sum()), device=device) - start.repeat_interleave(n)
            w = width.index_select(0, pair_face)
            row = first_row.index_select(0, pair_face) + local // w
            col = i0.index_select(0, pair_face) + local % w
            px, py = self._pixel_ndc(col, row, params.dtype)
            coverage, depth = pair_terms(params.index_select(1, pair_face), px, py, cfg, torch)
            kept = torch.nonzero(coverage > 0).squeeze(1)
            pixel = (row * size + col).index_select(0, kept)
            logit = (
                torch.log(coverage.index_select(0, kept)) + depth.index_select(0, kept) / cfg.gamma
            )
            logit_max.scatter_reduce_(0, pixel, logit, reduce="amax")
            pixels.append(pixel)
            faces.append(pair_face.index_select(0, kept))
            logits.append(logit)
        pixel, face, logit = torch.cat(pixels), torch.cat(faces), torch.cat(logits)
        if depth_cull:
            kept = torch.nonzero(logit >= logit_max.index_select(0, pixel) - DEPTH_CULL).squeeze(1)
            pixel, face = pixel.index_select(0, kept), face.index_select(0, kept)
        return pixel, face, logit_max

    @staticmethod
    def _face_chunks(counts: torch.Tensor) -> list[torch.Tensor]:
        """Split face ids into runs of about PAIR_CHUNK pairs (one face's pairs stay together)."""
        ids = torch.nonzero(counts).squeeze(1)
        if ids.numel() == 0:
            return []
        cumulative = torch.cumsum(counts[ids], 0)
        bucket = torch.div(cumulative - 1, PAIR_CHUNK, rounding_mode="floor")
        return [chunk for chunk in torch.split(ids, torch.bincount(bucket).tolist()) if len(chunk)]
