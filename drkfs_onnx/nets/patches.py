"""Cutting PoI maps into the patches HardNet describes."""

from __future__ import annotations

import math

import torch

from ..contract.config import PipelineConfig


def select_patches(maps: torch.Tensor, index: torch.Tensor, config: PipelineConfig) -> torch.Tensor:
    """(B, 1, S, S) maps, (N,) int64 rows of the (B * P) patch list (row-major per view; P = 225
    at 256/32/16) -> (N, 1, p, p) patches.

    Each patch row is a run of whole blocks of gcd(p, stride, S) pixels (16 here), so one gather
    of blocks cuts just the chosen patches, where unfolding every patch and then choosing moved
    all 5,625 patches' pixels, twice.
    """
    size, stride, side = config.patch_size, config.patch_stride, config.patches_per_side
    width, block = config.image_size, math.gcd(size, stride, config.image_size)
    view, cell = index // (side * side), index % (side * side)
    offsets = torch.arange(size, device=index.device)
    rows = (view * width + (cell // side) * stride)[:, None] + offsets  # (N, p) in the stacked maps
    first = (rows * width + ((cell % side) * stride)[:, None]) // block  # each row's first block
    blocks = first[:, :, None] + offsets[: size // block]  # (N, p, p / block)
    chosen = maps.reshape(-1, block).index_select(0, blocks.reshape(-1))
    return chosen.reshape(-1, 1, size, size)


def nonempty_patches_on_device(images: torch.Tensor, config: PipelineConfig) -> torch.Tensor:
    """(B, 1, S, S) rendered images -> (B * P,) bool on the images' device, without a host
    wait: the torch path's twin of ``contract.patch_grid.nonempty_patches`` (any non-background
    pixel in the patch's window grown by the detector's reach), as a max-pool of the
    non-background mask."""
    reach = config.detector_kernel // 2
    seen = (images.detach() != config.background).to(torch.float32)
    window = config.patch_size + 2 * reach
    pooled = torch.nn.functional.max_pool2d(seen, window, config.patch_stride, padding=reach)
    return pooled.reshape(-1) > 0
