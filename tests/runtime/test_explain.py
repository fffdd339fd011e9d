"""Where a score comes from: per-patch distances, their shares of the score, and the torch
method a training loop logs them with."""

import json

import numpy as np
import pytest
import torch
from conftest import ROOT

from drkfs_onnx import PipelineConfig, load_mesh
from drkfs_onnx.contract import match_rules
from drkfs_onnx.contract.cameras import rotation
from drkfs_onnx.contract.mesh import Mesh
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.render.torch_ops import TORCH_OPS
from drkfs_onnx.runtime.explain import explain
from drkfs_onnx.runtime.match import pairing_part, pairing_solid
from drkfs_onnx.runtime.scorer import Scorer

EXAMPLES = ROOT / "examples"
CHANGED = 0.05  # a pixel the removed leg changes by more than this is where the leg was


@pytest.fixture(scope="module")
def no_leg():
    return explain(Scorer(threads=2), EXAMPLES / "chair_no_leg.obj", EXAMPLES / "chair.obj")


def test_the_top_patch_of_each_view_that_sees_the_missing_leg_lies_where_the_leg_was(no_leg):
    config, scorer = no_leg.config, Scorer(threads=2)
    # (K, S, S) where the leg was: B's views against A's from the same ring of cameras
    ring = slice(no_leg.rings["b"] * config.num_views, (no_leg.rings["b"] + 1) * config.num_views)
    frame = scorer.features(EXAMPLES / "chair.obj").frame
    no_leg_views = scorer.views(load_mesh(EXAMPLES / "chair_no_leg.obj"), frame)[ring]
    leg = np.abs(no_leg.views["b"] - no_leg_views) > CHANGED
    seeing = [view for view in range(config.num_views) if leg[view].sum() >= 20]
    assert len(seeing) >= 3
    side, size, stride = config.patches_per_side, config.patch_size, config.patch_stride

    def held(view: int, row: int, column: int) -> int:
        """How many of the leg's pixels the patch at (row, column) of ``view`` covers."""
        return leg[
            view, stride * row : stride * row + size, stride * column : stride * column + size
        ].sum()

    for view in seeing:
        # the reference's patches search the chair without the leg: the leg's patch finds none
        row, column = np.unravel_index(no_leg.shares["b"][view].argmax(), (side, side))
        most = max(held(view, r, c) for r in range(side) for c in range(side))
        # the leg spans several overlapping patches: the top one holds at least half as much
        # of it as the one that holds most (most patches of a view hold none)
        assert held(view, row, column) >= 0.5 * most, (view, row, column)
    assert no_leg.top_patches(1)[0]["view"] in seeing


def test_the_explained_rings_are_the_comparison_whose_score_counts(no_leg):
    scorer = Scorer(threads=2)
    b = scorer.features(EXAMPLES / "chair.obj")
    a = scorer.features(EXAMPLES / "chair_no_leg.obj", b.frame)
    config = scorer.config
    scores = {
        (i, j): pairing_part(a, b, i, j, config) + pairing_solid(a, b, i, j, config)
        for i, j in match_rules.ring_pairings(config)
    }
    assert len(scores) == 3 and no_leg.score == min(scores.values())
    assert scores[no_leg.rings["a"], no_leg.rings["b"]] == no_leg.score


def test_shares_and_the_solid_change_sum_to_the_score_and_zero_is_clear(no_leg):
    total = sum(float(s.sum()) for s in no_leg.shares.values())
    assert 0.0 < no_leg.solid_change < no_leg.score  # the missing leg changes a solid region
    assert total == pytest.approx(1.0 - no_leg.solid_change / no_leg.score)
    config = Scorer(threads=2).config
    # global matching reduces the rows in another order than explain's patches: still 0 exactly
    descriptors_alone = Scorer(config.replace(solid_weight=0.0, matching="global"), threads=2)
    alone = explain(descriptors_alone, EXAMPLES / "chair_no_leg.obj", EXAMPLES / "chair.obj")
    assert alone.solid_change == 0.0
    assert sum(float(s.sum()) for s in alone.shares.values()) == pytest.approx(1.0)
    same = explain(Scorer(threads=2), EXAMPLES / "chair.obj", EXAMPLES / "chair.obj")
    assert same.score == 0.0 and all(not s.any() for s in same.shares.values())


@pytest.mark.parametrize(
    "reduction", [{"reduction": r} for r in ("sum", "mean", "power", "softmax")]
    + [{"reduction": "tail", "tail_fraction": 0.3}],
)  # fmt: skip
def test_a_rows_share_is_its_distance_times_the_scores_slope(reduction):
    config = PipelineConfig(**reduction)
    rng = np.random.default_rng(0)
    distances = torch.tensor(rng.uniform(0.0, 1.0, 12), requires_grad=True)
    weights = torch.tensor(rng.integers(1, 4, 12).astype(np.float64))
    (slope,) = torch.autograd.grad(
        match_rules.reduce(distances, weights, config, TORCH_OPS), distances
    )
    expected = (slope * distances).detach().numpy()
    shares = match_rules.shares(distances.detach().numpy(), weights.numpy(), config)
    assert np.allclose(shares, expected / expected.sum())


