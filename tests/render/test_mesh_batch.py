"""A batch of meshes in one pass: the batched metric and loss equal the per-mesh loop, in every
form a batch takes; the loss is a module; bad input is one clear ValueError."""

from types import SimpleNamespace

import numpy as np
import pytest
import torch
import trimesh
from conftest import ROOT, icosphere, loss_case

from drkfs_onnx import DRKFS, PipelineConfig
from drkfs_onnx.contract.patch_grid import nonempty_patches as numpy_nonempty
from drkfs_onnx.geometry import Smoothness, chamfer, surface_points
from drkfs_onnx.loss import DrkfsLoss, StagedTarget
from drkfs_onnx.nets.patches import nonempty_patches_on_device
from drkfs_onnx.render.mesh_batch import MeshBatch

VALUE_RTOL, COSINE = 1e-5, 0.99999


@pytest.fixture(scope="module")
def case():
    """A 1,280-face prediction, three nudged copies, and the chair it is fit to."""
    prediction, faces, truth = loss_case()
    nudges = 0.01 * torch.randn(3, *prediction.shape, generator=torch.Generator().manual_seed(1))
    return SimpleNamespace(preds=prediction[None] + nudges, faces=faces, truth=truth)


@pytest.fixture(scope="module")
def loss():
    return DrkfsLoss.pretrained()


def _value_and_grad(score, verts: torch.Tensor):
    verts = verts.detach().clone().requires_grad_(True)
    value = score(verts)
    value.sum().backward()
    return value.detach(), verts.grad


def _assert_batch_equals_loop(batched, looped) -> None:
    """(values (B,), gradients (B, V, 3)) of the batch against the loop's, mesh by mesh."""
    (values, grads), (loop_values, loop_grads) = batched, looped
    assert torch.allclose(values, loop_values, rtol=VALUE_RTOL, atol=0)
    for grad, loop_grad in zip(grads, loop_grads, strict=True):
        cosine = torch.nn.functional.cosine_similarity(grad.flatten(), loop_grad.flatten(), dim=0)
        assert cosine >= COSINE


@pytest.mark.parametrize("progress", [0.0, 1.0])  # the coarse stage and the loss preset
def test_a_template_batch_equals_the_loop_with_a_shared_target(case, loss, progress):
    target = loss.target(*case.truth)
    looped = [
        _value_and_grad(lambda v: loss(v, case.faces, target, progress), p) for p in case.preds
    ]
    loop = (torch.stack([v for v, _ in looped]), torch.stack([g for _, g in looped]))
    batched = _value_and_grad(
        lambda v: loss(v, case.faces, target, progress, batch_reduction="none"), case.preds
    )
    assert batched[0].shape == (3,)
    _assert_batch_equals_loop(batched, loop)
    mean = loss(case.preds, case.faces, target, progress)
    total = loss(case.preds, case.faces, target, progress, batch_reduction="sum")
    assert torch.allclose(mean * 3, total) and torch.allclose(total, batched[0].sum())


def test_meshes_of_different_sizes_equal_the_loop_in_every_form(loss):
    """Lists, packed tensors with counts and a PyTorch3D-like object give the per-mesh loop's
    values and gradients, each against its own ground truth (a batch of targets)."""
    meshes = [trimesh.creation.icosphere(2, radius=r) for r in (0.5, 0.7)] + [
        trimesh.creation.box((0.6, 0.4, 0.8))
    ]
    verts = [torch.tensor(m.vertices, dtype=torch.float32) for m in meshes]
    faces = [torch.tensor(m.faces) for m in meshes]
    truths = [v * 1.05 + 0.01 for v in verts]
    targets = [loss.target(t, f) for t, f in zip(truths, faces, strict=True)]
    looped = [
        _value_and_grad(lambda x, f=f, t=t: loss(x, f, t, 1.0), v)
        for v, f, t in zip(verts, faces, targets, strict=True)
    ]
    loop_values = torch.stack([v for v, _ in looped])
    batch_target = loss.target(truths, faces)
    assert batch_target[0].batch == 3
    stacked = StagedTarget.stack(targets)
    for one, batch in zip(stacked, batch_target, strict=True):
        assert torch.equal(one.features, batch.features)

    counts = [len(v) for v in verts]
    offsets = np.cumsum([0] + counts[:-1])
    packed_faces = torch.cat([f + int(o) for f, o in zip(faces, offsets, strict=True)])
    forms = {
        "lists": lambda vs: (list(vs), faces),
        "packed": lambda vs: (
            MeshBatch.packed(torch.cat(vs), packed_faces, counts, [len(f) for f in faces]),
            None,
        ),
        "meshes object": lambda vs: (
            SimpleNamespace(verts_list=lambda: list(vs), faces_list=lambda: faces),
            None,
        ),
    }
    for name, form in forms.items():
        leaves = [v.detach().clone().requires_grad_(True) for v in verts]
        values = loss(*form(leaves), batch_target, 1.0, batch_reduction="none")
        values.sum().backward()
        assert torch.allclose(values.detach(), loop_values, rtol=VALUE_RTOL, atol=0), name
        for leaf, (_, grad) in zip(leaves, looped, strict=True):
            cosine = torch.nn.functional.cosine_similarity(leaf.grad.flatten(), grad.flatten(), 0)
            assert cosine >= COSINE, name


