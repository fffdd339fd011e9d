"""The match contract: which patches may match, how best matches reduce to a score, and that the
torch path and the runtime compute the same number from the same descriptors."""

import numpy as np
import pytest
import torch

from drkfs_onnx.contract import match_rules
from drkfs_onnx.contract.array_ops import NUMPY_OPS
from drkfs_onnx.contract.config import DIRECTIONS, FULL_PARTS, ONE_REACH, PipelineConfig
from drkfs_onnx.contract.solid_change import view_solid_changes
from drkfs_onnx.match import (
    best_match_distances,
    descriptor_score,
    match_score,
    nearest_indices,
)
from drkfs_onnx.render.torch_ops import TORCH_OPS
from drkfs_onnx.runtime.features import MeshFeatures
from drkfs_onnx.runtime.match import descriptor_part, match, solid_views

# one ring, 5 x 5 patches a view, the descriptors' match alone (test_solid_change: the views'),
# a solid change, where a test adds one, at one reach of 2 everywhere
AT_2 = {"solid_shift": 2, **ONE_REACH}
GRID = PipelineConfig(num_views=3, turn_degrees=0.0, image_size=96, solid_weight=0.0, **AT_2)
# the default's: a ramp over reaches 2 and 3, 1 and 2 inside the mesh, raised to 1.5 there
RAMP = {name: PipelineConfig().to_dict()[name] for name in AT_2}
REDUCTIONS = [
    {"reduction": "sum"},
    {"reduction": "mean"},
    {"reduction": "tail", "tail_fraction": 0.07},
    {"reduction": "power", "power": 4.0},
    {"reduction": "softmax", "temperature": 0.05},
]


def test_window_table_holds_exactly_the_patches_within_r_steps_of_the_same_view():
    config = GRID.replace(matching="window", window=1)
    side, per_view = config.patches_per_side, config.patches_per_view
    table = match_rules.window_table(config)
    assert table.shape == (3 * per_view, 9)
    for index, near in enumerate(table):
        view, cell = divmod(index, per_view)
        row, col = divmod(cell, side)
        expected = {
            view * per_view + r * side + c
            for r in range(row - 1, row + 2)
            for c in range(col - 1, col + 2)
            if 0 <= r < side and 0 <= c < side
        }
        assert set(near.tolist()) == expected
    assert (match_rules.window_table(config.replace(window=0)) == np.arange(75)[:, None]).all()


def _expanded_tail(distances, weights, fraction):
    """The tail's definition on one row per patch: the mean of the k largest, k = q * patches."""
    rows = np.repeat(distances, weights.astype(int))
    k = max(fraction * len(rows), 1.0)
    ranked = np.sort(rows)[::-1]
    whole = int(np.floor(k))
    return (ranked[:whole].sum() + (k - whole) * ranked[min(whole, len(rows) - 1)]) / k


@pytest.mark.parametrize("fraction", [0.01, 0.1, 0.35, 1.0])
def test_tail_of_weighted_rows_equals_the_tail_of_one_row_per_patch(fraction):
    rng = np.random.default_rng(0)
    distances, weights = rng.random(40), rng.integers(1, 6, 40).astype(float)
    config = GRID.replace(reduction="tail", tail_fraction=fraction)
    expected = _expanded_tail(distances, weights, fraction)
    assert match_rules.reduce(distances, weights, config) == pytest.approx(expected, rel=1e-12)
    if fraction == 1.0:
        assert expected == pytest.approx(np.average(distances, weights=weights), rel=1e-12)


def test_power_and_softmax_follow_their_formulas_and_tend_to_the_maximum():
    rng = np.random.default_rng(1)
    distances, weights = rng.random(30), rng.integers(1, 4, 30).astype(float)
    power = GRID.replace(reduction="power", power=3.0)
    expected = (np.average(distances**3, weights=weights)) ** (1 / 3)
    assert match_rules.reduce(distances, weights, power) == pytest.approx(expected, rel=1e-12)
    soft = GRID.replace(reduction="softmax", temperature=0.2)
    expected = 0.2 * np.log(np.average(np.exp(distances / 0.2), weights=weights))
    assert match_rules.reduce(distances, weights, soft) == pytest.approx(expected, rel=1e-12)
    sharp = GRID.replace(reduction="softmax", temperature=1e-4)
    assert match_rules.reduce(distances, weights, sharp) == pytest.approx(distances.max(), abs=1e-3)


