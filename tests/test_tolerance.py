"""Nets with a viewer's tolerance (training.tolerance): the warp moves views as it says, the data
hold every tier with a small part removed, and fine-tuning lowers the objective on its data."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.synthetic.shapes import assemble, random_shape
from drkfs_onnx.synthetic.tiers import TIERS
from drkfs_onnx.training import tolerance

ROOT = Path(__file__).resolve().parents[1]
CONFIG = PipelineConfig(num_views=2, image_size=64, temperature=0.03)


@pytest.fixture(scope="module")
def chair_views() -> tolerance.TierViews:
    return tolerance.render_tier_views(CONFIG, ["chair"], 1, tolerance.TRAIN_SEED)


def test_a_warp_moves_every_pixel_by_its_offset_turn_and_scale():
    views = torch.rand(2, 16, 16)
    assert torch.allclose(tolerance.warped(views, torch.zeros(2, 2), 0.0), views, atol=1e-5)
    right = tolerance.warped(views, torch.tensor([[1.0, 0.0], [1.0, 0.0]]), 0.0)
    assert torch.allclose(right[:, :, 1:], views[:, :, :-1], atol=1e-5)
    assert float(right[:, :, 0].abs().max()) == 0.0  # background came in at the left
    down = tolerance.warped(views, torch.tensor([[0.0, 2.0], [0.0, 2.0]]), 0.5)
    assert torch.allclose(down[:, 2:], views[:, :-2], atol=1e-5)
    assert torch.allclose(down[:, :2], torch.full_like(down[:, :2], 0.5))
    # a positive turn is clockwise on screen (rows run down); a scale of 2 doubles the middle
    quarter = tolerance.warped(views, torch.zeros(2, 2), 0.0, [90.0, 90.0], [1.0, 1.0])
    assert torch.allclose(quarter, torch.rot90(views, -1, (1, 2)), atol=1e-4)
    flat = torch.zeros(1, 16, 16)
    flat[:, 6:10, 6:10] = 1.0
    assert float(tolerance.warped(flat, torch.zeros(1, 2), 0.0, [0.0], [2.0]).sum()) == (
        pytest.approx(4 * float(flat.sum()), rel=0.1)
    )


def test_the_data_hold_every_tier_and_the_smallest_part_removed(chair_views):
    assert set(chair_views.kinds) == set(TIERS)
    assert chair_views.images.shape[:3] == (1, 1 + len(chair_views.kinds), CONFIG.num_views)
    parts = random_shape("chair", np.random.default_rng(tolerance.TRAIN_SEED))
    variants = tolerance.tier_variants(parts, np.random.default_rng(0))
    small = next(v for v in variants if v.name == "small_part_removed")
    assert small.kind == "structural"
    assert {"turned_1", "turned_3"} <= {v.name for v in variants if v.kind == "invisible"}
    # exactly the smallest part's faces are gone
    smallest = min(parts, key=lambda p: float(np.prod(p.size)))
    gone = len(assemble(parts, 1)[1]) - len(small.faces)
    assert gone == len(assemble([smallest], 1)[1])
    assert all(float(np.prod(p.size)) >= float(np.prod(smallest.size)) for p in parts)


def test_fine_tuning_lowers_the_objective_on_its_own_data(chair_views):
    metric = DRKFS.pretrained(CONFIG)
    loss_fn = tolerance.tolerance_ranking(chair_views, seed=0)

    def objective() -> float:
        with torch.no_grad():
            return float(torch.stack([loss_fn(metric, step) for step in range(4)]).mean())

    before = objective()
    metric.detector.requires_grad_(True)
    metric.descriptor.requires_grad_(True)
    params = [*metric.detector.parameters(), *metric.descriptor.parameters()]
    optimizer = torch.optim.Adam(params, lr=1e-3)
    for step in range(12):
        optimizer.zero_grad()
        loss_fn(metric, step % 4).backward()
        optimizer.step()
    assert objective() < before


@pytest.mark.slow  # a study's end to end check
def test_the_bench_script_fine_tunes_and_judges_on_its_quick_plan(tmp_path):
    out, nets = tmp_path / "real_nets.json", tmp_path / "nets.pt"
    done = subprocess.run(
        [sys.executable, "bench/real_nets.py", "--out", str(out), "--quick", "--steps", "2",
         "--work", str(tmp_path / "work"), "--save-nets", str(nets)],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    results = json.loads(out.read_text())
    assert {"shipped nets", "tolerant nets", "tolerant nets, softmax t = 0.05"} <= set(
        results["rows"]
    )
    for row in results["rows"].values():
        assert 0.0 <= row["tiers"]["invisible_vs_structural"] <= 1.0
        assert row["real"]["training"]["invisible_vs_surface"] is not None  # woody, training side
    shipped = DRKFS.pretrained(PipelineConfig()).state_dict()
    tuned = torch.load(nets, weights_only=True)
    assert any(not torch.equal(shipped[k], tuned[k]) for k in shipped if k.startswith("descr"))
