"""Benchmark of the batched training loss against the per-mesh loop, in the same run.

    python bench/torch_batch.py [--out bench/results/torch_batch.json] [--devices cpu,cuda]
                                [--sizes 1,8,32] [--stages coarse,fine] [--threads 2]
                                [--repeats 3] [--rounds 1] [--no-before] [--loop-sizes 1,8,32]
                                [--eager-sizes 32] [--before-archive TAR]

For each device (CUDA where torch sees one), each stage of ``DrkfsLoss.pretrained()`` (coarse:
progress 0; fine: progress 1) and each batch size B (128 too on CUDA), B predictions (the
network study's 2,560-face prediction, ``network.loss_step_case``, nudged B ways) against the
study's chair, forward+backward:

- **batched**: one call for the whole batch: seconds per batch and per mesh, peak memory of
  the step, pixel-face pairs enumerated and kept, host waits (CUDA, counted under
  ``torch.cuda.set_sync_debug_mode("warn")``), kernel launches (CUDA) and the 15 ops, by
  input shapes, whose own kernels took most of the GPU's time under the profiler (CUDA);
- **loop**: the same code called mesh by mesh, as a user without batches would;
- **before**: the per-mesh loop of the code before batches (commit ``BEFORE``, exported from
  git into a temporary folder and run in a child process), where git has it;
- **batched_eager** (CPU, ``--eager-sizes``): the batched call with the rasteriser's
  equations eager (``DRKFS_COMPILE=0``; by default a CPU compiles them for a training step,
  and the batched and loop rows' first, untimed step pays the compile);
- **batched_tf32** (CUDA): the batched call with the nets' convolutions in TF32
  (``conv_precision="tf32"``; the default is IEEE float32);
- **chamfer_l2**: Chamfer-L2 of the same batch, 5,000 points a mesh against 5,000 on the chair,
  by ``torch.cdist``, forward+backward.

Each batched case runs in a child process of its own, so its peak memory (CPU: the rise of the
maximum resident set over the step) is its own. Ratios are taken within the run; absolute times
are noisy here. With ``--rounds N`` a case's children (batched, compiled, loop, before) run in
turn N times and each keeps its fastest round: these cores drift by 10-30% over minutes, and a
ratio of two times taken minutes apart drifts with them. ``--out`` is written after each row,
so a run stopped by a time limit keeps the rows it finished (on an H100 the first five cases of
the default sizes took 330 s; on an H200 ``--stages fine,coarse --sizes 32 --loop-sizes 32``
finished the fine stage, B = 32 and 128, within 250 s).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import torch

from drkfs_lab.studies.network import loss_step_case

ROOT = Path(__file__).resolve().parents[1]
BEFORE = "ecf7222"  # the last commit whose torch path took one mesh per call
STAGES = {"coarse": 0.0, "fine": 1.0}
POINTS = 5000

# The case every row times: the network study's loss step (``studies.network.loss_step_case``),
# made once by this script and read by every child, so this code and the code before batches
# time the same tensors.
CASE = """
import torch
from drkfs_onnx.loss import DrkfsLoss

prediction, faces, truth = torch.load(CASE_FILE, weights_only=True)
nudges = 0.01 * torch.randn(SIZE, *prediction.shape, generator=torch.Generator().manual_seed(1))
loss = DrkfsLoss.pretrained(**OPTIONS).to(DEVICE)
faces, truth = faces.to(DEVICE), tuple(t.to(DEVICE) for t in truth)
preds = (prediction[None] + nudges).to(DEVICE)
target = loss.target(*truth)
"""

LOOP = """
import json, time
def sync():
    if DEVICE == "cuda":
        torch.cuda.synchronize()
def step():
    for verts in preds:
        moved = verts.clone().requires_grad_(True)
        loss(moved, faces, target, PROGRESS).backward()
    sync()
step()
times = []
for _ in range(REPEATS):
    start = time.perf_counter()
    step()
    times.append(time.perf_counter() - start)
