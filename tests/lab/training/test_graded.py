"""Nets fine-tuned for the loss (training.graded): graded series grow, and the objective asks
the loss to grow with them; the bench script runs end to end on its quick plan."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import torch
from conftest import ROOT

from drkfs_lab.training import graded
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.metric import DRKFS

CONFIG = PipelineConfig.loss(num_views=2, image_size=64)


@pytest.fixture(scope="module")
def chair_series() -> graded.GradedViews:
    return graded.render_graded_views(CONFIG, ["chair"], 1, graded.HELDOUT_SEED)


def test_every_grade_changes_more_pixels_than_the_one_before(chair_series):
    assert chair_series.images.shape[:2] == (len(graded.GRADES), 1 + 6)
    for images in chair_series.images:
        change = graded.patch_change(images, CONFIG).sum(1)
        assert change[0] > 0
        assert (change[1:] > change[:-1]).sum() >= len(change) - 2  # a shift may cross an edge


def test_the_losss_shipped_nets_score_every_grade_above_the_one_before(chair_series):
    stats = graded.grade_stats(DRKFS.pretrained(CONFIG), chair_series)
    assert stats["all"]["scene_grows"] == 1.0
    assert stats["all"]["patch_grows"] > 0.95


def test_the_objective_is_zero_where_distances_grow_as_the_squared_change():
    change = torch.tensor([[0.01, 0.0], [0.02, 0.0], [0.04, 0.05]])
    grown = graded.grown_pairs(change)
    assert grown.tolist() == [[True, False], [True, False]]  # the second patch: from nothing
    assert float(graded.patch_hinge(change**2, change)) == 0.0
    assert float(graded.patch_hinge(change, change)) == pytest.approx(
        (graded.ELASTICITY - 1) * float(torch.tensor(2.0).log())  # grew as fast as the change
    )
    squared = change**graded.ELASTICITY
    assert torch.allclose(graded.patch_elasticity(squared, change), torch.tensor(2.0))
    assert torch.allclose(graded.patch_elasticity(change, change), torch.tensor(1.0))


def test_fine_tuning_lowers_the_objective_on_its_own_series(chair_series):
    metric = DRKFS.pretrained(CONFIG)
    images = chair_series.images[0]
    before = float(graded.series_loss(metric, images))
    metric.detector.requires_grad_(True)
    metric.descriptor.requires_grad_(True)
    optimizer = torch.optim.Adam([*metric.detector.parameters(), *metric.descriptor.parameters()],
                                 lr=1e-3)  # fmt: skip
    for _ in range(5):
        loss = graded.series_loss(metric, images)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    assert float(graded.series_loss(metric, images).detach()) < before


@pytest.mark.slow  # a study's end to end check
def test_the_bench_script_measures_growth_and_fits_on_its_quick_plan(tmp_path):
    out = tmp_path / "loss_nets.json"
    done = subprocess.run(
        [sys.executable, "bench/loss_nets.py", "--out", str(out), "--quick",
         "--work", str(tmp_path / "work"), "--threads", "1"],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    results = json.loads(out.read_text())
    assert set(results["growth_heldout"]) == {
        "correspondence nets (the loss's)", "metric nets (the scoring default's)",
        "fine-tuned for the loss",
    }  # fmt: skip
    fits = results["fits"]
    assert set(fits["mean_rank"]) == {"shipped nets", "fine-tuned for the loss"}
    for rows in fits["rows"].values():
        for judged in rows.values():
            assert 0.0 <= judged["F-score 1%"] <= 1.0
            assert "median_relative_error" in judged["landscape"]["as_fitted"]
