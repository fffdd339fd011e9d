"""Training objectives of the PoI detector and HardNet."""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F

from .data import crops

REPEAT_WINDOW = 15  # side of the windows compared across views
SHIFT = 4  # pixels: a window this far off the true match is a different place
PEAK_WINDOW = 15  # neighbourhood in which a map should have one clear peak
MARGIN = 1.0
NEAR_PIXELS = 16  # same pair and closer than this in view 0: not a negative
JITTER = 3  # pixels a positive patch is moved by, for the metric's grid misalignment


def detector_loss(
    maps: torch.Tensor,
    foreground: torch.Tensor,
    matches: torch.Tensor,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, dict[str, float]]:
    """Repeatability + peakiness of PoI maps, after R2D2 (Revaud et al. 2019) in TILDE's spirit.

    maps: (B, 2, S, S) the detector's maps of B view pairs, each view under its own light;
    foreground: (B, 2, S, S) bool; matches: (C, 5) pair id (in 0..B), row0, col0, row1, col1.

    TILDE trains its piecewise-linear regressor towards points that repeat across images of one
    scene under changing light. With ground-truth geometry we can ask for that directly:
    - repeatability: 1 - cosine similarity of the map windows around corresponding pixels of the
      two views (different viewpoint and light), so the map moves with the surface;
    - peakiness: 1 - mean over the shape of (local max - local mean), so the map does not go flat
      (a constant map repeats perfectly) but keeps distinct peaks; on flat faces the filters see
      a constant input and cannot peak, so peaks land on structure: edges, corners, junctions,
      silhouette ends.
    """
    b = len(maps)
    first = crops(maps[:, 0], matches[:, [0, 1, 2]], REPEAT_WINDOW).flatten(1)
    second = crops(maps[:, 1], matches[:, [0, 3, 4]], REPEAT_WINDOW).flatten(1)
    # the same window SHIFT pixels off along a random direction must look different
    angle = torch.rand(len(matches), generator=generator) * 2 * math.pi
    step = torch.stack([angle.sin(), angle.cos()], 1).mul(SHIFT).round().long()
    moved = matches[:, [0, 3, 4]] + torch.cat([torch.zeros_like(step[:, :1]), step], 1)
    off = crops(maps[:, 1], moved, REPEAT_WINDOW).flatten(1)
    aligned = F.cosine_similarity(first, second, dim=1, eps=1e-8)
    shifted = F.cosine_similarity(first, off, dim=1, eps=1e-8)
    repeat = (1 - aligned + shifted).mean()
    flat = maps.view(2 * b, 1, *maps.shape[2:])
    pad = PEAK_WINDOW // 2
    contrast = F.max_pool2d(flat, PEAK_WINDOW, 1, pad) - F.avg_pool2d(
        flat, PEAK_WINDOW, 1, pad, count_include_pad=False
    )
    mask = foreground.view_as(contrast).to(maps.dtype)
    peaky = 1 - (contrast * mask).sum() / mask.sum().clamp_min(1)
    return repeat + peaky, {
        "repeatability": float(repeat.detach()),
        "peakiness": float(peaky.detach()),
    }


def descriptor_distances(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """(N, D), (M, D) unit descriptors -> (N, M) Euclidean distances."""
    return torch.sqrt((2 - 2 * a @ b.t()).clamp_min(1e-8))


def hardest_triplet_loss(
    anchors: torch.Tensor, positives: torch.Tensor, same_place: torch.Tensor
) -> torch.Tensor:
    """HardNet's hardest-in-batch triplet margin loss (Mishchuk et al. 2017).

    anchors, positives: (B, D) unit descriptors, row i of both from one surface point;
    same_place: (B, B) bool, True where i and j are too close to count as a negative (the
    diagonal included).
    For each i the hardest negative is the nearest non-matching descriptor among anchors' and
    positives' rows and columns: loss = mean(max(0, margin + d(a_i, p_i) - d_neg)).
    """
    dist = descriptor_distances(anchors, positives)
    positive = dist.diagonal()
    masked = dist.masked_fill(same_place, float("inf"))
    hardest = torch.minimum(masked.min(dim=1).values, masked.min(dim=0).values)
    return (MARGIN + positive - hardest).clamp_min(0).mean()


def same_place(matches: torch.Tensor) -> torch.Tensor:
    """(B, 5) matches -> (B, B) bool: same pair and within NEAR_PIXELS in view 0."""
    same_pair = matches[:, 0, None] == matches[None, :, 0]
    gap = (matches[:, None, 1:3] - matches[None, :, 1:3]).abs().amax(-1)
    return same_pair & (gap < NEAR_PIXELS)


def correspondence_triplet(
    net: torch.nn.Module,
    maps: torch.Tensor,
    matches: torch.Tensor,
    rng: np.random.Generator,
    batch: int,
    patch_size: int,
) -> torch.Tensor:
    """HardNet's objective on view pairs: ``batch`` random correspondences, the second patch
    moved by up to JITTER pixels, through ``hardest_triplet_loss``.

    maps: (N, 2, S, S) PoI maps of the pairs; matches: (C, 5) correspondences (``sample_matches``).
    """
    rows = matches[torch.as_tensor(rng.choice(len(matches), batch, False))]
    moved = rows[:, [0, 3, 4]].clone()
    moved[:, 1:] += torch.as_tensor(rng.integers(-JITTER, JITTER + 1, (len(rows), 2)))
    first = crops(maps[:, 0], rows[:, [0, 1, 2]], patch_size)
    second = crops(maps[:, 1], moved, patch_size)
    anchors, positives = net(torch.cat([first, second]).unsqueeze(1)).chunk(2)
    return hardest_triplet_loss(anchors, positives, same_place(rows))
