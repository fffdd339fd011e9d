"""The solid change of two meshes' views, written once for torch and numpy (``ops``:
``array_ops``): the score's second term, which sees a small part removed or a hole cut where
the descriptors hardly do.

A viewer notices a region that changes as a whole (a hole, a missing tip) more than many
scattered changes (noise, faceting) or a shift of a pixel or two (a slight turn, a moved
outline). Per pixel, the change is how far its grey lies outside the range of the other view's
greys within ``solid_shift`` pixels, either way (the larger): a shift within that reach changes
nothing. Per view, the solid change is the largest change held over every pixel of a
``solid_block``-square (the change map's erosion): scattered changes and thin strips fall out.
The term is its mean over the views, times ``solid_weight`` (docs/benchmark.md, "A solid
change of the views").

Windows are taken where they fit inside the view ("valid"): the outer ``solid_shift`` +
(``solid_block`` - 1) / 2 pixels of each side, where the cameras frame no mesh, are left out.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .array_ops import ArrayOps
from .config import PipelineConfig


def window_extreme(images: Any, reach: int, pick: Callable) -> Any:
    """(..., S, S) -> (..., S - 2 reach, S - 2 reach): ``pick`` (``ops.minimum`` or
    ``ops.maximum``) over each pixel's (2 reach + 1)-square, where it fits inside the image."""
    if reach == 0:
        return images
    inner = images.shape[-1] - 2 * reach
    rows = images[..., 0:inner, :]
    for offset in range(1, 2 * reach + 1):
        rows = pick(rows, images[..., offset : offset + inner, :])
    found = rows[..., 0:inner]
    for offset in range(1, 2 * reach + 1):
        found = pick(found, rows[..., offset : offset + inner])
    return found


def view_range(views: Any, config: PipelineConfig, ops: ArrayOps) -> tuple[Any, Any]:
    """(..., K, S, S) views -> their (lowest, highest) grey within ``solid_shift`` pixels, each
    (..., K, S - 2 shift, S - 2 shift): what the other mesh's pixels are compared with, made
    once per mesh."""
    shift = config.solid_shift
    return window_extreme(views, shift, ops.minimum), window_extreme(views, shift, ops.maximum)


def _beyond(grey: Any, lowest: Any, highest: Any, ops: ArrayOps) -> Any:
    """How far each pixel's grey lies outside [lowest, highest]; 0 inside, with no gradient, so
    that views that do not change give the term none."""
    outside = ops.maximum(grey - highest, lowest - grey)
    return ops.where(outside > 0, outside, 0.0 * outside)


def solid_change(
    views_a: Any,
    views_b: Any,
    config: PipelineConfig,
    ops: ArrayOps,
    range_a: tuple[Any, Any] | None = None,
    range_b: tuple[Any, Any] | None = None,
) -> Any:
    """(..., K, S, S) two meshes' views of the same cameras -> (...) the mean over the views of
    the largest grey change held over a ``solid_block``-square (the module's doc). Each mesh's
    ``view_range`` may be passed in, made once; it is made here otherwise."""
    shift, size = config.solid_shift, views_a.shape[-1]
    range_a = view_range(views_a, config, ops) if range_a is None else range_a
    range_b = view_range(views_b, config, ops) if range_b is None else range_b
    inner = slice(shift, size - shift)
    change = ops.maximum(
        _beyond(views_b[..., inner, inner], *range_a, ops),
        _beyond(views_a[..., inner, inner], *range_b, ops),
    )
    held = window_extreme(change, (config.solid_block - 1) // 2, ops.minimum)
    return ops.amax(ops.amax(held, -1), -1).mean(-1)
