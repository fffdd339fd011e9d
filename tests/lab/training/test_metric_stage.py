"""The metric stage of training: labels from geometry, the ranking objective, the rules that pick
an objective and a width, and one step of each objective moving the nets."""

import numpy as np
import pytest
import torch

from drkfs_lab.training.metric_losses import RANK_MARGIN, ranking_loss
from drkfs_lab.training.metric_stage import (
    BASELINE,
    OBJECTIVES,
    Correspondences,
    admissible,
    choose_objective,
    choose_smallest,
)
from drkfs_lab.training.variant_views import (
    VARIANT_NAMES,
    VariantViews,
    changed_share,
    render_variant_views,
)
from drkfs_onnx import DRKFS, PipelineConfig

CONFIG = PipelineConfig(turn_degrees=0.0, num_views=2, image_size=64, patch_size=16, patch_stride=8)


@pytest.fixture(scope="module")
def views():
    return render_variant_views(CONFIG, ["chair", "table"], 2, seed=5)


def test_a_structural_edit_changes_more_of_the_picture_than_any_mild_one(views):
    assert views.images.shape == (4, 1 + len(VARIANT_NAMES), 2, 64, 64)
    assert torch.all(views.changed[:, 0] == 0)  # the base against itself
    share = views.changed.mean(dim=(2, 3))  # (bases, meshes)
    for part_removed in VariantViews.columns("structural")[::2]:
        assert VARIANT_NAMES[part_removed - 1].endswith("part_removed")
        # the removed part shows somewhere, in every base
        assert torch.all(views.changed[:, part_removed].amax(dim=(1, 2)) > 0.05)
    retessellated = VARIANT_NAMES.index("part:retessellated") + 1
    assert share[:, retessellated].max() < share[:, 1].min()


def test_changed_share_counts_foreground_flips_and_far_depths_only():
    depth = torch.full((1, 64, 64), 0.5)
    other = depth.clone()
    other[0, :8, :8] = 0  # a corner vanishes: 64 of the first patch's 256 pixels
    other[0, 40:, 40:] = 0.5001  # a tiny depth change, not another surface
    share = changed_share(depth, other, CONFIG)
    assert share[0, 0] == pytest.approx(64 / 256)
    assert share[0, 1:].sum() == pytest.approx(share[0, 1] + share[0, 7] + share[0, 8])
    assert share[0, -1] == 0


def test_ranking_loss_is_zero_only_when_every_structural_score_clears_the_margin():
    mild = torch.tensor([1.0, 2.0])
    margin = RANK_MARGIN
    clear = torch.tensor([2.0 * np.exp(margin) * 1.01])
    assert ranking_loss(mild, clear, margin) == 0
    assert ranking_loss(mild, torch.tensor([2.0]), margin) > 0
    # scale-free: scaling every score leaves it unchanged
    tight = ranking_loss(mild, torch.tensor([3.0]), margin)
    assert ranking_loss(10 * mild, torch.tensor([30.0]), margin) == pytest.approx(float(tight))


CHAMFER = {"accuracy_synthetic": 0.9, "accuracy_real": 0.8}


def _row(accuracy, synthetic=0.95, real=0.85, retrieval=0.9):
    return {
        "accuracy": accuracy,
        "accuracy_synthetic": synthetic,
        "accuracy_real": real,
        "retrieval": retrieval,
    }


def test_an_objective_must_beat_chamfer_on_both_halves_and_keep_retrieval():
    assert admissible(_row(0.9), CHAMFER)
    assert not admissible(_row(0.9, real=0.8), CHAMFER)
    assert not admissible(_row(0.9, retrieval=0.8), CHAMFER)
    rows = {
        BASELINE: _row(0.99),
        "a": _row(0.97, retrieval=0.5),
        "b": _row(0.93),
        "c": _row(0.92),
    }
    assert choose_objective(rows, CHAMFER) == "b"  # the baseline is a row, not a candidate
    assert choose_objective({BASELINE: _row(0.99), "a": _row(0.97, retrieval=0.5)}, CHAMFER) == "a"


def test_the_smallest_net_within_a_point_of_the_best_admissible_one_ships():
    rows = {1.0: _row(0.95), 0.5: _row(0.945), 0.25: _row(0.99, retrieval=0.1)}
    widths = {w: w for w in rows}
    assert choose_smallest(rows, widths, CHAMFER) == 0.5
    assert choose_smallest({1.0: _row(0.95), 0.5: _row(0.93)}, widths, CHAMFER) == 1.0
    # nothing admissible: the best accuracy decides
    low = {w: _row(0.9, retrieval=0.5) for w in rows} | {1.0: _row(0.95, retrieval=0.5)}
    assert choose_smallest(low, widths, CHAMFER) == 1.0


@pytest.mark.parametrize("objective", list(OBJECTIVES))
def test_one_step_of_each_objective_has_a_gradient_for_both_nets(views, objective):
    torch.manual_seed(0)
    metric = DRKFS(CONFIG.replace(descriptor_width=0.25))
    metric.detector.requires_grad_(True)
    metric.descriptor.requires_grad_(True)
    rows = torch.arange(130)
    centres = 20 + rows % 20  # patches and their jittered partners stay inside the 64 px maps
    matches = torch.stack([rows % 2, centres, centres, centres + 1, centres], 1)
    pairs = Correspondences(torch.rand(2, 2, 64, 64), matches)
    loss = OBJECTIVES[objective](views, 0, pairs)(metric, 0)
    loss.backward()
    assert torch.isfinite(loss) and loss > 0
    for net in (metric.detector, metric.descriptor):
        assert any(p.grad is not None and p.grad.abs().sum() > 0 for p in net.parameters())


def test_an_edit_shows_only_where_it_changes_more_than_every_mild_edit_there():
    meshes = 1 + len(VARIANT_NAMES)
    changed = torch.zeros(1, meshes, 1, 3)
    mild, structural = VariantViews.sources()[0]
    changed[0, mild[0]] = torch.tensor([0.1, 0.0, 0.0])  # a silhouette a mild edit moved
    changed[0, structural[0]] = torch.tensor([0.12, 0.3, 0.0])
    changed[0, structural[1]] = torch.tensor([0.14, 0.0, 0.0])  # an edit no camera really sees
    views = VariantViews(torch.zeros(1, meshes, 1, 4, 4), changed, torch.zeros(1))
    shows = views.shows_edit()[0]
    assert shows[structural[0]].tolist() == [False, True, False]
    assert not shows[structural[1]].any() and not shows[mild].any()
