"""The torch path on a CUDA device: the loss and the scoring metric move with ``.to("cuda")`` and
agree with the CPU (run where torch sees a GPU; skipped elsewhere, CI included)."""

import pytest
import torch

from drkfs_onnx import DRKFS, PipelineConfig
from drkfs_onnx.fitting.network import loss_step_case
from drkfs_onnx.loss import DrkfsLoss

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")


def _value_and_gradient(score, verts: torch.Tensor, device: str):
    moved = verts.detach().to(device, copy=True).requires_grad_(True)
    value = score(moved)
    value.backward()
    assert value.device.type == device
    return float(value.detach()), moved.grad.cpu()


def _assert_agree(cpu, cuda):
    (a, grad_a), (b, grad_b) = cpu, cuda
    assert b == pytest.approx(a, rel=1e-3)
    # TF32 convolutions on the device: the gradient's direction, not every digit
    cosine = torch.nn.functional.cosine_similarity(grad_a.flatten(), grad_b.flatten(), dim=0)
    assert cosine > 0.999


@pytest.mark.parametrize("progress", [0.0, 1.0])  # the coarse stage and the loss preset
def test_the_loss_runs_on_cuda_and_agrees_with_the_cpu(progress):
    prediction, faces, truth, _ = loss_step_case()

    def on(device: str):
        loss = DrkfsLoss.pretrained().to(device)
        target = loss.target(*(t.to(device) for t in truth))
        moved = faces.to(device)
        return _value_and_gradient(lambda v: loss(v, moved, target, progress), prediction, device)

    _assert_agree(on("cpu"), on("cuda"))


def test_the_scoring_metric_runs_on_cuda_and_agrees_with_the_cpu():
    prediction, faces, truth, _ = loss_step_case()
    metric = DRKFS.pretrained(PipelineConfig.paper(num_views=6, image_size=128))

    def on(device: str):
        metric.to(device)
        moved, (verts, truth_faces) = faces.to(device), (t.to(device) for t in truth)
        return _value_and_gradient(
            lambda v: metric(v, moved, verts, truth_faces), prediction, device
        )

    _assert_agree(on("cpu"), on("cuda"))
