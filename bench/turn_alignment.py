"""Would turning each mesh onto its reference before it is rendered forgive a turn about any axis
while keeping what a viewer sees, and at what cost? The turn is drkfs-1.2's
(``contract.alignment``): found as registration finds one, points sampled on the mesh's surface
fitted to planes through their nearest of the reference's (point-to-plane ICP, rotation alone,
about the frame's origin, the reference's bounding-box centre, where the benchmark's turns sit),
none of a turn up to ``--least-degrees``, all of one from twice that, at most
``--most-degrees``.

Measured against drkfs-1.1 (no turn), each compared mesh described again after its turn, on
"meshes as they come", the synthetic tiers, both sides of the real tiers, the bars, the slide
check (on the runtime path) and (with --human) people's judgments. Retrieval only with
--retrieval: each of its 10,920 ordered pairs describes its query again.

    python bench/turn_alignment.py --out bench/results/turn_alignment_blas.json --human DIR

The cost is the turn's search alone, against describing a mesh (render and nets), both timed
in the run: a metric that turns describes the turned mesh instead of the mesh. The runs
turn_alignment.json, turn_alignment_4_steps.json and turn_alignment_trimmed.json searched with
scipy's KD-tree and 8,192 and 2,048 points, by this study's own search as of commit 49ecf5e.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from drkfs_lab.benchmark import as_they_come, human, sets
from drkfs_lab.benchmark.methods import DrkfsOnnx, Method
from drkfs_lab.benchmark.real_tiers import HELDOUT_MESHES, TRAINING_MESHES
from drkfs_lab.benchmark.run import (
    as_they_come_checks,
    as_they_come_line,
    bars_summary,
    lever_summary,
    retrieval_summary,
    score_everything,
    tier_accuracy,
)
from drkfs_lab.real_levers import runtime_slide
from drkfs_onnx import load_mesh
from drkfs_onnx.contract.alignment import aligning_turn, reference_surface, rotation_vector
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.contract.versions import metric_config
from drkfs_onnx.runtime import Scorer

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
TURNING = metric_config("drkfs-1.2")  # the turn's settings the options start from


def turning_config(least: float, args: argparse.Namespace) -> PipelineConfig:
    """drkfs-1.1 with the turn the options ask for."""
    return metric_config(as_they_come.UNTURNED).replace(
        align_degrees=args.most_degrees,
        align_from_degrees=least,
        align_reference_points=args.reference_samples,
        align_points=args.samples,
        align_steps=args.steps,
        align_fitted=args.fitted,
    )


class Recorded(Method):
    """A turning ``DrkfsOnnx`` that records the turn applied to each compared mesh (degrees,
    by the mesh's key) and the seconds its searches took (searched once more, apart)."""

    def __init__(self, method: DrkfsOnnx):
        self.method, self.outputs = method, method.outputs
        self.search_seconds, self.searches, self.degrees = 0.0, 0, {}

    def for_retrieval(self) -> Recorded:
        """A twin whose searches count apart: retrieval's are not the comparisons'."""
        return Recorded(self.method)

    @property
    def scorer(self) -> Scorer:
        return self.method.scorer

    def prepare(self, placed):
        return self.method.prepare(placed)

    def compare(self, a, b):
        placed, config = a[0], self.method.scorer.config
        start = time.perf_counter()
        turn = aligning_turn(placed.verts, placed.faces, b[2], config)
        self.search_seconds += time.perf_counter() - start
        self.searches += 1
        self.degrees[placed.key] = float(np.degrees(np.linalg.norm(rotation_vector(turn))))
        return self.method.compare(a, b)


def new_mesh_seconds(repeats: int, threads: int, config: PipelineConfig) -> dict:
    """Seconds to describe a new mesh (the example chair), to sample it as a reference and to
    search its turn onto a reference (the chair without a leg), interleaved; the ratio is a new
    mesh's cost with a search, or with both, over without."""
    scorer = Scorer(metric=as_they_come.UNTURNED, threads=threads, cache_size=0)
    chair, no_leg = load_mesh(EXAMPLES / "chair.obj"), load_mesh(EXAMPLES / "chair_no_leg.obj")
    frame = frame_of(no_leg.vertices)
    reference = reference_surface(place(no_leg.vertices, frame), no_leg.faces, config)
    placed = place(chair.vertices, frame)
    scorer.features(chair, frame)  # opens the graph's session
    seconds = {"describe": 0.0, "sample as a reference": 0.0, "search a turn": 0.0}
    for _ in range(repeats):
        start = time.perf_counter()
        scorer.features(chair, frame)
        described = time.perf_counter()
        reference_surface(placed, chair.faces, config)
        as_reference = time.perf_counter()
        aligning_turn(placed, chair.faces, reference, config)
        for name, seconds_taken in zip(
            seconds,
            (described - start, as_reference - described, time.perf_counter() - as_reference),
            strict=True,
        ):
            seconds[name] += seconds_taken / repeats
    describe = seconds["describe"]
    return {
        **seconds,
        "ratio": 1 + seconds["search a turn"] / describe,
        "ratio as a reference too": 1
        + (seconds["search a turn"] + seconds["sample as a reference"]) / describe,
    }


def command_line(parser: argparse.ArgumentParser, args: argparse.Namespace) -> str:
    """The command a run records: each option set to other than its default, in the order
    declared, the Geo-metric clone as DIR; the threads and repeats, which change how fast and
    not what, left out."""
    words = ["python bench/turn_alignment.py"]
    for name, value in vars(args).items():
        if name in ("threads", "repeats") or value == parser.get_default(name):
            continue
        flag = "--" + name.replace("_", "-")
        if value is True:
            words.append(flag)
        elif name == "human":
            words.append(f"{flag} DIR")
        else:
            shown = value if isinstance(value, list) else [value]
            words.append(
                " ".join([flag, *(f"{x:g}" if isinstance(x, float) else str(x) for x in shown)])
            )
    return " ".join(words)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--least-degrees", type=float, nargs="+", default=[TURNING.align_from_degrees]
    )
    parser.add_argument("--most-degrees", type=float, default=TURNING.align_degrees)
    parser.add_argument(
        "--steps", type=int, default=TURNING.align_steps, help="Gauss-Newton steps a search"
    )
    parser.add_argument(
        "--fitted",
        type=float,
        default=TURNING.align_fitted,
        help="share of the points a step after the first fits",
    )
    parser.add_argument("--reference-samples", type=int, default=TURNING.align_reference_points)
    parser.add_argument("--samples", type=int, default=TURNING.align_points)
    parser.add_argument("--retrieval", action="store_true", help="score retrieval too (slow)")
    parser.add_argument("--out", type=Path, help="the JSON to write (default: print only)")
    parser.add_argument("--human", type=Path, help="a Geo-metric clone (see drkfs bench --human)")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=10, help="new meshes timed")
    args = parser.parse_args()
    start = time.perf_counter()
    bench = sets.tier_set(quick=False)
    sets.real_tiers(bench, [*TRAINING_MESHES, *HELDOUT_MESHES])
    sets.bars(bench)
    as_they_come.add_section(bench)
    jod = human.add_human(bench, args.human) if args.human else None
    if args.retrieval:
        sets.retrieval(bench, list(sets.ALL_FAMILIES), sets.RETRIEVAL_PER_FAMILY)
    default = DrkfsOnnx("default", metric_config(as_they_come.UNTURNED), None, args.threads)
    configs = {least: turning_config(least, args) for least in args.least_degrees}
    aligned = [
        Recorded(DrkfsOnnx(f"aligned, none up to {least:g} degrees", config, None, args.threads))
        for least, config in configs.items()
    ]
    methods = {m.outputs[0]: m for m in (default, *aligned)}
    scores, costs = score_everything(bench, list(methods.values()), print)
    rows = {}
    for name, values in scores.comparisons.items():
        rows[name] = {
            "config": methods[name].scorer.config.to_dict(),
            **lever_summary(bench, values),
            "bars": bars_summary(bench, values),
            "slide": runtime_slide(methods[name]),
            **(
                {"retrieval": retrieval_summary(bench, scores.retrieval[name])}
                if args.retrieval
                else {}
            ),
            "human": None if jod is None else human.human_agreement(bench, values, jod),
            "as_they_come": {
                **tier_accuracy(bench, values, as_they_come.GROUP),
                "checks": as_they_come_checks(bench, values),
            },
        }
        for side in ("training", "held_out"):
            print(f"{name}: {as_they_come_line(rows[name]['as_they_come'], side)}")
    describe = costs["default"]["seconds_per_mesh"]
    results = {
        "command": command_line(parser, args),
        "metric": as_they_come.UNTURNED,
        "methods": rows,
        "seconds": {
            "describe_a_mesh": describe,
            **{f"{m.outputs[0]}: search a turn": m.search_seconds / m.searches for m in aligned},
        },
        "new_mesh_seconds": new_mesh_seconds(
            args.repeats, args.threads, configs[args.least_degrees[-1]]
        ),
        "degrees": {m.outputs[0]: m.degrees for m in aligned},
        "values": {
            name: {f"{c.base}/{c.label}": values.get(i) for i, c in enumerate(bench.comparisons)}
            for name, values in scores.comparisons.items()
        },
        "run_seconds": time.perf_counter() - start,
    }
    print(json.dumps(results["seconds"]))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
