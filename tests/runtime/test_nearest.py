"""Exact copies among descriptor rows are found by their bits."""

import numpy as np
from conftest import unit_rows

from drkfs_onnx.runtime.nearest import exact_copies, row_hashes


def test_exact_copies_are_bit_identical_rows_only():
    rng = np.random.default_rng(1)
    targets = unit_rows(rng, 50)
    targets[7] = targets[3]  # a duplicated target row
    one_bit_off = targets[5].copy()
    one_bit_off.view(np.uint32)[0] ^= 1
    queries = np.stack([targets[3], targets[49], one_bit_off, -targets[0], unit_rows(rng, 1)[0]])
    got = exact_copies(queries, row_hashes(queries), targets, row_hashes(targets))
    assert got.tolist() == [True, True, False, False, False]
    colliding = np.zeros(len(queries), np.uint64), np.zeros(len(targets), np.uint64)
    assert not exact_copies(queries, colliding[0], targets, colliding[1])[2:].any()
    none = targets[:0]
    assert not exact_copies(queries, row_hashes(queries), none, row_hashes(none)).any()


def test_row_hashes_depend_only_on_the_row():
    rng = np.random.default_rng(2)
    rows = unit_rows(rng, 20)
    assert np.array_equal(row_hashes(rows)[::-1], row_hashes(rows[::-1].copy()))
    assert len(set(row_hashes(rows).tolist())) == 20
