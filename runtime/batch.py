"""A batch's rows scored one by one, in this process or on Ray workers, results in input order.

Every per-row failure (a bad mesh, a broken features file, a worker that died) becomes that row's
result, so one bad row never loses another's. Ray is imported only for ``ray_results``
(``pip install "drkfs-onnx[ray]"``).
"""

from __future__ import annotations

import os
import time
from collections import Counter, deque
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import MeshError

from .features import MeshFeatures
from .scorer import Scorer, reference_of

Row = tuple[int, str, str]  # (index in the pairs file, mesh_a, mesh_b)
# How many rows each Ray worker holds at once: one running, one queued behind it.
ROWS_PER_WORKER = 2


@dataclass(frozen=True)
class ScorerSpec:
    """What builds a Scorer, as plain data a Ray worker can receive."""

    config: PipelineConfig
    model: str | None = None
    threads: int | None = None
    normalization: str = "joint"
    max_faces: int | None = None

    def build(self, progress=None) -> Scorer:
        """The scorer; ``progress`` as ``Scorer``'s (a callable stays out of the plain data)."""
        return Scorer(
            self.config,
            model=self.model,
            threads=self.threads,
            normalization=self.normalization,
            max_faces=self.max_faces,
            progress=progress,
        )


@dataclass(frozen=True)
class Failure:
    """Why a reference could not be described (every row that needs it fails with it)."""

    message: str


@dataclass(frozen=True)
class RowResult:
    score: float | None
    error: str
    seconds: float


def _message(exc: Exception) -> str:
    return str(exc) or type(exc).__name__


class RowScorer:
    """One Scorer that turns each row's failure into the row's result; the body of a Ray worker.

    ``describe(b)`` -> B's MeshFeatures (or a Failure); ``score(a, b, reference)`` -> RowResult,
    with B's features from ``describe`` or, without them, from B's path.
    """

    def __init__(self, scorer: Scorer | ScorerSpec):
        self.scorer = scorer.build() if isinstance(scorer, ScorerSpec) else scorer

    def describe(self, b: str) -> MeshFeatures | Failure:
        try:
            reference = reference_of(Path(b))
            return reference if isinstance(reference, MeshFeatures) else self.scorer.features(b)
        except (MeshError, ValueError, OSError) as exc:
            return Failure(_message(exc))

    def score(self, a: str, b: str, reference: MeshFeatures | Failure | None = None) -> RowResult:
        start = time.perf_counter()
        try:
            if not a or not b:
                raise ValueError("the row needs two meshes, mesh_a and mesh_b")
            if isinstance(reference, Failure):
                raise ValueError(reference.message)
            if reference is None:
                reference = reference_of(Path(b))
            value = self.scorer.score(Path(a), reference)
            return RowResult(value, "", time.perf_counter() - start)
        except (MeshError, ValueError, OSError) as exc:
            return RowResult(None, _message(exc), time.perf_counter() - start)


def serial_results(rows: list[Row], scorer: RowScorer) -> Iterator[tuple[int, RowResult]]:
    for index, a, b in rows:
        yield index, scorer.score(a, b)