@pytest.mark.parametrize("options", REDUCTIONS)
def test_every_reduction_is_exactly_zero_on_zero_distances_with_finite_gradients(options):
    config = GRID.replace(**options)
    zeros = torch.zeros(20, dtype=torch.float64, requires_grad=True)
    value = match_rules.reduce(zeros, torch.ones(20, dtype=torch.float64), config, TORCH_OPS)
    value.backward()
    assert value.item() == 0.0
    assert torch.isfinite(zeros.grad).all()


def _features(
    dense: np.ndarray, empty: np.ndarray, config: PipelineConfig, views: np.ndarray | None = None
) -> MeshFeatures:
    seen = np.flatnonzero((dense != empty).any(1))
    return MeshFeatures(
        descriptors=dense[seen],
        patch_index=seen,
        empty_descriptor=empty,
        centre=np.zeros(3),
        scale=1.0,
        normalization="joint",
        model="test",
        config=config,
        views=views,
    )


def _near_tie_sets():
    """Two descriptor sets of every patch of GRID: background rows share one descriptor, and
    each of B's rows has a rival at a distance within 1e-6 of its best match."""
    rng = np.random.default_rng(2)
    rows, dim = GRID.num_views * GRID.patches_per_view, 16
    empty = np.full(dim, 0.25, np.float32)
    a = rng.normal(size=(rows, dim)).astype(np.float32)
    b = a + rng.normal(scale=0.05, size=(rows, dim)).astype(np.float32)
    # near ties: B's odd row mirrors its even neighbour through A's even row (its grid
    # neighbour too), so that row of A has two best matches within float rounding
    even = np.arange(0, rows - 1, 2)
    b[even + 1] = 2 * a[even] - b[even] + rng.normal(scale=1e-7, size=(len(even), dim))
    for dense in (a, b):
        dense[rng.random(rows) < 0.3] = empty
    b[:10] = a[:10]  # exact copies match at 0
    return a, b, empty


@pytest.mark.parametrize("options", REDUCTIONS)
@pytest.mark.parametrize("matching", [{"matching": "global"}, {"matching": "window", "window": 1}])
@pytest.mark.parametrize("direction", DIRECTIONS)
def test_torch_and_runtime_compute_the_same_score(options, matching, direction):
    config = GRID.replace(**options, **matching, direction=direction)
    a, b, empty = _near_tie_sets()
    expected = float(match_score(torch.from_numpy(a), torch.from_numpy(b), config))
    got = match(_features(a, empty, config), _features(b, empty, config), config)
    assert got == pytest.approx(expected, rel=1e-5)


def _shaded_views(config: PipelineConfig) -> np.ndarray:
    """(K * T, 96, 96) views of a smoothly shaded square on background, as a mesh's."""
    views = np.zeros((config.views_per_mesh, 96, 96), np.float32)
    views[:, 20:70, 30:80] = np.linspace(0.3, 0.6, 50, dtype=np.float32)
    return views


