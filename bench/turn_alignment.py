"""Would turning each mesh onto its reference before it is rendered forgive a turn about any axis
while keeping what a viewer sees, and at what cost? The turn is found as registration finds one:
points sampled on the mesh's surface fitted to planes through its nearest points of the
reference's (point-to-plane ICP, rotation alone, about the reference's bounding-box centre, where
the benchmark's turns and the metric's frame sit), none of a turn up to ``--least-degrees`` (what
fitting two samplings of one surface finds), all of one from twice that, at most
``--most-degrees``, so that a larger turn still counts from there.

Measured without changing the metric: the default's scorer, each compared mesh described again
after the turn is applied, on "meshes as they come", the synthetic tiers, both sides of the real
tiers, the bars, the slide check (on the runtime path) and (with --human) people's judgments.
Retrieval only with --retrieval: each of its 10,920 ordered pairs describes its query again.

    python bench/turn_alignment.py --out bench/results/turn_alignment.json --human DIR
    python bench/turn_alignment.py \
        --least-degrees 0.1 --fitted 0.6 --retrieval --out OUT --human DIR

The cost is the turn's search alone, against describing a mesh (render and nets), both timed
in the run: a metric that aligned would describe the turned mesh instead of the mesh. With
``--nearest blas`` the nearest points are found by the runtime's BLAS product, as a server
install (no scipy) would find them.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from drkfs_lab.benchmark import as_they_come, human, sets
from drkfs_lab.benchmark.methods import DrkfsOnnx, Method, Placed
from drkfs_lab.benchmark.point_metrics import sample_surface
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
from drkfs_onnx import PipelineConfig, load_mesh
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.contract.nearest import lift, nearest_lifted
from drkfs_onnx.contract.versions import LATEST
from drkfs_onnx.runtime import Scorer

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
REFERENCE_SAMPLES = 8192  # the reference's points, each with its face's normal
SAMPLES = 2048  # the turned mesh's points
STEPS = 3  # Gauss-Newton steps of a search, each against the nearest points found anew
NEAREST = ("kd", "blas")  # scipy's KD-tree; runtime/nearest.py's BLAS product (base install)
REACH = 0.1  # a point farther from the reference's nearest (unit-sphere frame) is not fitted
FACING = 0.5  # nor one whose face's normal and its nearest's meet at a cosine below this
LEAST_DEGREES = [0.0, 0.1]


def turn_of(vector: np.ndarray) -> np.ndarray:
    """(3, 3) the rotation by |vector| radians about ``vector`` (Rodrigues)."""
    angle = float(np.linalg.norm(vector))
    if angle == 0.0:
        return np.eye(3)
    k = np.cross(np.eye(3), vector / angle)  # the cross-product matrix of the unit axis
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def aligning_turn(
    points: np.ndarray, normals: np.ndarray, reference: tuple[np.ndarray, np.ndarray, cKDTree],
    least_degrees: float, most_degrees: float, steps: int, fitted: float = 1.0,
) -> np.ndarray:  # fmt: skip
    """(3, 3) the rotation about the origin that best lays ``points`` on the reference's
    surface (Gauss-Newton on the point-to-plane distances to the nearest reference points,
    the rotation linearised at each step), as much of it as ``kept_turn`` keeps. The first
    step fits every point; each later one the share ``fitted`` of them nearest their planes
    (a trimmed fit: a part moved, added or thickened does not pull the turn)."""
    ref_points, ref_normals, tree = reference
    turn = np.eye(3)
    for step_number in range(steps):
        moved, moved_normals = points @ turn.T, normals @ turn.T
        distance, nearest = tree.query(moved)
        kept = (distance < REACH) & (np.abs((moved_normals * ref_normals[nearest]).sum(1)) > FACING)
        if kept.sum() < 3:
            break
        n = ref_normals[nearest[kept]]
        residual = ((moved[kept] - ref_points[nearest[kept]]) * n).sum(1)
        rows = np.cross(moved[kept], n)
        if step_number and fitted < 1.0:
            near = np.abs(residual) <= np.quantile(np.abs(residual), fitted)
            rows, residual = rows[near], residual[near]
        step = np.linalg.lstsq(rows, -residual, rcond=None)[0]
        turn = turn_of(step) @ turn
    return turn_of(kept_turn(rotation_vector(turn), least_degrees, most_degrees))


def kept_turn(vector: np.ndarray, least_degrees: float, most_degrees: float) -> np.ndarray:
    """The part of a found turn (axis times radians) that is applied: none up to
    ``least_degrees`` (what a fit of two samplings of one surface finds: a file's faces, a
    simplification's), all of it from twice that, a smoothstep between (the applied turn
    grows continuously with the found one); at most ``most_degrees``."""
    angle = float(np.degrees(np.linalg.norm(vector)))
    if angle <= least_degrees:
        return np.zeros(3)
    ramp = 1.0 if angle >= 2 * least_degrees else (angle - least_degrees) / least_degrees
    kept = ramp * ramp * (3 - 2 * ramp) * min(angle, most_degrees)
    return vector * kept / angle


def rotation_vector(turn: np.ndarray) -> np.ndarray:
    """The axis times the angle (radians) of a rotation matrix."""
    skew = np.array([turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0], turn[1, 0] - turn[0, 1]])
    sine, cosine = np.linalg.norm(skew) / 2, (np.trace(turn) - 1) / 2
    if sine == 0.0:
        return np.zeros(3)
    return skew / (2 * sine) * np.arctan2(sine, cosine)


class BlasNearest:
    """Each query point's nearest of ``points`` by the runtime's BLAS search (no scipy), with
    cKDTree's ``query`` signature."""

    def __init__(self, points: np.ndarray):
        self.points, self.lifted = points, lift(points)

    def query(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        nearest = nearest_lifted(x, self.lifted)
        return np.linalg.norm(x - self.points[nearest], axis=1), nearest


@dataclass(frozen=True)
class Search:
    """How a turn is searched: the points sampled on each side, the steps, the share of points
    each step after the first fits, and the nearest-point search (``NEAREST``)."""

    reference_samples: int = REFERENCE_SAMPLES
    samples: int = SAMPLES
    steps: int = STEPS
    fitted: float = 1.0
    nearest: str = "kd"

    def reference(self, verts: np.ndarray, faces: np.ndarray):
        """A reference's points, their normals and their nearest-point search; None where the
        surface has no area."""
        found = sample_surface(verts, faces, self.reference_samples, 0)
        if not len(found.points):
            return None
        finder = (cKDTree if self.nearest == "kd" else BlasNearest)(found.points)
        return found.points, found.normals, finder

    def turn(self, verts, faces, reference, least: float, most: float) -> np.ndarray:
        """(3, 3) the turn applied to a mesh before it is compared with ``reference``."""
        found = sample_surface(verts, faces, self.samples, 1)
        if reference is None or not len(found.points):
            return np.eye(3)
        return aligning_turn(
            found.points, found.normals, reference, least, most, self.steps, self.fitted
        )  # fmt: skip

    def settings(self) -> dict:
        """The JSON's record of the search (its defaults' fields left out where unchanged)."""
        return {
            "reference_samples": self.reference_samples,
            "samples": self.samples,
            "steps": self.steps,
            **({"fitted": self.fitted} if self.fitted != 1.0 else {}),
            **({"nearest": self.nearest} if self.nearest != "kd" else {}),
            "reach": REACH,
            "facing": FACING,
        }


class Aligned(Method):
    """The default's scorer with each compared mesh (A) turned onto the reference (B) first:
    ``prepare`` samples a mesh as a reference and describes it, ``compare`` finds A's turn onto
    B, describes A turned and matches it against B."""

    def __init__(self, method: DrkfsOnnx, name: str, least: float, most: float, search: Search):
        self.method, self.outputs = method, (name,)
        self.bounds, self.search = (least, most), search
        self.search_seconds, self.searches, self.degrees = 0.0, 0, {}

    def for_retrieval(self) -> Aligned:
        """A twin whose searches count apart: retrieval's are not the comparisons'."""
        return Aligned(self.method, self.outputs[0], *self.bounds, self.search)

    def prepare(self, placed):
        start = time.perf_counter()
        reference = self.search.reference(placed.verts, placed.faces)
        sampling = time.perf_counter() - start
        features, seconds = self.method.prepare(placed)
        return (placed, reference, features), sampling + seconds

    def compare(self, a, b):
        (placed, _, features), (_, reference, reference_features) = a, b
        start = time.perf_counter()
        turn = self.search.turn(placed.verts, placed.faces, reference, *self.bounds)
        self.search_seconds += time.perf_counter() - start
        self.searches += 1
        self.degrees[placed.key] = float(np.degrees(np.linalg.norm(rotation_vector(turn))))
        if not np.array_equal(turn, np.eye(3)):
            turned = Placed(f"{placed.key}@aligned", placed.verts @ turn.T, placed.faces)
            features = self.method.prepare(turned)[0]
        return self.method.compare(features, reference_features)


def new_mesh_seconds(repeats: int, threads: int, most_degrees: float, search: Search) -> dict:
    """Seconds to describe a new mesh (the example chair), to sample it as a reference (its
    points and their search) and to search its turn onto a reference (the chair without a leg),
    interleaved; the ratio is a new mesh's cost with a search, or with both, over without."""
    scorer = Scorer(threads=threads, cache_size=0)
    chair, no_leg = load_mesh(EXAMPLES / "chair.obj"), load_mesh(EXAMPLES / "chair_no_leg.obj")
    frame = frame_of(no_leg.vertices)
    reference = search.reference(place(no_leg.vertices, frame), no_leg.faces)
    placed = place(chair.vertices, frame)
    scorer.features(chair, frame)  # opens the graph's session
    seconds = {"describe": 0.0, "sample as a reference": 0.0, "search a turn": 0.0}
    for _ in range(repeats):
        start = time.perf_counter()
        scorer.features(chair, frame)
        described = time.perf_counter()
        search.reference(placed, chair.faces)
        as_reference = time.perf_counter()
        search.turn(placed, chair.faces, reference, LEAST_DEGREES[-1], most_degrees)
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
    parser.add_argument("--least-degrees", type=float, nargs="+", default=LEAST_DEGREES)
    parser.add_argument("--most-degrees", type=float, default=4.0)
    parser.add_argument("--steps", type=int, default=STEPS, help="Gauss-Newton steps a search")
    parser.add_argument(
        "--fitted", type=float, default=1.0, help="share of the points a step after the first fits"
    )
    parser.add_argument("--reference-samples", type=int, default=REFERENCE_SAMPLES)
    parser.add_argument("--samples", type=int, default=SAMPLES)
    parser.add_argument("--nearest", choices=NEAREST, default=NEAREST[0])
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
    default = DrkfsOnnx("default", PipelineConfig(), None, args.threads)
    search = Search(
        args.reference_samples, args.samples, args.steps, args.fitted, args.nearest
    )  # fmt: skip
    aligned = [
        Aligned(
            default,
            f"aligned, none up to {least:g} degrees",
            least,
            args.most_degrees,
            search,
        )
        for least in args.least_degrees
    ]
    methods = {m.outputs[0]: m for m in (default, *aligned)}
    scores, costs = score_everything(bench, list(methods.values()), print)
    rows = {}
    for name, values in scores.comparisons.items():
        rows[name] = {
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
        "metric": LATEST,
        "least_degrees": args.least_degrees,
        "most_degrees": args.most_degrees,
        "search": search.settings(),
        "methods": rows,
        "seconds": {
            "describe_a_mesh": describe,
            **{f"{m.outputs[0]}: search a turn": m.search_seconds / m.searches for m in aligned},
        },
        "new_mesh_seconds": new_mesh_seconds(args.repeats, args.threads, args.most_degrees, search),
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
