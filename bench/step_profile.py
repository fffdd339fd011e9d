"""Where a DR-KFS training step of the single-view study goes, and what HardNet in bfloat16
saves, measured in one run:

    python bench/step_profile.py --out bench/single_view/step_profile.json [--repeats 3]

The study's generator makes a batch of 16 shapes from their views; at each stage of the loss
(coarse: 12 views of 64 px; fine: the loss preset) the step's parts are timed apart: render
(forward), describe (detector and HardNet, forward), match, the describe's backward and the
render's backward (best of ``--repeats`` batches after one warm-up). Then HardNet on the fine
stage's non-empty patches as a step runs it, forward and backward, its convs in float32 and in
bfloat16 (``conv_precision="bfloat16"``; a CPU with AVX-512 BF16 or AMX runs them natively), with
the descriptors' largest difference.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from drkfs_lab.studies.shape_generator import ShapeGenerator
from drkfs_lab.studies.single_view import DRKFS_SHADED, FULL, draw_batch, training_data
from drkfs_lab.studies.study import machine
from drkfs_lab.studies.views import CHANNELS, IMAGE_SIZE
from drkfs_onnx.contract.mesh import place_by
from drkfs_onnx.loss import COARSE_TO_FINE, StagedTarget
from drkfs_onnx.match import match_score
from drkfs_onnx.metric import CPU_PATCH_GROUP
from drkfs_onnx.nets.patches import nonempty_patches_on_device, select_patches
from drkfs_onnx.render.mesh_batch import MeshBatch
from drkfs_onnx.render.torch_ops import TORCH_OPS

PARTS = ("render", "describe", "match", "describe_backward", "render_backward")


def step_parts(metric, model, views, targets, faces, rng, stage: int, repeats: int) -> dict:
    """Each part's best seconds over ``repeats`` batches of 16, after one warm-up batch."""
    best = dict.fromkeys(PARTS, float("inf"))
    for k in range(repeats + 1):
        batch = draw_batch(rng, len(views), 16)
        target = StagedTarget.stack([targets[i] for i in batch.shapes.tolist()])[stage]
        with torch.no_grad():
            verts = model(views[batch.shapes, batch.inputs])
        verts.requires_grad_()
        clock = [time.perf_counter()]
        meshes = MeshBatch.of(verts, faces)
        moved = meshes.moved(place_by(meshes.verts, metric.normalization, target.frame, TORCH_OPS))
        images = metric.render(moved)
        clock.append(time.perf_counter())
        seen = images.detach().requires_grad_()
        described = metric.describe(seen)
        clock.append(time.perf_counter())
        described = described.reshape(16, -1, described.shape[-1])
        config, table = metric.config, metric.window_table
        score = match_score(described, target.features, config, None, table).mean()
        clock.append(time.perf_counter())
        (grad,) = torch.autograd.grad(score, seen)
        clock.append(time.perf_counter())
        images.backward(grad)
        clock.append(time.perf_counter())
        if k:
            for name, start, end in zip(PARTS, clock[:-1], clock[1:], strict=True):
                best[name] = min(best[name], end - start)
    return best


def hardnet_dtypes(metric, patches: torch.Tensor, repeats: int) -> dict:
    """HardNet on ``patches`` as a training step runs it (the fixed nets' backward, groups of
    ``CPU_PATCH_GROUP``), forward and backward, its convs in float32 against bfloat16."""
    found, outputs = {}, {}
    for dtype in (torch.float32, torch.bfloat16):
        times = []
        for _ in range(repeats + 1):
            inputs = patches.clone().requires_grad_()
            start = time.perf_counter()
            out = metric.descriptor(inputs, CPU_PATCH_GROUP, dtype)
            out.square().sum().backward()
            times.append(time.perf_counter() - start)
        found[str(dtype).removeprefix("torch.")] = min(times[1:])
        outputs[dtype] = out.detach()
    found["bfloat16_over_float32"] = found["bfloat16"] / found["float32"]
    scale = outputs[torch.float32].abs().max()
    found["largest_difference_over_largest_value"] = float(
        (outputs[torch.bfloat16] - outputs[torch.float32]).abs().max() / scale
    )
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="the JSON to write (default: print only)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    root = Path(__file__).resolve().parent / "single_view"
    _, views, terms = training_data(root, FULL, torch.device("cpu"))
    loss, targets = terms.prepare(DRKFS_SHADED)
    torch.manual_seed(0)
    model = ShapeGenerator(CHANNELS, IMAGE_SIZE).eval()
    faces = model.faces
    rng = np.random.default_rng(0)
    stages = {}
    for index, stage in enumerate(COARSE_TO_FINE):
        metric = loss.metrics[index]
        parts = step_parts(metric, model, views["train"], targets, faces, rng, index, args.repeats)
        stages[f"until {stage.until}"] = {"config": stage.config.to_dict(), "seconds": parts,
                                          "total": sum(parts.values())}  # fmt: skip
    fine = loss.metrics[-1]
    with torch.no_grad():
        verts = model(views["train"][:16, 0])
        images = fine.render(verts, faces)
    seen = torch.nonzero(nonempty_patches_on_device(images, fine.config)).squeeze(1)
    patches = select_patches(fine.detector(images), seen, fine.config)
    results = {
        "command": f"python bench/step_profile.py --repeats {args.repeats} --threads "
        f"{args.threads}" + (f" --out {args.out}" if args.out else ""),
        **machine(),
        "batch": 16,
        "stages": stages,
        "hardnet_patches": len(patches),
        "hardnet_forward_backward_s": hardnet_dtypes(fine, patches, args.repeats),
    }
    text = json.dumps(results, indent=1)
    print(text)
    if args.out:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