def test_torch_patch_distances_are_the_runtimes(no_leg):
    metric = DRKFS.pretrained()
    pred, truth = (load_mesh(EXAMPLES / n) for n in ("chair_no_leg.obj", "chair.obj"))

    def tensors(mesh):
        return torch.tensor(mesh.vertices, dtype=torch.float32), torch.tensor(mesh.faces)

    with torch.no_grad():
        target = metric.target(*tensors(truth))
        found = metric.patch_distances(*tensors(pred), target)
    assert set(found) == {"a", "b"}
    for side, grid in found.items():
        config = metric.config
        assert grid.shape == (config.num_views, config.patches_per_side, config.patches_per_side)
        assert np.allclose(grid.numpy(), no_leg.distances[side], atol=2e-3)


def test_explain_out_names_the_picture_it_wrote_and_refuses_an_unknown_format(tmp_path):
    from typer.testing import CliRunner

    from drkfs_onnx.runtime.cli import app

    pair = [str(EXAMPLES / "chair_no_leg.obj"), str(EXAMPLES / "chair.obj")]
    result = CliRunner().invoke(app, ["explain", *pair, "--out", str(tmp_path / "ex"), "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["picture"] == str(tmp_path / "ex.png")
    assert (tmp_path / "ex.png").stat().st_size > 0
    refused = CliRunner().invoke(app, ["explain", *pair, "--out", str(tmp_path / "ex.foo")])
    assert refused.exit_code == 2 and "write a .png, .pdf, .svg picture" in refused.output


def test_explain_shows_the_views_the_score_compared_and_scores_as_the_scorer(no_leg):
    scorer = Scorer(threads=2)
    chair, leg = (load_mesh(EXAMPLES / n) for n in ("chair.obj", "chair_no_leg.obj"))
    frame = scorer.features(chair).frame
    k = no_leg.config.num_views
    for side, mesh in (("a", leg), ("b", chair)):
        ring = no_leg.rings[side]
        rendered = scorer.views(mesh, frame)[ring * k : (ring + 1) * k]
        np.testing.assert_array_equal(no_leg.views[side], rendered)
    assert no_leg.score == scorer.score(leg, chair)


def test_the_top_patches_list_each_spot_once_and_none_where_nothing_differs(no_leg):
    top = no_leg.top_patches(10)
    spots = [(p["view"], p["row"], p["column"]) for p in top]
    assert len(set(spots)) == len(spots) == 10
    assert [p["share"] for p in top] == sorted((p["share"] for p in top), reverse=True)
    for patch, spot in zip(top, spots, strict=True):
        # a spot's share is both meshes' patches there; its mesh the one that carries more
        shares = {side: float(no_leg.shares[side][spot]) for side in patch["sides"]}
        assert patch["share"] == pytest.approx(sum(shares.values()))
        assert patch["mesh"] == max(shares, key=shares.get)
    same = explain(Scorer(threads=2), EXAMPLES / "chair.obj", EXAMPLES / "chair.obj")
    assert same.top_patches() == []


def test_the_picture_shows_each_meshs_plain_views_above_where_it_differs(no_leg):
    pytest.importorskip("matplotlib")
    from drkfs_onnx.runtime.explain_plot import explanation_figure

    figure = explanation_figure(no_leg, top=3)
    k = no_leg.config.num_views
    axes = [a for a in figure.axes if a.images]  # the colour bar draws no image
    assert len(axes) == 4 * k
    for row, side in ((0, "a"), (2, "b")):
        for view in range(k):
            plain, overlaid = axes[row * k + view], axes[(row + 1) * k + view]
            assert len(plain.images) == 1 and not plain.patches  # the render alone
            np.testing.assert_array_equal(plain.images[0].get_array(), no_leg.views[side][view])
            assert len(overlaid.images) == 2  # the render, and the distances over it
    outlines = sum(len(a.patches) for a in axes)
    assert outlines == sum(len(p["sides"]) for p in no_leg.top_patches(3))


def test_explain_under_a_turning_version_explains_the_mesh_as_the_score_turns_it():
    turning = Scorer(metric="drkfs-1.2", threads=2)
    chair = load_mesh(EXAMPLES / "chair.obj")
    centre = (chair.vertices.max(0) + chair.vertices.min(0)) / 2
    tilted = Mesh((chair.vertices - centre) @ rotation(0, 2.0).T + centre, chair.faces, "tilted")
    explained = explain(turning, tilted, chair)
    assert explained.score == pytest.approx(turning.score(tilted, chair), rel=1e-12)
    assert explained.score < 0.2 * Scorer(metric="drkfs-1.1", threads=2).score(tilted, chair)
