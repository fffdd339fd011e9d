"""Named metric versions (``contract.versions``): a version's config is frozen, the newest is
``PipelineConfig()``, and every record names the version it was made under."""

import pytest

from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract.cli_options import PRESETS, pick_config
from drkfs_onnx.contract.versions import (
    CUSTOM,
    LATEST,
    VERSIONS,
    metric_config,
    metric_name,
    serving_version,
)


def test_the_default_is_the_newest_version_so_a_default_change_must_name_a_new_one():
    assert PipelineConfig() == metric_config(LATEST)


def test_each_version_writes_out_every_setting_so_no_default_can_move_it():
    fields = set(PipelineConfig().to_dict())
    for name, settings in VERSIONS.items():
        assert set(settings) == fields, name


def test_the_presets_are_versions_and_each_version_is_named_back():
    assert metric_config(PRESETS["paper"]) == PipelineConfig.paper()
    assert metric_config(PRESETS["structure"]) == PipelineConfig.structure()
    for name in VERSIONS:
        assert metric_name(metric_config(name)) == name
        assert pick_config(metric=name) == metric_config(name)


def test_an_overridden_setting_is_no_version_but_its_views_still_are_one():
    windowed = PipelineConfig(window=1)
    assert metric_name(windowed) == CUSTOM
    assert serving_version(windowed) == LATEST  # the match alone changed
    assert serving_version(PipelineConfig(image_size=96)) == CUSTOM
    # a graph serves every version of its nets and view size: the newest names it
    assert serving_version(metric_config("drkfs-1.0"), "graph") == "drkfs-1.0"
    assert serving_version(PipelineConfig(num_views=3), "graph") == LATEST
    with pytest.raises(ValueError, match="unknown metric 'drkfs-0.1'"):
        metric_config("drkfs-0.1")
