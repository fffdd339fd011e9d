"""What one large mesh costs the server scorer, and what --max-faces saves: the Stanford bunny
subdivided to 1.1M and 4.4M faces (PLY), each scored against the bunny by ``drkfs-score pair``
in a process of its own, and the 4.4M one refused by ``--max-faces 1000000``.

    python bench/large_mesh.py [--threads 2] [--out bench/results/large_mesh.json]

Per case: the wall seconds of the command and the process's peak resident memory.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import trimesh

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "meshes" / "stanford-bunny.obj"
# the command in a child, which prints its exit status and peak resident memory last: VmHWM,
# the high-water mark of the child's own memory (getrusage's would carry this script's peak
# over the exec)
CHILD = """
import json, sys
from drkfs_onnx.runtime.cli import app
status = app(sys.argv[1:], standalone_mode=False) or 0
with open("/proc/self/status") as handle:
    peak = next(int(line.split()[1]) for line in handle if line.startswith("VmHWM:")) * 1024
print(json.dumps({"status": status, "peak_bytes": peak}))
"""


def subdivided(folder: Path) -> dict[str, Path]:
    """The bunny subdivided twice (1.1M faces) and three times (4.4M), as PLY files."""
    mesh = trimesh.load(BUNNY, process=False)
    verts, faces, written = mesh.vertices, mesh.faces, {}
    for times in (1, 2, 3):
        verts, faces = trimesh.remesh.subdivide(verts, faces)
        if times >= 2:
            path = folder / f"bunny_{len(faces)}.ply"
            trimesh.Trimesh(verts, faces, process=False).export(path)
            written[f"{len(faces):,} faces"] = path
    return written


def run(args: list[str]) -> dict:
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", CHILD, *args], capture_output=True, text=True, check=False
    )
    seconds = time.perf_counter() - start
    report = json.loads(done.stdout.strip().splitlines()[-1])
    return {**report, "seconds": seconds, "stderr": done.stderr.strip().splitlines()[-2:]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    threads = ["--threads", str(args.threads)]
    cases = {}
    with tempfile.TemporaryDirectory() as folder:
        meshes = subdivided(Path(folder))
        cases["the bunny (69k faces)"] = run(["pair", str(BUNNY), str(BUNNY), *threads])
        for name, path in meshes.items():
            cases[name] = run(["pair", str(path), str(BUNNY), *threads])
            print(name, cases[name], flush=True)
        biggest = str(list(meshes.values())[-1])
        refused = ["pair", biggest, str(BUNNY), "--max-faces", "1000000", *threads]
        cases["the largest, refused by --max-faces 1000000"] = run(refused)
    result = {
        "command": "python bench/large_mesh.py " + " ".join(sys.argv[1:]),
        "machine": {"processor": platform.processor() or platform.machine()},
        "cases": cases,
    }
    text = json.dumps(result, indent=1)
    if args.out is None:
        print(text)
    else:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
