"""The nearest-row search finds each query's nearest target."""

import numpy as np
import pytest
from conftest import unit_rows

from drkfs_onnx.contract.nearest import lift, nearest_lifted


def test_nearest_equals_brute_force_over_several_blocks():
    rng = np.random.default_rng(0)
    targets = unit_rows(rng, 300)
    # near-duplicates of targets and unrelated rows: 600 queries, 10 blocks, the last one partial
    near = targets[rng.integers(0, 300, 400)] + 1e-2 * unit_rows(rng, 400)
    queries = np.concatenate([near, unit_rows(rng, 200)]).astype(np.float32)
    q, t = queries.astype(np.float64), targets.astype(np.float64)
    whole = nearest_lifted(queries, lift(targets))
    got = nearest_lifted(queries, lift(targets), block_bytes=4 * 301 * 64)  # 64 query rows
    assert got.shape == (len(queries),)
    assert np.array_equal(got, ((q[:, None] - t[None]) ** 2).sum(-1).argmin(1))
    assert np.array_equal(whole, got)


def test_no_targets_is_an_error():
    with pytest.raises(ValueError, match="no target"):
        nearest_lifted(np.zeros((2, 128), np.float32), lift(np.zeros((0, 128), np.float32)))
