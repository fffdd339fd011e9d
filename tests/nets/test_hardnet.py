"""HardNet (``nets.hardnet``): unit descriptors, folded batch norm, the fixed nets' backward."""

import pytest
import torch
import torch.nn.functional as F

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.nets.detector import PoIDetector
from drkfs_onnx.nets.hardnet import HardNet

CONFIG = PipelineConfig.paper()


def test_hardnet_full_width_is_l2net():
    net = HardNet(CONFIG)
    assert sum(p.numel() for p in net.parameters()) == 1_334_560
    half = HardNet(CONFIG.replace(descriptor_width=0.5))
    assert sum(p.numel() for p in half.parameters()) < 1_334_560 / 2


@pytest.mark.parametrize("width", [1.0, 0.25])
def test_hardnet_gives_unit_descriptors(width):
    torch.manual_seed(0)
    net = HardNet(CONFIG.replace(descriptor_width=width)).eval()
    desc = net(torch.rand(5, 1, 32, 32))
    assert desc.shape == (5, 128)
    assert torch.allclose(desc.norm(dim=1), torch.ones(5), atol=1e-5)


def test_evaluation_folds_batchnorm_into_the_convs_without_changing_descriptors():
    torch.manual_seed(0)
    net = HardNet(PipelineConfig(descriptor_width=0.5))
    for norm in net.features:  # running statistics far from the identity
        if isinstance(norm, torch.nn.BatchNorm2d):
            norm.running_mean.uniform_(-1.0, 1.0)
            norm.running_var.uniform_(0.5, 4.0)
    patches = torch.rand(20, 1, 32, 32, requires_grad=True)
    net.eval()
    folded = net(patches)
    normalised = F.instance_norm(patches, eps=net.patch_norm_eps)
    layered = net.features(normalised).flatten(1)  # the modules one by one, as trained
    layered = layered / layered.norm(dim=1, keepdim=True)
    torch.testing.assert_close(folded, layered, atol=1e-5, rtol=1e-5)
    (grad_folded,) = torch.autograd.grad(folded.sum(), patches)
    (grad_layered,) = torch.autograd.grad(layered.sum(), patches)
    torch.testing.assert_close(grad_folded, grad_layered, atol=1e-4, rtol=1e-4)


@pytest.mark.parametrize(("size", "group"), [(32, None), (20, None), (32, 3)])
def test_fixed_nets_backward_equals_autograds(size, group):
    """With fixed weights (as in the metric) the detector and HardNet send the patches their
    gradient by hand-written backwards (transposed convs, the ReLU masks kept as bytes), and a
    CPU runs the detector's conv in its space-to-depth form: the same maps, descriptors and
    gradient as autograd's through the plain layers, for any upstream gradient, patch size (20
    px: a 5 x 5 map before the last conv, and images of no whole 4 x 4 blocks) and group of
    patches per pass (4 patches in groups of 3: the last group shorter)."""
    torch.manual_seed(0)
    config = PipelineConfig(descriptor_width=0.5, patch_size=size)
    detector, net = PoIDetector(config), HardNet(config).eval()
    images = torch.rand(4, 1, size, size, requires_grad=True)
    upstream = torch.randn(4, config.descriptor_dim)
    found, described, maps = {}, {}, {}
    for frozen in (False, True):
        detector.requires_grad_(not frozen)
        net.requires_grad_(not frozen)
        maps[frozen] = detector(images)
        described[frozen] = net(maps[frozen], group if frozen else None)
        (found[frozen],) = torch.autograd.grad((described[frozen] * upstream).sum(), images)
    torch.testing.assert_close(maps[True], maps[False], atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(described[True], described[False], atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(found[True], found[False], atol=1e-6, rtol=1e-5)
    assert found[True].abs().max() > 0


@pytest.mark.parametrize("frozen", [False, True])
def test_convs_in_bfloat16_give_float32_descriptors_near_float32s(frozen):
    """``dtype`` runs the evaluation convs in bfloat16 (the cheaper training step's HardNet):
    float32 unit descriptors within bfloat16's rounding of float32's, forward and, for fixed
    nets, backward; the patches' gradient in float32."""
    torch.manual_seed(0)
    net = HardNet(PipelineConfig(descriptor_width=0.5)).eval().requires_grad_(not frozen)
    patches = torch.rand(6, 1, 32, 32, requires_grad=True)
    upstream = torch.randn(6, 128)
    found = {}
    for dtype in (None, torch.bfloat16):
        described = net(patches, 4, dtype)
        (grad,) = torch.autograd.grad((described * upstream).sum(), patches)
        found[dtype] = described, grad
    (exact, exact_grad), (cheap, cheap_grad) = found[None], found[torch.bfloat16]
    assert cheap.dtype == cheap_grad.dtype == torch.float32
    torch.testing.assert_close(cheap.norm(dim=1), torch.ones(6))
    assert (cheap - exact).abs().max() < 0.02 * exact.abs().max()
    assert not torch.equal(cheap, exact)  # the convs did run in bfloat16
    assert F.cosine_similarity(cheap_grad.flatten(), exact_grad.flatten(), dim=0) > 0.97


def test_hardnet_ignores_patch_brightness_and_contrast():
    torch.manual_seed(0)
    net = HardNet(CONFIG).eval()
    patch = torch.rand(1, 1, 32, 32)
    assert torch.allclose(net(patch), net(0.3 * patch + 0.5), atol=1e-4)
