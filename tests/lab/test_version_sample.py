"""bench/version_sample.py: each named version still scores the benchmark's fixed sample of
pairs as it did when it was made."""

import json

import pytest
from conftest import ROOT

from drkfs_lab.version_sample import sample, scores
from drkfs_onnx.contract.versions import VERSIONS


@pytest.fixture(scope="module")
def version_sample():
    return sample()


@pytest.mark.parametrize(
    "version",
    [pytest.param(v, marks=pytest.mark.slow) if v == "drkfs-paper" else v for v in VERSIONS],
)
def test_each_version_scores_the_committed_sample_of_bench_pairs_as_it_did(version, version_sample):
    """A version's scores of the benchmark's fixed sample (bench/version_sample.py) are those
    committed when it was made, whatever the default has become since."""
    committed = json.loads((ROOT / "bench/results/version_sample.json").read_text())
    again = scores(version, version_sample)
    assert again.keys() == committed["versions"][version].keys()
    for key, value in again.items():
        assert value == pytest.approx(committed["versions"][version][key], rel=1e-6), key
