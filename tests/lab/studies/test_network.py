"""The network study (``python bench/fit.py --network``): the reconstruction network, the
cameras its silhouettes are judged from, and the quick plan end to end through the CLI."""

import json
import struct
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
import torch
import trimesh
from conftest import ROOT
from typer.testing import CliRunner

from drkfs_lab.benchmark.point_metrics import iou, is_watertight
from drkfs_lab.fit import app as fit_app
from drkfs_lab.judging.judges import HIGHER_IS_BETTER, VISUAL, SilhouetteJudge, unseen_cameras
from drkfs_lab.studies.losses import CHAMFER, alone
from drkfs_lab.studies.network import (
    FULL,
    JUDGED,
    PRIMITIVES,
    QUICK_NETWORK,
    TEST_SEED,
    TRAIN_SEED,
    VALIDATION_SEED,
    Reconstructor,
    Trainings,
    choose_loss,
    draw_gallery,
    make_shape,
    train,
)
from drkfs_lab.studies.study import slug
from drkfs_onnx.contract.cameras import make_cameras
from drkfs_onnx.contract.config import PipelineConfig

# the studies' end to end checks: python -m pytest -m slow (.ci/run runs them)
pytestmark = pytest.mark.slow


def test_the_network_starts_as_closed_spheres_and_gives_every_parameter_a_gradient():
    torch.manual_seed(0)
    model = Reconstructor()
    points = make_shape("chair", TRAIN_SEED).points
    verts = model(torch.stack([points, points * 0.5]))
    assert verts.shape == (2, PRIMITIVES * 162, 3) and model.faces.shape == (PRIMITIVES * 320, 3)
    np.testing.assert_allclose(verts[0].detach(), model.spheres().detach(), atol=0.05)
    assert is_watertight(verts[0].detach().double().numpy(), model.faces.numpy())
    assert not torch.allclose(verts[0], verts[1])  # the code depends on the input points
    verts.sum().backward()
    assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in model.parameters())


def test_training_validation_and_test_shapes_differ_and_are_normalised():
    a, b, c = (make_shape("chair", s) for s in (TRAIN_SEED, VALIDATION_SEED, TEST_SEED))
    for one, other in ((a, b), (a, c), (b, c)):
        assert not np.allclose(one.verts.max(0), other.verts.max(0))
    # each split's seeds stay below the next one's first
    assert TRAIN_SEED + FULL.train_per_family <= VALIDATION_SEED
    assert VALIDATION_SEED + FULL.validation_per_family <= TEST_SEED
    lower, upper = a.verts.min(0), a.verts.max(0)
    assert np.linalg.norm(upper - lower) == pytest.approx(2.0)


def test_silhouette_cameras_are_none_of_the_losses_and_half_look_from_below():
    cameras = unseen_cameras(PipelineConfig.loss(), 8)
    assert (cameras.eyes[:, 1] < 0).sum() == 4
    for views in (2, 6, 12, 25):  # the quick judge, the loss, its coarse stage, the paper's
        trained = make_cameras(PipelineConfig.loss(num_views=views)).eyes
        distances = np.linalg.norm(cameras.eyes[:, None] - trained[None], axis=-1)
        assert distances.min() > 0.2  # camera distance 2.5: at least ~5 degrees apart
    judge = SilhouetteJudge(QUICK_NETWORK.judge_config, 8)
    box = trimesh.creation.box((0.8, 0.8, 0.8))
    mask = judge.mask(box.vertices, box.faces)
    assert iou(mask, mask) == 1.0 and 0 < mask.mean() < 1
    smaller = judge.mask(box.vertices * 0.5, box.faces)
    assert iou(smaller, mask) == pytest.approx(0.25, abs=0.05)  # areas scale by 1/4


