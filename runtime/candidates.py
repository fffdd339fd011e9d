"""Pixel-face pairs the numpy renderer must compute exactly: those that may be covered and unhidden.

A pixel further than the cut-off radius outside one of a face's edge lines is uncovered, so each
row of the face's bounding box (grown by the radius) lists one span of columns: those the three
lines allow (``face_tests``: float32 signed distance to each edge's line, the face plane's
inverse depth, both affine in the pixel). A pixel inside a face is covered at least as much as on
its edge, so there the face's plane depth bounds the pixel's winning logit from below; any pair
whose plane depth lies more than DEPTH_CULL + CULL_MARGIN logits under such a bound is hidden.

Most hidden pairs belong to faces turned away from the camera, so the faces turned towards it are
listed first; their bounds, reduced to a min-pyramid over square tiles, drop whole faces of the
rest whose nearest vertex lies under the bound of every tile their box touches, before their
pairs are listed. Any subset of bounds is a valid bound, so the pairs returned are the same as
listing every face: only the work differs.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from drkfs_onnx.contract.array_ops import NUMPY_OPS
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.render_equations import (
    DEPTH_CULL,
    LOOSE_RADIUS,
    TINY_LENGTH,
    background_logit,
    edge_lines,
    line_columns,
    pixel_span,
)

# float32 logits near 1 / gamma = 1e4 are good to ~1e-3; a wide margin costs a few pairs
CULL_MARGIN = 2.0
# A pair whose float32 logit lies this far under its pixel's bound is hidden.
HIDDEN_BELOW = DEPTH_CULL + CULL_MARGIN
PAIR_CHUNK = 1 << 18
# Inverse-depth slope (per NDC unit) above which float32 plane evaluation is not trusted.
MAX_SLOPE = 100.0


def select(mask: np.ndarray, *arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """The entries of each array where ``mask`` holds. One index list gathered per array is
    several times faster than boolean indexing each array."""
    index = np.flatnonzero(mask)
    return tuple(array[index] for array in arrays)


@dataclass(frozen=True)
class FaceTests:
    """Per face (of all K*F view-faces), float32: ``lines`` (3 edges x (a, b, c)) give the
    signed distance a*px + b*py + c to each edge's line, positive inside; ``plane`` (a, b, c) the
    face plane's inverse depth, clamped to ``[lowest, highest]`` (its vertices' range), exact
    where ``trusted``. ``facing`` is the sign of the face's screen winding."""

    lines: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]
    plane: tuple[np.ndarray, np.ndarray, np.ndarray]
    lowest: np.ndarray
    highest: np.ndarray
    trusted: np.ndarray
    facing: np.ndarray


def face_tests(params: np.ndarray) -> FaceTests:
    """(9, K*F) screen params (x0, y0, x1, y1, x2, y2, w0, w1, w2) -> ``FaceTests``.

    Edge-on faces (steep planes, where float32 cancellation would mislead) get their highest
    vertex depth and are not trusted, so they never cull."""
    x0, y0, x1, y1, x2, y2, w0, w1, w2 = params
    area2 = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
    lines = [tuple(v.astype(np.float32) for v in line) for line in edge_lines(params, NUMPY_OPS)]
    safe = np.where(np.abs(area2) > TINY_LENGTH**2, area2, 1.0)
    # w(p) = w0 + (w1 - w0) * beta + (w2 - w0) * gamma, barycentrics affine in p
    slope_x = ((w1 - w0) * (y2 - y0) - (w2 - w0) * (y1 - y0)) / safe
    slope_y = ((w2 - w0) * (x1 - x0) - (w1 - w0) * (x2 - x0)) / safe
    trusted = (np.abs(area2) > TINY_LENGTH**2) & (np.abs(slope_x) + np.abs(slope_y) < MAX_SLOPE)
    lowest, highest = params[6:].min(0), params[6:].max(0)
    slope_x, slope_y = np.where(trusted, slope_x, 0.0), np.where(trusted, slope_y, 0.0)
    offset = np.where(trusted, w0 - slope_x * x0 - slope_y * y0, highest)
    plane = tuple(v.astype(np.float32) for v in (slope_x, slope_y, offset))
    return FaceTests(
        tuple(lines),
        plane,
        lowest.astype(np.float32),
        highest.astype(np.float32),
        trusted,
        np.sign(area2),
    )


