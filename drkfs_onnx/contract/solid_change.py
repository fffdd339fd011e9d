"""The solid change of two meshes' views, written once for torch and numpy (``ops``:
``array_ops``): the score's second term, which sees a small part removed or a hole cut where
the descriptors hardly do.

A viewer notices a region that changes as a whole (a hole, a missing tip) more than many
scattered changes (noise, faceting) or a shift of a pixel or two (a slight turn, a moved
outline). Per pixel, the change at a reach is how far its grey lies outside the range of the
other view's greys within that many pixels, either way (the larger): a shift within the reach
changes nothing. A pixel's change is the mean of its changes at the reaches ``solid_reaches``
gives: ``solid_shift`` and the ``solid_ramp`` below it, so that a growing shift raises it step
by step instead of at one reach; where both views show the mesh, each reach is
``solid_inner_drop`` less and the mean is raised to ``solid_inner_power`` (a hole shows the
mesh's inside in both views, where a moved part's outline shows the background in one; a
strong change of grey there counts more than a faint one, a facet's). Per view, the solid
change is the largest change held over every pixel of a ``solid_block``-square (the change
map's erosion): scattered changes and thin strips fall out. The term is its mean over the
views, times ``solid_weight`` (bench/records/real_levers.md, "A solid change of the views"); in the
own-ring pairing of two rings of cameras, each camera's larger change of its two rings where
``solid_both_rings`` (``match_rules.pairing_solid``).

Windows are taken where they fit inside the view ("valid"): the outer ``solid_shift`` +
(``solid_block`` - 1) / 2 pixels of each side, where the cameras frame no mesh, are left out.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .array_ops import ArrayOps
from .config import PipelineConfig

Ranges = dict[int, tuple[Any, Any]]  # reach -> a view's (lowest, highest) grey within it


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


def solid_reaches(config: PipelineConfig) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The reaches a pixel's change is the mean over: (where both views show the mesh,
    elsewhere)."""
    outline = tuple(range(config.solid_shift - config.solid_ramp, config.solid_shift + 1))
    return tuple(r - config.solid_inner_drop for r in outline), outline


def view_range(views: Any, reach: int, ops: ArrayOps) -> tuple[Any, Any]:
    """(..., K, H, W) views -> their (lowest, highest) grey within ``reach`` pixels, each (...,
    K, H - 2 reach, W - 2 reach): what the other mesh's pixels are compared with."""
    return window_extreme(views, reach, ops.minimum), window_extreme(views, reach, ops.maximum)


def view_ranges(views: Any, config: PipelineConfig, ops: ArrayOps) -> Ranges:
    """(..., K, H, W) views -> their ``view_range`` at each reach of ``solid_reaches``, made
    once per mesh."""
    inside, outline = solid_reaches(config)
    return {reach: view_range(views, reach, ops) for reach in sorted({*inside, *outline})}


def view_solid_changes(
    views_a: Any,
    views_b: Any,
    config: PipelineConfig,
    ops: ArrayOps,
    ranges_a: Ranges | None = None,
    ranges_b: Ranges | None = None,
) -> Any:
    """(..., K, H, W) two meshes' views of the same cameras (or the same window of them) ->
    (..., K) each view's largest change held over a ``solid_block``-square (the module's doc).
    Each mesh's ``view_ranges`` may be passed in, made once; they are made here otherwise."""
    ranges_a = view_ranges(views_a, config, ops) if ranges_a is None else ranges_a
    ranges_b = view_ranges(views_b, config, ops) if ranges_b is None else ranges_b
    inside, outline = solid_reaches(config)
    change = reach_change(
        views_a, views_b, ranges_a, ranges_b, inside, outline, config.solid_inner_power,
        config.background, ops,
    )  # fmt: skip
    return held_change(change, config.solid_block, ops)


def held_change(change: Any, block: int, ops: ArrayOps) -> Any:
    """(..., K, H, W) a change map -> (..., K) each view's largest change held over every pixel
    of a ``block``-square."""
    held = window_extreme(change, (block - 1) // 2, ops.minimum)
    return ops.amax(ops.amax(held, -1), -1)


def reach_change(
    views_a: Any, views_b: Any, ranges_a: Ranges, ranges_b: Ranges, inside: tuple[int, ...],
    outline: tuple[int, ...], inner_power: float, background: float, ops: ArrayOps,
) -> Any:  # fmt: skip
    """(..., H, W) two meshes' views and each one's ranges at every reach asked -> (...,
    H - 2 m, W - 2 m), m the largest reach: each pixel's mean change over the reaches
    ``inside``, raised to ``inner_power``, where both views show the mesh, and over the reaches
    ``outline`` elsewhere."""
    outer = max(*inside, *outline)
    height, width = views_a.shape[-2], views_a.shape[-1]
    maps = {}
    for reach in {*inside, *outline}:
        change = pixel_change(views_a, views_b, ranges_a[reach], ranges_b[reach], reach, ops)
        crop = outer - reach  # to the largest reach's window
        maps[reach] = change[..., crop : change.shape[-2] - crop, crop : change.shape[-1] - crop]
    edge = _mean([maps[r] for r in outline])
    if inside == outline and inner_power == 1.0:
        return edge
    window = (..., slice(outer, height - outer), slice(outer, width - outer))
    shown = (views_a[window] != background) & (views_b[window] != background)
    inner = ops.power(_mean([maps[r] for r in inside]), inner_power)
    return ops.where(shown, inner, edge)


def _mean(maps: list[Any]) -> Any:
    total = maps[0]
    for more in maps[1:]:
        total = total + more
    return total if len(maps) == 1 else total / len(maps)


def pixel_change(
    views_a: Any, views_b: Any, range_a: tuple[Any, Any], range_b: tuple[Any, Any], shift: int,
    ops: ArrayOps,
) -> Any:  # fmt: skip
    """(..., H, W) two meshes' views and each one's range at reach ``shift`` -> (...,
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
