"""Benchmark of the torch metric: renderer and whole metric, forward and forward+backward.

    python bench/torch_metric.py [--out bench/results/torch_metric.json] [--repeats 2]

Meshes come from the repository's meshes/ (read in place): woody (~1k faces), cow (~5k), rocker-arm
(~20k), at the paper's config (25 views, 256 px). Each case runs in its own process so its peak
memory (max RSS) is its own. The sparse renderer is compared with the dense reference of the
tests at a size where the dense one runs, in the same run.

The training step: one DR-KFS step of the network study's prediction (8 deformed icospheres,
2,560 faces) against a prepared synthetic chair, render + features + match + backward: at each
stage of the loss (``drkfs_onnx.loss.DrkfsLoss.pretrained()``: its coarse stage and the loss
preset ``PipelineConfig.loss()``, goal 0.5 s) and at the first studies'
``PipelineConfig.training()``, the last with and without the BatchNorm folding, in the same
process.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import subprocess
import sys
import time
import warnings
from dataclasses import asdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT / "meshes"
CASES = {"1k": "woody.obj", "5k": "cow.obj", "20k": "rocker-arm.obj"}
WIDTHS = (1.0, 0.5, 0.25)


def timed_call(fn, repeats: int):
    """(best seconds over repeats, the last call's output)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        output = fn()
        times.append(time.perf_counter() - start)
    return min(times), output


def best_time(fn, repeats: int) -> float:
    return timed_call(fn, repeats)[0]


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def run_case(mesh_name: str, width: float, repeats: int, profile: bool) -> dict:
    import torch

    from drkfs_onnx import DRKFS, PipelineConfig, load_mesh
    from drkfs_onnx.contract.mesh import normalize_pair
    from drkfs_onnx.render.torch_ops import TORCH_OPS

    baseline_mb = _rss_mb()
    mesh = load_mesh(MESHES / mesh_name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        metric = DRKFS.pretrained(PipelineConfig.paper(descriptor_width=width))
    ref = torch.tensor(mesh.vertices, dtype=torch.float32)
    faces = torch.tensor(mesh.faces)
    generator = torch.Generator().manual_seed(0)
    pred = ref + 0.005 * ref.abs().max() * torch.randn(ref.shape, generator=generator)
    placed, _ = normalize_pair(pred, ref, ops=TORCH_OPS)

    def render_forward():
        with torch.no_grad():
            metric.render(placed, faces)

    def render_backward():
        verts = placed.clone().requires_grad_(True)
        metric.render(verts, faces).sum().backward()

    def metric_forward():
        with torch.no_grad():
            metric(pred, faces, ref, faces)

    def metric_backward():
        verts = pred.clone().requires_grad_(True)
        metric(verts, faces, ref, faces).backward()

    metric_backward()  # warm-up
    result = {
        "mesh": mesh_name,
        "faces": len(mesh.faces),
        "descriptor_width": width,
        "render_forward_s": best_time(render_forward, repeats),
        "render_forward_backward_s": best_time(render_backward, repeats),
        "metric_forward_s": best_time(metric_forward, repeats),
        "metric_forward_backward_s": best_time(metric_backward, repeats),
    }
    if profile:
        from torch.profiler import profile as torch_profile

        with torch_profile() as prof:
            metric_backward()
        events = sorted(prof.key_averages(), key=lambda e: e.self_cpu_time_total, reverse=True)
        total = sum(e.self_cpu_time_total for e in events)
        result["profile_top_ops"] = [
            {"op": e.key, "share": round(e.self_cpu_time_total / total, 3)} for e in events[:8]
        ]
    result["peak_rss_mb"] = _rss_mb()
    result["peak_rss_over_imports_mb"] = result["peak_rss_mb"] - baseline_mb
    return result


def run_training_step(repeats: int) -> dict:
    """One training step of the network study's prediction against a prepared target."""
    import torch

    from drkfs_lab.studies.network import loss_step_case
    from drkfs_onnx import DRKFS, PipelineConfig
    from drkfs_onnx.loss import DrkfsLoss

    prediction, faces, truth, name = loss_step_case()

    def timed_step(loss_of) -> float:
        def step():
            verts = prediction.clone().requires_grad_(True)
            loss_of(verts).backward()

        step()  # warm-up
        return best_time(step, repeats)

    loss = DrkfsLoss.pretrained()
    target = loss.target(*truth)
    stages = {
        f"stage {i} (until {stage.until:g})": timed_step(
            lambda v, p=stage.until - 1e-9: loss(v, faces, target, p)
        )
        for i, stage in enumerate(loss.stages)
    }
    metric = DRKFS.pretrained(PipelineConfig.training())
    with torch.no_grad():
        first = metric.target(*truth)
    folded = timed_step(lambda v: metric.score_to(v, faces, first))
    # the baseline: the layers one by one, as before the folding (an instance attribute shadows
    # the method; nn.Module's own __setattr__ would file the Sequential as a submodule instead)
    descriptor = metric.descriptor
    object.__setattr__(descriptor, "_folded", descriptor.features)
    layered = timed_step(lambda v: metric.score_to(v, faces, first))
    del descriptor.__dict__["_folded"]
    from torch.profiler import profile as torch_profile

    verts = prediction.clone().requires_grad_(True)
    with torch_profile() as prof:
        loss(verts, faces, target, 1.0).backward()
    events = sorted(prof.key_averages(), key=lambda e: e.self_cpu_time_total, reverse=True)
    total = sum(e.self_cpu_time_total for e in events)
    return {
        "prediction_faces": len(faces),
        "target": name,
        "loss": {
            "stages": [{"config": s.config.to_dict(), "until": s.until} for s in loss.stages],
            "soft_match": None if loss.soft is None else asdict(loss.soft),
            "step_s": stages,
            "goal_s": 0.5,
            "profile_top_ops_loss_preset": [
                {"op": e.key, "share": round(e.self_cpu_time_total / total, 3)} for e in events[:8]
            ],
        },
        "training_config": {
            "config": "PipelineConfig.training()",
            "step_s": folded,
            "step_without_batchnorm_folding_s": layered,
        },
    }


def run_dense_comparison(repeats: int) -> dict:
    """Sparse vs the tests' dense reference, same mesh and config, forward only."""
    import torch
    import trimesh

    sys.path.insert(0, str(ROOT / "tests"))
    from dense_reference import dense_render

    from drkfs_onnx import PipelineConfig
    from drkfs_onnx.render.renderer import Renderer

    config = PipelineConfig.paper(num_views=4, image_size=64)
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.8)
    verts = torch.tensor(sphere.vertices, dtype=torch.float32)
    faces = torch.tensor(sphere.faces)
    renderer = Renderer(config)
    with torch.no_grad():
        sparse_s, sparse = timed_call(lambda: renderer.render(verts, faces), repeats)
        dense_s, dense = timed_call(
            lambda: dense_render(verts, faces, renderer.cameras, config, "shaded"), repeats
        )
        diff = (sparse - dense).abs()
    return {
        "faces": len(faces),
        "views": config.num_views,
        "image_size": config.image_size,
        "sparse_forward_s": sparse_s,
        "dense_forward_s": dense_s,
        "dense_over_sparse": dense_s / sparse_s,
        "max_abs_difference": float(diff.max()),
    }


def _in_subprocess(args: list[str]) -> dict:
    out = subprocess.run(
        [sys.executable, __file__, *args], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "bench" / "results" / "torch_metric.json"))
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--case", help=argparse.SUPPRESS)
    parser.add_argument("--width", type=float, default=1.0, help=argparse.SUPPRESS)
    parser.add_argument("--profile", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--dense", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--training-step", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.training_step:
        print(json.dumps(run_training_step(args.repeats)))
        return
    if args.case:
        print(json.dumps(run_case(args.case, args.width, args.repeats, args.profile)))
        return
    if args.dense:
        print(json.dumps(run_dense_comparison(args.repeats)))
        return
    if not MESHES.is_dir():
        sys.exit(f"real meshes not found at {MESHES}")
    import torch

    repeats = ["--repeats", str(args.repeats)]
    cases = []
    for label, name in CASES.items():
        for width in WIDTHS if label == "5k" else (1.0,):
            extra = ["--profile"] if label == "5k" else []
            print(f"case {label} width {width} ...", file=sys.stderr, flush=True)
            row = _in_subprocess(["--case", name, "--width", str(width), *repeats, *extra])
            cases.append({"size": label, **row})
    print("dense reference ...", file=sys.stderr, flush=True)
    dense = _in_subprocess(["--dense", *repeats])
    print("training step ...", file=sys.stderr, flush=True)
    training = _in_subprocess(["--training-step", *repeats])
    goal = next(c for c in cases if c["size"] == "5k" and c["descriptor_width"] == 1.0)
    report = {
        "command": "python bench/torch_metric.py",
        "machine": {
            "cpu_threads": torch.get_num_threads(),
            "torch": torch.__version__,
            "python": platform.python_version(),
        },
        "config": "PipelineConfig.paper(descriptor_width=w): 25 views, 256 px; shipped weights",
        "goal": {"metric_forward_backward_s_at_5k": 3.0, "peak_memory_mb": 2048},
        "goal_case_paper_width": {
            "metric_forward_backward_s": goal["metric_forward_backward_s"],
            "peak_rss_mb": goal["peak_rss_mb"],
        },
        "cases": cases,
        "sparse_vs_dense": dense,
        "training_step": training,
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(report, indent=2) + "\n")
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