def test_the_form_and_weight_with_most_validation_wins_are_chosen_and_a_tie_keeps_the_first():
    candidates = [r.name for r in FULL.candidates()]
    assert len(candidates) == len(FULL.forms) * len(FULL.chamfer_weights)

    def row(win: bool) -> dict:
        """Beats (or loses to) a Chamfer row of ones on every visual metric."""
        return {m: 2.0 if (m in HIGHER_IS_BETTER) == win else 0.5 for m in VISUAL} | {
            "Chamfer-L1": 1.0
        }

    def table(wins: dict[str, list[bool]]) -> dict:
        """Two shapes; each candidate wins on the shapes ``wins`` says, else loses."""
        ones = {m: 1.0 for m in [*VISUAL, "Chamfer-L1"]}
        return {
            f"shape {i}": {"Chamfer": ones}
            | {name: row(wins.get(name, [False, False])[i]) for name in candidates}
            for i in range(2)
        }

    last = candidates[-1]  # the second form at the last weight
    chosen = choose_loss(FULL, table({candidates[0]: [True, False], last: [True, True]}))
    assert (chosen["form"], chosen["chamfer_weight"]) == (FULL.forms[1], FULL.chamfer_weights[-1])
    assert chosen["shares"][candidates[0]] == 0.5 and chosen["shares"][last] == 1.0
    tie = choose_loss(FULL, table({candidates[0]: [True, False], last: [False, True]}))
    assert (tie["form"], tie["chamfer_weight"]) == (FULL.forms[0], FULL.chamfer_weights[0])


def test_training_runs_on_deterministic_kernels_and_gives_the_callers_setting_back():
    """Without them, indexing's backward sums in an order that follows thread timing."""
    seen = []

    def spy(verts: torch.Tensor) -> torch.Tensor:
        seen.append(torch.are_deterministic_algorithms_enabled())
        return verts.square().mean()

    points = torch.stack([make_shape("chair", TRAIN_SEED).points])
    assert not torch.are_deterministic_algorithms_enabled()
    train(QUICK_NETWORK, alone(CHAMFER), points, [[(1.0, spy)]], lambda _: None)
    assert seen == [True] * QUICK_NETWORK.steps
    assert not torch.are_deterministic_algorithms_enabled()


def test_the_seed_draws_the_initial_weights_and_batches_and_the_same_seed_repeats_them():
    points = torch.stack([make_shape(f, TRAIN_SEED).points for f in QUICK_NETWORK.families])

    def weights(seed: int) -> torch.Tensor:
        terms = [[(1.0, lambda verts: verts.square().mean())]] * len(points)
        plan = replace(QUICK_NETWORK, seed=seed)
        model = train(plan, alone(CHAMFER), points, terms, lambda _: None)["model"]
        return torch.cat([p.detach().flatten() for p in model.parameters()])

    assert torch.equal(weights(0), weights(0))
    assert not torch.equal(weights(0), weights(1))


def test_a_seed_is_refused_where_nothing_is_drawn_at_random(tmp_path):
    result = CliRunner().invoke(fit_app, ["--quick", "--seed", "1", "--out", str(tmp_path)])
    assert result.exit_code == 2 and "--seed is for --network" in result.output
    assert not (tmp_path / "results.json").exists()


def test_a_stopped_study_resumes_with_the_networks_it_had_trained(tmp_path):
    torch.manual_seed(3)
    model = Reconstructor()
    result = {"model": model, "history": [1.0, 0.5], "seconds_per_step": 0.2}
    recipe = FULL.candidates()[0]
    Trainings(tmp_path, FULL).put(recipe, result)
    resumed = Trainings(tmp_path, FULL).get(recipe)
    points = make_shape("chair", TEST_SEED).points[None]
    with torch.no_grad():
        assert torch.equal(resumed["model"](points), model(points))
    assert resumed["history"] == [1.0, 0.5] and resumed["seconds_per_step"] == 0.2
    assert Trainings(tmp_path, QUICK_NETWORK).get(recipe) is None  # trained under another plan
    assert Trainings(tmp_path, FULL).get(FULL.candidates()[1]) is None  # never trained


