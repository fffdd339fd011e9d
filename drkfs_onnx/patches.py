"""Cutting PoI maps into the patches HardNet describes."""

from __future__ import annotations

import torch
import torch.nn.functional as F

from . import patch_grid
from .config import PipelineConfig


def extract_patches(maps: torch.Tensor, config: PipelineConfig) -> torch.Tensor:
    """(B, 1, S, S) maps -> (B * P, 1, p, p) patches, row-major per view (P = 225 at 256/32/16)."""
    size, stride = config.patch_size, config.patch_stride
    columns = F.unfold(maps, kernel_size=size, stride=stride)  # (B, p*p, P)
    return columns.transpose(1, 2).reshape(-1, 1, size, size)


def nonempty_patches(images: torch.Tensor, config: PipelineConfig) -> torch.Tensor:
    """(B, 1, S, S) rendered images -> (B * P,) bool on the images' device; see
    ``patch_grid.nonempty_patches``."""
    mask = patch_grid.nonempty_patches(images.detach()[:, 0].cpu().numpy(), config)
    return torch.from_numpy(mask).to(images.device)
