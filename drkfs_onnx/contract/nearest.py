"""Each query row's nearest target row, with numpy's BLAS: the runtime's descriptor match
(``runtime.match``) and the turn of a mesh onto its reference (``contract.alignment``).

The same float32 ranking as the exported match graph (``models/match.onnx``), which other runtimes
can use; in onnxruntime the graph is slower (bench/score.py, ``nearest_search_s``). BLAS threads
follow OPENBLAS_NUM_THREADS / OMP_NUM_THREADS, not the Scorer's ``threads``.
"""

from __future__ import annotations

import numpy as np

# Bytes of one block's float32 product: a whole search of up to ~4,000 x 4,000 rows in one BLAS
# call; fewer, larger calls are faster than cache-sized blocks (docs/design_notes.md).
BLOCK_BYTES = 1 << 26


def lift(targets: np.ndarray) -> np.ndarray:
    """(M, D) -> (M, D + 1) float32 rows [-2t, |t|^2]: [q, 1] . lifted = |t|^2 - 2 q.t ranks the
    targets by distance to q."""
    targets = np.asarray(targets, dtype=np.float32)
    return np.concatenate([-2.0 * targets, (targets * targets).sum(1, keepdims=True)], axis=1)


def nearest_lifted(
    queries: np.ndarray, lifted_targets: np.ndarray, block_bytes: int = BLOCK_BYTES
) -> np.ndarray:
    """(N, D) float32 queries, (M, D + 1) ``lift``-ed targets -> (N,) int64 index of each
    query's nearest target.

    One float32 product of lifted rows per block of ``block_bytes``. A float32 near-tie can pick a
    target whose distance exceeds the minimum by float32 rounding (~1e-7); callers that need
    exact zeros match exact copies themselves.
    """
    if len(lifted_targets) == 0:
        raise ValueError("no target descriptors to match against")
    lifted_queries = np.concatenate(
        [np.asarray(queries, dtype=np.float32), np.ones((len(queries), 1), np.float32)], axis=1
    )
    nearest = np.zeros(len(queries), np.int64)
    rows = max(1, block_bytes // (lifted_targets.itemsize * len(lifted_targets)))
    for start in range(0, len(queries), rows):
        # BLAS reads the transpose in place
        block = lifted_queries[start : start + rows] @ lifted_targets.T
        nearest[start : start + rows] = block.argmin(1)
    return nearest
