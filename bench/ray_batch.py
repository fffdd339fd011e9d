"""Benchmark of batch scoring on Ray: pairs per second with 1 and 2 workers against the serial
batch, in the same run.

    python bench/ray_batch.py --out bench/results/ray_batch.json [--copies 20]

The batch: each shared mesh against ``--copies`` copies of itself jittered by 0.2% of its size
(seeded), the default config. Each run is ``drkfs-score batch`` in its own process, one thread
per scorer: serial (the baseline), then ``--ray local`` with 1 and 2 workers. Ray's fixed cost
(starting a local instance and its workers) is measured by a one-row batch and reported apart, so
``pairs_per_s_after_start`` is the throughput a long batch approaches.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT / "meshes"
JITTER = 0.002
RUNS = {
    "serial": [],
    "ray, 1 worker": ["--ray", "local", "--workers", "1"],
    "ray, 2 workers": ["--ray", "local", "--workers", "2"],
}
# one thread per scorer, BLAS included
SINGLE_THREADED = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def write_pairs(folder: Path, copies: int) -> Path:
    """Jittered copies of every shared mesh as OBJ files, and the pairs CSV scoring each against
    its original (the reference)."""
    import trimesh

    from drkfs_onnx import load_mesh

    rows = []
    for seed, path in enumerate(sorted(MESHES.glob("*.obj"))):
        mesh = load_mesh(path)
        size = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
        rng = np.random.default_rng(seed)
        for copy in range(copies):
            noise = rng.normal(scale=JITTER * size, size=mesh.vertices.shape)
            target = folder / f"{path.stem}-{copy}.obj"
            trimesh.Trimesh(mesh.vertices + noise, mesh.faces, process=False).export(target)
            rows.append((target, path))
    pairs = folder / "pairs.csv"
    pairs.write_text("mesh_a,mesh_b\n" + "".join(f"{a},{b}\n" for a, b in rows))
    return pairs


def run_batch(pairs: Path, out: Path, options: list[str]) -> tuple[float, list[dict]]:
    start = time.perf_counter()
    command = ["drkfs-score", "batch", str(pairs), "--out", str(out), "--threads", "1", *options]
    subprocess.run(command, check=True, capture_output=True, env=SINGLE_THREADED)
    seconds = time.perf_counter() - start
    return seconds, list(csv.DictReader(out.open()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="bench/results/ray_batch.json")
    parser.add_argument("--copies", type=int, default=20)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        pairs = write_pairs(folder, args.copies)
        one_row = folder / "one.csv"
        one_row.write_text("".join(pairs.read_text().splitlines(keepends=True)[:2]))
        runs, scores = {}, {}
        for label, options in RUNS.items():
            start_s, _ = run_batch(one_row, folder / f"{label}-one.csv", options)
            seconds, records = run_batch(pairs, folder / f"{label}.csv", options)
            scores[label] = [record["score"] for record in records]
            runs[label] = {
                "seconds": seconds,
                "one_row_seconds": start_s,
                "pairs_per_s": len(records) / seconds,
                "pairs_per_s_after_start": len(records) / (seconds - start_s),
                "failed": sum(record["error"] != "" for record in records),
            }
            print(
                f"{label:16} {len(records)} pairs in {seconds:.1f} s "
                f"({runs[label]['pairs_per_s']:.2f} pairs/s; one row {start_s:.1f} s)"
            )
    serial = runs["serial"]["pairs_per_s_after_start"]
    for row in runs.values():
        row["over_serial_after_start"] = row["pairs_per_s_after_start"] / serial
    report = {
        "command": f"python bench/ray_batch.py --out {args.out} --copies {args.copies}",
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "pairs": len(scores["serial"]),
        "threads_per_scorer": 1,
        "runs": runs,
        "same_scores_as_serial": {label: s == scores["serial"] for label, s in scores.items()},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
