"""bench/real_levers.py's recombinations: the netted outline change (a part moved is lost at one
place and gained at another, so the two nearly cancel; a part removed is only lost), and the
own-ring pairing's solid change taken over both rings' views."""

from types import SimpleNamespace

import numpy as np
import pytest

from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract.config import FULL_PARTS
from drkfs_onnx.contract.solid_change import solid_reaches


@pytest.fixture(scope="module")
def real_levers():
    from drkfs_lab import real_levers

    return real_levers


def _views(*bars: tuple[int, int]) -> np.ndarray:
    """(1, 48, 48): a grey body and 6-px bars at the (row, column) corners given."""
    view = np.zeros((1, 48, 48))
    view[0, 30:44, 8:40] = 0.5
    for row, col in bars:
        view[0, row : row + 6, col : col + 6] = 0.8
    return view


def _peaks(real_levers, views_a, views_b):
    config = PipelineConfig(image_size=48)
    inside, outline = solid_reaches(config)
    change = real_levers.pixel_changes(views_a, views_b, config, inside, outline, 1.5)
    held = real_levers.moves_change(views_a, views_b, change, config)
    return [float(h.max()) for h in held]  # inner, lost, gained


def test_a_removed_part_is_lost_and_not_gained(real_levers):
    inner, lost, gained = _peaks(real_levers, _views((10, 10)), _views())
    assert lost == pytest.approx(0.8) and gained == 0.0 and inner == 0.0


def test_a_moved_part_is_lost_and_gained_alike(real_levers):
    inner, lost, gained = _peaks(real_levers, _views((10, 10)), _views((10, 30)))
    assert lost == pytest.approx(0.8) and gained == pytest.approx(0.8) and inner == 0.0


def test_a_shift_within_the_reach_changes_nothing(real_levers):
    assert _peaks(real_levers, _views((10, 10)), _views((10, 12))) == [0.0, 0.0, 0.0]


class _Rings:
    """Features whose ring ``i`` is ``i``: the stub descriptor part below reads the pairing."""

    def ring(self, i: int) -> int:
        return i


def _recombined_score(
    real_levers, monkeypatch, both_rings: str | None, both_parts=0.0, **options
) -> float:
    """A, whose turned ring alone shows a bar, against B, which shows none: each ring pairing's
    descriptor part 1 across rings (a turn the mesh does not have), 0 for ring 0 against ring
    0 and 0.2 for ring 1 against ring 1; the solid change at weight 1."""
    config = PipelineConfig(  # a recombined lever turns no mesh onto another
        image_size=48,
        num_views=1,
        turn_degrees=2.5,
        solid_weight=1.0,
        align_degrees=0.0,
        **FULL_PARTS,
    )
    parts = {(0, 0): 0.0, (1, 1): 0.2, (0, 1): 1.0, (1, 0): 1.0}
    monkeypatch.setattr(real_levers, "descriptor_part", lambda a, b, _: parts[a, b])
    method = SimpleNamespace(scorer=SimpleNamespace(config=config), symmetric=True)
    lever = real_levers.Recombined(
        method, "lever", 1, both_rings=both_rings, both_parts=both_parts, **options
    )
    a = (_Rings(), np.concatenate([_views(), _views((10, 10))]))
    b = (_Rings(), np.concatenate([_views(), _views()]))
    return lever.compare(a, b)[0]


def test_a_change_only_the_turned_ring_shows_counts_with_both_rings(real_levers, monkeypatch):
    assert _recombined_score(real_levers, monkeypatch, None) == 0.0
    # each camera's larger change of its two rings: the bar's 0.8; the views' mean: half of it
    assert _recombined_score(real_levers, monkeypatch, "max") == pytest.approx(0.8)
    assert _recombined_score(real_levers, monkeypatch, "mean") == pytest.approx(0.4)


def test_both_parts_weighs_the_turned_rings_own_descriptor_part(real_levers, monkeypatch):
    assert _recombined_score(real_levers, monkeypatch, None, 0.5) == pytest.approx(0.1)
    assert _recombined_score(real_levers, monkeypatch, None, 0.25) == pytest.approx(0.05)
    assert _recombined_score(real_levers, monkeypatch, "max", 0.25) == pytest.approx(0.85)


def test_a_convex_part_counts_a_moderate_descriptor_part_less_and_keeps_the_solid_change(
    real_levers, monkeypatch
):
    # the own-ring pairing's part 0.1 (both_parts 0.5) squared about 1, and about 0.5
    score = _recombined_score(real_levers, monkeypatch, None, 0.5, part_power=(2.0, 1.0))
    assert score == pytest.approx(0.01)
    score = _recombined_score(real_levers, monkeypatch, None, 0.5, part_power=(2.0, 0.5))
    assert score == pytest.approx(0.02)
    # the turned ring's bar still counts whole: 0.05 squared plus the solid change's 0.8
    score = _recombined_score(real_levers, monkeypatch, "max", 0.25, part_power=(2.0, 1.0))
    assert score == pytest.approx(0.0025 + 0.8)
    # linear up to a knee: 0.1 above 0.05 is 0.05 + 0.05^2; 0.1 below 0.2 keeps its value
    score = _recombined_score(real_levers, monkeypatch, None, 0.5, part_power=(2.0, 1.0, 0.05))
    assert score == pytest.approx(0.05 + 0.0025)
    score = _recombined_score(real_levers, monkeypatch, None, 0.5, part_power=(2.0, 1.0, 0.2))
    assert score == pytest.approx(0.1)
