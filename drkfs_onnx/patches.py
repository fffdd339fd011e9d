"""Cutting PoI maps into the patches HardNet describes."""

from __future__ import annotations

import torch
import torch.nn.functional as F

from .config import PipelineConfig


def extract_patches(maps: torch.Tensor, config: PipelineConfig) -> torch.Tensor:
    """(B, 1, S, S) maps -> (B * P, 1, p, p) patches, row-major per view (P = 225 at 256/32/16)."""
    size, stride = config.patch_size, config.patch_stride
    columns = F.unfold(maps, kernel_size=size, stride=stride)  # (B, p*p, P)
    return columns.transpose(1, 2).reshape(-1, 1, size, size)


def nonempty_patches(images: torch.Tensor, config: PipelineConfig) -> torch.Tensor:
    """(B, 1, S, S) rendered images -> (B * P,) bool: does the patch's PoI map see anything?

    A patch whose window, grown by the detector's reach, holds only background pixels has the
    constant PoI map of an empty scene, hence one shared descriptor: computing it once is exact.
    """
    reach = config.detector_kernel // 2
    seen = (images != config.background).to(images.dtype)
    hit = F.max_pool2d(
        seen, kernel_size=config.patch_size + 2 * reach, stride=config.patch_stride, padding=reach
    )
    return hit.reshape(-1) > 0
