"""The pairs an image is made of: each planned pair's coverage, depth and blend logit, without
autograd, and the pairs kept (covered, not hidden far behind a nearer face), listed once."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import torch

from ..contract.config import PipelineConfig
from ..contract.render_equations import DEPTH_CULL, background_logit, pair_logits, pair_terms
from .compile_policy import fused
from .pair_plan import PairPlan, pair_chunk
from .torch_ops import TORCH_OPS


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


def _terms_and_logits(params, face, px, py, config: PipelineConfig, ops):
    """A chunk's coverage D', normalised inverse depth (``pair_terms``) and blend logit
    (``pair_logits``), (P,) each, from the screen's params (9, N) and the pairs' faces: compiled
    as one, the faces' gather and the logit are fused with the terms (on a GPU 9 floats a pair
    and a pass per step of the logit less)."""
    coverage, depth = pair_terms(params.index_select(1, face), px, py, config, ops)
    return coverage, depth, pair_logits(coverage, depth, config, ops)


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
    terms = fused(_terms_and_logits, cfg, params.device.type, params.requires_grad)
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
