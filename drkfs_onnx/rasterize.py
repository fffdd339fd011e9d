"""Sparse soft rasteriser (SoftRas' formulation) in plain torch, sized for a batch of meshes.

Each face covers pixel p with probability D = sigmoid(+-d^2 / sigma), d the screen distance from
p to the triangle (+ inside, - outside). Like SoftRas' kernel we cut D where it falls below
``coverage_eps``; we shift and rescale it there, D' = max(D - eps, 0) / (1 - eps), so the cut is
continuous and the function stays smooth for gradients.

Cost grows with the pixel-face pairs within the cut-off radius of each face's edge lines, not
pixels x faces, and a batch of B meshes' K views is one screen of B * K views:

1. a ``PairPlan`` enumerates those pairs, a span of columns in each row of a face's box, in
   chunks of ``pair_chunk(device)`` pairs (a CPU's cache; millions on a GPU);
2. ``kept_pairs`` computes their coverage, depth and blend logit without autograd, each pixel's
   largest logit, and lists once the pairs the image is made of: covered, and not hidden behind a
   nearer face by more than ``DEPTH_CULL`` softmax logits (their weight is below
   exp(-DEPTH_CULL) of the front face's);
3. ``pixel_sums`` sums a shader's per-pair terms per pixel, and its backward recomputes each
   chunk's edges and sends the pixels' gradients to the faces by ``pair_terms_grad``, the gradient
   written out (its parts summed per face, then ``face_params_grad``), instead of keeping
   autograd's graph of every pair (14 GB for 32 meshes on a GPU).

A step waits for the host three times whatever the batch: the plan's box rows and chunks, and
the kept pairs' count. The equations are compiled on a GPU, and on a CPU for a training step
(``_compiles``). They are ``render_math``'s, shared with the numpy renderer.
"""

from __future__ import annotations

import functools
import os
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from types import SimpleNamespace

import torch

from .config import PipelineConfig
from .render_math import (
    DEPTH_CULL,
    LOOSE_RADIUS,
    PAIR_GRAD_PARTS,
    ScreenFaces,
    background_logit,
    edge_lines,
    face_params_grad,
    line_columns,
    pair_logits,
    pair_terms,
    pair_terms_grad,
    pixel_centre,
    pixel_span,
    project_faces,
    to_camera,
)


def _scatter_sum(index: torch.Tensor, values: torch.Tensor, length: int) -> torch.Tensor:
    return values.new_zeros(length).index_add(0, index, values)