@dataclass(frozen=True)
class PixelBoxes:
    """Each view-face's box of pixels, grown by the cut-off radius: first column ``i0``, first
    row ``j0``, ``width`` and ``height`` (int32; an invisible face's box is empty)."""

    i0: np.ndarray
    j0: np.ndarray
    width: np.ndarray
    height: np.ndarray

    @cached_property
    def counts(self) -> np.ndarray:
        return self.width * self.height


def pixel_boxes(params: np.ndarray, visible: np.ndarray, config: PipelineConfig) -> PixelBoxes:
    i0, width, j0, height = (
        value.astype(np.int32)
        for coords in (params[0:6:2], params[1:6:2])
        for value in pixel_span(coords.min(0), coords.max(0), config, NUMPY_OPS)
    )
    return PixelBoxes(i0, j0, width * visible.astype(np.int32), height)


def faces_over(
    pixels: np.ndarray, params: np.ndarray, visible: np.ndarray, views: int, config: PipelineConfig
) -> np.ndarray:
    """(K*F,) bool: the visible faces whose box (``pixel_boxes``) holds one of ``pixels`` (flat
    indices), from a summed-area table of the pixels per view."""
    size = config.image_size
    marked = np.zeros(views * size * size, np.int32)
    marked[pixels] = 1
    table = np.zeros((views, size + 1, size + 1), np.int64)
    table[:, 1:, 1:] = marked.reshape(views, size, size).cumsum(1).cumsum(2)
    boxes = pixel_boxes(params, visible, config)
    view = np.arange(len(boxes.i0)) // (len(boxes.i0) // views)
    i0, j0 = boxes.i0, boxes.j0
    i1, j1 = i0 + boxes.width, j0 + boxes.height
    held = table[view, j1, i1] - table[view, j0, i1] - table[view, j1, i0] + table[view, j0, i0]
    return (boxes.counts > 0) & (held > 0)


