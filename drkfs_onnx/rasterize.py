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
The equations are ``render_math``'s, shared with the numpy renderer; this module holds what only
autograd needs: the two passes.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import torch

from .cameras import Cameras
from .config import PipelineConfig
from .render_math import (
    DEPTH_CULL,
    ScreenFaces,
    background_logit,
    pair_logit,
    pair_terms,
    pixel_centre,
    pixel_span,
    project_faces,
    to_camera,
)

# Pairs per chunk of the candidate pass: small enough for elementwise work to stay in cache.
PAIR_CHUNK = 1 << 17


def _scatter_sum(index: torch.Tensor, values: torch.Tensor, length: int) -> torch.Tensor:
    return values.new_zeros(length).index_add(0, index, values)


def _scatter_max(out: torch.Tensor, index: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    return out.scatter_reduce_(0, index, values, reduce="amax")


TORCH_OPS = SimpleNamespace(
    where=torch.where, minimum=torch.minimum, maximum=torch.maximum, clip=torch.clip,
    ceil=torch.ceil, floor=torch.floor, sqrt=torch.sqrt, exp=torch.exp, log=torch.log,
    sigmoid=torch.sigmoid, stack=torch.stack, einsum=torch.einsum, scatter_sum=_scatter_sum,
    scatter_max=_scatter_max,
)  # fmt: skip


@dataclass
class Fragments:
    """Pixel-face pairs of K views of size S x S.

    pixel: (P,) flat index into (K, S, S); face: (P,) flat index into (K, F);
    coverage: (P,) D' in (0, 1]; depth: (P,) normalised inverse depth (larger is nearer);
    logit_max: (K*S*S,) the softmax shift per pixel (max of ``pair_logit``, background
    included), a constant for autograd.
    """

    pixel: torch.Tensor
    face: torch.Tensor
    coverage: torch.Tensor
    depth: torch.Tensor
    logit_max: torch.Tensor


def to_screen(
    verts: torch.Tensor, faces: torch.Tensor, cameras: Cameras, config: PipelineConfig
) -> tuple[torch.Tensor, ScreenFaces]:
    """(V, 3) world vertices, (F, 3) faces -> (K, V, 3) camera-frame vertices and the faces
    projected into the cameras' views."""
    rotations = torch.as_tensor(cameras.rotations, dtype=verts.dtype, device=verts.device)
    eyes = torch.as_tensor(cameras.eyes, dtype=verts.dtype, device=verts.device)
    verts_cam = to_camera(verts, rotations, eyes, TORCH_OPS)
    return verts_cam, project_faces(verts_cam, faces, cameras.focal, config, TORCH_OPS)


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
        coverage, depth = pair_terms(tri, px, py, self.config, TORCH_OPS)
        return Fragments(pixel, face, coverage, depth, logit_max)

    def _pixel_ndc(
        self, col: torch.Tensor, row: torch.Tensor, dtype: torch.dtype
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Pixel centres in NDC; rows wrap across views."""
        size = self.config.image_size
        return pixel_centre(col.to(dtype), size), pixel_centre((row % size).to(dtype), size)

    def _pixel_boxes(self, params: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Per face: first column and row, width and height of its bounding box grown by the
        cut-off radius, clipped to the image."""
        xs, ys = params[0:6:2], params[1:6:2]
        i0, width = pixel_span(xs.amin(0), xs.amax(0), self.config, TORCH_OPS)
        j0, height = pixel_span(ys.amin(0), ys.amax(0), self.config, TORCH_OPS)
        return i0.long(), j0.long(), width.long(), height.long()

    def _candidates(
        self, screen: ScreenFaces, depth_cull: bool
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        cfg = self.config
        size = cfg.image_size
        params = screen.params.detach()
        device = params.device
        logit_max = torch.full(
            (screen.num_views * size * size,),
            background_logit(cfg),
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
            tri = params.index_select(1, pair_face)
            coverage, depth = pair_terms(tri, px, py, cfg, TORCH_OPS)
            kept = torch.nonzero(coverage > 0).squeeze(1)
            pixel = (row * size + col).index_select(0, kept)
            coverage, depth = coverage.index_select(0, kept), depth.index_select(0, kept)
            logit = pair_logit(coverage, depth, cfg, TORCH_OPS)
            TORCH_OPS.scatter_max(logit_max, pixel, logit)
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
