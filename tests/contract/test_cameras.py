"""The cameras every path shares (``contract.cameras``): the upper hemisphere, its rings."""

import numpy as np

from drkfs_onnx.contract.cameras import hemisphere_directions, make_cameras, rotation_y
from drkfs_onnx.contract.config import (
    PipelineConfig,
)


def test_views_cover_the_upper_hemisphere_evenly():
    dirs = hemisphere_directions(25)
    assert np.allclose(np.linalg.norm(dirs, axis=1), 1)
    assert (dirs[:, 1] > 0).all()
    # even spread: every view has a neighbour within 45 degrees, none closer than 15
    cos = dirs @ dirs.T
    np.fill_diagonal(cos, -1)
    nearest = np.degrees(np.arccos(cos.max(1)))
    assert nearest.max() < 45 and nearest.min() > 15


def test_cameras_look_at_the_origin_with_orthonormal_frames():
    cams = make_cameras(PipelineConfig.paper())
    assert len(cams) == 25
    for rot in cams.rotations:
        assert np.allclose(rot @ rot.T, np.eye(3), atol=1e-12)
    origin = cams.world_to_camera(np.zeros((1, 3)))
    assert np.allclose(origin[:, 0, :2], 0, atol=1e-12)
    assert np.allclose(origin[:, 0, 2], PipelineConfig().camera_distance)
    # world up appears as image up (negative camera y) from every view
    up = cams.world_to_camera(np.array([[0.0, 0.5, 0.0]]))[:, 0]
    assert (up[:, 1] < 0).all()


def test_a_turned_ring_repeats_the_cameras_turned_about_the_vertical():
    default = PipelineConfig()
    assert default.rings == (0.0, default.turn_degrees) and default.turn_degrees > 0
    assert default.views_per_mesh == 2 * default.num_views
    one = make_cameras(default.one_ring())
    both = make_cameras(default)
    assert len(one) == default.num_views and len(both) == default.views_per_mesh
    assert np.array_equal(both.eyes[: len(one)], one.eyes)
    # turned by -turn: each camera of the second ring sees the mesh as if turned by +turn
    assert np.allclose(both.eyes[len(one) :], one.eyes @ rotation_y(-default.turn_degrees).T)
    # the paper, the nets' training and the loss see one ring
    for config in (PipelineConfig.paper(), PipelineConfig.training(), PipelineConfig.loss()):
        assert config.rings == (0.0,) and config.views_per_mesh == config.num_views