@pytest.mark.parametrize("config", [PipelineConfig(), PipelineConfig.structure()])
def test_the_scoring_metric_scores_a_batch_as_the_loop(case, config):
    """The default (window match, softmax) and the structure preset (global match, power mean):
    forward(A batch, B batch) equals each pair scored alone."""
    metric = DRKFS.pretrained(config)
    truth_verts, truth_faces = case.truth
    references = torch.stack([truth_verts, truth_verts * 1.1])
    preds = case.preds[:2]
    with torch.no_grad():
        loop = torch.stack(
            [metric(p, case.faces, r, truth_faces) for p, r in zip(preds, references, strict=True)]
        )
        batch = metric(preds, case.faces, references, truth_faces, batch_reduction="none")
    assert torch.allclose(batch, loop, rtol=VALUE_RTOL, atol=0)
    # one reference shared by the batch
    with torch.no_grad():
        shared = metric(preds, case.faces, truth_verts, truth_faces, batch_reduction="none")
        first = metric(preds[0], case.faces, truth_verts, truth_faces)
    assert shared.shape == (2,) and torch.allclose(shared[0], first, rtol=VALUE_RTOL, atol=0)


def test_the_loss_is_a_module_that_moves_and_saves_with_a_model(loss):
    model = torch.nn.Module()
    model.loss = loss
    names = set(model.state_dict())
    assert "loss.metrics.0.descriptor.features.0.weight" in names
    assert "loss.metrics.1.detector.conv.weight" in names
    buffers = dict(model.named_buffers())
    assert "loss.metrics.0.renderer.rotations" in buffers  # cameras move with .to()
    assert "loss.metrics.0.window_table" in buffers  # the match table too
    assert model.to("cpu") is model and loss.metrics[0].renderer.eyes.device.type == "cpu"
    assert isinstance(loss.metrics, torch.nn.ModuleList)
    # a Target (and a staged batch of them) moves too
    verts, faces = (torch.as_tensor(a) for a in icosphere(1))
    target = loss.target(verts.float(), faces)
    moved = target.to("cpu")
    assert isinstance(moved, StagedTarget) and moved[0].features.device.type == "cpu"


def test_bad_input_is_one_value_error_naming_what_was_expected(loss):
    verts, faces = (torch.as_tensor(a) for a in icosphere(1))
    verts = verts.float()
    target = loss.target(verts, faces)
    diverged = verts.clone()
    diverged[3, 1] = float("inf")
    cases = [
        (verts[:, :2], faces, r"verts: expected a float tensor \(V, 3\) or \(B, V, 3\)"),
        (verts.long(), faces, r"verts: expected a float tensor"),
        (verts, faces.float(), r"faces: expected an integer tensor \(F, 3\)"),
        (verts[None].expand(2, -1, -1), faces[None].expand(3, -1, -1), r"B = 2"),
        (verts, torch.cat([faces, torch.tensor([[0, 1, len(verts)]])]), r"outside its"),
        (verts.to("meta"), faces.to("meta"), r"expected a tensor on cpu"),
        ([verts, verts], [faces], r"a list of 2"),
        ([], faces, r"at least one mesh"),
        # a NaN or infinite vertex drops its faces: the score would be finite and wrong
        (torch.full_like(verts, float("nan")), faces, r"verts: mesh 0 has NaN or infinite"),
        (torch.stack([verts, diverged]), faces, r"verts: mesh 1 has NaN or infinite"),
        ([verts, verts[:-1], diverged], faces[:10], r"verts: mesh 2 has NaN or infinite"),
    ]
    for bad_verts, bad_faces, message in cases:
        with pytest.raises(ValueError, match=message):
            loss(bad_verts, bad_faces, target)
    with pytest.raises(ValueError, match="unknown batch_reduction 'max'"):
        loss(verts[None], faces, target, batch_reduction="max")
    with pytest.raises(ValueError, match="verts: mesh 0 has NaN or infinite"):
        loss.target(diverged, faces)
    with pytest.raises(ValueError, match="target: on meta, the metric on cpu: move it"):
        loss(verts, faces, target.to("meta"))
    with pytest.raises(
        ValueError, match=r"target: \(108, 128\) descriptors, .* makes \(294, 128\)"
    ):
        loss(verts, faces, [target[1], target[0]])  # the stages' targets swapped
    batch_target = loss.target(verts[None].expand(2, -1, -1), faces)
    with pytest.raises(ValueError, match="a batch of 2 references needs as many predictions"):
        loss(verts[None].expand(3, -1, -1), faces, batch_target)


