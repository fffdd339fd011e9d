"""The torch path on a CUDA device: the loss and the scoring metric move with ``.to("cuda")`` and
agree with the CPU (run where torch sees a GPU; skipped elsewhere, CI included)."""

import pytest
import torch
from conftest import ROOT, loss_case

from drkfs_lab.benchmark.torch_checks import agreement, value_and_gradient
from drkfs_onnx import DRKFS, PipelineConfig
from drkfs_onnx.loss import DrkfsLoss

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")


@pytest.fixture(autouse=True)
def _default_compile(compile_setting):
    """The default's compiled equations (the rest of the tests run them eagerly)."""
    compile_setting("auto")


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
    prediction, faces, truth = loss_case()

    def on(device: str):
        loss = DrkfsLoss.pretrained().to(device)
        target = loss.target(*(t.to(device) for t in truth))
        moved = faces.to(device)
        return lambda v: loss(v, moved, target, progress)

    _assert_agree(on, prediction)


def test_the_scoring_metric_runs_on_cuda_and_agrees_with_the_cpu():
    prediction, faces, truth = loss_case()
    metric = DRKFS.pretrained(PipelineConfig.paper(num_views=6, image_size=128))

    def on(device: str):
        metric.to(device)
        moved, (verts, truth_faces) = faces.to(device), (t.to(device) for t in truth)
        return lambda v: metric(v, moved, verts, truth_faces)

    _assert_agree(on, prediction)


def test_a_batch_on_cuda_equals_the_loop_there_with_few_host_waits():
    """Four predictions in one call give each mesh's value and gradient of the loop on the GPU,
    and a step waits for the host at most four times (``set_sync_debug_mode``)."""
    import warnings

    prediction, faces, truth = loss_case()
    loss = DrkfsLoss.pretrained().to("cuda")
    faces = faces.cuda()
    target = loss.target(*(t.cuda() for t in truth))
    nudges = 0.01 * torch.randn(4, *prediction.shape, generator=torch.Generator().manual_seed(1))
    preds = (prediction[None] + nudges).cuda()
    for progress in (0.0, 1.0):
        looped = []
        for verts in preds:
            moved = verts.clone().requires_grad_(True)
            value = loss(moved, faces, target, progress)
            value.backward()
            looped.append((value.detach(), moved.grad))
        moved = preds.clone().requires_grad_(True)
        torch.cuda.synchronize()
        torch.cuda.set_sync_debug_mode("warn")
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                values = loss(moved, faces, target, progress, batch_reduction="none")
                values.sum().backward()
        finally:
            torch.cuda.set_sync_debug_mode("default")
        waits = [w for w in caught if "synchroniz" in str(w.message)]
        assert len(waits) <= 4, [str(w.message) for w in waits]
        expected = torch.stack([v for v, _ in looped])
        assert torch.allclose(values.detach(), expected, rtol=1e-5, atol=0)
        for grad, (_, loop_grad) in zip(moved.grad, looped, strict=True):
            cosine = torch.nn.functional.cosine_similarity(grad.flatten(), loop_grad.flatten(), 0)
            assert cosine >= 0.99999, f"stage at {progress}: gradient cosine {float(cosine):.8f}"


def test_the_readme_training_example_runs_on_cuda(monkeypatch):
    """The README's example picks the GPU where there is one, and runs there unchanged."""
    import re

    root = ROOT
    text = (root / "README.md").read_text()
    code = re.search(r"<!-- training-loop example -->\s*```python\n(.*?)```", text, re.S).group(1)
    namespace: dict = {}
    monkeypatch.chdir(root)
    exec(compile(code, "README.md", "exec"), namespace)
    offsets = namespace["offsets"]
    assert offsets.device.type == "cuda" and torch.isfinite(offsets.grad).all()
