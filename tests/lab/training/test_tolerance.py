"""Nets with a viewer's tolerance (training.tolerance): the warp moves views as it says, the data
hold every tier with a small part removed, and fine-tuning lowers the objective on its data."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys

import numpy as np
import pytest
import torch
from conftest import ROOT
from typer.testing import CliRunner

from drkfs_lab.benchmark.tiers import TIERS
from drkfs_lab.training import tolerance
from drkfs_onnx.cli import app
from drkfs_onnx.contract.config import NETS_TRAINED_AT, PipelineConfig
from drkfs_onnx.contract.model_files import MANIFEST, shipped_entry
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.synthetic.shapes import assemble, random_shape
from drkfs_onnx.synthetic.variants import face_areas, salient_tip

CONFIG = PipelineConfig(
    turn_degrees=0.0, num_views=2, image_size=64, temperature=0.03, nets="metric"
)


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


def test_salient_data_also_remove_a_tip_and_cut_a_hole_of_a_few_percent_of_the_area():
    parts = random_shape("lamp", np.random.default_rng(tolerance.TRAIN_SEED))
    plain = tolerance.tier_variants(parts, np.random.default_rng(0))
    salient = tolerance.tier_variants(parts, np.random.default_rng(0), salient=True)
    assert [v.name for v in salient[: len(plain)]] == [v.name for v in plain]
    extra = {v.name: v for v in salient[len(plain) :]}
    assert {v.kind for v in extra.values()} == {"structural"}
    verts, faces = assemble(parts, tolerance.FINE_SUBDIVISIONS)
    whole = float(face_areas(verts, faces).sum())
    tip = salient_tip(verts, faces)
    for name in ("tip_removed", "hole_cut"):
        kept = extra[name].faces
        assert np.array_equal(extra[name].verts, verts)  # the fine surface, only faces gone
        assert 0.001 < 1 - face_areas(verts, kept).sum() / whole < 0.05, name
    # the tip's own faces are gone
    centres = verts[extra["tip_removed"].faces].mean(1)
    assert np.linalg.norm(centres - tip, axis=1).min() > 0.05 * np.linalg.norm(np.ptp(verts, 0))


def test_no_fine_tuning_resumes_the_checkpoint_of_other_data_or_views(tmp_path):
    shipped = tolerance.checkpoint_path(tmp_path, 400, 2e-4, 0.05, True)
    # the shipped nets' run keeps its name, so drkfs tune-tolerant resumes the judged checkpoint
    assert shipped.name == "tolerant_400_0.0002_t0.05_simplification.pt"
    others = [
        tolerance.checkpoint_path(tmp_path, 400, 2e-4, 0.05, True, salient=True),
        tolerance.checkpoint_path(tmp_path, 400, 2e-4, 0.05, True, series_weight=3.0),
        tolerance.checkpoint_path(tmp_path, 400, 2e-4, 0.05, True, image_size=192),
        tolerance.checkpoint_path(tmp_path, 400, 2e-4, 0.05, True, image_size=144),
        tolerance.checkpoint_path(tmp_path, 400, 2e-4, 0.05, True, image_size=144, num_views=5),
        tolerance.checkpoint_path(tmp_path, 400, 2e-4, 0.05, False),
        tolerance.checkpoint_path(tmp_path, 400, 2e-4, 0.05, True, slides=1),
        tolerance.checkpoint_path(tmp_path, 400, 2e-4, 0.05, True, slides=2),
    ]
    assert len({shipped, *others}) == 1 + len(others)


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


def test_a_simplification_series_coarsens_to_its_face_counts_or_is_refused(monkeypatch):
    parts = random_shape("chair", np.random.default_rng(tolerance.SIMPLIFY_SEED))
    series = tolerance.simplification_series(parts)
    assert series is not None and len(series) == 1 + len(tolerance.SIMPLIFIED_FACES)
    counts = [len(f) for _, f in series]
    assert counts[0] > counts[1] > counts[2] > counts[3]
    assert all(c <= 1.2 * t for c, t in zip(counts[1:], tolerance.SIMPLIFIED_FACES, strict=True))
    # a simplification that stalls (returns its input) gives no series
    monkeypatch.setattr(tolerance, "simplified", lambda verts, faces, keep: (verts, faces))
    assert tolerance.simplification_series(parts) is None


def test_a_slide_series_moves_one_part_by_even_steps_to_the_slide_range():
    parts = random_shape("chair", np.random.default_rng(tolerance.SLIDE_SEED))
    series = tolerance.slide_series(parts, np.random.default_rng(0))
    base = assemble(parts, 1)
    assert len(series) == 1 + tolerance.SLIDE_STEPS
    assert np.array_equal(series[0][0], base[0]) and np.array_equal(series[0][1], base[1])
    moved = [v - base[0] for v, _ in series[1:]]
    slid = np.abs(moved[-1]).sum(1) > 0  # the one part's vertices
    assert 0 < slid.sum() < len(base[0])
    size = float(np.linalg.norm(np.ptp(base[0], axis=0)))
    steps = [m[slid, 0].mean() for m in moved]
    assert steps == pytest.approx(
        [tolerance.SLIDE_RANGE * size * (k + 1) / tolerance.SLIDE_STEPS for k in range(5)]
    )
    assert all(np.abs(m[slid][:, 1:]).max() == 0 for m in moved)  # sideways only
    # with the part removed last: the same slides, then the shape without the slid part
    with_removed = tolerance.slide_series(parts, np.random.default_rng(0), removed=True)
    assert len(with_removed) == 2 + tolerance.SLIDE_STEPS
    assert len(with_removed[-1][0]) == len(base[0]) - slid.sum()


def test_an_even_rise_costs_nothing_and_a_jump_costs_its_excess():
    even = torch.linspace(0.2, 1.0, 5)
    assert float(tolerance.uneven_rise(even)) == 0.0
    # a last step twice the others', within SLIDE_EVEN times the even step: still nothing
    assert float(tolerance.uneven_rise(torch.tensor([0.15, 0.3, 0.45, 0.6, 0.9]))) == 0.0
    # three times the others': the excess over SLIDE_EVEN even steps, of the rise
    excess = 0.45 / 1.05 - tolerance.SLIDE_EVEN / 5
    uneven = tolerance.uneven_rise(torch.tensor([0.15, 0.3, 0.45, 0.6, 1.05]))
    assert float(uneven) == pytest.approx(excess, rel=1e-4)
    # all the rise in the last step: the step is the whole rise, SLIDE_EVEN / 5 of it allowed
    jump = tolerance.uneven_rise(torch.tensor([0.0, 0.0, 0.0, 0.0, 1.0]))
    assert float(jump) == pytest.approx(1 - tolerance.SLIDE_EVEN / 5, rel=1e-5)


def test_the_slide_term_asks_a_slid_part_to_rise_evenly(chair_views):
    metric = DRKFS.pretrained(CONFIG).eval()
    base = chair_views.images[0, 0]  # (K, S, S)
    noise = torch.rand(base.shape, generator=torch.Generator().manual_seed(0)) - 0.5

    def term(levels: list[float]) -> float:
        slides = torch.stack([base, *(base + a * noise for a in levels)])[None]
        with torch.no_grad():
            alone = tolerance.tolerance_ranking(chair_views, 0)(metric, 0)
            both = tolerance.tolerance_ranking(chair_views, 0, slides=slides)(metric, 0)
        return float(both - alone)

    assert term([0.1, 0.2, 0.3, 0.4, 0.5]) < term([0.0, 0.0, 0.0, 0.0, 0.5])
    # with the part removed last, a removal scoring far above the furthest slide costs less
    # than one scoring as little
    assert term([0.1, 0.2, 0.3, 0.4, 0.5, 2.0]) < term([0.1, 0.2, 0.3, 0.4, 0.5, 0.5])


def test_the_simplification_term_asks_a_coarser_simplification_to_score_higher(chair_views):
    metric = DRKFS.pretrained(CONFIG).eval()
    base = chair_views.images[0, 0]  # (K, S, S)
    noise = torch.rand(base.shape, generator=torch.Generator().manual_seed(0)) - 0.5

    def term(levels: torch.Tensor) -> float:
        series = torch.stack([base, *(base + a * noise for a in levels)])[None]
        with torch.no_grad():
            alone = tolerance.tolerance_ranking(chair_views, 0)(metric, 0)
            both = tolerance.tolerance_ranking(chair_views, 0, series)(metric, 0)
        return float(both - alone)

    # unchanged simplifications all score 0: every pair falls short by the whole margin
    assert term(torch.zeros(3)) == pytest.approx(tolerance.SIMPLIFY_MARGIN, rel=1e-4)
    assert term(torch.tensor([0.02, 0.2, 0.6])) < term(torch.tensor([0.6, 0.2, 0.02]))


def test_tune_tolerant_adds_its_weights_and_how_they_were_made_to_the_manifest(tmp_path):
    out = tmp_path / "models"
    out.mkdir()
    # a drkfs train run's metric nets in --out (here the shipped ones, moved a little): the
    # tolerant nets start from them, not from the shipped ones
    metric = PipelineConfig(nets="metric")
    state = DRKFS.pretrained(metric).state_dict()
    state["detector.conv.bias"] = state["detector.conv.bias"] + 0.01
    torch.save(state, out / "drkfs_metric_w0.5.pt")
    digest = hashlib.sha256((out / "drkfs_metric_w0.5.pt").read_bytes()).hexdigest()
    kept = {
        "file": "drkfs_metric_w0.5.pt",
        "sha256": digest,
        "config": shipped_entry(metric, any_rendering=True)["config"],
        "default": True,
    }
    (out / MANIFEST).write_text(json.dumps({"command": "drkfs train", "weights": [kept]}))
    for _ in range(2):  # a rerun replaces its own entry and keeps the others
        result = CliRunner().invoke(
            app, ["tune-tolerant", "--quick", "--out", str(out), "--work", str(tmp_path / "w")]
        )
        assert result.exit_code == 0, result.output
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["command"] == "drkfs train"
    assert [e["file"] for e in manifest["weights"]] == [kept["file"], "drkfs_tolerant_w0.5.pt"]
    entry = manifest["weights"][1]
    assert hashlib.sha256((out / entry["file"]).read_bytes()).hexdigest() == entry["sha256"]
    # trained at the cameras the shipped nets were, whatever the default's
    assert PipelineConfig.from_dict(entry["config"]) == PipelineConfig(
        nets="tolerant", **NETS_TRAINED_AT
    )
    made = entry["made_by"]
    assert made["from"] == {"file": "drkfs_metric_w0.5.pt", "sha256": digest}
    assert made["command"].startswith("drkfs tune-tolerant") and made["steps"] == 2
    assert made["objective"]["after"] < made["objective"]["before"]
    assert made["resumed_at"] == 2  # the rerun found the finished checkpoint
    tuned = torch.load(out / entry["file"], weights_only=True)
    assert not torch.equal(tuned["detector.conv.bias"], state["detector.conv.bias"])
    DRKFS(PipelineConfig(nets="tolerant")).load_state_dict(tuned)


def test_tune_tolerant_refuses_metric_nets_that_do_not_match_their_manifest(tmp_path):
    out = tmp_path / "models"
    out.mkdir()
    entry = dict(shipped_entry(PipelineConfig(nets="metric"), any_rendering=True))
    (out / entry["file"]).write_bytes(b"not the trained weights")
    (out / MANIFEST).write_text(json.dumps({"weights": [entry]}))
    result = CliRunner().invoke(
        app, ["tune-tolerant", "--quick", "--out", str(out), "--work", str(tmp_path / "w")]
    )
    assert result.exit_code == 2 and "sha256 does not match" in result.output
    assert not (out / "drkfs_tolerant_w0.5.pt").exists()


@pytest.mark.slow  # a study's end to end check
def test_the_bench_script_fine_tunes_and_judges_on_its_quick_plan(tmp_path):
    out, nets = tmp_path / "real_nets.json", tmp_path / "nets.pt"
    done = subprocess.run(
        [sys.executable, "bench/real_nets.py", "--out", str(out), "--quick", "--steps", "2",
         "--work", str(tmp_path / "work"), "--save-nets", str(nets), "--simplification",
         "--salient", "--series-weight", "3"],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    results = json.loads(out.read_text())
    assert results["data"]["simplification_series"] >= 1
    plain = tolerance.tier_variants(random_shape("chair", np.random.default_rng(0)),
                                    np.random.default_rng(0))  # fmt: skip
    assert len(results["data"]["variants"]) == len(plain) + 2  # the tip and the hole
    assert results["command"].endswith("--salient --series-weight 3 --quick")
    assert (tmp_path / "work" / "quick" / "tolerant_2_0.0002_t0.1_simplification_salient_w3.pt"
            ).exists()  # fmt: skip
    assert {"metric nets", "tolerant nets", "tolerant nets, softmax t = 0.05"} <= set(
        results["rows"]
    )
    for row in results["rows"].values():
        assert 0.0 <= row["tiers"]["invisible_vs_structural"] <= 1.0
        assert row["real"]["training"]["invisible_vs_surface"] is not None  # woody, training side
    start = DRKFS.pretrained(PipelineConfig(nets="metric")).state_dict()  # what it tunes
    tuned = torch.load(nets, weights_only=True)
    assert any(not torch.equal(start[k], tuned[k]) for k in start if k.startswith("descr"))
