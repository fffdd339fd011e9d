"""The PoI detector (``nets.detector``): piecewise-linear maxout maps of a view's size."""

import torch

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.nets.detector import PoIDetector

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
