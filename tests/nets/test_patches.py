"""Patches (``nets.patches``): 32 px windows at stride 16, their gradient, the non-empty mask."""

import pytest
import torch
import torch.nn.functional as F

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.nets.patches import nonempty_patches_on_device, select_patches

CONFIG = PipelineConfig.paper()


def test_patches_are_the_32px_windows_at_stride_16_the_index_names():
    maps = torch.rand(2, 1, 256, 256)
    patches = select_patches(maps, torch.tensor([16, 225 + 14]), CONFIG)
    assert patches.shape == (2, 1, 32, 32)
    assert torch.equal(patches[0, 0], maps[0, 0, 16:48, 16:48])  # row 1, column 1 of view 0
    assert torch.equal(patches[1, 0], maps[1, 0, 0:32, 224:256])


@pytest.mark.parametrize(
    "config", [CONFIG, CONFIG.replace(image_size=70, patch_size=12, patch_stride=6)]
)
def test_selected_patches_are_unfolds_rows_with_its_gradient(config):
    """Rows of unfold's row-major patch list, in the index's order, also where the patch rows
    share no 16-pixel blocks (gcd 2 here)."""
    size, count = config.patch_size, 3 * config.patches_per_view
    maps = torch.rand(3, 1, config.image_size, config.image_size, requires_grad=True)
    index = torch.cat(
        [
            torch.randperm(count, generator=torch.Generator().manual_seed(0)),
            torch.tensor([0, count - 1, 5, 5]),
        ]
    )
    patches = select_patches(maps, index, config)
    every = (
        F.unfold(maps, size, stride=config.patch_stride).transpose(1, 2).reshape(-1, 1, size, size)
    )
    assert patches.shape == (len(index), 1, size, size)
    assert torch.equal(patches, every[index])
    weights = torch.rand(patches.shape)
    (grad,) = torch.autograd.grad((patches * weights).sum(), maps)
    (expected,) = torch.autograd.grad((every[index] * weights).sum(), maps)
    assert torch.allclose(grad, expected)


def test_nonempty_mask_sees_content_within_the_detectors_reach():
    images = torch.zeros(1, 1, 256, 256)
    images[0, 0, 100, 40] = 0.5  # column 40 lies in patch columns 1 and 2 only
    mask = nonempty_patches_on_device(images, CONFIG).view(15, 15)
    reach = CONFIG.detector_kernel // 2
    for row in range(15):
        for col in range(15):
            y0, x0 = 16 * row - reach, 16 * col - reach
            sees = y0 <= 100 < y0 + 32 + 2 * reach and x0 <= 40 < x0 + 32 + 2 * reach
            assert bool(mask[row, col]) == sees
