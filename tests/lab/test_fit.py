"""Fitting meshes with DR-KFS and other losses: the differentiable pieces, the fit loop, the
study end to end (quick plan, through the CLI), and the README's training-loop example."""

import json
import shutil
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

from drkfs_lab.fit import app as fit_app
from drkfs_lab.judging.judges import METRICS, VISUAL, Judge
from drkfs_lab.judging.rule import share
from drkfs_lab.studies.landscape import AGREEMENT, CHECKS, probe
from drkfs_lab.studies.losses import (
    FORMS,
    SHIPPED,
    pixel_with_chamfer,
    with_both,
    with_chamfer,
    with_pixel,
)
from drkfs_lab.studies.mesh_fit import (
    ChamferLoss,
    DrkfsTerm,
    Fade,
    FitSettings,
    Objective,
    fit_mesh,
    float_tensor,
)
from drkfs_lab.studies.problems import perturbed, shared, synthetic
from drkfs_lab.studies.study import (
    FULL,
    QUICK_STUDY,
    RANK_NOISE,
    Checkpoint,
    Fitter,
    first_within_noise,
    fitting_study,
    intact,
    mean_ranks,
    slug,
    study_recipes,
)
from drkfs_onnx.geometry import Smoothness, chamfer, surface_points
from drkfs_onnx.synthetic.shapes import Part, assemble, random_shape

# the studies' end to end checks: python -m pytest -m slow (.ci/run runs them)
pytestmark = pytest.mark.slow


def _box(scale: float = 1.0, subdivisions: int = 2):
    verts, faces = assemble([Part("box", (0.0, 0.0, 0.0), (scale,) * 3)], subdivisions)
    return float_tensor(verts), torch.as_tensor(faces)


def test_surface_points_lie_on_the_surface_and_carry_gradients():
    verts, faces = _box()
    verts.requires_grad_(True)
    points = surface_points(verts, faces, 500, torch.Generator().manual_seed(0))
    # on a unit cube centred at the origin every point has a coordinate at +-0.5
    assert torch.allclose(points.detach().abs().max(1).values, torch.tensor(0.5), atol=1e-6)
    points.sum().backward()
    assert torch.isfinite(verts.grad).all() and verts.grad.abs().sum() > 0