@pytest.mark.parametrize("solid", [AT_2, RAMP], ids=["one reach", "ramp"])
@pytest.mark.parametrize(("turn", "hole"), [(0.0, 0.3), (2.5, 0.1)])
def test_a_solid_change_adds_the_same_term_to_torch_and_runtime_scores(turn, hole, solid):
    """B holds a hole of 0.3 in its own ring's views and of 0.1 in its turned ring's: with one
    ring the term sees the first, with two the least pairing, A's own ring against B's turned
    one, the second (its descriptors tie with the others'). Inside the mesh the change is
    raised to the config's power."""
    config = GRID.replace(turn_degrees=turn, solid_weight=0.5, **solid)
    rings = len(config.rings)
    a, b, empty = _near_tie_sets()
    a, b = np.concatenate([a] * rings), np.concatenate([b] * rings)
    views_a = _shaded_views(config)
    views_b = views_a.copy()
    views_b[: config.num_views, 40:50, 40:50] += 0.3
    views_b[config.num_views :, 40:50, 40:50] += 0.1
    torch_score = match_score(
        torch.from_numpy(a), torch.from_numpy(b), config, None, None,
        torch.from_numpy(views_a), torch.from_numpy(views_b),
    )  # fmt: skip
    fa, fb = _features(a, empty, config, views_a), _features(b, empty, config, views_b)
    runtime = match(fa, fb, config)
    descriptors = match(fa, fb, config.replace(solid_weight=0.0))
    torch_descriptors = match_score(torch.from_numpy(a), torch.from_numpy(b), config.replace(
        solid_weight=0.0))  # fmt: skip
    # the solid part: 0.5 x the hole's change in each view, less the shading's slope within the
    # reach; torch's to its float32 rounding of a descriptor part of 54
    part, torch_part = runtime - descriptors, float(torch_score - torch_descriptors)
    power = config.solid_inner_power
    assert part == pytest.approx(torch_part, abs=2e-5)
    assert 0.5 * (hole - 0.02) ** power < part <= 0.5 * hole**power + 1e-6
    with pytest.raises(ValueError, match="features without their views"):
        match(_features(a, empty, config), _features(b, empty, config), config)


@pytest.mark.parametrize("solid", [AT_2, RAMP], ids=["one reach", "ramp"])
def test_the_runtimes_window_and_skipped_pairings_give_the_whole_computations_score(
    monkeypatch, solid
):
    """The runtime computes the solid change only where either mesh shows anything, and skips a
    ring pairing whose descriptors alone score the best total so far: neither moves a bit."""
    import drkfs_onnx.runtime.match as runtime_match

    config = GRID.replace(turn_degrees=2.5, solid_weight=0.5, **solid)
    one = config.one_ring()
    a, b, empty = _near_tie_sets()
    far = b + np.float32(0.3)  # B's turned ring: its descriptors far from A's
    a, b = np.concatenate([a, a]), np.concatenate([b, far])
    views_a = _shaded_views(config)
    views_b = views_a.copy()
    views_b[:, 18:22, 28:40] = 0.8  # a solid change at the edge of what A shows
    views_b[4, 60:66, 60:66] = 0.0  # and a hole in the own ring
    fa, fb = _features(a, empty, config, views_a), _features(b, empty, config, views_b)
    pairings = match_rules.ring_pairings(config)

    def whole(i: int, j: int) -> np.ndarray:  # each view's solid change over the whole views
        return view_solid_changes(fa.ring(i).views, fb.ring(j).views, one, NUMPY_OPS)

    for i, j in [*pairings, (1, 1)]:
        assert np.array_equal(solid_views(fa.ring(i), fb.ring(j), one), whole(i, j))
        assert whole(i, j).max() > 0
    every_pairing = min(
        match_rules.pairing_part(
            i, j, lambda k, m: descriptor_part(fa.ring(k), fb.ring(m), one), config
        )
        + float(match_rules.pairing_solid(i, j, whole, config, NUMPY_OPS))
        for i, j in pairings
    )
    calls = []
    counted = runtime_match.solid_views
    monkeypatch.setattr(
        runtime_match, "solid_views", lambda *args: calls.append(1) or counted(*args)
    )
    assert match(fa, fb, config) == every_pairing
    # a pairing far on its descriptors was never computed: the own-ring pairing's two rings
    # and at most one turned pairing
    assert len(calls) < len(pairings) + 1


