"""Training: procedural shapes and variants, ground-truth correspondences, objectives, the
resumable optimiser loop, a quick end-to-end run and the shipped weights' manifest."""

import hashlib
import json
import warnings

import numpy as np
import pytest
import torch
import trimesh
from typer.testing import CliRunner

from drkfs_lab.training.data import correspond, render_pairs, sample_matches
from drkfs_lab.training.metric_stage import BASELINE
from drkfs_lab.training.net_losses import detector_loss, hardest_triplet_loss
from drkfs_lab.training.run import QUICK_TRAIN, train_steps
from drkfs_onnx import DRKFS, PipelineConfig
from drkfs_onnx.cli import app
from drkfs_onnx.contract.model_files import MANIFEST, models_dir, shipped_entry
from drkfs_onnx.synthetic.shapes import FAMILIES, assemble, random_shape
from drkfs_onnx.synthetic.variants import MILD, STRUCTURAL, make_variants


@pytest.mark.parametrize("family", list(FAMILIES))
def test_every_family_makes_closed_outward_parts_that_vary_with_the_seed(family):
    first, second = random_shape(family, 1), random_shape(family, 2)
    assert len(first) >= 3 and first != second
    for part in first:
        mesh = trimesh.Trimesh(*part.mesh(), process=False)
        assert mesh.is_watertight and mesh.volume > 0
    assert first == random_shape(family, 1)


def test_variants_edit_one_shape_structurally_and_mildly():
    parts = random_shape("chair", 0)
    variants = make_variants(parts, np.random.default_rng(0))
    assert [v.name for v in variants] == [*STRUCTURAL, *MILD]
    base_faces = len(assemble(parts, 1)[1])
    by_name = {v.name: v for v in variants}
    assert len(by_name["part_removed"].faces) < base_faces < len(by_name["part_added"].faces)
    assert len(by_name["retessellated"].faces) == 4 * base_faces
    for name in ("jittered", "part_shifted", "part_thickened", "rotated"):
        assert len(by_name[name].faces) == base_faces


@pytest.fixture(scope="module")
def pairs():
    return render_pairs(PipelineConfig(image_size=128), ["chair", "mug"], 1, 2, seed=3)


def test_correspondences_map_back_to_where_they_came_from(pairs):
    config = PipelineConfig(image_size=128)
    matches = sample_matches(pairs, config, 200, 8, seed=0)
    assert len(matches) > 200
    back, seen = correspond(pairs.swapped(), matches[:, 0], matches[:, 3:5], config)
    error = (back - matches[:, 1:3]).abs().amax(1)[seen]
    assert seen.float().mean() > 0.95 and error.float().mean() < 0.5 and error.max() <= 2


def test_hidden_points_have_no_correspondence(pairs):
    config = PipelineConfig(image_size=128)
    background = torch.nonzero(pairs.depth[0, 0] == 0)[:50]
    _, seen = correspond(pairs, torch.zeros(len(background), dtype=torch.long), background, config)
    assert not seen.any()


def test_triplet_loss_is_zero_for_matching_and_far_descriptors():
    eye = torch.eye(4)
    same = torch.eye(4, dtype=torch.bool)
    assert hardest_triplet_loss(eye, eye, same) == 0
    assert hardest_triplet_loss(eye, eye.roll(1, 0), same) > 1


def test_detector_loss_penalises_flat_maps():
    matches = torch.tensor([[0, 30, 30, 32, 31]])
    foreground = torch.ones(1, 2, 64, 64, dtype=torch.bool)
    flat, parts = detector_loss(torch.full((1, 2, 64, 64), 0.5), foreground, matches)
    assert parts["peakiness"] == pytest.approx(1.0)
    peaks = torch.zeros(1, 2, 64, 64)
    peaks[0, 0, ::8, ::8] = peaks[0, 1, 2::8, 1::8] = 1.0
    assert detector_loss(peaks, foreground, matches)[0] < flat


