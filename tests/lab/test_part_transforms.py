"""bench/part_transforms.py: a transform of the descriptors' part scored offline as the runtime
scores it, which misorderings no transform can mend, and the rule's candidates."""

from types import SimpleNamespace

import numpy as np
import pytest

from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract.config import TWO_SIDED


@pytest.fixture(scope="module")
def study():
    from drkfs_lab import part_transforms

    return part_transforms


def test_the_records_are_the_default_before_its_window_with_parts_in_full(study):
    config = study.recorded_config()
    assert (config.moderate_slope, config.moderate_from, config.moderate_to) == (1.0, 0.0, 0.0)
    window = {"moderate_slope": 0.6, "moderate_from": 0.04, "moderate_to": 0.18}
    # the default but for its window, its light (openings seen dark since) and no turn (drkfs-1.2)
    assert config.replace(**window) == PipelineConfig(align_degrees=0.0, **TWO_SIDED)


def test_the_offline_score_is_the_least_pairing_of_transformed_part_plus_weighted_term(study):
    parts = np.array([[[0.2, 0.01], [0.05, 0.3], [0.1, 0.2]]])  # one comparison, 3 pairings
    assert study.scored(parts, lambda p: p) == pytest.approx([0.21])
    assert study.scored(parts, lambda p: p**2) == pytest.approx([0.05])  # 0.04 + 0.01
    assert study.scored(parts, lambda p: p, weight=0.1) == pytest.approx([0.08])  # 0.05 + 0.03


def test_a_variant_no_larger_in_part_and_term_at_some_pairing_cannot_be_ordered_above(study):
    lower = np.array([[0.05, 0.01], [0.2, 0.006]])  # a surface variant's two pairings
    hole = np.array([[0.01, 0.005], [0.3, 0.5]])  # its first pairing under both of lower's
    assert study.dominated(lower, hole)
    rng = np.random.default_rng(0)
    for _ in range(20):  # under any non-decreasing transform and weight it scores no higher
        power, weight = rng.uniform(0.3, 3.0), rng.uniform(0.0, 10.0)
        pair = np.stack([lower, hole])
        low, high = study.scored(pair, lambda p, q=power: p**q, weight)
        assert high <= low
    tip = np.array([[0.01, 0.2], [0.3, 0.5]])  # a larger term at every pairing: orderable
    assert not study.dominated(lower, tip)
    low, high = study.scored(np.stack([lower, tip]), lambda p: p, 10.0)
    assert high > low


def _bench(*rows):
    """A bench of (group, base, kind, label) comparisons."""
    comparisons = [SimpleNamespace(group=g, base=b, kind=k, label=label) for g, b, k, label in rows]
    return SimpleNamespace(comparisons=comparisons)


def test_misordered_names_each_pair_of_one_base_scored_the_wrong_way(study):
    bench = _bench(
        ("tiers", "sofa", "invisible", "thickened"),
        ("tiers", "sofa", "surface", "noise"),
        ("tiers", "sofa", "structural", "removed"),
        ("tiers", "cup", "surface", "noise"),
    )
    values = {0: 0.26, 1: 0.25, 2: 0.9, 3: 0.0}
    assert study.misordered(bench, values, "tiers") == {("sofa", "thickened", "noise")}


def test_unorderable_counts_a_sides_pairs_and_names_those_no_transform_mends(study):
    bench = _bench(("real", "real-cow", "surface", "noise"),
                   ("real", "real-cow", "structural", "hole_cut"),
                   ("real", "real-cow", "structural", "tip_removed"),
                   ("real", "real-stanford-bunny", "surface", "noise"),
                   ("real", "real-stanford-bunny", "structural", "hole_cut"))  # fmt: skip
    parts = np.array([
        [[0.09, 0.005]],  # the cow's noise
        [[0.01, 0.0]],  # its hole: a smaller part and term, unorderable
        [[0.02, 0.1]],  # its tip: a larger term, orderable
        [[0.05, 0.0]],  # the bunny's noise
        [[0.06, 0.01]],  # its hole: larger in both, orderable
    ])  # fmt: skip
    recorded = {"comparisons": ([0, 1, 2, 3, 4], parts)}
    result = study.unorderable(bench, recorded)
    cow = result["training"]["surface_vs_structural"]
    assert cow == {"pairs": 2, "unorderable": ["cow: hole_cut <= noise"], "best_share": 0.5}
    assert result["held_out"]["surface_vs_structural"]["unorderable"] == []
    assert result["held_out"]["invisible_vs_structural"]["pairs"] == 0


def _row(**changes) -> dict:
    """A row that keeps every target, with ``changes`` made to it."""
    row = {
        "synthetic_lost": [],
        "real": {"training": {"invisible_vs_surface": 1.0}},
        "checks": {"training": {"turn": {"share": 1.0}, "salient": {"share": 1.0}}},
        "slide": {"max_over_mean_step": 2.9},
        "bars": {"deletion_over_max_shift": 1.7},
        "retrieval": {"nearest_neighbour_accuracy": 0.84},
        "human": {"close_flipped": -0.63, "far_normal": -0.433},
    }
    return row | changes


def test_a_candidate_keeps_every_synthetic_pair_check_and_target_the_default_keeps(study):
    default = _row()
    assert study.candidate(_row(), default)
    assert not study.candidate(_row(synthetic_lost=[("sofa", "part_thickened", "noise")]), default)
    assert not study.candidate(_row(slide={"max_over_mean_step": 3.0002}), default)
    assert not study.candidate(_row(bars={"deletion_over_max_shift": 1.59}), default)
    assert not study.candidate(_row(retrieval={"nearest_neighbour_accuracy": 0.829}), default)
    assert not study.candidate(_row(human={"close_flipped": -0.63, "far_normal": -0.42}), default)
    checks = {"training": {"turn": {"share": 0.8}, "salient": {"share": 1.0}}}
    assert not study.candidate(_row(checks=checks), default)
    real = {"training": {"invisible_vs_surface": 0.96}}
    assert not study.candidate(_row(real=real), default)
