"""The single-view study (``python bench/single_view.py``, bench/records/single_view.md): SoftRas'
shape generator, its regularisers, the views it sees, the split of shapes and views, and (slow) the
quick plan end to end, resumed, and judged on other test seeds."""

import hashlib
import json
import math
from dataclasses import replace

import numpy as np
import pytest
import torch
import trimesh
from typer.testing import CliRunner

from drkfs_lab.benchmark.point_metrics import is_watertight
from drkfs_lab.single_view import app
from drkfs_lab.studies import single_view as study
from drkfs_lab.studies.finetune import (
    arm,
    compared,
    finetune_markdown,
    judge_finetuned,
    judged,
    protocol_of,
)
from drkfs_lab.studies.network import TEST_SEED as NETWORK_TEST_SEED
from drkfs_lab.studies.shape_generator import (
    FLATTEN_WEIGHT,
    LAPLACIAN_WEIGHT,
    SPHERE_RADIUS,
    Regularisers,
    ShapeGenerator,
)
from drkfs_lab.studies.single_view import (
    BASELINES,
    DRKFS_RECIPES,
    FINETUNE,
    FINETUNE_TUNED,
    HELD_OUT_AZIMUTHS,
    JUDGED,
    MATCHED,
    QUICK,
    TEST_SEED,
    TRAIN_AZIMUTHS,
    TRAIN_SEED,
    VALIDATION_SEED,
    Networks,
    SavedRunError,
    SilhouetteDRKFS,
    Terms,
    by_name,
    draw_batch,
    iou_loss,
    shares,
    study_sets,
    train,
    validation_choice,
    views_of,
)
from drkfs_lab.studies.views import (
    AZIMUTHS,
    CHANNELS,
    ELEVATION,
    IMAGE_SIZE,
    VIEW_CONFIG,
    ViewRenderer,
)
from drkfs_onnx.contract.cameras import Cameras, look_at
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.render.renderer import Renderer


def test_the_scripts_help_shows_flags_plainly():
    """A flag takes no value, so its help shows none (typer's rich help printed <bool>)."""
    result = CliRunner().invoke(app, ["--help"])
    assert result.exit_code == 0 and "--curve / --no-curve" in result.output
    assert "<bool>" not in result.output


def test_the_generator_starts_as_a_sphere_every_vertex_can_leave_and_every_weight_learns():
    torch.manual_seed(0)
    model = ShapeGenerator(CHANNELS, IMAGE_SIZE)
    template = model.template()
    assert template.shape == (642, 3) and model.faces.shape == (1280, 3)
    np.testing.assert_allclose(template.norm(dim=1), SPHERE_RADIUS, rtol=1e-5)
    assert (template != 0).all()  # a zero coordinate could never move (its sign is 0)
    verts = model(torch.rand(3, CHANNELS, IMAGE_SIZE, IMAGE_SIZE))
    assert verts.shape == (3, 642, 3) and verts.abs().max() < 1
    assert is_watertight(verts[0].detach().double().numpy(), model.faces.numpy())
    assert not torch.allclose(verts[0], verts[1])  # the mesh depends on the image
    verts.sum().backward()
    assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in model.parameters())