def test_chamfer_is_zero_on_itself_and_the_sum_of_both_mean_squared_nearest_distances():
    a = torch.tensor([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    b = torch.tensor([[0.0, 0.5, 0.0]])
    assert chamfer(a, a).item() == 0.0
    # a -> b: 0.25 and 1.25, mean 0.75; b -> a: 0.25
    assert chamfer(a, b).item() == pytest.approx(1.0)


def test_smoothness_ignores_the_template_and_rigid_shifts_but_not_a_bump():
    template, faces = _box()
    smooth = Smoothness(template, faces)
    assert smooth(template).item() == 0.0
    assert smooth(template + torch.tensor([0.3, -0.1, 0.2])).item() == pytest.approx(0, abs=1e-10)
    bumped = template.clone()
    bumped[0] += 0.1
    assert smooth(bumped).item() > 0


def test_an_objective_starts_at_the_sum_of_its_weights():
    template, faces = _box(0.8)
    target = _box(1.0)
    loss = ChamferLoss(target[0].double().numpy(), target[1].numpy(), faces)
    objective = Objective([(1.0, loss), (2.5, lambda v: (v * v).sum())], template)
    assert objective(template).item() == pytest.approx(3.5, rel=0.1)  # Chamfer is resampled


def test_a_faded_term_weighs_fully_before_its_fade_half_midway_and_is_not_computed_after():
    template, _ = _box(0.8)
    calls = []

    def counted(verts: torch.Tensor) -> torch.Tensor:
        calls.append(1)
        return (verts * verts).sum()

    fade = Fade(0.5, 0.8)
    objective = Objective(
        [(1.0, lambda v: v.sum() * 0 + 1.0), (2.0, counted)], template, [None, fade]
    )
    for progress, expected in ((0.2, 3.0), (0.5, 3.0), (0.65, 2.0), (0.8, 1.0), (0.95, 1.0)):
        objective.at(progress)
        calls.clear()
        assert objective(template).item() == pytest.approx(expected)
        assert len(calls) == (0 if progress >= fade.end else 1)


class _Staged(DrkfsTerm):
    """A term that records the progress it is told (a DrkfsTerm without the nets)."""

    def __init__(self):
        self.progress, self.seen = 0.0, []

    def __call__(self, verts):
        self.seen.append(self.progress)
        return ((verts - 1.0) ** 2).sum()


def test_a_staged_term_is_told_each_steps_progress_in_the_whole_fit():
    template, faces = _box(0.6)
    term = _Staged()
    fit_mesh(Objective([(1.0, term)], template), template, faces, FitSettings(steps=4))
    assert term.seen[1:] == [0.0, 0.25, 0.5, 0.75]  # after the scale, once per step
    term.seen.clear()
    probe(Objective([(1.0, term)], template), template, faces, FitSettings(steps=100), checks=1)
    assert max(term.seen) < 0.05  # the probe's five steps are the first 5% of the fit


def test_a_fit_runs_on_deterministic_kernels_and_gives_the_callers_setting_back():
    template, faces = _box(0.6)
    seen = []

    def spy(verts: torch.Tensor) -> torch.Tensor:
        seen.append(torch.are_deterministic_algorithms_enabled())
        return verts.square().mean()

    fit_mesh(Objective([(1.0, spy)], template), template, faces, FitSettings(steps=3))
    assert seen == [False, True, True, True]  # the scale at the template, then each step
    assert not torch.are_deterministic_algorithms_enabled()


def test_fitting_a_small_box_to_a_large_one_with_chamfer_closes_the_gap():
    template, faces = _box(0.6)
    target_verts, target_faces = _box(1.0)
    loss = ChamferLoss(target_verts.double().numpy(), target_faces.numpy(), faces)
    objective = Objective([(1.0, loss)], template)
    result = fit_mesh(objective, template, faces, FitSettings(steps=60, learning_rate=0.01))
    assert result.objective[-1] < 0.1 * result.objective[0]
    half_size = np.abs(result.verts).max(0)
    np.testing.assert_allclose(half_size, 0.5, atol=0.05)  # from 0.3 to the target's 0.5


def test_the_probe_trusts_a_smooth_objective_and_not_a_staircase():
    template, faces = _box(0.6)
    goal = template * 1.5
    smooth = probe(
        Objective([(1.0, lambda v: ((v - goal) ** 2).sum())], template),
        template,
        faces,
        FitSettings(),
    )
    assert len(smooth["checks"]) == CHECKS
    assert smooth["median_relative_error"] < 1e-3  # a quadratic: central differences are exact
    assert smooth["monotone_share"] == 1.0 and smooth["monotone_at_start"]
    # ripples far finer than a step: autograd follows the ripple, the step jumps over it
    ripples = Objective(
        [(1.0, lambda v: ((v - goal) ** 2).sum() + 0.01 * torch.sin(2000 * v).sum())], template
    )
    rough = probe(ripples, template, faces, FitSettings())
    assert rough["median_relative_error"] > AGREEMENT and rough["monotone_share"] < 1.0


def test_templates_share_the_targets_frame_and_differ_from_it():
    problem = synthetic("chair", 3)
    lower, upper = problem.target_verts.min(0), problem.target_verts.max(0)
    np.testing.assert_allclose((lower + upper) / 2, 0.0, atol=1e-12)
    assert np.linalg.norm(upper - lower) == pytest.approx(2.0)
    parts = random_shape("chair", 3)
    assert len(perturbed(parts, np.random.default_rng(0))) == len(parts)
    assert len(problem.template_faces) == 4 * len(problem.target_faces)  # subdivided once
    assert not np.allclose(problem.template_verts.max(0), upper)


def test_a_real_target_gets_an_icosphere_inside_its_box(real_meshes):
    problem = shared("cow")
    assert len(problem.template_faces) == 1280
    inside = np.abs(problem.template_verts).max(0) < np.abs(problem.target_verts).max(0)
    assert inside.all()


def test_mean_ranks_and_shares_follow_each_metrics_direction():
    rows = {
        "a": {"F-score 1%": 0.9, "Chamfer-L1": 0.02, "volumetric IoU": None},
        "b": {"F-score 1%": 0.5, "Chamfer-L1": 0.01, "volumetric IoU": 0.5},
    }
    assert mean_ranks(rows) == {"a": 1.5, "b": 1.5}  # IoU is missing for a: not ranked
    table = {
        "p": {"Chamfer": {"DR-KFS": 2.0, "pixel MSE": 0.1}, "X": {"DR-KFS": 1.0, "pixel MSE": 0.2}}
    }
    result = share(table, "X", "Chamfer", ("DR-KFS", "pixel MSE"))
    assert result["wins"] == 1 and result["share"] == 0.5
    assert result["cell_wins"] == {"p/DR-KFS": True, "p/pixel MSE": False}


def test_a_candidate_within_the_studys_noise_of_the_best_ties_and_the_earlier_one_wins():
    assert first_within_noise({"simple": 2.0, "elaborate": 2.0 - 0.9 * RANK_NOISE}) == "simple"
    assert first_within_noise({"simple": 2.0, "elaborate": 2.0 - 1.1 * RANK_NOISE}) == "elaborate"
    assert first_within_noise({"worse": 3.0, "best": 1.0, "tied": 1.1}) == "best"


def test_a_checkpoint_keeps_finished_fits_for_the_same_plan_only(tmp_path):
    path = tmp_path / "checkpoint.json"
    Checkpoint(path, QUICK_STUDY).put("chair 3/Chamfer", {"F-score 1%": 0.5})
    assert Checkpoint(path, QUICK_STUDY).get("chair 3/Chamfer") == {"F-score 1%": 0.5}
    assert Checkpoint(path, FULL).get("chair 3/Chamfer") is None  # another plan starts afresh
    Checkpoint(path, QUICK_STUDY).remove()
    assert not path.exists()


def test_a_checkpoint_made_on_another_torch_build_starts_afresh(tmp_path, monkeypatch):
    path = tmp_path / "checkpoint.json"
    Checkpoint(path, QUICK_STUDY).put("chair 3/Chamfer", {"F-score 1%": 0.5})
    monkeypatch.setattr(torch, "__version__", "0.0.0+other")  # its float sums differ
    assert Checkpoint(path, QUICK_STUDY).get("chair 3/Chamfer") is None


def test_the_full_study_fits_the_shipped_form_and_a_plan_cannot_fit_a_form_it_does_not_compare():
    assert FULL.form == SHIPPED and set(FULL.forms) == set(FORMS)
    with pytest.raises(ValueError, match="not among the compared forms"):
        replace(QUICK_STUDY, form=SHIPPED)  # the quick plan leaves the coarse stage out


def test_the_control_is_the_three_term_loss_without_its_drkfs_term():
    three = with_both("window r0 mean", 0.3, 1.0)
    assert three.terms == ((1.0, "pixel MSE"), (0.3, "window r0 mean"), (1.0, "Chamfer"))
    assert three.forms == ["window r0 mean"] and not three.rendered
    control = pixel_with_chamfer(1.0)
    assert control.terms == tuple(t for t in three.terms if t[1] not in three.forms)
    assert control.forms == []


@pytest.fixture(scope="module")
def quick_study(tmp_path_factory, real_meshes):
    out = tmp_path_factory.mktemp("fit")
    result = CliRunner().invoke(fit_app, ["--quick", "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out, result.output


def test_quick_study_chooses_a_loss_form_then_its_weights_on_its_own_problems(quick_study):
    out, output = quick_study
    study = json.loads((out / "results.json").read_text())["loss_study"]
    assert set(study["problems"]) == {"table 3"}  # none of the fitting study's problems
    ranks = study["forms"]["mean_rank"]
    assert set(ranks) == set(QUICK_STUDY.forms)
    assert study["forms"]["chosen"] == first_within_noise(ranks)
    assert study["form"] == QUICK_STUDY.form  # the weights are the plan's form's, whoever ranks
    for weights in ("pixel_weight", "chamfer_weight"):
        assert all(QUICK_STUDY.form in name for name in study[weights]["mean_rank"])
    assert study["pixel_weight"]["chosen"] in QUICK_STUDY.pixel_weights
    assert study["chamfer_weight"]["chosen"] in QUICK_STUDY.chamfer_weights
    for row in study["rows"].values():  # every rendered form probed on every problem
        if row["recipe"][-1][1] != "Chamfer":
            assert row["landscape"]["as_fitted"]["monotone_share"] in (0.0, 1.0)  # one check
    assert f"loss study: {study['forms']['chosen']} ranks first; {study['form']}" in output


def test_a_resumed_study_fits_again_only_the_fit_whose_file_changed(quick_study, tmp_path):
    out = tmp_path / "fit"
    shutil.copytree(quick_study[0], out)
    results = json.loads((out / "results.json").read_text())
    checkpoint = Checkpoint(out / "checkpoint.json", QUICK_STUDY)  # the finished run, resumable
    for problem, rows in results["table"].items():
        probed = results["landscape"]["problems"][problem]
        for loss in results["losses"]:
            fit = results["fits"][problem][loss]
            checkpoint.put(f"{problem}/{loss}", {
                "judged": rows[loss], "fit": fit, "landscape": probed.get(loss),
            })  # fmt: skip
    changed = out / results["fits"]["woody"]["Chamfer"]["mesh"]
    mesh = trimesh.load(changed, process=False)
    mesh.apply_scale(2.0)
    mesh.export(changed)  # another run's file in its place

    class CountingFitter(Fitter):
        fitted: list[str] = []

        def fit(self, recipe, problem):
            self.fitted.append(f"{problem.name}/{recipe.name}")
            return super().fit(recipe, problem)

    study = results["loss_study"]
    recipes, form = study_recipes(study), study["form"]
    judge = Judge(QUICK_STUDY.judge_config, 1, QUICK_STUDY.unseen_views, lfd=False)
    try:
        fitter = CountingFitter(QUICK_STUDY, judge)
        fitting_study(QUICK_STUDY, fitter, recipes, form, out, checkpoint, lambda _: None)
    finally:
        judge.close()
    assert fitter.fitted == ["woody/Chamfer"]
    assert intact(out, checkpoint.get("woody/Chamfer")["fit"])
    assert not intact(out, {"mesh": results["fits"]["woody"]["Chamfer"]["mesh"]})  # no hash


def test_quick_study_writes_the_table_the_shares_and_the_summary(quick_study):
    out, output = quick_study
    results = json.loads((out / "results.json").read_text())
    names = {"chair 3", "woody"}
    assert set(results["table"]) == names and len(QUICK_STUDY.problems) == 2
    study = results["loss_study"]
    chosen = study["form"]
    pixel_weight = study["pixel_weight"]["chosen"]
    chamfer_weight = study["chamfer_weight"]["chosen"]
    three = with_both(chosen, pixel_weight, chamfer_weight).name
    control = pixel_with_chamfer(chamfer_weight).name
    assert results["losses"] == [
        "Chamfer", "pixel MSE", chosen, with_pixel(chosen, pixel_weight).name,
        with_chamfer(chosen, chamfer_weight).name, three, control,
    ]  # fmt: skip
    for rows in results["table"].values():
        assert set(rows) == {"template", *results["losses"]}
        for values in rows.values():
            assert set(values) == set(METRICS)
            assert values["LFD"] is None  # not asked for in the quick plan
    for against in ("beats_chamfer", "beats_pixel_mse"):
        for row in results[against].values():
            wins = sum(row["cell_wins"].values())
            assert row["wins"] == wins and row["share"] == pytest.approx(wins / row["cells"])
            assert row["cells"] == len(names) * (len(VISUAL) - 1)  # no LFD cells
    summary = results["summary"]
    best = summary["best_drkfs_loss"]
    assert best in results["losses"] and best not in ("Chamfer", "pixel MSE")
    assert summary["share_beats_chamfer"] == results["beats_chamfer"][best]["share"]
    assert summary["share_beats_pixel_mse"] == results["beats_pixel_mse"][best]["share"]
    assert summary["chamfer_l1_ratio"] == pytest.approx(
        results["chamfer_l1_over_chamfer_fit"][best]
    )
    drkfs_term = results["comparisons"][f"{three} vs {control}"]
    assert drkfs_term["visual"]["cells"] == len(names) * (len(VISUAL) - 1)
    assert drkfs_term["visual"] == {
        k: v for k, v in share(results["table"], three, control, VISUAL).items() if k != "cell_wins"
    }
    # seven losses ranked 1 to 7 on every metric of every problem
    assert sum(results["mean_rank"].values()) == pytest.approx(28.0)
    assert set(results["seconds_per_step"]["losses"]) == set(results["losses"])
    chair = results["fits"]["chair 3"]["Chamfer"]  # three steps of Chamfer already help
    assert chair["objective_last"] < chair["objective_first"]
    assert "best DR-KFS loss:" in output
    assert not (out / "checkpoint.json").exists()  # a finished run leaves no checkpoint
    # the DR-KFS loss and pixel MSE probed on every problem
    assert set(results["landscape"]["summary"]) == {"pixel MSE", chosen}
    assert all(
        set(rows) == {"pixel MSE", chosen} for rows in results["landscape"]["problems"].values()
    )


def test_quick_study_saves_every_fit_as_a_ply_of_the_templates_faces(quick_study):
    out, _ = quick_study
    results = json.loads((out / "results.json").read_text())
    best = results["summary"]["best_drkfs_loss"]
    for name, fits in results["fits"].items():
        template = trimesh.load(out / fits["template"], process=False)
        for loss in results["losses"]:
            mesh = trimesh.load(out / fits[loss]["mesh"], process=False)
            assert fits[loss]["mesh"] == f"meshes/{slug(name)}/{slug(loss)}.ply"
            np.testing.assert_array_equal(mesh.faces, template.faces)
            assert not np.allclose(mesh.vertices, template.vertices)  # the fit moved it
        # the best DR-KFS-containing loss's fit, under the name outside judges look for
        saved = (out / fits["best_drkfs"]).read_bytes()
        assert fits["best_drkfs"] == f"meshes/{slug(name)}/best_drkfs.ply"
        assert saved == (out / fits[best]["mesh"]).read_bytes()
    # the shared mesh is named, not copied into the output
    assert results["fits"]["woody"]["target"] == "meshes/woody.obj"
    assert not (out / "meshes" / "woody" / "target.ply").exists()


def test_quick_study_gallery_is_a_png_with_a_cell_per_mesh(quick_study):
    out, _ = quick_study
    data = (out / "gallery.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", data[16:24])
    assert width > 9 * 128 and height > 2 * 2 * 128  # 9 columns, 2 problems of 2 views


def test_each_ideas_three_term_fit_is_judged_beside_the_studys_reproduced_rows(
    quick_study, tmp_path
):
    """bench/fit_ideas.py: pixel MSE and the control fitted again equal the study's rows, so the
    ideas' recipes (each form in the study's three-term recipe) stand beside its table."""
    out, _ = quick_study
    ideas_out = tmp_path / "ideas.json"
    done = subprocess.run(
        [sys.executable, "bench/fit_ideas.py", "--study", str(out / "results.json"),
         "--out", str(ideas_out), "--work", str(tmp_path / "work"),
         "--threads", str(torch.get_num_threads())],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    study = json.loads((out / "results.json").read_text())
    results = json.loads(ideas_out.read_text())
    assert set(results["reproduced"]) == {
        "pixel MSE", "pixel MSE + 10 x Chamfer", "pixel MSE + 1 x window r0 mean + 10 x Chamfer"
    }  # fmt: skip
    assert all(check["exact"] and check["cells"] > 0 for check in results["reproduced"].values())
    ideas = results["ideas"]
    assert ideas["soft best match, coarse to fine"] == {
        "recipe": "pixel MSE + 1 x soft match, window r1, coarse to fine + 10 x Chamfer",
        "nets": "shipped",
        "reused": False,
    }
    assert ideas["nets fine-tuned for the loss"]["nets"] == "fine-tuned nets"
    assert ideas["structure first, pixel MSE last"]["recipe"] == (
        "pixel MSE + 1 x window r0 mean + 10 x Chamfer, pixel MSE alone from 0.8"
    )
    choice = study["loss_study"]
    weights = choice["pixel_weight"]["chosen"], choice["chamfer_weight"]["chosen"]
    three = with_both(choice["form"], *weights).name
    for problem, rows in results["table"].items():
        assert set(rows) == {"template", *study["losses"], *ideas}
        assert all(rows[name] == study["table"][problem][name] for name in study["losses"])
        for idea in ideas:
            assert 0.0 <= rows[idea]["F-score 1%"] <= 1.0
    for idea in (three, *ideas):
        against_pixel = results["shares"][idea]["pixel MSE"]["visual"]
        recomputed = share(results["table"], idea, "pixel MSE", VISUAL)
        assert against_pixel == {k: recomputed[k] for k in ("wins", "cells", "share")}
    shipped = results["shares"][three]["pixel MSE"]["visual"]["share"]
    assert shipped == study["beats_pixel_mse"][three]["share"]
    # refitted on the study's own machine, the rivals are the study's rows, so the like-with-like
    # shares are the committed-row ones
    assert set(results["reproduced"]) == set(next(iter(results["here"].values())))
    for idea in ideas:
        for label, here in results["shares_here"][idea].items():
            assert here == results["shares"][idea][label]
    # the fade's control is the same fade on the control's two terms
    assert ideas["the control, pixel MSE last"]["recipe"] == (
        "pixel MSE + 10 x Chamfer, pixel MSE alone from 0.8"
    )
    fade = results["shares"]["structure first, pixel MSE last"]["the control, pixel MSE last"]
    recomputed = share(
        results["table"], "structure first, pixel MSE last", "the control, pixel MSE last", VISUAL
    )
    assert fade["visual"] == {k: recomputed[k] for k in ("wins", "cells", "share")}
    assert "the control, pixel MSE last" not in results["shares"]["the control, pixel MSE last"]
    # --ideas-from takes the rows an earlier output has and fits only what it lacks: here the
    # control and the fade's control, which on this machine fit to the same rows again
    partial = json.loads(ideas_out.read_text())
    del partial["ideas"]["the control, pixel MSE last"]
    for problem in partial["table"]:
        del partial["table"][problem]["the control, pixel MSE last"]
        del partial["here"][problem]["pixel MSE + 10 x Chamfer"]
    earlier = tmp_path / "partial.json"
    earlier.write_text(json.dumps(partial))
    again = tmp_path / "again.json"
    done = subprocess.run(
        [sys.executable, "bench/fit_ideas.py", "--study", str(out / "results.json"),
         "--out", str(again), "--ideas-from", str(earlier),
         "--threads", str(torch.get_num_threads())],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    reran = json.loads(again.read_text())
    assert {i for i, idea in reran["ideas"].items() if not idea["reused"]} == {
        "the control, pixel MSE last"
    }
    assert reran["rivals_reused"] == ["pixel MSE", three]
    assert reran["table"] == results["table"] and reran["here"] == results["here"]


def test_the_fit_scripts_help_shows_flags_plainly():
    """A flag takes no value, so its help shows none (typer's rich help printed <bool>)."""
    result = CliRunner().invoke(fit_app, ["--help"])
    assert result.exit_code == 0 and "--quick" in result.output
    assert "<bool>" not in result.output
