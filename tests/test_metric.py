"""The DRKFS module: a differentiable, deterministic metric with exact zero on identical meshes."""

import hashlib
import json
import warnings

import numpy as np
import pytest
import torch
from conftest import ROOT, icosphere

import drkfs_onnx
from drkfs_onnx import DRKFS, PipelineConfig
from drkfs_onnx.contract import model_files
from drkfs_onnx.contract.alignment import turn_of
from drkfs_onnx.contract.config import NETS
from drkfs_onnx.contract.versions import metric_config
from drkfs_onnx.metric import MissingWeights, Target
from drkfs_onnx.synthetic.shapes import assemble, chair
from drkfs_onnx.synthetic.variants import without

FAST = PipelineConfig(num_views=4, image_size=128, descriptor_width=0.25, nets="metric")


@pytest.fixture(scope="module")
def metric() -> DRKFS:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return DRKFS.pretrained(FAST)


def _mesh(parts=None, dtype=torch.float32):
    verts, faces = assemble(parts if parts is not None else chair(), 1)
    return torch.tensor(verts, dtype=dtype), torch.tensor(faces)


def test_features_at_the_paper_config_have_225_descriptors_per_view():
    torch.manual_seed(0)
    verts, faces = icosphere(1)
    metric = DRKFS(PipelineConfig.paper(descriptor_width=0.25))
    feats = metric.features(torch.tensor(verts, dtype=torch.float32), torch.tensor(faces))
    assert feats.shape == (25 * 225, 128)


def test_identical_meshes_score_exactly_zero(metric):
    verts, faces = _mesh()
    assert metric(verts, faces, verts.clone(), faces).item() == 0.0


def test_score_is_deterministic_and_positive_for_a_change(metric):
    a, b = _mesh(without(chair(), "leg_0")), _mesh()
    first = metric(*a, *b)
    assert first.item() > 0
    assert torch.equal(first, metric(*a, *b))


def test_gradients_reach_both_meshes_vertices():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        metric = DRKFS.pretrained(FAST.replace(direction="both"))
    verts_a, faces_a = _mesh(without(chair(), "back"))
    verts_b, faces_b = _mesh()
    verts_a.requires_grad_(True)
    verts_b.requires_grad_(True)
    metric(verts_a, faces_a, verts_b, faces_b).backward()
    for grad in (verts_a.grad, verts_b.grad):
        assert torch.isfinite(grad).all()
        assert grad.abs().sum() > 0


def test_a_prepared_target_scores_like_forward_and_passes_gradients(metric):
    pred_verts, pred_faces = _mesh(without(chair(), "leg_1"))
    truth = _mesh()
    with torch.no_grad():
        target = metric.target(*truth)
    assert not target.features.requires_grad
    pred_verts = (pred_verts * 3.0 + 1.0).requires_grad_(True)  # joint: placed by the truth
    score = metric.score_to(pred_verts, pred_faces, target)
    assert torch.equal(score, metric(pred_verts, pred_faces, *truth))
    score.backward()
    assert torch.isfinite(pred_verts.grad).all() and pred_verts.grad.abs().sum() > 0


def test_skipping_empty_patches_is_exact(metric):
    """Describing only patches that see the mesh equals describing all of them."""
    from drkfs_onnx.nets.patches import select_patches

    verts, faces = _mesh()
    images = metric.render(verts - verts.mean(0), faces)
    all_rows = torch.arange(len(images) * FAST.patches_per_view)
    every = metric.descriptor(select_patches(metric.detector(images), all_rows, FAST))
    assert torch.allclose(metric.describe(images), every, atol=1e-5)


def test_each_normalisation_ignores_pose_scale():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        metric = DRKFS.pretrained(FAST, normalization="each")
    verts, faces = _mesh()
    moved = verts * 3.0 + torch.tensor([5.0, -2.0, 1.0])
    assert (
        metric(moved, faces, verts, faces).item()
        < 1e-3 * metric(*_mesh(without(chair(), "back")), verts, faces).item()
    )


def test_nets_stay_frozen_in_eval_mode(metric):
    metric.train()
    assert not metric.detector.training and not metric.descriptor.training
    assert not any(p.requires_grad for p in metric.parameters())


def test_pretrained_without_shipped_weights_refuses_unless_random_is_asked_for():
    unshipped = FAST.replace(descriptor_dim=64)
    with pytest.raises(MissingWeights, match="descriptor dim 64.*random_weights=True"):
        DRKFS.pretrained(unshipped)
    first = DRKFS.pretrained(unshipped, random_weights=True)
    second = DRKFS.pretrained(unshipped, random_weights=True)
    for a, b in zip(first.state_dict().values(), second.state_dict().values(), strict=True):
        assert torch.equal(a, b)  # seeded: the same random nets every time