def test_the_own_ring_pairing_sees_a_change_only_the_turned_rings_cameras_show():
    """A change only the turned ring's cameras show (a sliver at an edge the own ring misses)
    counts in the own-ring pairing where ``solid_both_rings``, each camera's larger change of
    its two rings, the same in torch and the runtime; with the own ring alone it does not. The
    rings' descriptors differ, so the turned pairings score far above the own one."""
    config = GRID.replace(turn_degrees=2.5, solid_weight=0.5, **RAMP)
    a, _, empty = _near_tie_sets()
    other = np.random.default_rng(3).normal(size=a.shape).astype(np.float32)
    sets = np.concatenate([a, other])
    views_a = _shaded_views(config)
    views_b = views_a.copy()
    views_b[config.num_views :, 40:50, 40:50] += 0.3  # the turned ring's views only
    scores = {}
    for both in (False, True):
        asked = config.replace(solid_both_rings=both)
        fa, fb = _features(sets, empty, asked, views_a), _features(sets, empty, asked, views_b)
        scores[both] = match(fa, fb, asked)
        torch_score = match_score(
            torch.from_numpy(sets), torch.from_numpy(sets), asked, None, None,
            torch.from_numpy(views_a), torch.from_numpy(views_b),
        )  # fmt: skip
        assert scores[both] == pytest.approx(float(torch_score), abs=2e-5)
    power = config.solid_inner_power
    assert scores[False] == 0.0
    assert 0.5 * 0.28**power < scores[True] <= 0.5 * 0.3**power + 1e-6


def test_a_window_narrower_than_a_block_changes_nothing():
    """Where the meshes show only a line, or only the views' outer rows, no block changes as a
    whole: the runtime's window says 0, as the whole views do, instead of failing."""
    for shift, rows in ((0, slice(40, 41)), (2, slice(0, 1)), (1, slice(0, 2))):
        config = GRID.replace(solid_weight=1.0, solid_shift=shift)
        views_a = np.zeros((config.views_per_mesh, 96, 96), np.float32)
        views_a[:, rows, 10:80] = 0.5
        views_b = views_a.copy()
        views_b[:, rows, 10:80] = 0.9
        a, _, empty = _near_tie_sets()
        fa, fb = _features(a, empty, config, views_a), _features(a, empty, config, views_b)
        whole = view_solid_changes(views_a, views_b, config, NUMPY_OPS)
        assert np.array_equal(solid_views(fa, fb, config), whole)
        assert not whole.any()


def test_one_described_mesh_serves_every_solid_change_setting():
    """A mesh's features serve every match setting (MATCH_FIELDS), the solid change's reach
    included: each reach's view ranges are its own, not those of the first reach asked."""
    config = GRID.replace(solid_weight=1.0)
    a, b, empty = _near_tie_sets()
    ramp = np.linspace(0.0, 1.0, 96, dtype=np.float32)  # a grey ramp along x, in every view
    views_a = np.broadcast_to(ramp, (config.views_per_mesh, 96, 96)).copy()
    views_b = np.roll(views_a, 2, axis=-1)  # a shift of 2 pixels: seen at reach 1, not at 2
    shared = _features(a, empty, config, views_a), _features(b, empty, config, views_b)
    for solid in ({"solid_shift": 1}, {"solid_shift": 2}, RAMP, {"solid_shift": 1}):
        asked = config.replace(**solid)
        fresh = _features(a, empty, config, views_a), _features(b, empty, config, views_b)
        assert match(*shared, asked) == match(*fresh, asked)
    reach_1, reach_2 = (match(*shared, config.replace(solid_shift=s)) for s in (1, 2))
    assert reach_1 > reach_2


@pytest.mark.parametrize("matching", ["global", "window"])
def test_both_directions_make_the_score_order_free_and_zero_on_copies(matching):
    config = GRID.replace(matching=matching, direction="both", reduction="tail")
    a, b, empty = _near_tie_sets()
    fa, fb = _features(a, empty, config), _features(b, empty, config)
    assert match(fa, fb, config) == match(fb, fa, config)
    assert match(fa, _features(a.copy(), empty, config), config) == 0.0


