"""Which pixel-face pairs a screen's faces may cover: ``PairPlan`` enumerates them, chunk by
chunk, from each face's box of pixels and its edge lines."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import torch

from ..contract.config import PipelineConfig
from ..contract.render_equations import (
    LOOSE_RADIUS,
    ScreenFaces,
    edge_lines,
    line_columns,
    pixel_centre,
    pixel_span,
)
from .torch_ops import TORCH_OPS


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


@dataclass
class PairChunk:
    """One chunk of pixel-face pairs: pixel (P,) flat index into (views, S, S); face (P,) int32
    flat index into the screen's faces; px, py (P,) the pixel centres in NDC."""

    pixel: torch.Tensor
    face: torch.Tensor
    px: torch.Tensor
    py: torch.Tensor


class PairPlan:
    """The pixel-face pairs of a screen's faces, enumerated chunk by chunk: in each row of a
    face's bounding box grown by the cut-off radius, the columns within ``LOOSE_RADIUS`` times
    the radius of each of its edge lines' inner sides (``render_equations.edge_lines``: no pixel
    beyond is covered), row after row, face after face: fewer pairs than the boxes hold
    (docs/design_notes.md).

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

    def __iter__(self) -> Iterator[PairChunk]:
        size = self.config.image_size
        for first, end, total in self.chunks:
            row, rank = _owners_ranks(self.counts[first:end], total)
            row = row + first
            col = self.first_col.index_select(0, row) + rank
            px = pixel_centre(col.to(self.dtype), size)
            pixel = self.row_start.index_select(0, row) + col
            yield PairChunk(pixel, self.row_face.index_select(0, row), px,
                        self.row_py.index_select(0, row))  # fmt: skip

    @property
    def num_pixels(self) -> int:
        return self.num_views * self.config.image_size**2

    def num_pairs(self) -> int:
        return sum(n for _, _, n in self.chunks)
