"""Held-out measurements of the correspondence stage: detector repeatability (against Harris and
DoG), descriptor FPR95 and model cost."""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from drkfs_onnx.contract.config import PipelineConfig

from .data import ViewPairs, correspond, crops
from .net_losses import descriptor_distances

KEYPOINTS = 100  # per view, after 5 x 5 non-maximum suppression
NMS_WINDOW = 5
REPEAT_PIXELS = 3.0  # a keypoint repeats if one is detected this close to its projection


def gaussian_blur(images: torch.Tensor, sigma: float) -> torch.Tensor:
    """(B, 1, S, S) -> the same blurred by a separable Gaussian of ``sigma`` pixels (edges
    replicated)."""
    radius = max(1, math.ceil(3 * sigma))
    x = torch.arange(-radius, radius + 1, dtype=images.dtype)
    k = torch.exp(-(x**2) / (2 * sigma**2))
    k = k / k.sum()
    out = F.conv2d(F.pad(images, (radius, radius, 0, 0), mode="replicate"), k.view(1, 1, 1, -1))
    return F.conv2d(F.pad(out, (0, 0, radius, radius), mode="replicate"), k.view(1, 1, -1, 1))


def harris(images: torch.Tensor, k: float = 0.04) -> torch.Tensor:
    """(B, 1, S, S) -> Harris corner response (Gaussian derivatives at sigma 1, window 2)."""
    smooth = gaussian_blur(images, 1.0)
    dx = (smooth[..., :, 2:] - smooth[..., :, :-2]) / 2
    dy = (smooth[..., 2:, :] - smooth[..., :-2, :]) / 2
    dx, dy = F.pad(dx, (1, 1, 0, 0)), F.pad(dy, (0, 0, 1, 1))
    xx, yy, xy = (gaussian_blur(t, 2.0) for t in (dx * dx, dy * dy, dx * dy))
    return xx * yy - xy * xy - k * (xx + yy) ** 2


def difference_of_gaussians(images: torch.Tensor, sigma: float = 1.6) -> torch.Tensor:
    """(B, 1, S, S) -> |DoG| at one octave step, Lowe's base scale."""
    return (gaussian_blur(images, sigma * math.sqrt(2)) - gaussian_blur(images, sigma)).abs()


def keypoints(response: torch.Tensor, foreground: torch.Tensor) -> list[torch.Tensor]:
    """(B, S, S) responses -> per map (k, 2) row, col of the KEYPOINTS strongest local maxima
    on the foreground."""
    r = response.unsqueeze(1)
    peak = (r == F.max_pool2d(r, NMS_WINDOW, 1, NMS_WINDOW // 2)).squeeze(1) & foreground
    out = []
    for resp, mask in zip(response, peak, strict=True):
        idx = torch.nonzero(mask)
        order = resp[mask].argsort(descending=True)[:KEYPOINTS]
        out.append(idx[order])
    return out


def repeatability(response: torch.Tensor, pairs: ViewPairs, config: PipelineConfig) -> float:
    """Share of covisible keypoints detected again within REPEAT_PIXELS in the other view.

    response: (N, 2, S, S) a detector's responses to the N pairs; both directions averaged.
    """
    foreground = pairs.depth > 0
    repeated, covisible = 0, 0
    for direction, oriented in enumerate((pairs, pairs.swapped())):
        source = keypoints(response[:, direction], foreground[:, direction])
        target = keypoints(response[:, 1 - direction], foreground[:, 1 - direction])
        for i, (points, others) in enumerate(zip(source, target, strict=True)):
            if len(points) == 0:
                continue
            mapped, seen = correspond(oriented, torch.full((len(points),), i), points, config)
            mapped = mapped[seen].float()
            covisible += len(mapped)
            if len(mapped) and len(others):
                gap = torch.cdist(mapped, others.float()).min(dim=1).values
                repeated += int((gap <= REPEAT_PIXELS).sum())
    return repeated / max(covisible, 1)


def fpr_at_95_recall(positive: torch.Tensor, negative: torch.Tensor) -> float:
    """False positive rate (%) at the distance threshold that accepts 95% of positive pairs."""
    threshold = torch.quantile(positive, 0.95)
    return 100.0 * float((negative <= threshold).float().mean())


@torch.no_grad()
def descriptor_fpr95(
    net: nn.Module, maps: torch.Tensor, matches: torch.Tensor, patch_size: int, seed: int
) -> float:
    """FPR95 of ``net`` on patches of corresponding points (positives) and of the same points
    paired with a random other match, from another place (negatives).

    maps: (N, 2, S, S) PoI maps; matches: (C, 5) held-out correspondences.
    """
    gen = torch.Generator().manual_seed(seed)
    first = crops(maps[:, 0], matches[:, [0, 1, 2]], patch_size).unsqueeze(1)
    second = crops(maps[:, 1], matches[:, [0, 3, 4]], patch_size).unsqueeze(1)
    a, b = net(first), net(second)
    positive = descriptor_distances(a, b).diagonal()
    other = torch.randperm(len(matches), generator=gen)
    far = (matches[:, 0] != matches[other, 0]) | (
        (matches[:, 1:3] - matches[other, 1:3]).abs().amax(1) >= patch_size
    )
    negative = ((a[far] - b[other][far]) ** 2).sum(1).sqrt()
    return fpr_at_95_recall(positive, negative)


def conv_flops(net: nn.Module, example: torch.Tensor) -> int:
    """Multiply-adds x 2 of the convolutions of one forward pass of ``example``."""
    total = 0

    def count(module: nn.Conv2d, _inputs, output: torch.Tensor) -> None:
        nonlocal total
        k = module.kernel_size[0] * module.kernel_size[1] * module.in_channels // module.groups
        total += 2 * output.numel() * k

    hooks = [m.register_forward_hook(count) for m in net.modules() if isinstance(m, nn.Conv2d)]
    with torch.no_grad():
        net(example)
    for hook in hooks:
        hook.remove()
    return total
