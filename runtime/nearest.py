"""Exact copies among descriptor rows: the rows a match pairs at distance 0 whatever float32
rounding says (the nearest-row search is ``contract.nearest``'s)."""

from __future__ import annotations

import numpy as np

HASH_SEED = 20261122


def row_hashes(rows: np.ndarray) -> np.ndarray:
    """(N, D) float32 -> (N,) uint64: a hash of each row's bits (equal rows, equal hashes)."""
    bits = np.ascontiguousarray(rows, dtype=np.float32).view(np.uint32).astype(np.uint64)
    # odd 64-bit multipliers, fixed so hashes are reproducible; products wrap modulo 2**64
    weights = np.random.default_rng(HASH_SEED).integers(1, 2**63, bits.shape[1], np.uint64)
    return bits @ (weights | np.uint64(1))


def exact_copies(
    queries: np.ndarray, query_hashes: np.ndarray, targets: np.ndarray, target_hashes: np.ndarray
) -> np.ndarray:
    """(N,) bool: which query rows have a bit-identical row among the targets (hashes from
    ``row_hashes``; a hash match is confirmed by comparing the rows)."""
    if len(targets) == 0:
        return np.zeros(len(queries), bool)
    order = np.argsort(target_hashes)
    at = np.minimum(np.searchsorted(target_hashes[order], query_hashes), len(order) - 1)
    candidate = order[at]
    copies = np.zeros(len(queries), bool)
    same_hash = np.flatnonzero(target_hashes[candidate] == query_hashes)
    copies[same_hash] = (queries[same_hash] == targets[candidate[same_hash]]).all(1)
    return copies
