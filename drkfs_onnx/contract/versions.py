"""Named, frozen versions of the metric: a score quoted as ``drkfs-1.0`` means the same next
year, whatever ``PipelineConfig()`` has become by then (LPIPS names its versions the same way).

Each version is every setting written out, never derived from the class's defaults, so moving a
default cannot move a version. ``PipelineConfig()`` is the default version (``LATEST``: a test
holds the two equal); a change of the default adds a version here and an entry to CHANGELOG.md. A
version may be named before it becomes the default (drkfs-1.2).
"""

from __future__ import annotations

from .config import PipelineConfig

_DRKFS_1_0 = {
    "num_views": 5, "image_size": 144, "turn_degrees": 2.5, "fov_degrees": 50.0,
    "camera_distance": 2.5, "sigma": 1e-05, "gamma": 0.0001, "coverage_eps": 0.0001,
    "background_eps": 0.001, "background": 0.0, "light_direction": (-0.4, -0.6, -0.7),
    "ambient": 0.3, "diffuse": 0.7, "back_light": 0.0, "back_push": 0.05, "detector_kernel": 9,
    "detector_n": 2, "detector_m": 2, "patch_size": 32, "patch_stride": 16,
    "descriptor_dim": 128, "descriptor_width": 0.5, "nets": "tolerant", "patch_norm_eps": 0.001,
    "matching": "window", "window": 0, "direction": "both", "reduction": "softmax",
    "tail_fraction": 0.05, "power": 8.0, "temperature": 0.05, "solid_weight": 1.2,
    "solid_shift": 3, "solid_block": 3, "solid_ramp": 1, "solid_inner_drop": 1,
    "solid_inner_power": 1.5, "turned_part_share": 0.2, "solid_both_rings": True,
    "moderate_slope": 0.6, "moderate_from": 0.04, "moderate_to": 0.18, "winding": "file",
    "align_degrees": 0.0, "align_from_degrees": 0.1, "align_reference_points": 2048,
    "align_points": 1024, "align_steps": 3, "align_fitted": 0.6, "align_reach": 0.1,
    "align_facing": 0.5,
}  # fmt: skip
_PARTS_IN_FULL = {"moderate_slope": 1.0, "moderate_from": 0.0, "moderate_to": 0.0}

VERSIONS: dict[str, dict] = {
    # the benchmark's choice: tolerant nets, 5 views of 144 px in two rings 2.5 degrees apart,
    # window r0 match reduced by softmax, moderated parts, the views' solid change, openings
    # seen dark
    "drkfs-1.0": _DRKFS_1_0,
    # drkfs-1.0 with each face's outside read from the surface: a file's face winding moves
    # no score
    "drkfs-1.1": {**_DRKFS_1_0, "winding": "geometry"},
    # drkfs-1.1 with each compared mesh turned onto its reference first, by up to 4 degrees: a
    # turn a viewer does not see about any axis moves no score
    "drkfs-1.2": {**_DRKFS_1_0, "winding": "geometry", "align_degrees": 4.0},
    # drkfs-1.0's nets, cameras, light and solid change with a global match reduced by the
    # power mean of order 8, parts in full: listens to the few patches a missing part changes
    "drkfs-structure-1.0": {
        **_DRKFS_1_0,
        "matching": "global",
        "reduction": "power",
        **_PARTS_IN_FULL,
    },  # fmt: skip
    "drkfs-structure-1.1": {
        **_DRKFS_1_0,
        "matching": "global",
        "reduction": "power",
        **_PARTS_IN_FULL,
        "winding": "geometry",
    },  # fmt: skip
    # the DR-KFS paper's recipe (Jin et al. 2020): 25 views of 256 px, full-width nets trained
    # on view correspondences, every patch of A searches all of B's, distances summed
    "drkfs-paper": {
        **_DRKFS_1_0,
        "num_views": 25,
        "image_size": 256,
        "turn_degrees": 0.0,
        "back_light": 1.0,
        "back_push": 0.0,
        "descriptor_width": 1.0,
        "nets": "correspondence",
        "matching": "global",
        "direction": "forward",
        "reduction": "sum",
        "solid_weight": 0.0,
        **_PARTS_IN_FULL,
    },  # fmt: skip
}
LATEST = "drkfs-1.1"
CUSTOM = "custom"  # a config that is no named version (a setting overridden)


def metric_config(name: str) -> PipelineConfig:
    """The frozen config of the version ``name``; ValueError lists the versions."""
    if name not in VERSIONS:
        raise ValueError(f"unknown metric {name!r}; use one of {', '.join(VERSIONS)}")
    return PipelineConfig.from_dict(VERSIONS[name])


def metric_name(config: PipelineConfig) -> str:
    """The version whose config ``config`` is, else ``CUSTOM``."""
    return next((n for n in VERSIONS if metric_config(n) == config), CUSTOM)


def served_versions(config: PipelineConfig, artefact: str = "features") -> list[str]:
    """Every version whose settings that shape ``artefact`` (``PipelineConfig.shaping``)
    ``config`` shares: a features file described, or a feature graph ('graph') exported, under
    ``config`` serves each of them."""
    part = config.shaping(artefact)
    return [n for n in VERSIONS if metric_config(n).shaping(artefact) == part]


def serving_version(config: PipelineConfig, artefact: str = "features") -> str:
    """The version ``config`` is, else of ``served_versions`` the newest (``LATEST`` where it is
    one), else ``CUSTOM``: what a features file was described, or a feature graph exported,
    for."""
    named = metric_name(config)
    if named != CUSTOM:
        return named
    served = served_versions(config, artefact)
    return LATEST if LATEST in served else (served[-1] if served else CUSTOM)


def in_words(name: str) -> str:
    """A version's name as an error message says it: "drkfs-1.1's", "a custom config's"."""
    return "a custom config's" if name == CUSTOM else f"{name}'s"