def test_window_matching_sees_a_patch_that_moved_where_global_matching_finds_it_elsewhere():
    a, _, empty = _near_tie_sets()
    b = a.copy()
    b[[7, 60]] = a[[60, 7]]  # two patches of different views swap: the same descriptors
    glob = GRID.replace(matching="global", reduction="sum")
    window = glob.replace(matching="window", window=1)
    fa, fb = _features(a, empty, glob), _features(b, empty, glob)
    assert match(fa, fb, glob) == 0.0
    assert match(fa, fb, window) > 0.0


def test_global_matching_sees_a_part_missing_from_a_only_backward_window_both_ways():
    """Globally, A's background patches find B's background elsewhere (forward 0); only B's
    patches of the part search A in vain (backward). Position-wise, A's background where B has
    the part is a mismatch too."""
    a, _, empty = _near_tie_sets()
    config = GRID.replace(matching="global", reduction="sum")
    without = a.copy()
    without[20:25] = empty  # a part that B shows and A lacks
    fa, fb = _features(without, empty, config), _features(a, empty, config)
    assert match(fa, fb, config.replace(direction="forward")) == 0.0
    assert match(fa, fb, config.replace(direction="backward")) > 0.0
    window = config.replace(matching="window", window=0)
    assert min(match(fa, fb, window.replace(direction=d)) for d in DIRECTIONS) > 0.0


@pytest.mark.parametrize("matching", ["global", "window"])
def test_a_turned_ring_counts_the_least_of_own_against_own_and_own_against_turned(matching):
    rings = GRID.replace(turn_degrees=2.0, matching=matching, **FULL_PARTS)  # parts in full
    a, b, empty = _near_tie_sets()
    other = np.random.default_rng(3).normal(size=a.shape).astype(np.float32)  # far from both

    def score(a_rings, b_rings):
        fa = _features(np.concatenate(a_rings), empty, rings)
        fb = _features(np.concatenate(b_rings), empty, rings)
        expected = float(match_score(torch.from_numpy(fa.dense), torch.from_numpy(fb.dense), rings))
        assert match(fa, fb, rings) == pytest.approx(expected, rel=1e-5)  # torch = runtime
        return expected

    one_ring = match(_features(a, empty, GRID), _features(b, empty, GRID), GRID.replace(
        matching=matching, **FULL_PARTS))  # fmt: skip
    # own vs own: the turned ring's own comparison (other against other, 0) has its share
    share = rings.turned_part_share
    assert score([a, other], [b, other]) == pytest.approx((1 - share) * one_ring, rel=1e-6)
    assert score([a, other], [other, a]) == 0.0  # A's own ring is B's turned ring
    assert score([other, b], [b, other]) == 0.0  # and the other way round
    # both turned is no turn between them: that pairing is not searched
    assert score([other, a], [b[:, ::-1].copy(), a]) > 0.0


def test_a_moderated_part_counts_at_the_slope_inside_its_window_and_in_full_outside():
    parts = np.array([0.005, 0.04, 0.1, 0.18, 0.2, 0.5])
    out = match_rules.moderated_part(parts, 0.6, 0.04, 0.18)
    assert out[:2] == pytest.approx([0.005, 0.04])  # in full below the window
    assert out[2] == pytest.approx(0.04 + 0.6 * 0.06)  # at the slope inside
    assert out[5] - out[4] == pytest.approx(0.3)  # above it, differences kept
    tensor = match_rules.moderated_part(torch.from_numpy(parts), 0.6, 0.04, 0.18, TORCH_OPS)
    assert tensor.numpy() == pytest.approx(out)
    assert match_rules.moderated_part(0.1, 1.0, 0.04, 0.18) == 0.1  # slope 1: no window


