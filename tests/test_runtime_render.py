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


@pytest.mark.parametrize("mesh", [icosphere, _chair])
def test_numpy_images_equal_torch_float64_images(mesh):
    verts, faces = mesh()
    expected = Renderer(CONFIG).render(torch.tensor(verts), torch.tensor(faces)).numpy()
    got = NumpyRenderer(CONFIG).render(verts, faces)
    assert got.dtype == np.float32 and got.shape == (5, 64, 64)
    assert np.abs(got - expected).max() < 1e-6


def test_a_mesh_behind_every_camera_renders_background():
    verts, faces = icosphere(0, radius=0.1)
    got = NumpyRenderer(CONFIG).render(verts + 100.0, faces)
    assert np.all(got == CONFIG.background)
