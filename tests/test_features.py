"""PoI detector, patches, HardNet and matching: shapes and the properties the metric relies on."""

import pytest
import torch
import torch.nn.functional as F

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.match import best_match_distances, match_score, nearest_indices
from drkfs_onnx.nets.detector import PoIDetector
from drkfs_onnx.nets.hardnet import HardNet
from drkfs_onnx.nets.patches import nonempty_patches_on_device, select_patches

CONFIG = PipelineConfig.paper()


def test_detector_maps_images_to_maps_of_the_same_size():
    torch.manual_seed(0)
    maps = PoIDetector(CONFIG)(torch.rand(3, 1, 256, 256))
    assert maps.shape == (3, 1, 256, 256)


def test_detector_is_piecewise_linear_maxout():
    """score = sum_n delta_n max_m (W_mn * I + b_mn), checked pixel by pixel."""
    torch.manual_seed(0)
    config = CONFIG.replace(detector_kernel=3, detector_n=2, detector_m=3)
    det = PoIDetector(config)
    image = torch.rand(1, 1, 6, 6)
    padded = torch.nn.functional.pad(image, (1, 1, 1, 1), value=config.background)
    window = padded[0, 0, 3:6, 4:7]  # centred on pixel (3, 4)
    responses = (det.conv.weight[:, 0] * window).sum((1, 2)) + det.conv.bias
    score = responses[:3].max() - responses[3:].max()
    assert torch.isclose(det(image)[0, 0, 3, 4], torch.sigmoid(score), atol=1e-6)


def test_background_gives_one_constant_poi_value_everywhere():
    torch.manual_seed(0)
    maps = PoIDetector(CONFIG)(torch.zeros(1, 1, 64, 64))
    assert torch.allclose(maps, maps[0, 0, 0, 0].expand_as(maps), atol=1e-6)


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


def test_hardnet_ignores_patch_brightness_and_contrast():
    torch.manual_seed(0)
    net = HardNet(CONFIG).eval()
    patch = torch.rand(1, 1, 32, 32)
    assert torch.allclose(net(patch), net(0.3 * patch + 0.5), atol=1e-4)


def _brute_force(a, b):
    return torch.cdist(a.double(), b.double()).pow(2).min(1).values


def test_best_match_equals_brute_force_across_chunks(monkeypatch):
    import drkfs_onnx.match as matching

    torch.manual_seed(0)
    a, b = torch.randn(700, 16), torch.randn(300, 16)
    monkeypatch.setattr(matching, "CHUNK_ROWS", 64)
    found = best_match_distances(a, b, PipelineConfig.paper()).double()
    assert torch.allclose(found, _brute_force(a, b), atol=1e-4)
    assert nearest_indices(a[:0], b).shape == (0,)


def test_paper_match_sums_forward_best_matches_and_both_averages_the_directions():
    torch.manual_seed(0)
    a, b = torch.randn(50, 8), torch.randn(30, 8)
    ab, ba = _brute_force(a, b), _brute_force(b, a)
    paper = PipelineConfig.paper()
    assert torch.isclose(match_score(a, b, paper).double(), ab.sum(), rtol=1e-5)
    mean = paper.replace(reduction="mean")
    assert torch.isclose(match_score(a, b, mean).double(), ab.mean(), rtol=1e-5)
    both = match_score(a, b, paper.replace(direction="both")).double()
    assert torch.isclose(both, (ab.sum() + ba.sum()) / 2, rtol=1e-5)
    backward = match_score(a, b, paper.replace(direction="backward")).double()
    assert torch.isclose(backward, ba.sum(), rtol=1e-5)


def test_match_gradient_reaches_both_sets():
    a = torch.randn(20, 8, requires_grad=True)
    b = torch.randn(10, 8, requires_grad=True)
    match_score(a, b, PipelineConfig.paper()).backward()
    assert a.grad.abs().sum() > 0 and b.grad.abs().sum() > 0