def test_an_interrupted_fit_resumes_to_the_same_weights(tmp_path):
    data = torch.randn(64, 3)

    def loss_fn(model, step):
        rows = torch.as_tensor(np.random.default_rng(step).choice(64, 8, replace=False))
        return (torch.nn.functional.dropout(model(data[rows]), 0.5) ** 2).mean()

    def fresh():
        torch.manual_seed(0)
        return torch.nn.Linear(3, 2)

    straight = fresh()
    train_steps(straight, loss_fn, 6, 0.1, tmp_path / "straight.pt", every=2)

    def killed_at_step_3(model, step):
        if step == 3:
            raise KeyboardInterrupt
        return loss_fn(model, step)

    resumed = fresh()
    with pytest.raises(KeyboardInterrupt):
        train_steps(resumed, killed_at_step_3, 6, 0.1, tmp_path / "resumed.pt", every=2)
    assert torch.load(tmp_path / "resumed.pt")["step"] == 2
    resumed = fresh()
    train_steps(resumed, loss_fn, 6, 0.1, tmp_path / "resumed.pt", every=2)
    for a, b in zip(straight.parameters(), resumed.parameters(), strict=True):
        assert torch.equal(a, b)


def _check_manifest(folder):
    manifest = json.loads((folder / MANIFEST).read_text())
    assert {"command", "seed", "commit", "data", "seconds", "detectors", "descriptors"} <= set(
        manifest
    )
    assert sum(entry["default"] for entry in manifest["weights"]) == 1
    for entry in manifest["weights"]:
        path = folder / entry["file"]
        assert hashlib.sha256(path.read_bytes()).hexdigest() == entry["sha256"]
        metric = DRKFS(PipelineConfig.from_dict(entry["config"]))
        metric.load_state_dict(torch.load(path, weights_only=True))
    return manifest


def test_quick_training_writes_weights_that_match_their_manifest(tmp_path):
    result = CliRunner().invoke(
        app, ["train", "--quick", "--out", str(tmp_path / "out"), "--work", str(tmp_path / "w")]
    )
    assert result.exit_code == 0, result.output
    assert "FPR95" in result.output
    manifest = _check_manifest(tmp_path / "out")
    assert manifest["command"].startswith("drkfs train") and "--quick" in manifest["command"]
    assert {row["detector"] for row in manifest["detectors"]} >= {"harris", "dog"}
    stage = manifest["metric"]
    # every objective and the paper-style baseline judged on the benchmark, the choice among them
    assert set(stage["objectives"]) == {BASELINE, *QUICK_TRAIN.metric.objectives}
    assert stage["objective"] in QUICK_TRAIN.metric.objectives
    nets = {PipelineConfig.from_dict(e["config"]).nets for e in manifest["weights"]}
    assert nets == {"metric", "correspondence"}


def test_shipped_weights_match_the_manifest_and_serve_every_preset():
    manifest = _check_manifest(models_dir())
    # the default's nets are the metric nets at width 0.5 (chosen on the benchmark by
    # bench/match_study.py; the manifest's "default" flag is the training run's own choice),
    # fine-tuned for a viewer's tolerance by drkfs tune-tolerant, which names what it started from
    default = shipped_entry(PipelineConfig(), any_rendering=True)
    assert default["file"] == "drkfs_tolerant_w0.5.pt"
    metric = shipped_entry(PipelineConfig(nets="metric"), any_rendering=True)
    assert default["made_by"]["from"] == {"file": metric["file"], "sha256": metric["sha256"]}
    assert default["made_by"]["command"].startswith("drkfs tune-tolerant --out models")
    assert shipped_entry(PipelineConfig.structure(), any_rendering=True) == default
    paper = PipelineConfig.from_dict(shipped_entry(PipelineConfig.paper())["config"])
    # the paper preset's nets were trained the paper's way, at its cameras and image size
    assert paper.shaping("features") == PipelineConfig.paper().shaping("features")
    # the softer training renderer and the loss preset show the correspondence nets other
    # images, not other nets
    training = shipped_entry(PipelineConfig.training(), any_rendering=True)
    assert training["file"] == "drkfs_correspondence_w0.5.pt"
    assert shipped_entry(PipelineConfig.loss(), any_rendering=True) == training
    assert sum(e["default"] for e in manifest["weights"]) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for config in (PipelineConfig(), PipelineConfig.paper(), PipelineConfig.loss()):
            DRKFS.pretrained(config)