def test_a_network_trained_on_another_torch_build_or_thread_count_is_trained_again(
    tmp_path, monkeypatch
):
    recipe = FULL.candidates()[0]
    result = {"model": Reconstructor(), "history": [1.0], "seconds_per_step": 0.2}
    Trainings(tmp_path, FULL).put(recipe, result)
    threads = torch.get_num_threads()
    monkeypatch.setattr(torch, "get_num_threads", lambda: threads + 1)
    assert Trainings(tmp_path, FULL).get(recipe) is None
    monkeypatch.setattr(torch, "get_num_threads", lambda: threads)
    assert Trainings(tmp_path, FULL).get(recipe) is not None
    monkeypatch.setattr(torch, "__version__", "0.0.0+other")
    assert Trainings(tmp_path, FULL).get(recipe) is None


@pytest.fixture(scope="module")
def quick_network_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("network")
    result = CliRunner().invoke(fit_app, ["--network", "--quick", "--seed", "1", "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out, result.output


def test_quick_network_study_judges_every_test_shape_and_saves_its_meshes(quick_network_study):
    out, output = quick_network_study
    results = json.loads((out / "results.json").read_text())
    names = {f"{family} {TEST_SEED}" for family in QUICK_NETWORK.families}
    assert results["plan"]["seed"] == 1 and "--seed 1" in results["command"]
    validation = results["validation"]
    assert validation["form"] in QUICK_NETWORK.forms
    assert validation["chamfer_weight"] in QUICK_NETWORK.chamfer_weights
    assert set(validation["shares"]) == {r.name for r in QUICK_NETWORK.candidates()}
    assert set(validation["table"]) == {f"{f} {VALIDATION_SEED}" for f in QUICK_NETWORK.families}
    assert not (out / "checkpoint").exists()  # a finished study removes its checkpoint
    recipes = QUICK_NETWORK.recipes(validation["form"], validation["chamfer_weight"])
    losses = [recipe.name for recipe in recipes]
    assert results["plan"]["losses"] == losses and len(losses) == 5
    assert set(results["table"]) == names
    for name, rows in results["table"].items():
        assert set(rows) == set(losses)
        for loss in losses:
            assert set(JUDGED) <= set(rows[loss])
            mesh = trimesh.load(out / results["meshes"][name][loss], process=False)
            assert len(mesh.faces) == PRIMITIVES * 320
            assert results["meshes"][name][loss] == f"meshes/{slug(name)}/{slug(loss)}.ply"
    for loss in losses[1:]:  # LFD is not asked for in the quick plan
        assert results["beats_chamfer"][loss]["cells"] == len(names) * (len(VISUAL) - 1)
    # every candidate is judged on the test shapes too, the chosen one in the study's table
    # and the others beside it, so a run tells how much validation's choice mattered
    on_test = results["candidates_on_test"]
    chosen = recipes[-1].name
    others = {r.name for r in QUICK_NETWORK.candidates()} - {chosen}
    assert {name: set(rows) for name, rows in on_test["table"].items()} == {
        name: others for name in names
    }
    assert set(on_test["shares"]) == {r.name for r in QUICK_NETWORK.candidates()}
    assert on_test["shares"][chosen]["beats_chamfer"] == {
        k: results["beats_chamfer"][chosen][k] for k in ("wins", "cells", "share")
    }
    assert (
        on_test["shares"][chosen]["chamfer_l1_ratio"]
        == (results["chamfer_l1_over_chamfer_trained"][chosen])
    )
    # the candidates and the chosen form's losses are trained, no other form's
    trained = [*recipes, *QUICK_NETWORK.candidates()]
    assert set(results["training"]) == {recipe.name for recipe in trained}
    # every network starts from the same weights: the first objective is the sum of the weights
    for recipe in trained:
        first = results["training"][recipe.name]["objective_first"]
        assert first == pytest.approx(sum(w for w, _ in recipe.terms)), recipe.name
    summary = results["summary"]
    assert summary["best_drkfs_loss"] in losses[2:]
    assert (
        summary["share_beats_pixel_mse"]
        == (results["beats_pixel_mse"][summary["best_drkfs_loss"]]["share"])
    )
    assert "beats Chamfer on" in output and "best DR-KFS loss:" in output


def test_the_network_gallery_is_drawn_from_the_saved_meshes_alone(quick_network_study):
    out, _ = quick_network_study
    drawn = (out / "gallery.png").read_bytes()
    assert drawn[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", drawn[16:24])
    shapes = len(QUICK_NETWORK.families) * QUICK_NETWORK.test_per_family
    assert width > 6 * 128 and height > shapes * 2 * 128  # target + 5 losses; 2 views a shape
    (out / "gallery.png").unlink()
    draw_gallery(out)  # from results.json and the PLY files: no network, no judge
    assert (out / "gallery.png").read_bytes() == drawn


def test_the_combinations_script_retrains_chamfer_exactly_and_adds_two_networks(
    quick_network_study, tmp_path
):
    study, _ = quick_network_study
    out = tmp_path / "network" / "combinations.json"
    done = subprocess.run(
        [sys.executable, "bench/network_combinations.py", "--quick", "--out", str(out),
         "--study", str(study / "results.json"), "--threads", str(torch.get_num_threads())],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    results = json.loads(out.read_text())
    # same weights, batches and draws: the Chamfer network judges exactly as the study's did,
    # so the study's rows stand beside the new ones
    assert results["reproduced"]["exact"] and results["reproduced"]["cells"] > 0
    assert results["torch"] == torch.__version__  # a rerun repeats bit for bit on one build
    committed = json.loads((study / "results.json").read_text())
    # the form and the weight beside Chamfer of the study's chosen network
    form, weight = committed["validation"]["form"], committed["validation"]["chamfer_weight"]
    three = f"pixel MSE + 0.3 x {form} + {weight:g} x Chamfer"
    control = f"pixel MSE + {weight:g} x Chamfer"
    study_losses = committed["plan"]["losses"]
    assert results["losses"] == [*study_losses, three, control]
    for name, rows in results["table"].items():
        assert set(rows) == set(results["losses"])
        for loss in (three, control):
            assert (out.parent / results["meshes"][name][loss]).exists()
    assert sum(results["mean_rank"].values()) == pytest.approx(28.0)  # seven ranked 1 to 7
    drkfs_term = results["comparisons"][f"{three} vs {control}"]["visual"]
    assert drkfs_term["cells"] == len(QUICK_NETWORK.families) * (len(VISUAL) - 1)


def test_a_candidate_retrained_at_the_studys_seed_scores_as_the_study_judged_it(
    quick_network_study, tmp_path
):
    study, _ = quick_network_study
    committed = json.loads((study / "results.json").read_text())
    passed_over = [
        r for r in QUICK_NETWORK.candidates() if r.name not in committed["plan"]["losses"]
    ][0]
    (_, form), (weight, _) = passed_over.terms
    out = tmp_path / "candidate.json"
    done = subprocess.run(
        [sys.executable, "bench/network_candidate.py", "--quick", "--study",
         str(study / "results.json"), "--form", form, "--chamfer-weight", str(weight),
         "--out", str(out), "--threads", str(torch.get_num_threads())],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    results = json.loads(out.read_text())
    assert results["reproduced"]["exact"] and results["seed"] == 1
    assert results["candidate"] == passed_over.name and not results["chosen_by_validation"]
    # trained again from the same weights and batches, the candidate judges exactly as the
    # study judged it on the test shapes among the candidates validation passed over
    on_test = committed["candidates_on_test"]["shares"][passed_over.name]
    for against in ("beats_chamfer", "beats_pixel_mse"):
        assert {k: results[against][k] for k in ("wins", "cells", "share")} == on_test[against]
    assert results["chamfer_l1_over_chamfer_trained"] == on_test["chamfer_l1_ratio"]
    assert not (tmp_path / "meshes").exists()  # the candidate's meshes are not saved
