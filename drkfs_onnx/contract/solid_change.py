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
    """(..., H, W) -> (..., H - 2 reach, W - 2 reach): ``pick`` (``ops.minimum`` or
    ``ops.maximum``) over each pixel's (2 reach + 1)-square, where it fits inside the image."""
    if reach == 0:
        return images
    height, width = images.shape[-2] - 2 * reach, images.shape[-1] - 2 * reach
    rows = images[..., 0:height, :]
    for offset in range(1, 2 * reach + 1):
        rows = pick(rows, images[..., offset : offset + height, :])
    found = rows[..., 0:width]
    for offset in range(1, 2 * reach + 1):
        found = pick(found, rows[..., offset : offset + width])
    return found


def view_range(views: Any, config: PipelineConfig, ops: ArrayOps) -> tuple[Any, Any]:
    """(..., K, H, W) views -> their (lowest, highest) grey within ``solid_shift`` pixels, each
    (..., K, H - 2 shift, W - 2 shift): what the other mesh's pixels are compared with, made
    once per mesh."""
    shift = config.solid_shift
    return window_extreme(views, shift, ops.minimum), window_extreme(views, shift, ops.maximum)


def solid_change(
    views_a: Any,
    views_b: Any,
    config: PipelineConfig,
    ops: ArrayOps,
    range_a: tuple[Any, Any] | None = None,
    range_b: tuple[Any, Any] | None = None,
) -> Any:
    """(..., K, H, W) two meshes' views of the same cameras (or the same window of them) ->
    (...) the mean over the views of the largest grey change held over a ``solid_block``-square
    (the module's doc). Each mesh's ``view_range`` may be passed in, made once; it is made here
    otherwise."""
    range_a = view_range(views_a, config, ops) if range_a is None else range_a
    range_b = view_range(views_b, config, ops) if range_b is None else range_b
    change = pixel_change(views_a, views_b, range_a, range_b, config.solid_shift, ops)
    held = window_extreme(change, (config.solid_block - 1) // 2, ops.minimum)
    return ops.amax(ops.amax(held, -1), -1).mean(-1)


def pixel_change(
    views_a: Any, views_b: Any, range_a: tuple[Any, Any], range_b: tuple[Any, Any], shift: int,
    ops: ArrayOps,
) -> Any:  # fmt: skip
    """(..., H, W) two meshes' views and each one's ``view_range`` at reach ``shift`` -> (...,
    H - 2 shift, W - 2 shift): how far each pixel's grey lies outside the other view's range,
    the larger way; 0 inside it."""
    height, width = views_a.shape[-2], views_a.shape[-1]
    inner_b = views_b[..., shift : height - shift, shift : width - shift]
    inner_a = views_a[..., shift : height - shift, shift : width - shift]
    outside = ops.maximum(
        ops.maximum(inner_b - range_a[1], range_a[0] - inner_b),
        ops.maximum(inner_a - range_b[1], range_b[0] - inner_a),
    )
    # 0 inside the range, with no gradient there, so that unchanged views give the term none
    return outside * (outside > 0)
