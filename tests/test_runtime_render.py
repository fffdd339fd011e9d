"""The runtime's numpy renderer computes the torch renderer's evaluation images."""

import numpy as np
import pytest
import torch
from conftest import icosphere

from drkfs_onnx import PipelineConfig
from drkfs_onnx.render import Renderer
from drkfs_onnx.runtime.render import NumpyRenderer
from drkfs_onnx.shapes import assemble, chair

CONFIG = PipelineConfig(num_views=5, image_size=64)


def _chair():
    verts, faces = assemble(chair(), 1)
    return verts - verts.mean(0), faces


def _layers():
    """A small square in front of a large one (occluding edges over a surface), a vertical face
    (steep in depth from cameras near the top) and a zero-area face."""
    square = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float64)
    verts = np.concatenate(
        [
            0.6 * square,
            0.25 * square + [0.1, 0.05, 0.3],
            [[0, 0, 0.5], [0.5, 0, 0.5], [0.5, 0, 0.9]],
        ]
    )
    verts = np.concatenate([verts, [[-0.5, 0.3, 0.1], [-0.3, 0.3, 0.1], [-0.1, 0.3, 0.1]]])
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [8, 9, 10], [11, 12, 13]])
    return verts, faces


@pytest.mark.parametrize("mesh", [icosphere, _chair, _layers])
@pytest.mark.parametrize("size", [64, 192])
def test_numpy_images_equal_torch_float64_images(mesh, size):
    config = CONFIG.replace(image_size=size)
    verts, faces = mesh()
    expected = Renderer(config).render(torch.tensor(verts), torch.tensor(faces)).numpy()
    got = NumpyRenderer(config).render(verts, faces)
    assert got.dtype == np.float32 and got.shape == (5, size, size)
    assert np.abs(got - expected).max() < 1e-6


def test_a_mesh_behind_every_camera_renders_background():
    verts, faces = icosphere(0, radius=0.1)
    got = NumpyRenderer(CONFIG).render(verts + 100.0, faces)
    assert np.all(got == CONFIG.background)