def test_the_window_reads_the_own_ring_pairings_blend_and_passes_gradients_at_its_slope():
    a, b, empty = _near_tie_sets()
    other = np.random.default_rng(3).normal(size=a.shape).astype(np.float32)
    rings = GRID.replace(turn_degrees=2.0, **FULL_PARTS)
    fa = _features(np.concatenate([a, other]), empty, rings)
    fb = _features(np.concatenate([b, other]), empty, rings)
    blended = match(fa, fb, rings)  # (1 - share) of A's own ring against B's, in full
    low, high = blended / 2, 2 * blended
    windowed = rings.replace(moderate_slope=0.5, moderate_from=low, moderate_to=high)
    assert match(fa, fb, windowed) == pytest.approx(low + 0.5 * (blended - low), rel=1e-6)
    # the torch path's gradient inside the window is the slope's share of the part's
    dense_a = torch.from_numpy(fa.dense).requires_grad_(True)
    match_score(dense_a, torch.from_numpy(fb.dense), windowed).backward()
    inside = dense_a.grad.clone()
    dense_a.grad = None
    match_score(dense_a, torch.from_numpy(fb.dense), rings).backward()
    assert torch.allclose(inside, 0.5 * dense_a.grad, rtol=1e-4, atol=1e-8)


def test_the_nets_train_on_the_descriptors_part_in_full():
    a, b, empty = _near_tie_sets()
    full = GRID.replace(**FULL_PARTS)
    dense_a, dense_b = (torch.from_numpy(_features(x, empty, full).dense) for x in (a, b))
    part = float(match_score(dense_a, dense_b, full))
    windowed = full.replace(moderate_slope=0.5, moderate_from=part / 4, moderate_to=2 * part)
    assert float(descriptor_score(dense_a, dense_b, windowed)) == pytest.approx(part)
    assert float(match_score(dense_a, dense_b, windowed)) < part


def test_a_moderate_descriptor_part_counts_at_the_windows_slope_on_both_paths():
    a, b, empty = _near_tie_sets()
    full = GRID.replace(**FULL_PARTS)
    fa, fb = _features(a, empty, full), _features(b, empty, full)
    part = match(fa, fb, full)

    def windowed(slope: float, low: float, high: float) -> float:
        config = full.replace(moderate_slope=slope, moderate_from=low, moderate_to=high)
        score = match(fa, fb, config)
        dense = match_score(torch.from_numpy(fa.dense), torch.from_numpy(fb.dense), config)
        assert score == pytest.approx(float(dense), rel=1e-5)  # torch = runtime
        return score

    # inside the window: in full up to its start, at the slope above it
    assert windowed(0.5, part / 4, 2 * part) == pytest.approx(part / 4 + 0.5 * 0.75 * part)
    # above it: the window's width counts at the slope, the rest in full
    assert windowed(0.5, part / 4, part / 2) == pytest.approx(part - 0.5 * part / 4)
    assert windowed(0.5, 2 * part, 3 * part) == pytest.approx(part)  # below it: in full
    assert windowed(1.0, part / 4, 2 * part) == pytest.approx(part)  # slope 1: no window


def test_runtime_refuses_features_of_another_config_or_graph():
    a, b, empty = _near_tie_sets()
    fa = _features(a, empty, GRID)
    other_size = _features(b, empty, GRID.replace(image_size=128))
    with pytest.raises(ValueError, match="image_size 128 \\(asked 96\\)"):
        match(fa, other_size, GRID)
    other_graph = MeshFeatures(**{**vars(_features(b, empty, GRID)), "model": "other"})
    with pytest.raises(ValueError, match="different feature graphs"):
        match(fa, other_graph, GRID)


def test_config_checks_match_settings_and_keeps_the_paper_preset():
    paper = PipelineConfig.paper()
    assert (paper.num_views, paper.image_size) == (25, 256)
    assert (paper.matching, paper.direction, paper.reduction) == ("global", "forward", "sum")
    assert paper.shaping("features") == PipelineConfig.paper(reduction="tail").shaping("features")
    bad = [{"matching": "nearest"}, {"direction": "up"}, {"reduction": "max"}, {"window": -1},
           {"tail_fraction": 0.0}, {"power": 0.5}, {"temperature": 0.0}]  # fmt: skip
    for settings in bad:
        with pytest.raises(ValueError):
            PipelineConfig(**settings)


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
