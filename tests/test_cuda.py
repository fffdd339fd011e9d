"""The torch path on a CUDA device: the loss and the scoring metric move with ``.to("cuda")`` and
agree with the CPU (run where torch sees a GPU; skipped elsewhere, CI included)."""

import pytest
import torch

from drkfs_onnx import DRKFS, PipelineConfig
from drkfs_onnx.benchmark.torch_checks import agreement, value_and_gradient
from drkfs_onnx.fitting.network import loss_step_case
from drkfs_onnx.loss import DrkfsLoss

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")


def _assert_agree(on, prediction: torch.Tensor) -> None:
    """``on(device)``: the score of vertices on that device. Its value and gradient on CUDA must
    be computed there and agree with the CPU's."""

    def scored_on(device: str):
        score = on(device)

        def checked(verts: torch.Tensor) -> torch.Tensor:
            value = score(verts)
            assert value.device.type == device
            return value

        return value_and_gradient(checked, prediction, device)()

    found = agreement(scored_on("cpu"), scored_on("cuda"))
    assert found["value_relative_difference"] < 1e-3
    assert found["gradient_cosine"] > 0.999


@pytest.mark.parametrize("progress", [0.0, 1.0])  # the coarse stage and the loss preset
def test_the_loss_runs_on_cuda_and_agrees_with_the_cpu(progress):
    prediction, faces, truth, _ = loss_step_case()

    def on(device: str):
        loss = DrkfsLoss.pretrained().to(device)
        target = loss.target(*(t.to(device) for t in truth))
        moved = faces.to(device)
        return lambda v: loss(v, moved, target, progress)

    _assert_agree(on, prediction)


def test_the_scoring_metric_runs_on_cuda_and_agrees_with_the_cpu():
    prediction, faces, truth, _ = loss_step_case()
    metric = DRKFS.pretrained(PipelineConfig.paper(num_views=6, image_size=128))

    def on(device: str):
        metric.to(device)
        moved, (verts, truth_faces) = faces.to(device), (t.to(device) for t in truth)
        return lambda v: metric(v, moved, verts, truth_faces)

    _assert_agree(on, prediction)
