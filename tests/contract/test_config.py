"""The frozen pipeline config (``contract.config``): presets, stage settings, records."""

import dataclasses

import pytest

from drkfs_onnx.contract.config import (
    ADDED_BY_VERSION,
    FREE_FIELDS,
    FULL_PARTS,
    GRAPH_FREE_FIELDS,
    MATCH_FIELDS,
    NETS_TRAINED_AT,
    ONE_REACH,
    OWN_RING_ONLY,
    RENDER_FIELDS,
    STAGE_SETTINGS,
    STAGES,
    TWO_SIDED,
    VIEW_FIELDS,
    CameraSettings,
    MatchSettings,
    PipelineConfig,
    ShadingSettings,
)
from drkfs_onnx.contract.versions import VERSIONS, metric_config


def test_paper_preset_is_the_papers_pipeline():
    config = PipelineConfig.paper()
    assert (config.num_views, config.image_size) == (25, 256)
    assert (config.patch_size, config.patch_stride, config.patches_per_view) == (32, 16, 225)
    assert config.descriptor_dim == 128


def test_training_preset_is_the_previous_default_with_a_softer_renderer():
    training, default = PipelineConfig.training(), PipelineConfig()
    assert training.sigma > default.sigma and training.gamma > default.gamma
    # at the cameras the nets were trained at, not the default's, so the loss stays as chosen
    assert {name: getattr(training, name) for name in NETS_TRAINED_AT} == NETS_TRAINED_AT
    assert (training.num_views, training.image_size) != (default.num_views, default.image_size)
    previous = PipelineConfig.structure(nets="correspondence", **NETS_TRAINED_AT)
    assert training.replace(sigma=default.sigma, gamma=default.gamma) == previous
    loss, first = PipelineConfig.loss(), PipelineConfig.training()
    assert loss.shaping("features") == first.shaping("features")
    assert PipelineConfig.training(num_views=2).num_views == 2


def test_only_the_default_reads_the_descriptors_part_through_its_window():
    # the window's ends are in the default's units (softmax at t = 0.05 over its views); the
    # presets, the loss and the config the nets were trained at count the part in full
    assert PipelineConfig().moderate_slope < 1.0
    assert {name: NETS_TRAINED_AT[name] for name in FULL_PARTS} == FULL_PARTS
    for preset in (PipelineConfig.paper(), PipelineConfig.structure(), PipelineConfig.training(),
                   PipelineConfig.loss()):  # fmt: skip
        assert {name: getattr(preset, name) for name in FULL_PARTS} == FULL_PARTS


def test_presets_share_the_defaults_cameras_and_differ_in_nets_and_match():
    default, structure = PipelineConfig(), PipelineConfig.structure()
    assert (default.nets, default.matching, default.reduction) == ("tolerant", "window", "softmax")
    assert structure.shaping("features") == default.shaping("features")  # the same descriptors
    assert (structure.matching, structure.reduction, structure.power) == ("global", "power", 8.0)
    assert PipelineConfig.paper().nets == PipelineConfig.loss().nets == "correspondence"


def test_every_setting_belongs_to_one_stage_and_the_artefacts_keys_come_from_the_stages():
    stages = [name for fields in STAGES.values() for name in fields]
    assert sorted(stages) == sorted(f.name for f in dataclasses.fields(PipelineConfig))
    assert len(set(stages)) == len(stages)
    assert set(VIEW_FIELDS) == {*STAGES["cameras"], *STAGES["raster"], *STAGES["shading"]}
    assert set(MATCH_FIELDS) == {*STAGES["match"], *STAGES["solid_change"]}
    # the nets' weights and a feature graph serve other views of a mesh however turned: never
    # another net or match
    for reused in (RENDER_FIELDS, GRAPH_FREE_FIELDS):
        assert set(reused) <= {*VIEW_FIELDS, *STAGES["alignment"]}


