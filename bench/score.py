"""Benchmark of server scoring: the default config against the paper preset and Chamfer-L1,
onnxruntime against torch eager, in the same process.

    python bench/score.py --out bench/results/score.json [--repeats 3]

Per mesh, for the default config (``PipelineConfig()``) and the paper preset
(``PipelineConfig.paper()``) with 2 threads: seconds per new mesh (render + features, split),
seconds per match of two described meshes (the mesh against a copy jittered by 0.2% of its
size, so no descriptor has an exact copy), the torch path's (``DRKFS`` eager) new mesh and match
as ratios, its forward+backward for the jittered copy against a prepared target (what a training
step costs), the two paths' score difference, and the peak memory (max RSS) of the torch-free
part, measured before torch is imported. Chamfer-L1 (the benchmark's 20k samples) is timed on the
same pair. The paper preset's global search is also timed alone, by numpy's BLAS against the
exported match graph in onnxruntime and against the bare float32 product of the two sets. Each
case runs in its own process. A last case measures what decimation above the face budget
changes.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT.parent / "shared" / "meshes"
CASES = {
    "chair (288 faces)": ROOT / "examples" / "chair.obj",
    "cow (5.8k faces)": MESHES / "cow.obj",
    "fandisk (12.9k faces)": MESHES / "fandisk.obj",
}
DECIMATION_MESHES = ("stanford-bunny.obj", "beast.obj")
JITTER = 0.002


def _best(fn, repeats: int) -> tuple[float, object]:
    times, output = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        output = fn()
        times.append(time.perf_counter() - start)
    return min(times), output


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _jittered(mesh):
    from drkfs_onnx import check_mesh

    size = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    noise = np.random.default_rng(0).normal(scale=JITTER * size, size=mesh.vertices.shape)
    return check_mesh(mesh.vertices + noise, mesh.faces, mesh.source + " (jittered)")


def _nearest_search(queries: np.ndarray, targets: np.ndarray, repeats: int) -> dict:
    """Seconds of the nearest search alone, by the Scorer's numpy search and by the exported
    match graph in onnxruntime (both return each query's nearest target), and of the float32
    product of the two sets alone: the search's floor with this BLAS."""
    from drkfs_onnx.runtime.nearest import lift, nearest_indices
    from drkfs_onnx.runtime.sessions import open_match

    graph = open_match(threads=2).session
    lifted = lift(targets)  # cached per reference mesh by the Scorer
    numpy_s, by_numpy = _best(lambda: nearest_indices(queries, lifted), repeats)
    onnx_s, (by_graph,) = _best(lambda: graph.run(None, {"a": queries, "b": targets}), repeats)
    product_s, _ = _best(lambda: queries @ targets.T, repeats)
    return {
        "numpy": numpy_s,
        "blas_product": product_s,
        "numpy_over_blas_product": numpy_s / product_s,
        "onnx_match_graph": onnx_s,
        "onnx_over_numpy": onnx_s / numpy_s,
        "same_nearest": float(np.mean(by_numpy == by_graph)),
    }


PRESETS = ("default", "paper")
GOALS = {"new_mesh_s": 0.2, "match_s": 0.001, "torch_step_s": 1.0}  # the default config's


def _chamfer(mesh, other, repeats: int) -> dict:
    from drkfs_onnx.benchmark.methods import SURFACE_SAMPLES
    from drkfs_onnx.benchmark.point_metrics import sample_surface, surface_distances

    def sample(m):
        return sample_surface(m.vertices, m.faces, SURFACE_SAMPLES)

    new_s, samples = _best(lambda: sample(mesh), repeats)
    others = sample(other)
    match_s, _ = _best(lambda: surface_distances(others, samples), repeats)
    return {"new_mesh_s": new_s, "match_s": match_s}


def run_case(path: Path, preset: str, repeats: int) -> dict:
    from drkfs_onnx import PipelineConfig, load_mesh
    from drkfs_onnx.runtime import Scorer

    config = PipelineConfig.paper() if preset == "paper" else PipelineConfig()
    mesh = load_mesh(path)
    other = _jittered(mesh)
    scorer = Scorer(config, threads=2)

    def new_mesh():
        scorer.cache.clear()
        return scorer.features(mesh)

    new_s, reference = _best(new_mesh, repeats)
    centre, scale = reference.centre, reference.scale
    placed = (mesh.vertices - centre) / scale
    render_s, _ = _best(lambda: scorer.renderer.render(placed, mesh.faces), repeats)
    prediction = scorer.features(other, (centre, scale))
    match_s, ort_score = _best(lambda: scorer.match(prediction, reference), 5 * repeats)
    runtime = {"new_mesh_s": new_s, "render_s": render_s, "features_s": new_s - render_s}
    runtime.update(match_s=match_s, peak_rss_mb=_rss_mb())
    if config.matching == "global":
        runtime["nearest_search_s"] = _nearest_search(
            prediction.descriptors, reference.descriptors, 5 * repeats
        )

    import torch

    from drkfs_onnx import DRKFS
    from drkfs_onnx.matching import match_score

    torch.set_num_threads(2)
    metric = DRKFS.pretrained(config)
    verts = torch.tensor(placed, dtype=torch.float32)
    verts_other = torch.tensor((other.vertices - centre) / scale, dtype=torch.float32)
    faces = torch.tensor(mesh.faces)
    with torch.no_grad():
        torch_new_s, target = _best(lambda: metric.target(verts, faces), repeats)
        torch_pred = metric.features(verts_other, faces)
        torch_match_s, torch_score = _best(
            lambda: match_score(torch_pred, target.features, config), 5 * repeats
        )

    def training_step():
        leaf = verts_other.clone().requires_grad_(True)
        metric.score_to(leaf, faces, target).backward()
        return leaf.grad

    step_s, grad = _best(training_step, repeats)
    torch_score = float(torch_score)
    return {
        "mesh": path.name,
        "faces": int(len(mesh.faces)),
        "preset": preset,
        "config": config.to_dict(),
        "nonempty_patches": int(len(reference.descriptors)),
        "runtime": runtime,
        "torch_eager": {
            "new_mesh_s": torch_new_s,
            "match_s": torch_match_s,
            "forward_backward_to_target_s": step_s,
            "gradient_finite": bool(torch.isfinite(grad).all()),
        },
        "torch_over_runtime": {"new_mesh": torch_new_s / new_s, "match": torch_match_s / match_s},
        "score": {"runtime": ort_score, "torch": torch_score},
        "score_relative_difference": abs(ort_score - torch_score) / torch_score,
        "chamfer_l1": _chamfer(mesh, other, repeats),
        "goal_met": {
            "new_mesh_le_0.2s": new_s <= GOALS["new_mesh_s"],
            "match_le_1ms": match_s <= GOALS["match_s"],
            "torch_step_le_1s": step_s <= GOALS["torch_step_s"],
        },
    }


def run_decimation(name: str, repeats: int) -> dict:
    from drkfs_onnx import load_mesh
    from drkfs_onnx.runtime import Scorer
    from drkfs_onnx.runtime.decimate import decimate, face_budget

    mesh = load_mesh(MESHES / name)
    other = _jittered(mesh)
    full = Scorer(threads=2)
    budgeted = Scorer(threads=2, face_budget=face_budget(full.config))
    rows = {}
    for label, scorer in (("full", full), ("decimated", budgeted)):

        def new_mesh(scorer=scorer):
            scorer.cache.clear()
            return scorer.features(mesh)

        seconds, features = _best(new_mesh, repeats)
        rows[label] = {"new_mesh_s": seconds, "jittered_pair_score": scorer.score(other, mesh)}
        rows[label]["features"] = features
    centre, scale = rows["full"]["features"].centre, rows["full"]["features"].scale
    kept = decimate((mesh.vertices - centre) / scale, mesh.faces, full.config)[1]
    change = budgeted.match(rows["decimated"].pop("features"), rows["full"].pop("features"))
    full_score = rows["full"]["jittered_pair_score"]
    return {
        "mesh": name,
        "faces": int(len(mesh.faces)),
        "budget": face_budget(full.config),
        "faces_after": int(len(kept)),
        **rows,
        "decimated_vs_full_score": change,
        "jittered_pair_relative_change": abs(rows["decimated"]["jittered_pair_score"] - full_score)
        / full_score,
        "speedup": rows["full"]["new_mesh_s"] / rows["decimated"]["new_mesh_s"],
    }


def _child(args: list[str]) -> dict:
    result = subprocess.run(
        [sys.executable, __file__, *args], capture_output=True, text=True, check=False
    )
    if result.returncode != 0:
        raise RuntimeError(result.stderr)
    return json.loads(result.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="the JSON to write: bench/results/score.json")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--case", nargs=2, help=argparse.SUPPRESS)
    parser.add_argument("--decimation", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        print(json.dumps(run_case(Path(args.case[0]), args.case[1], args.repeats)))
        return
    if args.decimation:
        print(json.dumps(run_decimation(args.decimation, args.repeats)))
        return
    if args.out is None:
        parser.error("--out is required")
    cases = []
    for label, path in CASES.items():
        for preset in PRESETS:
            row = _child(["--case", str(path), preset, "--repeats", str(args.repeats)])
            cases.append(row)
            runtime, torch_row = row["runtime"], row["torch_eager"]
            print(
                f"{label:24} {preset:8} new {runtime['new_mesh_s']:.3f} s "
                f"(render {runtime['render_s']:.3f}) match {1000 * runtime['match_s']:.2f} ms; "
                f"torch fwd+bwd {torch_row['forward_backward_to_target_s']:.2f} s; Chamfer-L1 "
                f"new {row['chamfer_l1']['new_mesh_s']:.3f} s match "
                f"{1000 * row['chamfer_l1']['match_s']:.0f} ms"
            )
    decimation = [
        _child(["--decimation", name, "--repeats", str(args.repeats)]) for name in DECIMATION_MESHES
    ]
    for row in decimation:
        print(
            f"{row['mesh']}: {row['faces']} -> {row['faces_after']} faces, "
            f"{row['speedup']:.2f}x faster, pair score changes by "
            f"{100 * row['jittered_pair_relative_change']:.2f}%"
        )
    report = {
        "command": f"python bench/score.py --out {args.out} --repeats {args.repeats}",
        "goals": GOALS,
        "machine": {"platform": platform.platform(), "processor": platform.processor()},
        "threads": 2,
        "jitter": JITTER,
        "cases": cases,
        "decimation": decimation,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
