"""ONNX export: the feature and match graphs pass onnx's checks, carry the pipeline config, and
agree with the torch modules in onnxruntime for any batch and patch count; the shipped graphs are
current."""

import json

import numpy as np
import onnx
import onnxruntime as ort
import pytest
import torch

from drkfs_onnx import DRKFS, PipelineConfig
from drkfs_onnx.contract.model_files import (
    CONFIG_KEY,
    MATCH_FILE,
    SERVES_KEY,
    WEIGHTS_KEY,
    features_file,
    models_dir,
    shipped_weights,
)
from drkfs_onnx.contract.versions import CUSTOM, VERSIONS, metric_config
from drkfs_onnx.export import export_features, export_match, weights_digest
from drkfs_onnx.nets.patches import select_patches

CONFIG = PipelineConfig(num_views=4, image_size=96, descriptor_width=0.25, nets="metric")


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    torch.manual_seed(0)
    metric = DRKFS(CONFIG)
    folder = tmp_path_factory.mktemp("onnx")
    features = export_features(metric, folder / "features.onnx", weights_digest(metric))
    match = export_match(folder / "match.onnx", CONFIG.descriptor_dim)
    return metric, features, match


def test_graphs_pass_the_checker_and_carry_config_and_weights_hash(exported):
    metric, features, match = exported
    for path in (features, match):
        onnx.checker.check_model(onnx.load(path), full_check=True)
    meta = ort.InferenceSession(features).get_modelmeta().custom_metadata_map
    assert PipelineConfig.from_dict(json.loads(meta[CONFIG_KEY])) == CONFIG
    assert meta[WEIGHTS_KEY] == weights_digest(metric)


@pytest.mark.parametrize("views", [1, 3])
def test_feature_graph_matches_torch_for_any_batch_and_patch_selection(exported, views):
    metric, features, _ = exported
    images = torch.rand(views, 1, CONFIG.image_size, CONFIG.image_size)
    count = views * CONFIG.patches_per_view
    index = torch.randperm(count)[: max(1, count // 3)]
    with torch.no_grad():
        expected = metric.descriptor(select_patches(metric.detector(images), index, CONFIG))
    got = ort.InferenceSession(features).run(
        None, {"views": images.numpy(), "patch_index": index.numpy()}
    )[0]
    assert np.abs(got - expected.numpy()).max() <= 1e-4


def test_match_graph_finds_each_rows_nearest(exported):
    *_, match = exported
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(9, 128)), rng.normal(size=(6, 128))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    got = ort.InferenceSession(match).run(
        None, {"a": a.astype(np.float32), "b": b.astype(np.float32)}
    )[0]
    distances = ((a[:, None] - b[None]) ** 2).sum(-1)
    assert got.shape == (9,)
    assert np.array_equal(got, distances.argmin(1))


def test_shipped_graphs_carry_their_weights_hash_and_config():
    """Every weights file in the manifest has its feature graph at the paper's image size and
    the default's, tagged with its sha256 and its config."""
    for entry in shipped_weights():
        trained = PipelineConfig.from_dict(entry["config"])
        for size in {trained.image_size, PipelineConfig().image_size}:
            config = trained.replace(image_size=size)
            shipped = models_dir() / features_file(config)
            meta = ort.InferenceSession(shipped.read_bytes()).get_modelmeta().custom_metadata_map
            assert meta[WEIGHTS_KEY] == entry["sha256"]
            built = PipelineConfig.from_json(meta[CONFIG_KEY])
            assert built.shaping("features") == config.shaping("features")
    assert (models_dir() / MATCH_FILE).is_file()


def _hard_views(size: int) -> np.ndarray:
    """Views whose PoI maps are near-flat (where the patch normalisation's eps decides, the case
    that once broke parity), a shallow ramp, and uniform noise: (4, 1, S, S) float32."""
    rng = np.random.default_rng(1)
    flat = 0.5 + 1e-4 * rng.standard_normal((2, 1, size, size))
    ramp = np.broadcast_to(np.linspace(0.3, 0.3002, size), (1, 1, size, size))
    noise = rng.random((1, 1, size, size))
    return np.concatenate([flat, ramp, noise]).astype(np.float32)


@pytest.mark.parametrize("entry", shipped_weights(), ids=lambda entry: entry["file"])
def test_each_shipped_graph_is_a_current_export_and_matches_torch_on_near_flat_views(
    entry, tmp_path
):
    config = PipelineConfig.from_dict(entry["config"]).replace(
        image_size=PipelineConfig().image_size
    )
    metric = DRKFS.pretrained(config)
    fresh = ort.InferenceSession(export_features(metric, tmp_path / "f.onnx", entry["sha256"]))
    shipped = ort.InferenceSession((models_dir() / features_file(config)).read_bytes())
    views = _hard_views(config.image_size)
    index = np.arange(len(views) * config.patches_per_view)
    inputs = {"views": views, "patch_index": index}
    got = shipped.run(None, inputs)[0]
    assert np.abs(got - fresh.run(None, inputs)[0]).max() <= 1e-6
    # a fresh export names the versions whose graph it is ("custom" where none)
    served = fresh.get_modelmeta().custom_metadata_map[SERVES_KEY].split(", ")
    whose = [n for n in VERSIONS if features_file(metric_config(n)) == features_file(config)]
    assert served == (whose or [CUSTOM])
    with torch.no_grad():
        maps = metric.detector(torch.from_numpy(views))
        expected = metric.descriptor(select_patches(maps, torch.from_numpy(index), config))
    assert np.abs(got - expected.numpy()).max() <= 1e-4