# a value other than the default's for every field some artefact is free of
OTHER_VALUES = {
    "back_light": 1.0, "back_push": 0.0, "direction": "forward", "gamma": 0.1, "image_size": 128,
    "matching": "global", "moderate_from": 0.05, "moderate_slope": 1.0, "moderate_to": 0.2,
    "num_views": 6, "power": 4.0, "reduction": "sum", "sigma": 1e-4, "solid_block": 5,
    "solid_both_rings": False, "solid_inner_drop": 0, "solid_inner_power": 1.0, "solid_ramp": 0,
    "solid_shift": 2, "solid_weight": 0.0, "tail_fraction": 0.1, "temperature": 0.1,
    "turn_degrees": 0.0, "turned_part_share": 0.0, "winding": "file", "window": 1,
    "align_degrees": 4.0, "align_from_degrees": 0.2, "align_reference_points": 4096,
    "align_points": 512, "align_steps": 2, "align_fitted": 1.0, "align_reach": 0.2,
    "align_facing": 0.3,
}  # fmt: skip


def test_an_artefact_serves_every_config_that_differs_from_its_own_in_free_fields_alone():
    config = PipelineConfig()
    for artefact, free in FREE_FIELDS.items():
        for name in free:
            other = dataclasses.replace(config, **{name: OTHER_VALUES[name]})
            assert other.shaping(artefact) == config.shaping(artefact), (artefact, name)
    # a features file carries the surface a turn is fitted to: a turn shapes it
    assert config.replace(align_degrees=4.0).shaping("features") != config.shaping("features")
    # what shapes the descriptors is never free for a graph or the weights
    for artefact in ("graph", "weights"):
        other = config.replace(descriptor_width=1.0)
        assert other.shaping(artefact) != config.shaping(artefact)
    with pytest.raises(ValueError, match="unknown artefact"):
        config.shaping("feature")
    # a key, not a config to run: a patch larger than the default view keeps its weights' key
    large = config.replace(image_size=192, patch_size=160)
    assert large.shaping("weights").patch_size == 160
    # a graph describes views of any cameras' count, the weights views of any size too
    assert config.replace(image_size=128).shaping("graph") != config.shaping("graph")
    assert config.replace(image_size=128).shaping("weights") == config.shaping("weights")


def test_each_stages_settings_are_plain_frozen_data_with_the_configs_fields_and_defaults():
    config = PipelineConfig.structure()
    for stage, fields in STAGES.items():
        settings = config.stage(stage)
        assert isinstance(settings, STAGE_SETTINGS[stage])
        assert dataclasses.asdict(settings) == {name: getattr(config, name) for name in fields}
        assert dataclasses.asdict(STAGE_SETTINGS[stage]()) == {
            name: getattr(PipelineConfig(), name) for name in fields
        }
        with pytest.raises(dataclasses.FrozenInstanceError):
            settings.__setattr__(fields[0], None)
    assert PipelineConfig.from_stages(*(config.stage(stage) for stage in STAGES)) == config


def test_a_config_is_built_from_some_stages_settings_the_rest_at_their_defaults():
    built = PipelineConfig.from_stages(
        CameraSettings(num_views=6, turn_degrees=0.0), ShadingSettings(back_light=1.0)
    )
    assert built == PipelineConfig(num_views=6, turn_degrees=0.0, back_light=1.0)
    with pytest.raises(ValueError, match="num_views must be at least 1"):
        PipelineConfig.from_stages(CameraSettings(num_views=0))


def test_differences_are_named_stage_by_stage():
    made = PipelineConfig.from_stages(CameraSettings(num_views=6), MatchSettings(window=1))
    assert made.differences(PipelineConfig()) == (
        "cameras: num_views 6 (asked 5); match: window 1 (asked 0)"
    )
    assert PipelineConfig().differences(PipelineConfig()) == ""


def test_config_is_frozen_and_round_trips_through_json():
    config = PipelineConfig(num_views=12, light_direction=[0, -1, 0])
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.num_views = 3
    assert PipelineConfig.from_json(config.to_json()) == config
    assert hash(config) == hash(PipelineConfig.from_json(config.to_json()))


