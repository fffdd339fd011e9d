"""DR-KFS as a training loss: the loss preset, its coarse-to-fine stages, the soft match and the
README's training example."""

import re

import pytest
import torch
from conftest import ROOT

from drkfs_onnx import PipelineConfig, load_mesh
from drkfs_onnx.loss import COARSE_TO_FINE, DrkfsLoss, SoftMatch, Stage
from drkfs_onnx.match import best_match_distances, soft_match_distances

EXAMPLES = ROOT / "examples"


def _mesh(name: str):
    mesh = load_mesh(EXAMPLES / name)
    return torch.tensor(mesh.vertices, dtype=torch.float32), torch.tensor(mesh.faces)


def test_the_loss_preset_is_the_training_renderer_with_a_position_aligned_mean():
    config = PipelineConfig.loss()
    assert (config.sigma, config.gamma) == (PipelineConfig.training().sigma, 0.1)
    assert (config.matching, config.window, config.reduction) == ("window", 0, "mean")
    assert config.shaping("features") == PipelineConfig.training().shaping("features")  # same nets


def test_each_stage_runs_until_its_share_of_training_and_scores_a_mesh_zero_against_itself():
    loss = DrkfsLoss.pretrained()
    # past 1, a training run on past its schedule: the last stage
    assert [loss.stage(p) for p in (0.0, 0.39, 0.4, 0.9, 1.0, 1.5)] == [0, 0, 1, 1, 1, 1]
    verts, faces = _mesh("chair.obj")
    target = loss.target(verts, faces)
    assert len(target) == len(COARSE_TO_FINE)
    nudge = torch.tensor([0.005, 0.0, 0.0])
    for progress in (0.0, 0.4, 1.0):
        assert loss(verts, faces, target, progress).item() == 0.0
        assert loss(verts + nudge, faces, target, progress).item() > 0.0
    moved = verts.clone().requires_grad_(True)
    value = loss(moved + torch.tensor([0.02, 0.0, 0.0]), faces, target, 0.0)
    value.backward()
    assert value.item() > 0 and torch.isfinite(moved.grad).all() and moved.grad.abs().sum() > 0


@pytest.mark.parametrize("asked", [None, "tf32", "bfloat16"])
def test_a_training_step_runs_every_convolution_at_the_asked_precision(monkeypatch, asked):
    """cuDNN's TF32 (torch's own default for convolutions) turned a GPU batch's gradient away
    from the per-mesh loop's: the nets' convolutions, forward and backward, run in IEEE float32
    unless TF32 is asked for, and leave torch's setting as they found it. Under 'bfloat16'
    HardNet's run in bfloat16 and the detector's in IEEE float32."""
    import torch.nn.functional as F

    setting = torch.backends.cudnn.conv
    seen, dtypes = [], set()

    def recording(name, conv):
        def call(*args, **kwargs):
            seen.append((name, setting.fp32_precision))
            dtypes.add((name, args[0].dtype))
            return conv(*args, **kwargs)

        return call

    for name in ("conv2d", "conv_transpose2d"):
        monkeypatch.setattr(F, name, recording(name, getattr(F, name)))
    loss = DrkfsLoss.pretrained() if asked is None else DrkfsLoss.pretrained(conv_precision=asked)
    verts, faces = _mesh("chair.obj")
    target = loss.target(verts, faces)
    before = setting.fp32_precision
    seen.clear()
    moved = (verts + 0.01).requires_grad_(True)
    loss(moved, faces, target, 1.0).backward()
    expected = "tf32" if asked == "tf32" else "ieee"
    # the convs forward, their transposes backward
    assert set(seen) == {("conv2d", expected), ("conv_transpose2d", expected)}
    kinds = (torch.float32, torch.bfloat16) if asked == "bfloat16" else (torch.float32,)
    # HardNet's convs and the transposes of its own backward in bfloat16, the detector's not
    assert dtypes == {(name, kind) for name in ("conv2d", "conv_transpose2d") for kind in kinds}
    assert setting.fp32_precision == before
    with pytest.raises(ValueError, match="conv_precision 'bf16'; use one of ieee, tf32, bfloat16"):
        DrkfsLoss.pretrained(conv_precision="bf16")


def test_hardnet_in_bfloat16_keeps_the_loss_and_turns_its_gradient_little():
    """The cheaper CPU step (HardNet's convs in bfloat16): at both stages the loss within 0.2%
    of float32's and its gradient at cosine > 0.98 to float32's (measured on this CPU: 2.5e-5
    and 2e-4 of the value, cosine 0.999 and 0.994)."""
    verts, faces = _mesh("chair.obj")
    other, other_faces = _mesh("chair_no_leg.obj")
    found = {}
    for precision in ("ieee", "bfloat16"):
        loss = DrkfsLoss.pretrained(conv_precision=precision)
        target = loss.target(verts, faces)
        for progress in (0.0, 1.0):
            moved = other.clone().requires_grad_(True)
            value = loss(moved, other_faces, target, progress)
            value.backward()
            found[precision, progress] = (value.item(), moved.grad.flatten())
    for progress in (0.0, 1.0):
        (value, grad), (cheap, cheap_grad) = found["ieee", progress], found["bfloat16", progress]
        assert cheap == pytest.approx(value, rel=2e-3)
        assert torch.nn.functional.cosine_similarity(grad, cheap_grad, dim=0) > 0.98


