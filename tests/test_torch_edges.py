"""The torch path where a training run goes wrong: a prediction collapsed to a point, nets of
one's own, a target of the wrong kind, a match too large to build, a batch too large to index,
and a compiled equation that runs out of memory."""

import pytest
import torch
import trimesh

from drkfs_onnx import DRKFS, PipelineConfig
from drkfs_onnx.contract.mesh import check_mesh, frame_of
from drkfs_onnx.geometry import surface_points
from drkfs_onnx.loss import COARSE_TO_FINE, DrkfsLoss
from drkfs_onnx.match import soft_match_distances
from drkfs_onnx.render import kept_pairs
from drkfs_onnx.render.compile_policy import CompiledOrEager
from drkfs_onnx.render.torch_ops import TORCH_OPS

SMALL = PipelineConfig(turn_degrees=0.0, num_views=2, image_size=64)


def _sphere(radius: float = 0.5):
    sphere = trimesh.creation.icosphere(2, radius=radius)
    return torch.tensor(sphere.vertices, dtype=torch.float32), torch.as_tensor(sphere.faces)


def test_a_prediction_collapsed_to_a_point_scores_finite_with_a_finite_gradient_under_each():
    verts, faces = _sphere()
    point = torch.full_like(verts, 0.25)
    centre, scale = frame_of(point, TORCH_OPS)
    assert float(scale) == 1.0 and torch.equal(centre, torch.full((3,), 0.25))
    batch = torch.stack([point, 0.8 * verts]).requires_grad_()
    metric = DRKFS.pretrained(SMALL, normalization="each")
    scores = metric(batch, faces, verts, faces, batch_reduction="none")
    scores.sum().backward()
    assert torch.isfinite(scores).all() and torch.isfinite(batch.grad).all()
    assert batch.grad[1].abs().sum() > 0


def test_surface_points_of_a_mesh_with_no_area_lie_where_it_collapsed():
    verts, faces = _sphere()
    collapsed = torch.stack([verts, torch.full_like(verts, 0.25)])
    points = surface_points(collapsed, faces, 100, torch.Generator().manual_seed(0))
    assert torch.equal(points[1], torch.full((100, 3), 0.25))
    assert points[0].norm(dim=-1).max() <= 0.5 + 1e-6  # the sphere still by its area


def test_a_loss_from_ones_own_nets_keeps_their_normalisation_and_conv_precision():
    nets = DRKFS.pretrained(SMALL, normalization="each", conv_precision="tf32")
    loss = DrkfsLoss.from_nets(nets)
    assert {m.normalization for m in loss.metrics} == {"each"}
    assert {m.conv_precision for m in loss.metrics} == {"tf32"}


def test_a_single_target_where_the_loss_needs_one_per_stage_is_named():
    verts, faces = _sphere()
    loss = DrkfsLoss.pretrained()
    one_stage = loss.metrics[0].target(verts, faces)
    with pytest.raises(ValueError, match=f"one Target for each of its {len(COARSE_TO_FINE)} "):
        loss(verts, faces, one_stage, 0.0)


def test_a_soft_global_match_too_large_to_build_is_refused_before_it_is_built():
    queries = torch.zeros(25 * 225, 128)  # the paper preset's patches of one mesh
    config = PipelineConfig.paper()
    with pytest.raises(ValueError, match=r"would build 15\.1 GiB .* use matching='window'"):
        soft_match_distances(queries, queries, config, 0.1)
    small = torch.rand(2, 10, 8)
    assert soft_match_distances(small, small, config, 0.1).shape == (2, 10)


def test_a_batch_past_the_rasterisers_int32_indices_is_refused(monkeypatch):
    verts, faces = _sphere()
    metric = DRKFS.pretrained(SMALL)
    monkeypatch.setattr(kept_pairs, "INT32_LIMIT", 2 * 64 * 64 - 1)  # one mesh's pixels, less 1
    with pytest.raises(ValueError, match=r"8,192 pixels \(B x K x S\^2\), past the rasteriser"):
        metric.render(verts, faces)


def test_a_compiled_equation_that_runs_out_of_memory_raises_it_and_stays_compiled(monkeypatch):
    def out_of_memory(*tensors):
        raise torch.OutOfMemoryError("CUDA out of memory")

    monkeypatch.setattr(torch, "compile", lambda function, **options: out_of_memory)
    fused = CompiledOrEager(lambda x: x + 1)
    with pytest.raises(torch.OutOfMemoryError):
        fused(torch.zeros(1))
    assert fused.compiled is out_of_memory  # the next, smaller batch compiles again


def test_faces_of_no_area_are_dropped_by_the_torch_path_as_by_the_runtimes():
    verts, faces = _sphere()
    # a sliver across the sphere: two far vertices and their midpoint, one face of no area
    far = verts[[0, 5]]
    with_sliver = torch.cat([verts, far.mean(0, keepdim=True)])
    sliver = torch.tensor([[0, len(verts), 5]])
    sliver_faces = torch.cat([faces, sliver])
    metric = DRKFS.pretrained(SMALL)
    assert torch.equal(metric.render(with_sliver, sliver_faces), metric.render(verts, faces))
    checked = check_mesh(with_sliver.double().numpy(), sliver_faces.numpy())
    assert len(checked.faces) == len(faces)  # the runtime drops it by the same rule