@dataclass
class CandidatePairs:
    """Listed pairs: flat pixel (view * S * S + row * S + column) and view-face index, the
    float32 logit upper bound (plane depth / gamma), and whether the pair bounds its pixel's
    winning logit from below (``sure``: inside a trusted face)."""

    pixel: np.ndarray
    face: np.ndarray
    logit: np.ndarray
    sure: np.ndarray

    def unhidden(self, bound: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel and face of the pairs within HIDDEN_BELOW of their pixel's ``bound``."""
        return select(self.logit >= bound[self.pixel] - HIDDEN_BELOW, self.pixel, self.face)

    @staticmethod
    def concat(parts: list[CandidatePairs]) -> CandidatePairs:
        if not parts:
            empty = np.zeros(0, np.int64)
            return CandidatePairs(empty, empty, np.zeros(0, np.float32), np.zeros(0, bool))
        names = [field.name for field in fields(CandidatePairs)]
        return CandidatePairs(
            *(np.concatenate([getattr(p, name) for p in parts]) for name in names)
        )


def candidate_pairs(
    params: np.ndarray, visible: np.ndarray, views: int, config: PipelineConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Flat pixel and view-face indices of the pairs that may be covered and unhidden.

    params: (9, K*F) screen params, faces of view k at k*F .. (k+1)*F; visible: (K*F,) bool.
    """
    size = config.image_size
    tests, boxes = face_tests(params), pixel_boxes(params, visible, config)
    towards = _facing_camera(tests, visible, views)
    listed = np.nonzero(boxes.counts > 0)[0]
    first = _list_pairs(listed[towards[listed]], tests, boxes, views, config)
    # Coverage on a face's edge: (sigmoid(0) - eps) / (1 - eps); inside it is higher.
    edge_log_coverage = np.float32(
        np.log((0.5 - config.coverage_eps) / (1.0 - config.coverage_eps))
    )
    bound = np.full(views * size * size, background_logit(config), dtype=np.float32)

    def raise_bound(pairs: CandidatePairs) -> None:
        pixel, logit = select(pairs.sure, pairs.pixel, pairs.logit)
        np.maximum.at(bound, pixel, logit + edge_log_coverage)

    raise_bound(first)
    rest = listed[~towards[listed]]
    nearest = tests.highest[rest] * np.float32(1.0 / config.gamma)
    tile_bound = _box_minimum(bound.reshape(views, size, size), boxes, rest, views)
    second = _list_pairs(rest[nearest >= tile_bound - HIDDEN_BELOW], tests, boxes, views, config)
    raise_bound(second)
    (pixel_1, face_1), (pixel_2, face_2) = first.unhidden(bound), second.unhidden(bound)
    return np.concatenate([pixel_1, pixel_2]), np.concatenate([face_1, face_2])


def _facing_camera(tests: FaceTests, visible: np.ndarray, views: int) -> np.ndarray:
    """(K*F,) bool: faces whose screen winding is the one of the nearer faces in their view (the
    faces turned towards the camera on a consistently oriented surface)."""
    facing = tests.facing.reshape(views, -1)
    depth = np.where(visible, tests.highest, 0.0).reshape(views, -1)
    seen = visible.reshape(views, -1)
    positive = facing > 0
    mean_positive = (depth * positive).sum(1) / np.maximum((seen & positive).sum(1), 1)
    mean_negative = (depth * ~positive).sum(1) / np.maximum((seen & ~positive).sum(1), 1)
    sign = np.where(mean_positive >= mean_negative, 1.0, -1.0)
    return (facing == sign[:, None]).reshape(-1)


def _box_minimum(bound: np.ndarray, boxes: PixelBoxes, ids: np.ndarray, views: int) -> np.ndarray:
    """Minimum of ``bound`` (K, S, S) over tiles covering each box of ``ids``: at the level whose
    tiles are at least as wide as the box, the box touches at most 2 x 2 of them."""
    extent = np.maximum(boxes.width[ids], boxes.height[ids])
    level = np.ceil(np.log2(np.maximum(extent, 1))).astype(np.int64)
    view = ids // (len(boxes.i0) // views)
    i0, j0 = boxes.i0[ids], boxes.j0[ids]
    i1, j1 = i0 + boxes.width[ids] - 1, j0 + boxes.height[ids] - 1
    out = np.empty(len(ids), np.float32)
    tiles = bound
    for shift in range(int(level.max(initial=0)) + 1):
        if shift:
            tiles = _halve(tiles)
        at = level == shift
        if at.any():
            v = view[at]
            corners = [
                tiles[v, j >> shift, i >> shift] for j in (j0[at], j1[at]) for i in (i0[at], i1[at])
            ]
            out[at] = np.minimum.reduce(corners)
    return out


def _halve(tiles: np.ndarray) -> np.ndarray:
    """(K, H, W) -> (K, ceil(H/2), ceil(W/2)) minimum over 2 x 2 tiles (+inf beyond the edge,
    where no box reaches)."""
    k, h, w = tiles.shape
    padded = np.full((k, h + h % 2, w + w % 2), np.inf, np.float32)
    padded[:, :h, :w] = tiles
    rows = np.minimum(padded[:, 0::2], padded[:, 1::2])
    return np.minimum(rows[:, :, 0::2], rows[:, :, 1::2])


def _list_pairs(
    ids: np.ndarray, tests: FaceTests, boxes: PixelBoxes, views: int, config: PipelineConfig
) -> CandidatePairs:
    """Pairs of faces ``ids`` whose pixel lies within the radius of every edge line, in chunks:
    each box row's columns come as one span, so no pixel outside the span is ever tested."""
    size = config.image_size
    step, offset = 2.0 / size, 1.0 / size - 1.0
    faces_per_view = len(boxes.i0) // views
    inv_gamma = np.float32(1.0 / config.gamma)
    parts = []
    bucket = (np.cumsum(boxes.counts[ids]) - 1) // PAIR_CHUNK
    for chunk in np.split(ids, np.nonzero(np.diff(bucket))[0] + 1) if len(ids) else []:
        heights = boxes.height[chunk]
        row_owner = _owners(heights)
        face = chunk[row_owner]  # one entry per box row
        row = _ranks(heights, boxes.j0[chunk], row_owner)
        py = (row * step + offset).astype(np.float32)
        first, last, inner_first, inner_last = _row_spans(face, py, tests, boxes, config)
        count = np.maximum(last - first + 1, 0)
        owner = _owners(count)  # each pair's box row
        pair_face = face[owner]
        col = _ranks(count, first, owner)
        px = col.astype(np.float32) * np.float32(step) + np.float32(offset)
        a, b, c = tests.plane
        depth = a[pair_face] * px + (b[face] * py + c[face])[owner]
        depth = np.minimum(np.maximum(depth, tests.lowest[pair_face]), tests.highest[pair_face])
        sure = (col >= inner_first[owner]) & (col <= inner_last[owner]) & tests.trusted[pair_face]
        row_start = ((face // faces_per_view) * size + row) * size
        parts.append(CandidatePairs(row_start[owner] + col, pair_face, depth * inv_gamma, sure))
    return CandidatePairs.concat(parts)


def _owners(counts: np.ndarray) -> np.ndarray:
    """Which group each entry belongs to, for groups of ``counts`` entries laid end to end.
    Per-group values reach the entries by gathering with it: numpy's repeat holds the GIL, a
    gather does not, so threads rendering other views keep running."""
    return np.repeat(np.arange(len(counts)), counts)


def _ranks(counts: np.ndarray, firsts: np.ndarray, owners: np.ndarray) -> np.ndarray:
    """first, first + 1, .., first + n - 1 for each n of ``counts`` and first of ``firsts``,
    concatenated (``owners``: ``_owners(counts)``)."""
    starts = np.cumsum(counts) - counts
    return np.arange(len(owners)) + (firsts - starts)[owners]


def _row_spans(
    face: np.ndarray, py: np.ndarray, tests: FaceTests, boxes: PixelBoxes, config: PipelineConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per box row (of ``face`` at height ``py``): the first and last column of the box within
    LOOSE_RADIUS * radius of every edge line, and of those strictly inside all three (int64;
    first > last when none)."""
    size = config.image_size
    reach = np.float32(LOOSE_RADIUS * config.coverage_radius)
    # columns strictly between the largest root of a rising line and the smallest of a falling one
    first = inner_first = np.full(len(face), -np.inf, np.float32)
    last = inner_last = np.full(len(face), np.inf, np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        for a, b, c in tests.lines:
            # the line's distance at column i is a * step * (i - root); per_column = -1 / (a * step)
            slope = a[face]
            level, root, outer_root = line_columns(slope, b[face], c[face], py, reach, size)
            rising, falling = slope > 0, slope < 0
            first = np.maximum(first, np.where(rising, outer_root, -np.inf))
            last = np.minimum(last, np.where(falling, outer_root, np.inf))
            inner_first = np.maximum(inner_first, np.where(rising, root, -np.inf))
            inner_last = np.minimum(inner_last, np.where(falling, root, np.inf))
            # A flat (horizontal) line keeps all of the row or none of it. Every box row lies
            # within the radius of it (the box is the face's grown by the radius), so only the
            # inner span can lose a row.
            inner_first = np.where((slope == 0) & (level <= 0), np.inf, inner_first)
    box_first = boxes.i0[face].astype(np.float32)
    box_last = box_first + (boxes.width[face] - 1)
    first, inner_first = (
        np.clip(np.floor(v) + 1, box_first, box_last + 1) for v in (first, inner_first)
    )
    last, inner_last = (
        np.clip(np.ceil(v) - 1, box_first - 1, box_last) for v in (last, inner_last)
    )
    return tuple(v.astype(np.int64) for v in (first, last, inner_first, inner_last))