def test_the_devices_empty_patch_mask_is_the_runtimes(case):
    """The max-pool mask on the device and the runtime's integral-image mask agree on rendered
    views (and on single pixels at every distance from a patch)."""
    metric = DRKFS.pretrained(PipelineConfig.loss())
    with torch.no_grad():
        images = metric.render(case.preds[:2] * 0.8, case.faces)
    dots = torch.zeros(40, 1, 128, 128)
    for i, (row, col) in enumerate(np.random.default_rng(0).integers(0, 128, (40, 2))):
        dots[i, 0, row, col] = 0.3
    for views in (images, dots):
        found = nonempty_patches_on_device(views, metric.config)
        expected = numpy_nonempty(views[:, 0].numpy(), metric.config)
        assert np.array_equal(found.numpy(), expected)


def test_the_geometry_terms_take_batches():
    sphere = trimesh.creation.icosphere(2, radius=0.5)
    verts, faces = torch.tensor(sphere.vertices, dtype=torch.float32), torch.tensor(sphere.faces)
    batch = torch.stack([verts, 2 * verts])
    points = surface_points(batch, faces, 400, torch.Generator().manual_seed(0))
    assert points.shape == (2, 400, 3)
    radii = points.norm(dim=-1)
    assert (radii[0] <= 0.5 + 1e-5).all() and (radii[0] > 0.45).all()  # on the surface
    assert (radii[1] > 0.9).all()
    truth = surface_points(verts, faces, 300, torch.Generator().manual_seed(1))
    for norm in (1, 2):
        each = torch.stack([chamfer(p, truth, norm) for p in points])
        assert torch.allclose(chamfer(points, truth, norm, batch_reduction="none"), each)
        assert torch.allclose(chamfer(points, truth, norm), each.mean())
    assert chamfer(points[0], truth, 1) < chamfer(points[0], truth, 2) ** 0.5 * 2
    smooth = Smoothness(verts, faces)
    assert torch.allclose(smooth(batch), (smooth(batch[0]) + smooth(batch[1])) / 2)
    with pytest.raises(ValueError, match="unknown norm 3"):
        chamfer(points, truth, 3)


def test_a_degenerate_prediction_leaves_the_rest_of_its_batch_alone(case, loss):
    """A batch holding a prediction collapsed to a point, one flattened to a plane and one moved
    out of every view (a network early in training): every value and gradient is finite, and
    the healthy mesh's loss and gradient are those it has alone."""
    target, healthy = loss.target(*case.truth), case.preds[0]
    batch = torch.stack(
        [healthy, 0 * healthy, healthy * torch.tensor([1.0, 0.0, 1.0]), healthy + 100.0]
    )
    values, grads = _value_and_grad(
        lambda v: loss(v, case.faces, target, 0.0, batch_reduction="none"), batch
    )
    assert torch.isfinite(values).all() and torch.isfinite(grads).all()
    alone = _value_and_grad(lambda v: loss(v, case.faces, target, 0.0)[None], healthy[None])
    _assert_batch_equals_loop((values[:1], grads[:1]), alone)


def test_under_a_callers_mixed_precision_the_loss_terms_stay_float32(case, loss):
    """A forward inside ``torch.autocast`` (a network's mixed-precision step; the backward
    outside, as torch asks) gives the loss's and Chamfer's float32 values and gradients exactly,
    and Chamfer takes the half-precision points such a network outputs: under bfloat16 autocast
    the loss failed and Chamfer-L2 read 400x too large."""
    target, preds = loss.target(*case.truth), case.preds[:2]
    points = surface_points(preds, case.faces, 500, torch.Generator().manual_seed(0))
    truth = surface_points(*case.truth, 500, torch.Generator().manual_seed(1))

    def terms(verts, mixed: bool):
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=mixed):
            moved = points + verts.mean(1, keepdim=True)
            return torch.cat(
                [
                    loss(verts, case.faces, target, batch_reduction="none"),
                    chamfer(moved, truth, batch_reduction="none"),
                    chamfer(moved.bfloat16(), truth, batch_reduction="none"),
                ]
            )

    plain = _value_and_grad(lambda v: terms(v, False), preds)
    mixed = _value_and_grad(lambda v: terms(v, True), preds)
    assert mixed[0].dtype == torch.float32
    assert torch.equal(mixed[0], plain[0]) and torch.equal(mixed[1], plain[1])


def test_the_batch_benchmark_writes_its_rows(tmp_path):
    """bench/torch_batch.py at its smallest: one batched case with its pairs, memory and the
    batch's Chamfer-L2 beside it, as JSON."""
    import json
    import subprocess
    import sys

    script = ROOT / "bench" / "torch_batch.py"
    out = tmp_path / "batch.json"
    args = ["--devices", "cpu", "--sizes", "2", "--stages", "fine", "--repeats", "1"]
    args += ["--no-before", "--loop-sizes", "", "--eager-sizes", "", "--out", str(out)]
    subprocess.run([sys.executable, str(script), *args], check=True, capture_output=True)
    (row,) = json.loads(out.read_text())["rows"]
    assert (row["device"], row["stage"], row["batch"]) == ("cpu", "fine", 2)
    batched = row["batched"]
    assert 0 < batched["pairs_kept"] <= batched["pairs_enumerated"]
    assert batched["seconds_per_mesh"] == pytest.approx(batched["seconds"] / 2)
    assert batched["peak_memory_bytes"] > 0 and row["chamfer_l2_seconds"] > 0
