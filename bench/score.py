"""Benchmark of server scoring: onnxruntime runtime against torch eager, in the same process.

    python bench/score.py [--out bench/results/score.json] [--repeats 3]

Per mesh and HardNet width, at the paper's config (25 views, 256 px) with 2 threads:
seconds per new mesh (render + features, split), seconds per pair with cached features (the mesh
against a copy jittered by 0.2% of its size, so no descriptor has an exact copy), the same two
for the torch path (``DRKFS`` eager, no grad) as ratios, the two paths' score difference, and the
peak memory (max RSS) of the torch-free part, measured before torch is imported, and the nearest
search alone by numpy's BLAS against the exported match graph in onnxruntime and against the bare
float32 product of the two sets (its floor). Each case runs in its own process. A last case
measures what decimation above the face budget changes.
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
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT.parent / "shared" / "meshes"
CASES = {
    "chair (288 faces)": ROOT / "examples" / "chair.obj",
    "cow (5.8k faces)": MESHES / "cow.obj",
    "fandisk (12.9k faces)": MESHES / "fandisk.obj",
}
WIDTHS = (1.0, 0.5, 0.25)
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


def run_case(path: Path, width: float, repeats: int) -> dict:
    from drkfs_onnx import PipelineConfig, load_mesh
    from drkfs_onnx.runtime import Scorer

    config = PipelineConfig(descriptor_width=width)
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
    pair_s, ort_score = _best(lambda: scorer.match(prediction, reference), 5 * repeats)
    search = _nearest_search(prediction.descriptors, reference.descriptors, 5 * repeats)
    runtime_rss = _rss_mb()

    import torch

    from drkfs_onnx import DRKFS
    from drkfs_onnx.matching import match_score

    torch.set_num_threads(2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        metric = DRKFS.pretrained(config)
    verts = torch.tensor((mesh.vertices - centre) / scale, dtype=torch.float32)
    verts_other = torch.tensor((other.vertices - centre) / scale, dtype=torch.float32)
    faces = torch.tensor(mesh.faces)
    with torch.no_grad():
        torch_new_s, torch_ref = _best(lambda: metric.features(verts, faces), repeats)
        torch_pred = metric.features(verts_other, faces)
        torch_pair_s, torch_score = _best(lambda: match_score(torch_pred, torch_ref), 5 * repeats)
    torch_score = float(torch_score)
    return {
        "mesh": path.name,
        "faces": int(len(mesh.faces)),
        "width": width,
        "nonempty_patches": int(len(reference.descriptors)),
        "runtime": {
            "new_mesh_s": new_s,
            "render_s": render_s,
            "features_s": new_s - render_s,
            "cached_pair_s": pair_s,
            "nearest_search_s": search,
            "peak_rss_mb": runtime_rss,
        },
        "torch_eager": {"new_mesh_s": torch_new_s, "cached_pair_s": torch_pair_s},
        "torch_over_runtime": {
            "new_mesh": torch_new_s / new_s,
            "cached_pair": torch_pair_s / pair_s,
        },
        "score": {"runtime": ort_score, "torch": torch_score},
        "score_relative_difference": abs(ort_score - torch_score) / torch_score,
        "goal_met": {"new_mesh_le_0.5s": new_s <= 0.5, "cached_pair_le_10ms": pair_s <= 0.010},
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
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "score.json")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--case", nargs=2, help=argparse.SUPPRESS)
    parser.add_argument("--decimation", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        print(json.dumps(run_case(Path(args.case[0]), float(args.case[1]), args.repeats)))
        return
    if args.decimation:
        print(json.dumps(run_decimation(args.decimation, args.repeats)))
        return
    cases = []
    for label, path in CASES.items():
        for width in WIDTHS:
            row = _child(["--case", str(path), str(width), "--repeats", str(args.repeats)])
            cases.append(row)
            runtime = row["runtime"]
            search = runtime["nearest_search_s"]
            print(
                f"{label:24} w{width:<5g} new {runtime['new_mesh_s']:.3f} s "
                f"(render {runtime['render_s']:.3f}) pair {1000 * runtime['cached_pair_s']:.1f} ms"
                f" (BLAS product alone {1000 * search['blas_product']:.1f} ms,"
                f" onnx search {search['onnx_over_numpy']:.2f}x numpy)"
                f"  torch/ort {row['torch_over_runtime']['new_mesh']:.2f}x new, "
                f"{row['torch_over_runtime']['cached_pair']:.2f}x pair"
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
        "command": "python bench/score.py" + (f" --repeats {args.repeats}"),
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
