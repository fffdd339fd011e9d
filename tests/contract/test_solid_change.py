"""The views' solid change (contract.solid_change): a region that changes as a whole counts,
scattered changes, thin strips and shifts within the reach do not; a shift's change ramps up
over the reaches; inside the mesh the reach is shorter; torch and numpy agree."""

import numpy as np
import pytest
import torch

from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract.array_ops import NUMPY_OPS
from drkfs_onnx.contract.config import ONE_REACH
from drkfs_onnx.contract.solid_change import view_ranges, view_solid_changes, window_extreme
from drkfs_onnx.render.torch_ops import TORCH_OPS

CONFIG = PipelineConfig(solid_weight=1.0, solid_shift=2, solid_block=3, **ONE_REACH)
K, S = 5, 64


def _views(seed: int = 0) -> np.ndarray:
    """(K, S, S) smooth grey views with a background margin, as the cameras frame a mesh."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:S, 0:S] / S
    views = np.stack([0.5 + 0.3 * np.sin(6 * x + k) * np.cos(5 * y - k) for k in range(K)])
    views += 0.02 * rng.standard_normal(views.shape)
    views[:, :8], views[:, -8:], views[:, :, :8], views[:, :, -8:] = 0.0, 0.0, 0.0, 0.0
    return views.astype(np.float32)


def solid_change(a, b, config, ops, *ranges):
    """The one-ring term before its weight: the views' solid changes' mean over the views."""
    return view_solid_changes(a, b, config, ops, *ranges).mean(-1)


def _score(a: np.ndarray, b: np.ndarray, config: PipelineConfig = CONFIG) -> float:
    return float(solid_change(a, b, config, NUMPY_OPS))


def test_identical_views_score_zero():
    views = _views()
    assert _score(views, views) == 0.0


def test_a_region_changed_as_a_whole_counts_its_change_in_its_view():
    a = _views()
    b = a.copy()
    b[2, 30:36, 30:36] -= 0.4  # a dark hole of 6 x 6 pixels in view 2, far below its range
    # the hole is darker than anything within the reach by at least 0.4 minus the local spread
    assert 0.3 / K < _score(a, b) <= 0.4 / K + 1e-6
    assert _score(a, b) == pytest.approx(_score(b, a))  # either way


def test_scattered_changes_and_thin_strips_do_not_count():
    a = _views()
    speckled = a.copy()
    speckled[:, 10:54:2, 10:54:2] += 0.5  # every other pixel: no block changes as a whole
    strip = a.copy()
    strip[1, 20:40, 30:32] += 0.5  # 2 pixels wide, under the 3-pixel block
    assert _score(a, speckled) == 0.0
    assert _score(a, strip) == 0.0


@pytest.mark.parametrize("pixels", [1, 2])
def test_a_shift_within_the_reach_changes_nothing(pixels):
    a = _views()
    shifted = np.roll(a, pixels, axis=-1)
    assert _score(a, shifted) == 0.0
    assert _score(a, np.roll(a, 4, axis=-1)) > 0.0  # beyond the reach it counts


@pytest.mark.parametrize("ramp", [False, True], ids=["one reach", "the default's ramp"])
def test_torch_and_numpy_agree_and_torch_has_a_gradient_at_the_change(ramp):
    config = PipelineConfig(solid_weight=1.0) if ramp else CONFIG
    a, b = _views(1), _views(1)
    b[0, 20:28, 40:48] += 0.3
    expected = _score(a, b, config)
    views_b = torch.tensor(b, requires_grad=True)
    found = solid_change(torch.tensor(a), views_b, config, TORCH_OPS)
    assert float(found.detach()) == pytest.approx(expected, abs=1e-6)
    found.backward()
    grad = views_b.grad.abs()
    assert grad[0, 20:28, 40:48].sum() > 0  # the changed region moves the term
    assert grad[1:].sum() == 0  # unchanged views do not


def test_a_batch_scores_each_pair_and_a_precomputed_range_is_the_same():
    a, b = _views(2), _views(2)
    b[3, 30:40, 30:40] = 0.0
    batch = solid_change(np.stack([a, a]), np.stack([a, b]), CONFIG, NUMPY_OPS)
    assert batch[0] == 0.0 and batch[1] == pytest.approx(_score(a, b))
    ranges = view_ranges(a, CONFIG, NUMPY_OPS), view_ranges(b, CONFIG, NUMPY_OPS)
    assert solid_change(a, b, CONFIG, NUMPY_OPS, *ranges) == _score(a, b)


def test_a_growing_shift_raises_the_ramp_step_by_step():
    """Over reaches 2 and 3 a shift of 3 pixels counts half what it does at reach 2 alone,
    one of 2 nothing, and one of 4 more: no single reach where the change jumps."""
    ramp = CONFIG.replace(solid_shift=3, solid_ramp=1)
    a = _views()
    scores = [_score(a, np.roll(a, pixels, axis=-1), ramp) for pixels in (2, 3, 4)]
    assert scores[0] == 0.0 < scores[1] < scores[2]
    assert scores[1] == pytest.approx(0.5 * _score(a, np.roll(a, 3, axis=-1)), rel=1e-6)


def test_inside_the_mesh_the_reach_is_shorter_and_the_change_raised_to_its_power():
    """Where both views show the mesh the reach drops by one: a 2-pixel shift of the shading
    there counts, where the same shift of a flat shape's outline against the background does
    not. A flat region changed as a whole counts its change raised to the power."""
    drop = CONFIG.replace(solid_inner_drop=1)
    a = _views()
    inside = a.copy()
    inside[:, 8:-8, 8:-8] = np.roll(a, 2, axis=-1)[:, 8:-8, 8:-8]  # the outline kept
    assert _score(a, inside) == 0.0 < _score(a, inside, drop)
    flat = np.zeros((K, S, S), np.float32)
    flat[:, 20:40, 20:40] = 0.5
    moved = np.roll(flat, 2, axis=-1)
    assert _score(flat, moved, drop) == 0.0
    hole = flat.copy()
    hole[1, 26:32, 26:32] = 0.1
    powered = drop.replace(solid_inner_power=1.5)
    assert _score(flat, hole, powered) == pytest.approx(0.4**1.5 / K, rel=1e-6)


def test_window_extreme_is_the_min_over_each_square_that_fits():
    image = np.arange(36, dtype=np.float64).reshape(6, 6)
    found = window_extreme(image, 1, np.minimum)
    assert found.shape == (4, 4)
    assert found[0, 0] == image[0:3, 0:3].min() and found[3, 3] == image[3:6, 3:6].min()


@pytest.mark.parametrize(
    "changes",
    [
        {"solid_block": 2},
        {"solid_weight": -1.0},
        {"solid_shift": -1},
        {"solid_ramp": -1},
        {"solid_shift": 1, "solid_ramp": 1},
        {"solid_inner_power": 0.0},
    ],
)
def test_bad_solid_settings_are_refused(changes):
    with pytest.raises(ValueError, match="solid"):
        PipelineConfig(**changes)