print(json.dumps({"seconds": min(times)}))
"""


def synchronize(device: str) -> None:
    if device == "cuda":
        torch.cuda.synchronize()


def child(code: str, path: Path, env: dict | None = None, **values) -> dict:
    """Run ``code`` (the case, then a body printing one JSON line) with ``path`` first on
    sys.path, the capitals in ``values`` set and ``env`` added to the environment -> the JSON
    it printed."""
    header = "".join(f"{name} = {value!r}\n" for name, value in values.items())
    script = f"import sys\nsys.path.insert(0, {str(path)!r})\n" + header + code
    script += "\nimport drkfs_onnx\nassert drkfs_onnx.__file__.startswith(sys.path[0])\n"
    run = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        check=False,
        cwd=path,
        env={**os.environ, **(env or {})},
    )
    if run.returncode != 0:
        raise RuntimeError(f"child run failed:\n{run.stderr[-3000:]}")
    return json.loads(run.stdout.strip().splitlines()[-1])


def before_tree(folder: Path, archive: Path | None) -> Path | None:
    """The code before batches in ``folder``: from ``archive`` (a tar of ``git archive BEFORE
    drkfs_onnx runtime export pyproject.toml``, for a machine without the repository's history)
    or from git; None where neither has it. The weights are this checkout's ``models/``,
    unchanged since."""
    if archive is None:
        files = ["drkfs_onnx", "runtime", "export", "pyproject.toml"]
        run = subprocess.run(
            ["git", "-C", str(ROOT), "archive", BEFORE, *files], capture_output=True, check=False
        )
        if run.returncode != 0:
            return None
        data = run.stdout
    else:
        data = archive.read_bytes()
    subprocess.run(["tar", "-x", "-C", str(folder)], input=data, check=True)
    (folder / "models").symlink_to(ROOT / "models")
    return folder


BATCHED = """
import json, os, threading, time, warnings
TOP_OPS = 15
from drkfs_onnx.render.mesh_batch import MeshBatch
from drkfs_onnx.contract.mesh import place_by
from drkfs_onnx.render.torch_ops import TORCH_OPS
from drkfs_onnx.render.pair_plan import PairPlan

def sync():
    if DEVICE == "cuda":
        torch.cuda.synchronize()

def step():
    moved = preds.clone().requires_grad_(True)
    loss(moved, faces, target, PROGRESS).backward()
    sync()

found = {}
if DEVICE == "cuda":
    step()
    torch.cuda.reset_peak_memory_stats()
    base = torch.cuda.memory_allocated()
    step()
    found["peak_memory_bytes"] = torch.cuda.max_memory_allocated() - base
else:  # the resident set's rise over the first step (one-time allocations too: the compile's
    # about 135 MB), sampled
    def resident():
        with open("/proc/self/statm") as statm:
            return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    peak, done = [0], threading.Event()
    def sample():
        while not done.is_set():
            peak[0] = max(peak[0], resident())
            time.sleep(0.002)
    base = resident()
    sampler = threading.Thread(target=sample)
    sampler.start()
    step()
    done.set()
    sampler.join()
    found["peak_memory_bytes"] = max(peak[0], resident()) - base
# timed before the counts below: a profiler, once it has run, may leave its hooks on every launch
times = []
for _ in range(REPEATS):
    start = time.perf_counter()
    step()
    times.append(time.perf_counter() - start)
found["seconds"] = min(times)
if DEVICE == "cuda":
    torch.cuda.set_sync_debug_mode("warn")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        step_moved = preds.clone().requires_grad_(True)
        loss(step_moved, faces, target, PROGRESS).backward()
    torch.cuda.set_sync_debug_mode("default")
    sync()
    found["host_waits"] = sum("synchroniz" in str(w.message) for w in caught)
    activities = [torch.profiler.ProfilerActivity.CPU, torch.profiler.ProfilerActivity.CUDA]
    with torch.profiler.profile(activities=activities, record_shapes=True) as prof:
        step()
    found["kernel_launches"] = sum(
        1 for e in prof.events() if e.device_type == torch.autograd.DeviceType.CUDA
    )
    # where the GPU's time goes: the ops whose own kernels took most of it, by input shapes
    ops = sorted(prof.key_averages(group_by_input_shape=True),
                 key=lambda e: -e.self_device_time_total)[:TOP_OPS]
    found["top_ops"] = [{"op": e.key, "shapes": str(e.input_shapes)[:160], "calls": e.count,
                         "device_seconds": e.self_device_time_total / 1e6} for e in ops]
stage = loss.metrics[loss.stage(PROGRESS)]
with torch.no_grad():
    placed = place_by(preds, "joint", target[loss.stage(PROGRESS)].frame, TORCH_OPS)
    _, screen = stage.renderer.screen(MeshBatch.of(placed, faces))
    found["pairs_enumerated"] = PairPlan(screen, stage.config).num_pairs()
    found["pairs_kept"] = len(stage.renderer.rasterize(placed, faces).pixel)
print(json.dumps(found))
"""


def chamfer_seconds(device: str, size: int, repeats: int) -> float:
    """Chamfer-L2 by ``torch.cdist`` of (size, POINTS, 3) against (size, POINTS, 3),
    forward+backward: the best of ``repeats``."""
    generator = torch.Generator().manual_seed(0)
    points = torch.rand(size, POINTS, 3, generator=generator).to(device)
    truth = torch.rand(size, POINTS, 3, generator=generator).to(device)

    def step() -> None:
        moved = points.clone().requires_grad_(True)
        squared = torch.cdist(moved, truth) ** 2
        (squared.min(2).values.mean() + squared.min(1).values.mean()).backward()
        synchronize(device)

    step()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        step()
        times.append(time.perf_counter() - start)
    return min(times)


def case_rows(device: str, stage: str, size: int, args, old: Path | None, case: Path) -> dict:
    values = dict(DEVICE=device, SIZE=size, PROGRESS=STAGES[stage], REPEATS=args.repeats)
    values["CASE_FILE"] = str(case)
    threads = "import torch\n" + (
        f"torch.set_num_threads({args.threads})\n" if device == "cpu" else ""
    )
    # name: the environment it adds and DrkfsLoss.pretrained's options
    runs = {"batched": ({}, {})}
    if device == "cpu" and size in [int(s) for s in args.eager_sizes.split(",") if s]:
        runs["batched_eager"] = ({"DRKFS_COMPILE": "0"}, {})
    if device == "cuda":
        runs["batched_tf32"] = ({}, {"conv_precision": "tf32"})
    loops = {}
    if size in [int(s) for s in args.loop_sizes.split(",") if s]:
        loops = {"loop": ROOT} if old is None else {"loop": ROOT, "before": old}
    rounds = {name: [] for name in [*runs, *loops]}
    batched_code = threads + CASE + BATCHED
    for _ in range(args.rounds):
        for name, (env, options) in runs.items():
            rounds[name].append(child(batched_code, ROOT, env, OPTIONS=options, **values))
        for name, path in loops.items():
            rounds[name].append(child(threads + CASE + LOOP, path, OPTIONS={}, **values))
    fastest = {name: min(found, key=lambda r: r["seconds"]) for name, found in rounds.items()}
    batched = fastest["batched"]
    row = {
        "device": device,
        "stage": stage,
        "batch": size,
        "batched": {**batched, "seconds_per_mesh": batched["seconds"] / size},
        "chamfer_l2_seconds": chamfer_seconds(device, size, args.repeats),
    }
    row["batched_over_chamfer"] = batched["seconds"] / row["chamfer_l2_seconds"]
    variants = [name for name in runs if name != "batched"]
    for name in variants:
        found = fastest[name]
        row[name] = {**found, "seconds_per_mesh": found["seconds"] / size}
        row[f"{name}_over_chamfer"] = found["seconds"] / row["chamfer_l2_seconds"]
    for name in loops:
        seconds = fastest[name]["seconds"]
        row[name] = {"seconds": seconds, "seconds_per_mesh": seconds / size}
        for run in ["batched", *variants]:
            row[f"{run}_over_{name}"] = row[run]["seconds"] / seconds
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--devices", default="cpu,cuda")
    parser.add_argument("--sizes", default="1,8,32")
    parser.add_argument("--stages", default="coarse,fine")
    parser.add_argument("--loop-sizes", default="1,8,32", help="the sizes the loops run at")
    parser.add_argument(
        "--eager-sizes", default="32", help="CPU sizes also timed with DRKFS_COMPILE=0"
    )
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--rounds", type=int, default=1, help="times each case's children run in turn"
    )
    parser.add_argument("--no-before", action="store_true", help="skip the code before batches")
    parser.add_argument("--before-archive", type=Path, default=None)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    devices = [d for d in args.devices.split(",") if d != "cuda" or torch.cuda.is_available()]
    result = {
        "command": "python bench/torch_batch.py " + " ".join(sys.argv[1:]),
        "before_commit": BEFORE if not args.no_before else None,
        "machine": {
            "processor": platform.processor() or platform.machine(),
            "cpu_threads": args.threads,
            "torch": torch.__version__,
            "gpu": torch.cuda.get_device_name() if "cuda" in devices else None,
        },
        "rows": [],
    }

    def save() -> None:
        """The file holds every row so far: a run stopped by a time limit keeps what it did."""
        if args.out is not None:
            args.out.parent.mkdir(parents=True, exist_ok=True)
            args.out.write_text(json.dumps(result, indent=2) + "\n")

    with tempfile.TemporaryDirectory() as folder:
        old = None if args.no_before else before_tree(Path(folder), args.before_archive)
        prediction, faces, truth, _ = loss_step_case()
        case = Path(folder) / "case.pt"
        torch.save((prediction, faces, truth), case)
        for device in devices:
            sizes = [int(s) for s in args.sizes.split(",")] + ([128] if device == "cuda" else [])
            for stage in args.stages.split(","):
                for size in sizes:
                    row = case_rows(device, stage, size, args, old, case)
                    result["rows"].append(row)
                    print(json.dumps(row), flush=True)
                    save()
    if args.out is None:
        print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
