"""Benchmark of the torch path on a CUDA device against the CPU, in the same run.

    python bench/torch_cuda.py [--out bench/results/torch_cuda.json] [--threads 2] [--meshes DIR]

Timed on both: the shipped loss's training step at each of its stages (the network study's
prediction, 2,560 faces, against a synthetic chair: ``network.loss_step_case``), and the
scoring metric at the paper preset (25 views, 256 px), forward and forward+backward, on the shared
cow (~5k faces) and rocker-arm (~20k). Beside each time, how far the device's numbers are from
the CPU's: the relative difference of the value and the cosine between the two gradients (the
device's convolutions may run in TF32). The CPU runs at ``--threads`` (2: the project's machine).
Exits with a note where torch sees no CUDA device.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

import torch

from drkfs_lab.benchmark.torch_checks import agreement, value_and_gradient
from drkfs_lab.studies.network import loss_step_case
from drkfs_lab.torch_metric import MESHES, timed_call
from drkfs_onnx import DRKFS, PipelineConfig, load_mesh
from drkfs_onnx.contract.mesh import normalize_pair
from drkfs_onnx.loss import DrkfsLoss
from drkfs_onnx.render.torch_ops import TORCH_OPS

SCORED = {"5k": "cow.obj", "20k": "rocker-arm.obj"}


def synchronize(device: str) -> None:
    if device == "cuda":  # CUDA runs asynchronously: wait for its kernels before the clock
        torch.cuda.synchronize()


def timed(fn, device: str, repeats: int) -> tuple[float, object]:
    """(best seconds over ``repeats`` after a warm-up call, the last call's output)."""

    def call():
        output = fn()
        synchronize(device)
        return output

    call()  # warm-up, which also leaves the device idle before the first clock
    return timed_call(call, repeats)


def loss_steps(repeats: int) -> dict:
    prediction, faces, truth, name = loss_step_case()

    def on(device: str) -> dict:
        """Each stage's (seconds, (value, gradient)) on ``device``."""
        loss = DrkfsLoss.pretrained().to(device)
        target = loss.target(*(t.to(device) for t in truth))
        moved = faces.to(device)
        return {
            f"stage {i} (until {stage.until:g})": timed(
                value_and_gradient(
                    lambda v, p=stage.until - 1e-9: loss(v, moved, target, p), prediction, device
                ),
                device,
                repeats,
            )
            for i, stage in enumerate(loss.stages)
        }

    cpu, cuda = on("cpu"), on("cuda")
    return {
        "prediction_faces": len(faces),
        "target": name,
        "step_s": {
            stage: {
                "cpu": cpu[stage][0],
                "cuda": cuda[stage][0],
                "cpu_over_cuda": cpu[stage][0] / cuda[stage][0],
                **agreement(cpu[stage][1], cuda[stage][1]),
            }
            for stage in cpu
        },
    }


def scoring(meshes: Path, repeats: int) -> list[dict]:
    metric = DRKFS.pretrained(PipelineConfig.paper())

    def on(device: str, prediction: torch.Tensor, reference: torch.Tensor, faces: torch.Tensor):
        """(forward seconds, forward+backward seconds, (value, gradient)) on ``device``."""
        metric.to(device)
        ref, moved = reference.to(device), faces.to(device)

        def score(verts: torch.Tensor) -> torch.Tensor:
            return metric(verts, moved, ref, moved)

        def forward() -> torch.Tensor:
            with torch.no_grad():
                return score(prediction.to(device))

        backward = value_and_gradient(score, prediction, device)
        return timed(forward, device, repeats)[0], *timed(backward, device, repeats)

    rows = []
    for size, name in SCORED.items():
        mesh = load_mesh(meshes / name)
        reference = torch.tensor(mesh.vertices, dtype=torch.float32)
        faces = torch.tensor(mesh.faces)
        generator = torch.Generator().manual_seed(0)
        noise = torch.randn(reference.shape, generator=generator)
        noisy = reference + 0.005 * reference.abs().max() * noise
        prediction, _ = normalize_pair(noisy, reference, ops=TORCH_OPS)
        cpu = on("cpu", prediction, reference, faces)
        torch.cuda.reset_peak_memory_stats()
        cuda = on("cuda", prediction, reference, faces)
        rows.append(
            {
                "size": size,
                "mesh": name,
                "faces": len(faces),
                "cpu_forward_s": cpu[0],
                "cuda_forward_s": cuda[0],
                "cpu_over_cuda_forward": cpu[0] / cuda[0],
                "cpu_forward_backward_s": cpu[1],
                "cuda_forward_backward_s": cuda[1],
                "cpu_over_cuda_forward_backward": cpu[1] / cuda[1],
                "cuda_peak_memory_mb": torch.cuda.max_memory_allocated() / 2**20,
                **agreement(cpu[2], cuda[2]),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench/results/torch_cuda.json"))
    parser.add_argument("--threads", type=int, default=2, help="the CPU's torch threads")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--meshes", type=Path, default=MESHES, help="cow.obj and rocker-arm.obj")
    args = parser.parse_args()
    if not torch.cuda.is_available():
        sys.exit("torch sees no CUDA device: nothing to compare the CPU with")
    torch.set_num_threads(args.threads)
    report = {
        "command": f"python bench/torch_cuda.py --out {args.out}",
        "torch": torch.__version__,
        "gpu": torch.cuda.get_device_name(0),
        "platform": platform.platform(),
        "cpu_threads": args.threads,
        "repeats": args.repeats,
        "loss_step": loss_steps(args.repeats),
        "paper_preset": scoring(args.meshes, args.repeats),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1) + "\n")
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