def test_pretrained_loads_weights_listed_for_its_config(tmp_path, monkeypatch):
    torch.manual_seed(123)
    trained = DRKFS(FAST)
    torch.save(trained.state_dict(), tmp_path / "fast.pt")
    digest = hashlib.sha256((tmp_path / "fast.pt").read_bytes()).hexdigest()
    manifest = {"weights": [{"file": "fast.pt", "sha256": digest, "config": FAST.to_dict()}]}
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    monkeypatch.setattr(model_files, "models_dir", lambda: tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loaded = DRKFS.pretrained(FAST)
    for a, b in zip(trained.state_dict().values(), loaded.state_dict().values(), strict=True):
        assert torch.equal(a, b)
    # other cameras or pixels use the same nets; other nets do not
    other_views = DRKFS.pretrained(FAST.replace(num_views=5, image_size=64))
    assert torch.equal(other_views.detector.conv.weight, trained.detector.conv.weight)
    other_nets = next(nets for nets in NETS if nets != FAST.nets)
    for other in (FAST.replace(detector_m=3), FAST.replace(nets=other_nets)):
        with pytest.raises(MissingWeights):
            DRKFS.pretrained(other)
    (tmp_path / "fast.pt").write_bytes(b"tampered")
    with pytest.raises(ValueError, match="does not match the manifest"):
        DRKFS.pretrained(FAST)
    (tmp_path / "fast.pt").unlink()
    # without its .pt (an installed package), the weights come from a graph exported from it
    with pytest.raises(ValueError, match="neither fast.pt nor a feature graph exported from it"):
        DRKFS.pretrained(FAST)


def test_package_root_exposes_drkfs_lazily():
    assert drkfs_onnx.DRKFS is DRKFS
    with pytest.raises(AttributeError):
        drkfs_onnx.NoSuchThing  # noqa: B018


def test_demo_ranks_the_structural_edits_above_the_mild_ones(tmp_path):
    """``drkfs demo`` with the shipped default: the missing leg and backrest score above the
    shifted leg and the retessellated chair, and the reference scores 0."""
    from typer.testing import CliRunner

    from drkfs_onnx.cli import app

    result = CliRunner().invoke(app, ["demo", "--folder", str(tmp_path)])
    assert result.exit_code == 0, result.output
    scores = {line.split()[0]: float(line.split()[1]) for line in result.output.splitlines()[1:]}
    assert scores["chair.obj"] == 0.0
    mild = max(scores["chair_retessellated.obj"], scores["chair_leg_shifted.obj"])
    assert min(scores["chair_no_leg.obj"], scores["chair_no_back.obj"]) > mild


def test_drkfs_score_refuses_an_unknown_frame_in_one_line_before_loading_the_nets():
    from typer.testing import CliRunner

    from drkfs_onnx.cli import app

    chair = str(ROOT / "examples" / "chair.obj")
    result = CliRunner().invoke(app, ["score", chair, chair, "--normalize", "both"])
    assert result.exit_code == 2
    assert result.output == "error: unknown normalisation 'both'; use one of joint, each, none\n"


def test_a_turning_metric_turns_each_prediction_onto_its_own_reference_without_gradients():
    turning, plain = (DRKFS.pretrained(metric_config(v)) for v in ("drkfs-1.2", "drkfs-1.1"))
    verts, faces = _mesh()
    turn = torch.as_tensor(turn_of(np.radians([2.0, 0.0, 0.0])), dtype=verts.dtype)
    centre = (verts.amax(0) + verts.amin(0)) / 2  # the frame's origin, which the turn is about
    tilted = (verts - centre) @ turn.T + centre
    with torch.no_grad():
        target = turning.target(verts, faces)
        both = turning.target(torch.stack([verts, tilted]), faces)
    assert len(target.surface) == 1 and len(both.surface) == 2
    assert len(Target.stack([target, target]).surface) == 2
    leaf = torch.stack([tilted, verts]).requires_grad_(True)
    scores = turning.score_to(leaf, faces, target, batch_reduction="none")
    with torch.no_grad():
        untilted = plain.score_to(tilted, faces, plain.target(verts, faces))
    assert float(scores[0]) < 0.2 * float(untilted) and float(scores[1]) < 1e-9
    scores.sum().backward()  # the rotation is found without gradients; the vertices' flow
    assert torch.isfinite(leaf.grad).all() and leaf.grad[0].abs().sum() > 0
    with pytest.raises(ValueError, match="no surface samples of each reference"):
        turning.score_to(tilted, faces, plain.target(verts, faces))  # described for no turn
    # each prediction is turned onto its own reference: the tilted one onto itself, not at all
    own = turning.score_to(torch.stack([verts, tilted]), faces, both, batch_reduction="none")
    assert float(own.max()) < 1e-9
