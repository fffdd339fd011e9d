"""Each query descriptor's nearest target, with numpy's BLAS.

The same float32 ranking as the exported match graph (``models/match.onnx``), which other
runtimes can use; in onnxruntime on 2 cores the graph is slower (bench/score.py,
``nearest_search_s``): it reduces the full N x M matrix after the product, while 512-row blocks
stay in cache for the argmin. BLAS threads follow OPENBLAS_NUM_THREADS / OMP_NUM_THREADS, not the
Scorer's ``threads``.
"""

from __future__ import annotations

import numpy as np

CHUNK_ROWS = 512


def nearest_indices(queries: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """(N, D), (M, D) float32 -> (N,) int64 index of each query's nearest target.

    Ranks by |t|^2 - 2 q.t, one float32 product of lifted rows ([q, 1] . [-2t, |t|^2]) per block.
    A float32 near-tie can pick a target whose distance exceeds the minimum by float32 rounding
    (~1e-7); callers that need exact zeros match exact copies themselves.
    """
    if len(targets) == 0:
        raise ValueError("no target descriptors to match against")
    targets = np.asarray(targets, dtype=np.float32)
    lifted_targets = np.concatenate(
        [-2.0 * targets, (targets * targets).sum(1, keepdims=True)], axis=1
    ).T.copy()
    lifted_queries = np.concatenate(
        [np.asarray(queries, dtype=np.float32), np.ones((len(queries), 1), np.float32)], axis=1
    )
    nearest = np.zeros(len(queries), np.int64)
    for start in range(0, len(queries), CHUNK_ROWS):
        block = lifted_queries[start : start + CHUNK_ROWS] @ lifted_targets
        nearest[start : start + CHUNK_ROWS] = block.argmin(1)
    return nearest