def ray_results(
    rows: list[Row], spec: ScorerSpec, address: str, workers: int | None
) -> Iterator[tuple[int, RowResult]]:
    """The rows scored by ``workers`` Ray actors (one Scorer with ``spec.threads`` threads
    each; default: as many as the cluster's CPUs hold), yielded in input order as they finish.
    Ray is joined here, before any result is asked for: a cluster that cannot be reached is a
    ConnectionError before the batch writes anything.

    address: ``local`` starts a Ray instance on this machine (``workers`` x threads CPUs, or
    all cores); ``auto`` joins the cluster this machine belongs to; anything else is a cluster
    address (``ray://head:10001``, ``head:6379``). Each reference is described once, by one
    worker, and reaches the others through Ray's object store.
    """
    if not rows:
        return iter(())
    import ray

    threads = spec.threads or 1
    if address == "local":
        cpus = workers * threads if workers else os.cpu_count()
        ray.init(num_cpus=cpus, include_dashboard=False, logging_level="ERROR")
    else:
        try:
            ray.init(address=address, logging_level="ERROR")
        except ConnectionError as exc:
            why = (
                "this machine has joined no Ray cluster: start one (ray start --head) or use "
                "--ray local"
                if address == "auto"
                else f"no Ray cluster answered there ({exc})"
            )
            raise ConnectionError(f"--ray {address}: {why}") from exc
    try:
        if address != "local":
            check_workers(ray, address)
        available = int(ray.cluster_resources().get("CPU", 0))
        workers = workers or max(1, available // threads)
        if workers * threads > available:
            raise ValueError(
                f"{workers} workers x {threads} threads need {workers * threads} CPUs; "
                f"the Ray cluster has {available}"
            )
    except BaseException:
        ray.shutdown()
        raise
    return _ray_stream(ray, rows, spec, workers, threads)


def _ray_stream(ray, rows, spec, workers, threads) -> Iterator[tuple[int, RowResult]]:
    try:
        yield from _schedule(ray, rows, spec, workers, threads)
    finally:
        ray.shutdown()


def _can_score() -> str:
    """What a Ray worker answers when it can import the scorer: the package's folder."""
    import drkfs_onnx.runtime

    return str(Path(drkfs_onnx.runtime.__file__).parent)


def check_workers(ray, address: str, timeout: float = 120.0) -> None:
    """Refuse a Ray instance whose workers cannot import drkfs-onnx (another program's, or a
    cluster whose nodes lack the package) before any row is sent: there every row would fail
    with Ray's 'The actor never ran'."""
    try:
        ray.get(ray.remote(num_cpus=0)(_can_score).remote(), timeout=timeout)
    except Exception as exc:  # Ray raises many types for a worker that cannot start the task
        reason = [line for line in str(exc).splitlines() if line.strip()]
        raise ConnectionError(
            f"--ray {address}: joined a Ray instance whose workers cannot run drkfs-score "
            f"({reason[-1].strip() if reason else type(exc).__name__}); start Ray from this "
            "environment (ray start --head) with drkfs-onnx installed on every node, or use "
            "--ray local"
        ) from exc


def _schedule(ray, rows: list[Row], spec: ScorerSpec, workers: int, threads: int):
    worker_class = ray.remote(RowScorer).options(
        num_cpus=threads, max_restarts=-1, max_task_retries=0
    )
    actors = [worker_class.remote(spec) for _ in range(workers)]
    load = [0] * workers  # rows each actor holds
    rows_left = Counter(b for _, _, b in rows)  # per reference, rows not yet submitted
    described: dict[str, object] = {}  # B -> ObjectRef of its features
    running: dict[object, tuple[int, int]] = {}  # ObjectRef -> (index, actor)
    finished: dict[int, RowResult] = {}
    to_submit, to_yield = deque(rows), deque(index for index, _, _ in rows)
    while to_yield:
        while to_submit and len(running) < ROWS_PER_WORKER * workers:
            index, a, b = to_submit.popleft()
            actor = load.index(min(load))
            if b and b not in described:
                described[b] = actors[actor].describe.remote(b)
            running[actors[actor].score.remote(a, b, described.get(b))] = (index, actor)
            load[actor] += 1
            rows_left[b] -= 1
            if rows_left[b] == 0:
                described.pop(b, None)  # the object store frees it once its rows are done
        (ready,), _ = ray.wait(list(running), num_returns=1)
        index, actor = running.pop(ready)
        load[actor] -= 1
        try:
            finished[index] = ray.get(ready)
        except ray.exceptions.RayError as exc:  # the worker died or raised the unexpected
            last_line = [line for line in str(exc).splitlines() if line.strip()][-1]
            finished[index] = RowResult(None, f"worker failed: {last_line.strip()}", 0.0)
        while to_yield and to_yield[0] in finished:
            yield to_yield[0], finished.pop(to_yield.popleft())