def _scatter_max(out: torch.Tensor, index: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    return out.scatter_reduce_(0, index, values, reduce="amax")


def _take(values: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    return torch.take_along_dim(values, index, dim=-1)


TORCH_OPS = SimpleNamespace(
    where=torch.where, minimum=torch.minimum, maximum=torch.maximum, clip=torch.clip,
    sign=torch.sign, ceil=torch.ceil, floor=torch.floor, sqrt=torch.sqrt, exp=torch.exp,
    log=torch.log, sigmoid=torch.sigmoid, stack=torch.stack, take=_take,
    scatter_sum=_scatter_sum, scatter_max=_scatter_max,
)  # fmt: skip


def _owners_ranks(counts: torch.Tensor, total: int) -> tuple[torch.Tensor, torch.Tensor]:
    """For groups of ``counts`` entries laid end to end (``total`` in all): which group each
    entry belongs to, and its rank in it (0, 1, .., n - 1)."""
    owner = torch.arange(len(counts), device=counts.device).repeat_interleave(
        counts, output_size=total
    )
    starts = torch.cumsum(counts, 0) - counts
    return owner, torch.arange(total, device=counts.device) - starts.index_select(0, owner)


def pair_chunk(device: torch.device) -> int:
    """Pairs per chunk: on a CPU few enough for a chunk's temporaries to stay in cache; on a GPU
    enough to fill it, while one chunk's autograd temporaries stay under a gigabyte."""
    return 1 << 22 if device.type == "cuda" else 1 << 17


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


@dataclass
class Pairs:
    """One chunk of pixel-face pairs: pixel (P,) flat index into (views, S, S); face (P,) int32
    flat index into the screen's faces; px, py (P,) the pixel centres in NDC."""

    pixel: torch.Tensor
    face: torch.Tensor
    px: torch.Tensor
    py: torch.Tensor


class PairPlan:
    """The pixel-face pairs of a screen's faces, enumerated chunk by chunk: in each row of a
    face's bounding box grown by the cut-off radius, the columns within ``LOOSE_RADIUS`` times
    the radius of each of its edge lines' inner sides (``render_math.edge_lines``: no pixel
    beyond is covered), row after row, face after face. For the network study's 2,560-face
    prediction the spans hold 72% of the boxes' pixels at 128 px, 84% at 64 px
    (``bench/torch_batch.py``'s pairs enumerated, before and after).

    Building it waits for the host twice (the box rows' count, then the chunks' sizes);
    enumerating a chunk never does."""

    def __init__(self, screen: ScreenFaces, config: PipelineConfig):
        self.config, self.num_views = config, screen.num_views
        params = screen.params.detach()
        self.dtype, device = params.dtype, params.device
        size = config.image_size
        xs, ys = params[0:6:2], params[1:6:2]
        i0, width = pixel_span(xs.amin(0), xs.amax(0), config, TORCH_OPS)
        j0, height = pixel_span(ys.amin(0), ys.amax(0), config, TORCH_OPS)
        height = (height * (width > 0)).long() * screen.visible
        # one entry per box row: its face, its row in the image and in the stacked views
        face, rank = _owners_ranks(height, int(height.sum()))
        row = j0.long().index_select(0, face) + rank
        self.row_face = face.int()  # int32: gathers by it run faster
        self.row_py = pixel_centre(row.to(self.dtype), size)
        self.row_start = (face // screen.num_faces * size + row) * size
        first = i0.index_select(0, face)
        last = first + width.index_select(0, face) - 1
        reach = LOOSE_RADIUS * config.coverage_radius
        for a, b, c in edge_lines(params, TORCH_OPS):
            a = a.index_select(0, face)
            bound = line_columns(a, b.index_select(0, face), c.index_select(0, face),
                                 self.row_py, reach, size)[2]  # fmt: skip
            # fmax/fmin: a bound of 0 * inf (a level line at the reach) leaves the span as it is
            first = torch.where(a > 0, torch.fmax(first, torch.floor(bound) + 1), first)
            last = torch.where(a < 0, torch.fmin(last, torch.ceil(bound) - 1), last)
        self.first_col = first.long()
        self.counts = (last - first + 1).clamp_min(0).long()
        self.chunks = self._split(torch.cumsum(self.counts, 0), pair_chunk(device), size)

    @staticmethod
    def _split(cumulative: torch.Tensor, chunk: int, size: int) -> list[tuple[int, int, int]]:
        """(first row, end row, pairs) of runs of about ``chunk`` pairs; one box row's pairs
        stay together. A row holds at most ``size`` pairs, which bounds the number of runs
        without waiting for the total."""
        if len(cumulative) == 0:
            return []
        bucket = torch.div(cumulative - 1, chunk, rounding_mode="floor")
        runs = torch.arange(-(-len(cumulative) * size // chunk), device=bucket.device)
        ends = torch.searchsorted(bucket, runs, right=True)
        sizes = torch.diff(cumulative[ends - 1], prepend=cumulative.new_zeros(1))
        ends, sizes = torch.stack([ends, sizes]).tolist()  # one wait for both
        starts = [0] + ends[:-1]
        return [(s, e, n) for s, e, n in zip(starts, ends, sizes, strict=True) if n > 0]

    def __iter__(self) -> Iterator[Pairs]:
        size = self.config.image_size
        for first, end, total in self.chunks:
            row, rank = _owners_ranks(self.counts[first:end], total)
            row = row + first
            col = self.first_col.index_select(0, row) + rank
            px = pixel_centre(col.to(self.dtype), size)
            pixel = self.row_start.index_select(0, row) + col
            yield Pairs(pixel, self.row_face.index_select(0, row), px,
                        self.row_py.index_select(0, row))  # fmt: skip

    @property
    def num_pixels(self) -> int:
        return self.num_views * self.config.image_size**2

    def num_pairs(self) -> int:
        return sum(n for _, _, n in self.chunks)


@dataclass
class KeptPairs:
    """The pairs an image is made of: covered (D' > 0) and, for shaded images, not hidden
    behind a nearer face by more than ``DEPTH_CULL`` blend logits. pixel, face: (P,) int32
    indices (pixel int64 per chunk: index_add with int32 indices is several times slower on a
    CPU, where a gather by them is faster);
    coverage, depth: (P,) ``pair_terms`` and logit: (P,) ``pair_logit`` (no autograd); depth
    None where not asked for (the shaders never read it: a batch's pairs are kept until the
    backward, 4 bytes a pair saved);
    logit_max: (views * S * S,) each pixel's largest blend logit, the background's included
    (the softmax's shift, a constant for autograd)."""

    plan: PairPlan
    pixel: torch.Tensor
    face: torch.Tensor
    coverage: torch.Tensor
    depth: torch.Tensor | None
    logit: torch.Tensor
    logit_max: torch.Tensor

    def chunks(self) -> Iterator[KeptPairs]:
        """The pairs in runs of ``pair_chunk`` pairs, their pixels int64."""
        step = pair_chunk(self.pixel.device)
        for first in range(0, len(self.pixel), step):
            part = slice(first, first + step)
            pixel, face = self.pixel[part].long(), self.face[part]
            depth = None if self.depth is None else self.depth[part]
            yield KeptPairs(self.plan, pixel, face, self.coverage[part], depth,
                            self.logit[part], self.logit_max)  # fmt: skip


# DRKFS_COMPILE's values: where the rasteriser's per-pair equations are compiled
COMPILE_SETTINGS = ("auto", "0", "1")


def _compiles(device_type: str, differentiable: bool) -> bool:
    """Whether ``DRKFS_COMPILE`` asks for compiled equations: 'auto' (default) on a GPU, and on
    a CPU where the render is differentiable (a training step, whose many steps repay the
    compile: about 20 s once on 2 cores, then 2-3 s a process from inductor's disk cache, for
    a B = 32 step 1.6-1.8x faster in the coarse stage and 1.2-1.7x in the fine one, in
    ``bench/torch_batch.py``); '1' everywhere; '0' nowhere.
    A CPU's evaluation-only renders stay eager: one score would wait for the compiler."""
    wanted = os.environ.get("DRKFS_COMPILE", "auto")
    if wanted not in COMPILE_SETTINGS:
        raise ValueError(f"DRKFS_COMPILE={wanted!r}: use one of {', '.join(COMPILE_SETTINGS)}")
    return wanted == "1" or (wanted == "auto" and (device_type == "cuda" or differentiable))


class _CompiledOrEager:
    """An equation compiled by ``torch.compile``, or eager from the first call whose compile
    fails (a CPU without a working C++ compiler, say), with one warning that says why. An error
    of the equation itself is the eager call's, raised as it is; running out of memory is the
    caller's to handle (a smaller batch), and the equation stays compiled."""

    def __init__(self, eager: Callable):
        self.eager = eager
        self.compiled = torch.compile(eager, dynamic=True, options=_compile_options())

    def __call__(self, *tensors):
        if self.compiled is None:
            return self.eager(*tensors)
        try:
            return self.compiled(*tensors)
        except torch.OutOfMemoryError:
            raise
        except Exception as error:  # compilers fail in many ways; the eager call tells them apart
            result = self.eager(*tensors)
            self.compiled = None
            reason = (str(error).strip().splitlines() or [type(error).__name__])[0]
            warnings.warn(
                f"the rasteriser's equations run eagerly, slower: torch.compile failed "
                f"({reason[:300]}); DRKFS_COMPILE=0 skips the attempt",
                RuntimeWarning,
                stacklevel=2,
            )
            return result


@functools.cache
def _fused(
    equation: Callable, config: PipelineConfig, device_type: str, differentiable: bool
) -> Callable:
    """``equation(*tensors, config, TORCH_OPS)`` as a function of its tensors, compiled where
    ``_compiles`` says: its hundred-odd elementwise steps fused into a few kernels, where
    eagerly each is a pass over memory (and on a GPU a launch) of its own."""

    def eager(*tensors):
        return equation(*tensors, config, TORCH_OPS)

    return _CompiledOrEager(eager) if _compiles(device_type, differentiable) else eager


# Inductor's GPU kernels contract a * b + c into one rounding (FMA) and divide approximately,
# where eager torch, and so the CPU, rounds each step and divides exactly. A pair's depth comes
# from edge functions that cancel, and at the paper's gamma = 1e-4 its blend logit (depth /
# gamma) carried the difference into the gradient: the paper config (6 views of 128 px) on an
# H200, the gradient's cosine to the CPU's was 0.991 with inductor's defaults and 1.000000 with
# these (the B = 32 step as fast: coarse 52.0 -> 50.9 ms, fine 66.8 -> 61.4 ms)
EAGER_NUMERICS = {
    "emulate_precision_casts": True,  # no FMA contraction
    "eager_numerics.division_rounding": True,
    "emulate_divison_rounding": True,  # the division's setting in older torch, so spelt
}


def _compile_options() -> dict:
    """``EAGER_NUMERICS``' settings that this torch's inductor has (by either name)."""
    known = torch._inductor.config.get_config_copy()
    return {name: value for name, value in EAGER_NUMERICS.items() if name in known}


def _terms_and_logits(params, face, px, py, config: PipelineConfig, ops):
    """A chunk's coverage D', normalised inverse depth (``pair_terms``) and blend logit
    (``pair_logits``), (P,) each, from the screen's params (9, N) and the pairs' faces: compiled
    as one, the faces' gather and the logit are fused with the terms (on a GPU 9 floats a pair
    and a pass per step of the logit less)."""
    coverage, depth = pair_terms(params.index_select(1, face), px, py, config, ops)
    return coverage, depth, pair_logits(coverage, depth, config, ops)


def _terms_grad_at(params, face, pixel, coverage, grad_coverage, grad_depth, config, ops):
    """``pair_terms_grad`` of a chunk of kept pairs from the screen's params, the pairs' faces
    and flat pixel indices: the gather and the pixel centres fused with it where compiled."""
    size = config.image_size
    px = pixel_centre((pixel % size).to(params.dtype), size)
    py = pixel_centre((pixel // size % size).to(params.dtype), size)
    tri = params.index_select(1, face)
    return pair_terms_grad(tri, px, py, coverage, grad_coverage, grad_depth, config, ops)


INT32_LIMIT = 2**31 - 1


def check_index_range(pixels: int, view_faces: int) -> None:
    """A pair's pixel and face are int32 indices into the batch's B * K * S^2 pixels and
    B * K * F view-faces: refuse a batch either count overflows, before any index wraps."""
    for count, name in ((pixels, "pixels (B x K x S^2)"), (view_faces, "faces (B x K x F)")):
        if count > INT32_LIMIT:
            raise ValueError(
                f"the batch's views hold {count:,} {name}, past the rasteriser's int32 indices "
                f"({INT32_LIMIT:,}): split the batch"
            )


@torch.no_grad()
def kept_pairs(
    plan: PairPlan, params: torch.Tensor, depth_cull: bool, with_depth: bool = False
) -> KeptPairs:
    """The plan's pairs that make the image, listed once: one host wait (their count); their
    depth too where ``with_depth`` asks.

    Every enumerated pair's terms are kept until each pixel's largest logit is known, then the
    kept ones gathered; 16 bytes a pair while it runs (20 with the depth)."""
    cfg = plan.config
    check_index_range(plan.num_pixels, params.shape[-1])
    total = plan.num_pairs()
    int32 = dict(dtype=torch.int32, device=params.device)
    pixel, face = torch.empty(total, **int32), torch.empty(total, **int32)
    coverage, logit = params.new_empty(total), params.new_empty(total)
    depth = params.new_empty(total) if with_depth else None
    shift = params.new_full((plan.num_pixels,), background_logit(cfg))
    terms = _fused(_terms_and_logits, cfg, params.device.type, params.requires_grad)
    start = 0
    for pairs in plan:
        part = slice(start, start + len(pairs.pixel))
        pixel[part], face[part] = pairs.pixel, pairs.face
        coverage[part], pair_depth, logit[part] = terms(params, pairs.face, pairs.px, pairs.py)
        if with_depth:
            depth[part] = pair_depth
        TORCH_OPS.scatter_max(shift, pairs.pixel, logit[part])
        start = part.stop
    keep = coverage > 0
    if depth_cull:
        for first in range(0, total, pair_chunk(params.device)):
            part = slice(first, first + pair_chunk(params.device))
            keep[part] &= logit[part] >= shift.index_select(0, pixel[part]) - DEPTH_CULL
    index = torch.nonzero(keep).squeeze(1)
    del keep
    # one array at a time, each enumerated array freed once its kept pairs are taken
    pixel, face = pixel.index_select(0, index), face.index_select(0, index)
    coverage, logit = coverage.index_select(0, index), logit.index_select(0, index)
    depth = depth.index_select(0, index) if with_depth else None
    return KeptPairs(plan, pixel, face, coverage, depth, logit, shift)


class Shader:
    """Per-pair terms summed per pixel (``pixel_sums``), and their slopes for the backward:
    ``values(pairs, colors) -> (C, P)``; ``slopes(pairs, colors, grad (C, P)) -> (d/d coverage,
    d/d depth, d/d each pair's colour or None)`` of sum(grad * values), for a chunk of pairs."""

    channels: int

    def values(self, pairs: KeptPairs, colors: torch.Tensor) -> torch.Tensor:
        raise NotImplementedError

    def slopes(self, pairs: KeptPairs, colors: torch.Tensor, grad: torch.Tensor):
        raise NotImplementedError


class _PixelSums(torch.autograd.Function):
    """Per pixel, the sum over its kept pairs of a shader's terms. Backward recomputes each
    chunk's pair terms and sends the gradient to the faces by ``pair_terms_grad``."""

    @staticmethod
    def forward(ctx, pairs: KeptPairs, shader: Shader, params, colors):
        sums = params.new_zeros(shader.channels, pairs.plan.num_pixels)
        for chunk in pairs.chunks():
            sums.index_add_(1, chunk.pixel, shader.values(chunk, colors))
        ctx.pairs, ctx.shader = pairs, shader
        ctx.save_for_backward(params, colors)
        return sums

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        params, colors = ctx.saved_tensors
        pairs, shader, config = ctx.pairs, ctx.shader, ctx.pairs.plan.config
        grad_parts = params.new_zeros(PAIR_GRAD_PARTS, params.shape[1])
        grad_colors = torch.zeros_like(colors)
        terms_grad = _fused(_terms_grad_at, config, params.device.type, True)
        for chunk in pairs.chunks():
            pair_grad = grad.index_select(1, chunk.pixel)
            grad_coverage, grad_depth, grad_color = shader.slopes(chunk, colors, pair_grad)
            face = chunk.face.long()
            parts = terms_grad(params, chunk.face, chunk.pixel, chunk.coverage, grad_coverage,
                               grad_depth)  # fmt: skip
            grad_parts.index_add_(1, face, parts)
            if grad_color is not None:
                grad_colors.index_add_(0, face, grad_color)
        return None, None, face_params_grad(params, grad_parts, TORCH_OPS), grad_colors


def pixel_sums(
    pairs: KeptPairs, shader: Shader, params: torch.Tensor, colors: torch.Tensor
) -> torch.Tensor:
    """(C, views * S * S): per pixel, the sum of the shader's terms over its kept pairs;
    differentiable with respect to the faces' ``params`` (9, N) and ``colors`` (N,)."""
    return _PixelSums.apply(pairs, shader, params, colors)