@pytest.mark.parametrize(
    "bad",
    [{"num_views": 0}, {"image_size": 16}, {"detector_kernel": 4}, {"sigma": 0.0},
     {"camera_distance": 0.9}, {"patch_size": 30}, {"turn_degrees": -2.0},
     {"turn_degrees": 90.0}, {"turned_part_share": -0.1}, {"turned_part_share": 1.5},
     {"moderate_slope": 0.0}, {"moderate_slope": 1.5}, {"moderate_from": -0.1},
     {"moderate_from": 0.2, "moderate_to": 0.1}, {"back_light": -0.1}, {"back_light": 1.5},
     {"back_push": -0.01}, {"back_push": 1.0}],
)  # fmt: skip
def test_invalid_configs_are_refused(bad):
    with pytest.raises(ValueError):
        PipelineConfig(**bad)


def test_a_record_without_later_fields_reads_as_it_was_made():
    """A config written before a version added a field (a features file, a results JSON) takes
    the value it was made with: before drkfs-1.0 one ring, no solid change, one reach, the own
    ring alone, the descriptors' part in full, faces seen from behind lit as their fronts;
    before drkfs-1.1 the file's winding."""
    made_at_1_0 = metric_config("drkfs-1.0").to_dict()
    del made_at_1_0["winding"]
    assert PipelineConfig.from_dict(made_at_1_0) == metric_config("drkfs-1.0")
    record = PipelineConfig(back_light=0.0, back_push=0.05).to_dict()
    added = ("turn_degrees", "solid_weight", *ONE_REACH, *OWN_RING_ONLY, *FULL_PARTS, *TWO_SIDED)
    for name in added:
        del record[name]
    old = PipelineConfig.from_dict(record)
    assert old == PipelineConfig(
        turn_degrees=0.0, solid_weight=0.0, **ONE_REACH, **OWN_RING_ONLY, **FULL_PARTS,
        **TWO_SIDED,
    )  # fmt: skip
    assert (old.turned_part_share, old.solid_both_rings) == (0.0, False)
    assert old.moderate_slope == 1.0


def test_each_field_a_version_added_is_a_field_of_the_config_and_added_once():
    added = [name for fields in ADDED_BY_VERSION.values() for name in fields]
    assert len(added) == len(set(added))
    assert set(added) <= set(PipelineConfig().to_dict())
    assert set(ADDED_BY_VERSION) <= set(VERSIONS)


def test_unknown_keys_are_refused():
    with pytest.raises(ValueError, match="unknown config keys: colour"):
        PipelineConfig.from_dict({"colour": True})


def test_another_reduction_than_the_presets_counts_the_descriptors_part_in_full():
    from drkfs_onnx.contract.cli_options import pick_config

    window = ("moderate_slope", "moderate_from", "moderate_to")
    assert pick_config() == PipelineConfig()
    assert pick_config(reduction="softmax") == PipelineConfig()  # the preset's own: kept
    summed = pick_config(reduction="sum")
    assert {name: getattr(summed, name) for name in window} == FULL_PARTS
    assert (
        summed.replace(reduction="softmax", **{n: getattr(PipelineConfig(), n) for n in window})
        == PipelineConfig()
    )


def test_the_default_sees_openings_dark_and_two_sided_picks_the_previous_light():
    """The scoring default shades an opening's inside in the shell's shadow; the nets were
    trained, the loss chosen and the paper preset always ran under two-sided light, and keep it;
    --two-sided gives any preset that light."""
    from drkfs_onnx.contract.cli_options import pick_config

    default = PipelineConfig()
    assert (default.back_light, default.back_push) == (0.0, 0.05)
    assert PipelineConfig.structure().back_light == 0.0
    assert TWO_SIDED == {"back_light": 1.0, "back_push": 0.0, "winding": "file"}  # winding moot
    for two_sided in (PipelineConfig.paper(), PipelineConfig.training(), PipelineConfig.loss()):
        assert (two_sided.back_light, two_sided.back_push) == (1.0, 0.0)
    assert pick_config(two_sided=True) == PipelineConfig(**TWO_SIDED)
    assert pick_config("structure", two_sided=True) == PipelineConfig.structure(**TWO_SIDED)
    assert pick_config("paper", two_sided=True) == PipelineConfig.paper()