def test_flatten_is_zero_across_coplanar_faces_and_six_times_sixteen_ninths_on_a_tetrahedron():
    tetra = trimesh.Trimesh(
        [[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]],
        [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
    )
    verts = torch.tensor(tetra.vertices, dtype=torch.float32)
    regularisers = Regularisers(verts, torch.as_tensor(tetra.faces))
    # a regular tetrahedron's faces meet at acos(1/3): (1 + 1/3)^2 on each of its 6 edges
    assert float(regularisers.flatten(verts[None])) == pytest.approx(6 * 16 / 9, rel=1e-5)
    flat = verts.clone()
    flat[:, 2] = 0.0  # squashed: the faces of each side lie in one plane or fold back fully
    assert float(regularisers.flatten(flat[None])) > float(regularisers.flatten(verts[None]))
    sphere = trimesh.creation.icosphere(3)
    smooth = torch.tensor(sphere.vertices, dtype=torch.float32)
    faces = torch.as_tensor(sphere.faces)
    sphere_terms = Regularisers(smooth, faces)
    noisy = smooth + 0.02 * torch.randn(smooth.shape, generator=torch.Generator().manual_seed(0))
    for term in (sphere_terms.laplacian, sphere_terms.flatten):
        assert float(term(noisy[None])) > 2 * float(term(smooth[None]))
    assert float(sphere_terms(noisy[None])) == pytest.approx(
        LAPLACIAN_WEIGHT * float(sphere_terms.laplacian(noisy[None]))
        + FLATTEN_WEIGHT * float(sphere_terms.flatten(noisy[None])),
        rel=1e-6,
    )


def test_a_turned_mesh_seen_from_azimuth_zero_is_the_view_from_its_azimuth():
    box = trimesh.creation.box((0.8, 0.5, 0.3))
    box.vertices[:, 0] += 0.2 * box.vertices[:, 1]  # no symmetry a turn could hide
    verts = torch.tensor(box.vertices, dtype=torch.float32)
    faces = torch.as_tensor(box.faces)
    views = ViewRenderer()
    azimuth = 5
    angle, e = 2 * math.pi * azimuth / AZIMUTHS, math.radians(ELEVATION)
    eye = VIEW_CONFIG.camera_distance * np.array(
        [[math.cos(e) * math.sin(angle), math.sin(e), math.cos(e) * math.cos(angle)]]
    )
    camera = Cameras(look_at(eye), eye, views.renderer.cameras.focal)
    expected = Renderer(VIEW_CONFIG, camera).render(verts, faces)
    got = views(verts[None], faces, torch.tensor([azimuth]))
    torch.testing.assert_close(got, expected, atol=1e-4, rtol=0)
    assert not torch.allclose(got, views(verts[None], faces, torch.tensor([0])), atol=1e-2)


def test_shapes_and_input_views_are_split_and_disjoint_from_the_other_studies():
    seeds = [range(s, s + 100) for s in (TRAIN_SEED, VALIDATION_SEED, TEST_SEED)]
    assert all(set(a).isdisjoint(b) for i, a in enumerate(seeds) for b in seeds[i + 1 :])
    assert min(TRAIN_SEED, VALIDATION_SEED, TEST_SEED) > NETWORK_TEST_SEED + 100
    assert set(TRAIN_AZIMUTHS).isdisjoint(HELD_OUT_AZIMUTHS)
    assert sorted((*TRAIN_AZIMUTHS, *HELD_OUT_AZIMUTHS)) == list(range(AZIMUTHS))
    rng = np.random.default_rng(0)
    for _ in range(20):
        batch = draw_batch(rng, 30, 16)
        assert len(set(batch.shapes.tolist())) == 16
        drawn = {*batch.inputs.tolist(), *batch.others.tolist()}
        assert drawn <= set(TRAIN_AZIMUTHS)


def test_soft_iou_loss_is_zero_for_the_same_mask_and_one_for_disjoint_ones():
    mask = torch.zeros(1, 8, 8)
    mask[:, :4] = 1.0
    assert float(iou_loss(mask, mask)) == 0.0
    assert float(iou_loss(mask, 1 - mask)) == 1.0


def test_dr_kfs_on_silhouettes_describes_the_silhouette_not_the_shading():
    sphere = trimesh.creation.icosphere(2, radius=0.6)
    verts, faces = torch.tensor(sphere.vertices, dtype=torch.float32), torch.as_tensor(sphere.faces)
    config = VIEW_CONFIG.replace(num_views=2, image_size=64)
    shaded, outline = DRKFS(config), SilhouetteDRKFS(config)
    outline.load_state_dict(shaded.state_dict())
    assert torch.equal(
        outline.render(verts, faces), shaded.renderer.render(verts, faces, "silhouette")[:, None]
    )
    assert not torch.allclose(outline.render(verts, faces), shaded.render(verts, faces))


def test_networks_are_kept_in_half_precision_and_trained_again_under_another_plan(tmp_path):
    torch.manual_seed(0)
    model = ShapeGenerator(CHANNELS, IMAGE_SIZE).eval()
    kept = Networks(tmp_path, QUICK, torch.device("cpu"))
    kept.put(0, "a loss", {"model": model, "history": [1.0], "seconds_per_step": 0.5})
    loaded = kept.get(0, "a loss")
    images = torch.rand(2, CHANNELS, IMAGE_SIZE, IMAGE_SIZE)
    with torch.no_grad():
        torch.testing.assert_close(loaded["model"](images), model(images), atol=2e-3, rtol=0)
    other = Networks(tmp_path, replace(QUICK, steps=3), torch.device("cpu"))
    assert other.get(0, "a loss") is None and other.get(0, "a loss", any_key=True) is not None


def test_the_combination_that_beats_softras_on_most_visual_cells_is_chosen_ties_keep_drkfs():
    def row(lfd, silhouette, normals):
        return {"LFD": lfd, "silhouette IoU": silhouette, "normal consistency": normals,
                "Chamfer-L1": 0.1, "F-score 1%": 0.5, "volumetric IoU": None}  # fmt: skip

    softras = row(5000, 0.5, 0.7)
    table = {
        "a": {"SoftRas (silhouette IoU)": softras, "DR-KFS": row(4000, 0.4, 0.8),
              "DR-KFS + 1 x silhouette IoU": row(4000, 0.6, 0.8),
              "DR-KFS + 3 x Chamfer-L2": row(6000, 0.6, 0.8)},
    }  # fmt: skip
    choice = validation_choice(table)
    assert choice["chosen"] == "DR-KFS + 1 x silhouette IoU"
    assert choice["shares_of_visual_cells_beating_softras"]["DR-KFS"] == pytest.approx(2 / 3)
    table["a"]["DR-KFS + 1 x silhouette IoU"] = row(4000, 0.4, 0.8)
    assert validation_choice(table)["chosen"] == "DR-KFS"
    won = shares([table], "DR-KFS", "SoftRas (silhouette IoU)")
    assert won["LFD"] == {"wins": 1, "cells": 1, "share": 1.0}
    assert won["volumetric IoU"] == {"wins": 0, "cells": 0, "share": None}


@pytest.fixture(scope="module")
def quick_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("single-view")
    result = CliRunner().invoke(app, ["--quick", "--seeds", "0,1", "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out, json.loads((out / "results.json").read_text())


@pytest.mark.slow
def test_the_quick_study_judges_every_loss_on_every_test_shape_at_every_seed(quick_study):
    out, results = quick_study
    losses = results["plan"]["losses"]
    assert losses[:4] == [r.name for r in (*BASELINES, DRKFS_RECIPES[0])]
    assert losses[-1] == DRKFS_RECIPES[1].name  # the ablation, judged last
    assert results["validation"]["chosen"] in losses
    assert set(results["tables"]) == {"seed 0", "seed 1"}
    shapes = len(QUICK.families) * QUICK.test_per_family
    for table in results["tables"].values():
        assert len(table) == shapes
        assert all(set(rows) == set(results["plan"]["losses"]) for rows in table.values())
        assert all(set(row) == set(JUDGED) for rows in table.values() for row in rows.values())
    pooled = results["shares"]["pooled"]["DR-KFS"]["SoftRas (silhouette IoU)"]
    assert pooled["silhouette IoU"]["cells"] == 2 * shapes
    assert results["seconds_per_step"]["trainings"]["DR-KFS"].keys() == {"seed 0", "seed 1"}
    assert all(s > 0 for s in results["seconds_per_step"]["timed"].values())
    assert (out / "gallery.png").stat().st_size > 0
    for seed in (0, 1):
        for name in results["plan"]["losses"]:
            assert Networks(out / "networks", QUICK, torch.device("cpu")).get(seed, name)


@pytest.mark.slow
def test_a_rerun_resumes_every_network_and_judges_them_the_same(quick_study):
    out, results = quick_study
    again = CliRunner().invoke(app, ["--quick", "--seeds", "0,1", "--out", str(out)])
    assert again.exit_code == 0, again.output
    rerun = json.loads((out / "results.json").read_text())
    assert len(rerun["networks_resumed"]) >= 2 * len(results["plan"]["losses"])
    assert rerun["tables"] == results["tables"]
    other = CliRunner().invoke(app, ["--out", str(out), "--test-seeds", "6000"])
    assert other.exit_code == 0, other.output
    judged = json.loads((out / "test-seeds-6000.json").read_text())
    assert judged["test_seeds"] == [6000, 6000]
    assert set(judged["tables"]["seed 0"]).isdisjoint(results["tables"]["seed 0"])


@pytest.mark.slow
def test_the_controls_train_in_their_own_folder_and_other_test_seeds_judge_them(quick_study):
    out, results = quick_study
    ran = CliRunner().invoke(app, ["--quick", "--controls", "--seeds", "0,1", "--out", str(out)])
    assert ran.exit_code == 0, ran.output
    controls = study.Networks(out / study.CONTROLS_NETWORKS, QUICK, torch.device("cpu"))
    for name in {n for recipe, against in MATCHED.items() for n in (recipe, *against)}:
        assert controls.get(1, name) is not None, name
    other = CliRunner().invoke(app, ["--out", str(out), "--test-seeds", "6000"])
    assert other.exit_code == 0, other.output
    judged = json.loads((out / "test-seeds-6000.json").read_text())
    row = next(iter(judged["tables"]["seed 1"].values()))
    assert set(row) == set(results["plan"]["losses"])
    assert set(judged["controls"]["shares"]["pooled"]) == set(MATCHED)
    recipes = json.loads((out / "controls.json").read_text())["recipes"]
    row = next(iter(judged["controls"]["tables"]["seed 1"].values()))
    assert set(row) == set(recipes)


@pytest.mark.slow
def test_more_steps_train_beside_the_studys_networks_and_are_judged_with_them(quick_study):
    out, _ = quick_study
    saved = {p: p.read_bytes() for p in (out / "networks").rglob("*.pt")}
    args = ["--quick", "--out", str(out), "--steps", "3", "--seeds", "0"]
    result = CliRunner().invoke(app, [*args, "--losses", "SoftRas (silhouette IoU)"])
    assert result.exit_code == 0, result.output
    assert "seed 0, SoftRas (silhouette IoU), 3 steps: " in result.output
    longer = json.loads((out / "longer-3-steps-seed0.json").read_text())
    rows = {"SoftRas (silhouette IoU), 3 steps", "SoftRas (silhouette IoU), 2 steps",
            "DR-KFS, 2 steps", "DR-KFS + 3 x Chamfer-L2, 2 steps"}  # fmt: skip
    assert set(longer["means"]["mean"]) == rows
    assert all(set(judged) == rows for judged in longer["table"].values())
    assert {p: p.read_bytes() for p in (out / "networks").rglob("*.pt")} == saved
    assert Networks(out / "networks-3-steps", replace(QUICK, steps=3), torch.device("cpu")).get(
        0, "SoftRas (silhouette IoU)"
    )
    unknown = CliRunner().invoke(app, [*args, "--losses", "IoU"])
    assert unknown.exit_code != 0 and "no loss 'IoU'" in unknown.output
    # the run's networks, each named by its sha256, judged again: on its own test shapes as
    # the run judged them, and on other test shapes
    assert longer["networks"]["SoftRas (silhouette IoU), 3 steps"] == {
        "folder": "networks-3-steps", "loss": "SoftRas (silhouette IoU)",
        "sha256": hashlib.sha256((out / "networks-3-steps/seed0/softras_silhouette_iou.pt")
                                 .read_bytes()).hexdigest(),
    }  # fmt: skip
    assert {n["folder"] for r, n in longer["networks"].items() if "2 steps" in r} == {"networks"}
    assert set(longer["networks"]) == rows
    assert study.judge_longer(out, 3, (0,), TEST_SEED)["tables"]["seed 0"] == longer["table"]
    result = CliRunner().invoke(app, [*args, "--test-seeds", "7000"])
    assert result.exit_code == 0, result.output
    other = json.loads((out / "longer-3-steps-test-seeds-7000.json").read_text())
    assert other["networks"]["seed 0"] == {r: n["sha256"] for r, n in longer["networks"].items()}
    assert other["test_seeds"][0] == 7000 and set(other["means"]["mean"]) == rows
    assert set(other["tables"]["seed 0"]).isdisjoint(longer["table"])


def test_a_training_stopped_and_resumed_ends_where_a_straight_one_does(tmp_path):
    plan = replace(QUICK, steps=4)
    train_set, _, _ = study_sets(plan)
    views = views_of(train_set, tmp_path / "views.pt", ViewRenderer())
    faces = ShapeGenerator(CHANNELS, IMAGE_SIZE).faces
    terms = Terms(train_set, views, faces, 0)
    recipe = by_name("silhouette IoU + 3 x Chamfer-L2")  # the Chamfer term draws random points
    straight = train(plan, recipe, 0, views, terms, print)
    half = train(plan, recipe, 0, views, terms, print, until=2)
    resumed = train(plan, recipe, 0, views, terms, print, resume=half["state"])
    assert resumed["history"] == straight["history"] and len(half["history"]) == 2
    for name, value in straight["model"].state_dict().items():
        assert torch.equal(value, resumed["model"].state_dict()[name]), name
    # a fine-tuning starts from the weights it is given, not the seed's
    tuned = train(
        plan, recipe, 1, views, terms, print, until=0, start=straight["model"].state_dict()
    )
    for name, value in straight["model"].state_dict().items():
        assert torch.equal(value, tuned["model"].state_dict()[name]), name


@pytest.mark.slow
def test_the_controls_and_the_curve_judge_each_recipe_beside_its_controls(tmp_path, monkeypatch):
    monkeypatch.setattr(study, "CURVE_SAVE_EVERY", 1)  # a state saved after every step
    out, state = tmp_path / "out", tmp_path / "state"
    result = CliRunner().invoke(app, ["--quick", "--controls", "--seeds", "0", "--out", str(out)])
    assert result.exit_code == 0, result.output
    controls = json.loads((out / "controls.json").read_text())
    assert controls["processor"] and controls["cpu_count"] >= 1  # the machine it ran on
    for recipe, against in MATCHED.items():
        assert set(controls["shares"]["pooled"][recipe]) == set(against)
        assert controls["goal"][recipe]["met"] in (True, False)
    args = ["--quick", "--curve", "--seeds", "0", "--out", str(out), "--state", str(state)]
    assert CliRunner().invoke(app, args).exit_code == 0
    curve = json.loads((out / "curve.json").read_text())
    # the last point past the staged loss's 2 steps, at its fine stage
    assert list(curve["points"]) == ["1", "2", "3"] and (out / "curve.png").stat().st_size > 0
    # each point's network goes on from the one before: one run (a run a point, each on its
    # own schedule, would keep DR-KFS coarse a step longer at point 3)
    staged = replace(study.QUICK, steps=2)
    at = {p: study.Networks(state / f"networks-{p}-steps", staged, torch.device("cpu"))
          for p in (2, 3)}  # fmt: skip
    for name in curve["losses"]:
        two, three = (at[p].get(0, name, any_key=True)["history"] for p in (2, 3))
        assert len(three) == 3 and three[:2] == two
    again = CliRunner().invoke(app, args)  # every point trained and judged: nothing to do
    assert again.exit_code == 0 and json.loads((out / "curve.json").read_text()) == curve


@pytest.mark.slow
def test_the_finetuning_arms_start_from_one_network_and_are_judged_beside_it(tmp_path):
    out = tmp_path / "out"
    args = ["--quick", "--finetune", "--seeds", "0", "--out", str(out)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    found = json.loads((out / "finetune.json").read_text())
    for start, recipes in FINETUNE.items():
        assert found["arms"][start] == [arm(start, r) for r in recipes]
        assert {start, *found["arms"][start]} <= set(found["means"]["pooled"])
    for challenger, against in (pair for start in FINETUNE for pair in compared(start)):
        assert found["shares"]["pooled"][f"{challenger} | {against}"]["Chamfer-L1"]["cells"] > 0
    assert finetune_markdown(found).count("\n|") > 2 * len(FINETUNE)
    again = CliRunner().invoke(app, args)  # every arm saved: judged again, not retrained
    assert again.exit_code == 0
    assert json.loads((out / "finetune.json").read_text())["tables"] == found["tables"]


def test_a_second_drkfs_arm_is_compared_with_own_loss_control_and_the_first_drkfs_arm():
    assert list(FINETUNE_TUNED) == list(FINETUNE)
    for start in FINETUNE:
        own, drkfs, control, tuned = (arm(start, r) for r in FINETUNE_TUNED[start])
        assert FINETUNE_TUNED[start][:3] == FINETUNE[start]
        assert compared(start, FINETUNE_TUNED) == [
            (drkfs, own), (drkfs, control), (control, own),
            (tuned, own), (tuned, control), (tuned, drkfs),
        ]  # fmt: skip
    assert by_name(study.TUNED_RECIPE_IOU).terms == ((1.0, study.DRKFS_TUNED), (1.0, study.IOU))
    tuned_chamfer = by_name(study.TUNED_RECIPE_CHAMFER).terms
    assert tuned_chamfer == ((1.0, study.DRKFS_TUNED), (1.0, study.CHAMFER))
    for protocol in (FINETUNE, FINETUNE_TUNED):
        arms = {s: [arm(s, r) for r in recipes] for s, recipes in protocol.items()}
        assert protocol_of({"arms": arms}) == protocol


@pytest.mark.slow
def test_the_tuned_nets_arms_train_in_a_run_of_their_own_and_judge_again_on_other_shapes(
    tmp_path,
):
    out = tmp_path / "out"
    args = ["--quick", "--finetune", "--tuned-nets", "--seeds", "0", "--out", str(out)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    found = json.loads((out / "finetune-tuned-nets.json").read_text())
    assert not (out / "finetune.json").exists()
    assert list(found["arms"]) == list(FINETUNE_TUNED)
    assert found["command"].split(" --seeds")[0].endswith("--finetune --tuned-nets")
    pairs = [pair for start in FINETUNE_TUNED for pair in compared(start, FINETUNE_TUNED)]
    for challenger, against in pairs:
        assert found["shares"]["pooled"][f"{challenger} | {against}"]["Chamfer-L1"]["cells"] > 0
    # the saved networks judged again: on the run's own test shapes as the run judged them,
    # on other test shapes beside them, none trained again
    saved = sorted(p.stat().st_mtime_ns for p in out.glob("networks*/seed0/*.pt"))
    again = judge_finetuned(out, study.TEST_SEED, tuned_nets=True)
    assert again["tables"] == found["tables"] and again["networks"] == found["networks"]
    result = CliRunner().invoke(app, [*args, "--test-seeds", "7000"])
    assert result.exit_code == 0, result.output
    other = json.loads((out / "finetune-tuned-nets-test-seeds-7000.json").read_text())
    assert sorted(p.stat().st_mtime_ns for p in out.glob("networks*/seed0/*.pt")) == saved
    assert other["arms"] == found["arms"] and other["test_seeds"][0] == 7000
    assert set(other["tables"]["seed 0"]).isdisjoint(found["tables"]["seed 0"])


def test_a_steps_run_is_judged_again_only_with_the_networks_it_judged(tmp_path):
    def refusal(seeds: str = "0") -> str:
        args = ["--out", str(tmp_path), "--steps", "3", "--seeds", seeds, "--test-seeds", "7000"]
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 2, result.output
        return " ".join(result.output.split())

    assert "longer-3-steps-seed0.json: no run to judge again" in refusal()
    run = tmp_path / "longer-3-steps-seed0.json"
    command = "python bench/single_view.py --steps 3 --seeds 0 --losses 'SoftRas (silhouette IoU)'"
    run.write_text(json.dumps({"command": command, "quick": True}))  # it named no networks
    assert f"names no digest of its networks, so those beside it may be others; `{command}`" in (
        refusal()
    )
    row = "SoftRas (silhouette IoU), 3 steps"
    network = {"folder": "networks-3-steps", "loss": "SoftRas (silhouette IoU)"}
    other = {row: {**network, "sha256": hashlib.sha256(b"another network").hexdigest()}}
    run.write_text(json.dumps({"quick": True, "networks": other}))
    missing = "softras_silhouette_iou.pt: not the network longer-3-steps-seed0.json judged"
    assert missing in refusal()
    path = tmp_path / "networks-3-steps" / "seed0" / "softras_silhouette_iou.pt"
    path.parent.mkdir(parents=True)
    path.write_bytes(b"a network")
    assert missing in refusal()  # there, but another
    # seeds judged together must have judged the same rows under the same plan
    (tmp_path / "longer-3-steps-seed1.json").write_text(json.dumps({"quick": True, "networks": {}}))
    assert "longer-3-steps-seed1.json judged other networks than longer-3-steps-seed0.json" in (
        refusal("0,1")
    )


def test_a_finetuning_run_is_judged_again_only_with_the_networks_it_judged(tmp_path):
    command = f"`python bench/single_view.py --finetune --out {tmp_path}`"
    with pytest.raises(SavedRunError, match="no run to judge again") as error:
        judge_finetuned(tmp_path, 7000)
    assert command in str(error.value)
    run = tmp_path / "finetune.json"
    run.write_text(json.dumps({"quick": True, "seeds": [0]}))  # a run that named no networks
    with pytest.raises(SavedRunError, match="names no digest of its networks"):
        judge_finetuned(tmp_path, 7000)
    networks = {}
    for name in judged(FINETUNE):
        folder = "networks" if name in FINETUNE else "networks-finetuned"
        path = Networks(tmp_path / folder, QUICK, torch.device("cpu")).path(0, name)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(name.encode())
        networks[name] = hashlib.sha256(name.encode()).hexdigest()
    changed = arm(study.CHAMFER, FINETUNE[study.CHAMFER][1])
    networks[changed] = hashlib.sha256(b"another network").hexdigest()
    run.write_text(json.dumps({"quick": True, "seeds": [0], "networks": {"seed 0": networks}}))
    with pytest.raises(SavedRunError, match="not the network finetune.json judged") as error:
        judge_finetuned(tmp_path, 7000)
    assert "chamfer-l2_then_dr-kfs_1_x_chamfer-l2.pt" in str(error.value)