@pytest.mark.parametrize("stage", range(len(COARSE_TO_FINE)))
def test_the_scores_from_equal_groups_of_cameras_average_to_the_score_and_its_gradient(stage):
    """A step from some cameras (``view_groups``) is the loss in expectation: under the loss
    preset's mean of a window match, each camera's patches count once and equally."""
    loss = DrkfsLoss.pretrained()
    metric = loss.metrics[stage]
    verts, faces = _mesh("chair.obj")
    target = loss.target(verts, faces)[stage]
    count = metric.config.num_views

    def value_and_gradient(cameras):
        moved = (verts + torch.tensor([0.02, 0.01, 0.0])).requires_grad_(True)
        value = metric.score_to(moved, faces, target, cameras=cameras)
        value.backward()
        return value.detach().double(), moved.grad.double()

    every, every_grad = value_and_gradient(None)
    parts = [value_and_gradient(list(range(g, count, 3))) for g in range(3)]
    assert every > 0 and len({round(float(v), 6) for v, _ in parts}) == 3
    assert torch.isclose(sum(v for v, _ in parts) / 3, every, rtol=1e-5)
    assert torch.allclose(
        sum(g for _, g in parts) / 3, every_grad, atol=1e-6 * every_grad.abs().max()
    )


def test_a_loss_over_view_groups_scores_each_call_from_one_group_drawn_by_its_seed():
    verts, faces = _mesh("chair.obj")
    moved = verts + torch.tensor([0.02, 0.0, 0.0])
    runs = []
    for _ in range(2):
        loss = DrkfsLoss.pretrained(view_groups=2)
        target = loss.target(verts, faces)
        runs.append([loss(moved, faces, target, 1.0).item() for _ in range(6)])
    metric, fine = loss.metrics[1], target[1]
    groups = {metric.score_to(moved, faces, fine, cameras=[g, g + 2, g + 4]).item() for g in (0, 1)}
    assert runs[0] == runs[1] and set(runs[0]) == groups  # the same draws, both groups drawn


def test_view_groups_and_cameras_are_refused_where_they_would_not_average_to_the_score():
    with pytest.raises(
        ValueError,
        match=r"view_groups: a divisor of every stage's camera count \(\[12, 6\]\); got 4",
    ):
        DrkfsLoss.pretrained(view_groups=4)
    verts, faces = _mesh("chair.obj")
    scoring = DrkfsLoss.pretrained((Stage(PipelineConfig(), 1.0),)).metrics[0]
    target = scoring.target(verts, faces)
    with pytest.raises(ValueError, match="needs one ring of them and a window match"):
        scoring.score_to(verts, faces, target, cameras=[0, 1])
    metric = DrkfsLoss.pretrained().metrics[1]
    target = metric.target(verts, faces)
    for cameras in ([], [0, 0], [6]):
        with pytest.raises(ValueError, match="cameras: distinct indices of the config's 6"):
            metric.score_to(verts, faces, target, cameras=cameras)


def test_a_schedule_must_end_with_a_stage_that_runs_to_the_end():
    with pytest.raises(ValueError, match="last stage"):
        DrkfsLoss([], (Stage(PipelineConfig.loss(), 0.5),), None)


def test_the_soft_match_anneals_and_tends_to_the_best_match():
    soft = SoftMatch(start=0.1, end=0.01)
    assert soft.temperature(0.0) == pytest.approx(0.1) and soft.temperature(1.0) == pytest.approx(
        0.01
    )
    config = PipelineConfig.loss(window=1)
    size = config.num_views * config.patches_per_view
    generator = torch.Generator().manual_seed(0)
    queries = torch.nn.functional.normalize(torch.randn(size, 8, generator=generator), dim=1)
    targets = torch.nn.functional.normalize(torch.randn(size, 8, generator=generator), dim=1)
    hard = best_match_distances(queries, targets, config)
    cold = soft_match_distances(queries, targets, config, 1e-4)
    warm = soft_match_distances(queries, targets, config, 1.0)
    assert torch.allclose(cold.double(), hard.double(), atol=1e-5)
    assert (warm > hard - 1e-6).all() and (
        warm > hard + 1e-3
    ).any()  # a weighted mean of the window


def test_the_soft_loss_scores_a_mesh_zero_against_itself_only_in_the_limit():
    loss = DrkfsLoss.pretrained((Stage(PipelineConfig.loss(window=1), 1.0),), SoftMatch())
    verts, faces = _mesh("chair.obj")
    target = loss.target(verts, faces)
    assert loss(verts, faces, target, 1.0).item() < loss(verts, faces, target, 0.0).item()
    # its floor: a patch's neighbours weigh in at its temperature, far below a small nudge's
    nudged = loss(verts + torch.tensor([0.005, 0.0, 0.0]), faces, target, 1.0).item()
    assert 0.0 <= loss(verts, faces, target, 1.0).item() < 0.05 * nudged


def test_readme_training_loop_example_runs_and_prints_each_step(monkeypatch, capsys, tmp_path):
    text = (ROOT / "README.md").read_text()
    block = re.search(r"<!-- training-loop example -->\s*```python\n(.*?)```", text, re.S)
    assert block is not None, "README lost its training-loop example"
    code = block.group(1)
    namespace: dict = {}
    monkeypatch.chdir(tmp_path)  # it runs from any folder
    torch.manual_seed(0)  # the surface points it draws
    exec(compile(code, "README.md", "exec"), namespace)
    assert torch.isfinite(namespace["offsets"].grad).all()
    assert namespace["offsets"].abs().sum() > 0
    printed = capsys.readouterr().out.splitlines()
    # each stage's terms over their first value: 4.0 (1 + 3 x 1) where a stage starts
    stages = [0, 0, 1, 1, 1]  # coarse until progress 0.4
    assert [line.split(":")[0] for line in printed] == [
        f"step {i}, stage {stage}" for i, stage in enumerate(stages)
    ]
    values = [float(line.split(": ")[1]) for line in printed]
    assert values[0] == values[2] == 4.0 and values[1] < 4.0 and values[3] < values[2]
