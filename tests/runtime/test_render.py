"""The runtime's numpy renderer computes the torch renderer's evaluation images."""

from functools import partial
from unittest.mock import patch

import numpy as np
import pytest
import torch
from conftest import icosphere

from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract.array_ops import NUMPY_OPS
from drkfs_onnx.contract.cameras import make_cameras
from drkfs_onnx.contract.render_equations import DEPTH_CULL, pair_terms, project_faces
from drkfs_onnx.render.renderer import Renderer
from drkfs_onnx.runtime.candidates import (
    LOOSE_RADIUS,
    _row_spans,
    candidate_pairs,
    face_tests,
    faces_over,
    pixel_boxes,
)
from drkfs_onnx.runtime.render import VIEW_FACES_PER_CALL, NumpyRenderer
from drkfs_onnx.synthetic.shapes import assemble, chair

CONFIG = PipelineConfig(turn_degrees=0.0, num_views=5, image_size=64)


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


def _inside_out_sphere(subdivisions: int = 3):
    """Clockwise faces: the faces turned towards the camera wind the other way."""
    verts, faces = icosphere(subdivisions)
    return verts, faces[:, ::-1].copy()


@pytest.mark.parametrize("mesh", [icosphere, _chair, _layers, _inside_out_sphere])
@pytest.mark.parametrize("size", [64, 192])
def test_numpy_images_equal_torch_float64_images(mesh, size):
    config = CONFIG.replace(image_size=size)
    verts, faces = mesh()
    expected = Renderer(config).render(torch.tensor(verts), torch.tensor(faces)).numpy()
    got = NumpyRenderer(config).render(verts, faces)
    assert got.dtype == np.float32 and got.shape == (5, size, size)
    assert np.abs(got - expected).max() < 1e-6


def _bowl():
    """A sphere with its top cut away: the cameras see its inside through the opening."""
    verts, faces = icosphere(3)
    return verts, faces[verts[faces].mean(1)[:, 1] < 0.25]


@pytest.mark.parametrize("mesh", [_chair, _inside_out_sphere, _bowl])
@pytest.mark.parametrize(
    "share, push", [(0.0, 0.0), (0.3, 0.0), (0.0, 0.005), (0.0, 0.05), (0.3, 0.1)]
)
def test_numpy_images_equal_torch_images_with_faces_seen_from_behind_in_shadow(mesh, share, push):
    config = CONFIG.replace(back_light=share, back_push=push)
    verts, faces = mesh()
    expected = Renderer(config).render(torch.tensor(verts), torch.tensor(faces)).numpy()
    assert np.abs(NumpyRenderer(config).render(verts, faces) - expected).max() < 1e-6


def test_numpy_pushed_shadow_is_the_same_in_threads():
    """Views rendered in groups on threads, one view a call, list the faces again per group."""
    config = CONFIG.replace(back_light=0.0, back_push=0.05)
    verts, faces = _bowl()
    expected = NumpyRenderer(config).render(verts, faces)
    with patch("drkfs_onnx.runtime.render.VIEW_FACES_PER_CALL", len(faces)):
        assert np.array_equal(NumpyRenderer(config, threads=2).render(verts, faces), expected)


@pytest.mark.parametrize("push", [0.0, 0.05])
def test_a_mesh_behind_every_camera_renders_background(push):
    verts, faces = icosphere(0, radius=0.1)
    got = NumpyRenderer(CONFIG.replace(back_light=0.0, back_push=push)).render(verts + 100.0, faces)
    assert np.all(got == CONFIG.background)


@pytest.mark.parametrize("mesh", [_chair, partial(_inside_out_sphere, 2)], ids=["chair", "sphere"])
def test_candidates_hold_every_pair_the_exact_pass_keeps(mesh):
    """Brute force over every pixel-face pair: each covered pair within the depth cull of its
    pixel's winner is a candidate, although whole hidden faces are dropped before listing."""
    config = CONFIG.replace(image_size=40)
    verts, faces = mesh()
    cameras = make_cameras(config)
    screen = project_faces(cameras.world_to_camera(verts), faces, cameras.focal, config, NUMPY_OPS)
    params, visible = screen.params, screen.visible
    k, pixels = config.num_views, config.image_size**2
    pixel = np.arange(k * pixels).repeat(len(faces))
    face = (pixel // pixels) * len(faces) + np.tile(np.arange(len(faces)), k * pixels)
    face_pixel = pixel % pixels
    px = (2 * (face_pixel % config.image_size) + 1) / config.image_size - 1.0
    py = (2 * (face_pixel // config.image_size) + 1) / config.image_size - 1.0
    coverage, depth = pair_terms(params[:, face], px, py, config, NUMPY_OPS)
    covered = (coverage > 0) & visible[face]
    logit = np.where(covered, np.log(np.where(covered, coverage, 1.0)) + depth / config.gamma, 0)
    winner = np.full(k * pixels, config.background_eps / config.gamma)
    np.maximum.at(winner, pixel[covered], logit[covered])
    needed = covered & (logit >= winner[pixel] - DEPTH_CULL)

    got_pixel, got_face = candidate_pairs(params, visible, k, config)
    key = pixel * len(visible) + face
    assert np.isin(key[needed], got_pixel * len(visible) + got_face).all()
    assert len(got_pixel) < covered.sum()  # hidden pairs are dropped


def test_faces_over_are_the_visible_faces_whose_box_holds_a_marked_pixel():
    """The pushed shadow's second blend lists only these: brute force over each face's box."""
    config = CONFIG.replace(image_size=40)
    verts, faces = _chair()
    cameras = make_cameras(config)
    screen = project_faces(cameras.world_to_camera(verts), faces, cameras.focal, config, NUMPY_OPS)
    k, size = config.num_views, config.image_size
    pixels = np.random.default_rng(5).choice(k * size * size, 60, replace=False)
    got = faces_over(pixels, screen.params, screen.visible, k, config)
    boxes = pixel_boxes(screen.params, screen.visible, config)
    view, row, column = pixels // size**2, pixels // size % size, pixels % size
    expected = [
        any(
            v == index // len(faces) and i0 <= c < i0 + w and j0 <= r < j0 + h
            for v, r, c in zip(view, row, column, strict=True)
        )
        for index, (i0, j0, w, h) in enumerate(
            zip(boxes.i0, boxes.j0, boxes.width, boxes.height, strict=True)
        )
    ]
    assert np.array_equal(got, expected) and 0 < got.sum() < screen.visible.sum()


def test_row_spans_are_the_columns_every_edge_line_allows():
    """Per box row, the outer span is exactly the pixels within the loose radius of all three
    edge lines and the inner span those strictly inside, also where an edge is horizontal (its
    line keeps a whole row or none of it) or vertical."""
    config = CONFIG.replace(image_size=48)
    size, reach = config.image_size, LOOSE_RADIUS * config.coverage_radius
    corners = np.random.default_rng(3).uniform(-0.9, 0.9, (40, 3, 2))
    corners[0, 1, 1] = corners[0, 0, 1]
    corners[1, 2, 0] = corners[1, 1, 0]
    params = np.concatenate([corners.reshape(40, 6), np.full((40, 3), 0.5)], axis=1).T
    tests, boxes = face_tests(params), pixel_boxes(params, np.ones(40, bool), config)
    face = np.repeat(np.arange(40), boxes.height)
    row = np.concatenate([j + np.arange(h) for j, h in zip(boxes.j0, boxes.height, strict=True)])
    py = (2 * row + 1) / size - 1.0
    spans = np.stack(_row_spans(face, py, tests, boxes, config), axis=1)
    for f, y, (first, last, inner_first, inner_last) in zip(face, py, spans, strict=True):
        columns = boxes.i0[f] + np.arange(boxes.width[f])
        px = (2 * columns + 1) / size - 1.0
        distance = np.min([a[f] * px + b[f] * y + c[f] for a, b, c in tests.lines], axis=0)
        assert list(columns[distance > -reach]) == list(range(first, last + 1))
        assert list(columns[distance > 0]) == list(range(inner_first, inner_last + 1))


def test_a_large_mesh_costs_the_memory_of_one_view_not_of_all_of_them():
    """A mesh above VIEW_FACES_PER_CALL renders a view at a time: a 500k-face mesh under the
    paper preset peaked at 6.6 GB when its views were rendered together. Six views may cost
    little more than one (traced numpy allocations, one thread)."""
    import tracemalloc

    verts, faces = icosphere(6)  # 81,920 faces
    assert len(faces) > VIEW_FACES_PER_CALL

    def peak(views: int) -> int:
        renderer = NumpyRenderer(CONFIG.replace(num_views=views, image_size=128))
        tracemalloc.start()
        renderer.render(verts, faces)
        used = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return used

    assert peak(6) < 1.5 * peak(1)
