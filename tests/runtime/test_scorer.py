"""The onnxruntime scorer computes the torch metric's scores (parity), skips what a scene does not
need (empty patches, fine tessellation, repeated references) and refuses foreign models."""

import warnings
from dataclasses import replace

import numpy as np
import pytest
import torch
import trimesh
from conftest import ROOT

from drkfs_lab.benchmark import sets
from drkfs_onnx import DRKFS, PipelineConfig, load_mesh
from drkfs_onnx.contract.cameras import rotation, rotation_y
from drkfs_onnx.contract.config import TWO_SIDED
from drkfs_onnx.contract.mesh import Mesh, frame_of, place
from drkfs_onnx.contract.model_files import features_file, models_dir
from drkfs_onnx.contract.render_equations import opposed_edges
from drkfs_onnx.contract.versions import LATEST, metric_config
from drkfs_onnx.runtime import MeshFeatures, ModelMismatch, Scorer
from drkfs_onnx.runtime.scorer import WindingWarning

EXAMPLES = ROOT / "examples"
VARIANTS = ["chair_retessellated.obj", "chair_leg_shifted.obj", "chair_no_leg.obj"]


@pytest.fixture(scope="module")
def scorer():
    return Scorer(threads=2)


@pytest.fixture(scope="module")
def metric():
    return DRKFS.pretrained()


def test_same_images_give_the_torch_descriptors(scorer, metric):
    chair = load_mesh(EXAMPLES / "chair.obj")
    features = scorer.features(chair)
    verts = torch.tensor(place(chair.vertices, features.frame), dtype=torch.float32)
    with torch.no_grad():
        expected = metric.features(verts, torch.tensor(chair.faces)).numpy()
    empty = (expected == expected[0]).all(1)  # the corner patch sees only background
    assert features.empty == empty.sum() and len(features.descriptors) == (~empty).sum()
    assert np.abs(features.descriptors - expected[~empty]).max() <= 1e-4


def test_scores_equal_the_torch_scores_and_rank_the_same(scorer, metric):
    reference = EXAMPLES / "chair.obj"
    runtime = [scorer.score(EXAMPLES / name, reference) for name in VARIANTS]
    truth = load_mesh(reference)
    torch_scores = [metric.score_meshes(load_mesh(EXAMPLES / n), truth) for n in VARIANTS]
    assert np.allclose(runtime, torch_scores, rtol=1e-3, atol=0)
    assert np.array_equal(np.argsort(runtime), np.argsort(torch_scores))
    assert scorer.score(reference, reference) == 0.0


def test_scores_do_not_depend_on_view_batch_or_threads(scorer):
    a, b = EXAMPLES / "chair_no_leg.obj", EXAMPLES / "chair.obj"
    other = Scorer(threads=1, view_batch=3)
    assert other.score(a, b) == pytest.approx(scorer.score(a, b), rel=1e-5)


def test_a_reference_is_rendered_once_for_many_predictions(scorer):
    reference = EXAMPLES / "chair.obj"
    renders = []
    original = scorer.renderer.render
    scorer.renderer.render = lambda *args: renders.append(1) or original(*args)
    try:
        scorer.cache.clear()
        for name in VARIANTS[:2]:
            scorer.score(EXAMPLES / name, reference)
    finally:
        scorer.renderer.render = original
    assert len(renders) == 1 + 2


def test_precomputed_reference_features_round_trip(scorer, tmp_path):
    reference = EXAMPLES / "chair.obj"
    scorer.features(reference).save(tmp_path / "chair.npz")
    loaded = MeshFeatures.load(tmp_path / "chair.npz")
    a = EXAMPLES / "chair_no_leg.obj"
    assert scorer.score(a, loaded) == scorer.score(a, reference)
    # the features file's path is a reference too, as drkfs-score pair takes it
    assert scorer.score(a, tmp_path / "chair.npz") == scorer.score(a, str(tmp_path / "chair.npz"))
    assert scorer.score(a, str(tmp_path / "chair.npz")) == scorer.score(a, loaded)
    config = PipelineConfig()
    assert len(loaded.descriptors) + loaded.empty == config.views_per_mesh * config.patches_per_view
    assert np.array_equal(loaded.views, scorer.features(reference).views)  # the solid change's
    with np.load(tmp_path / "chair.npz") as saved:  # a reader sees which versions it serves
        assert list(saved["serves"]) == [LATEST, "drkfs-structure-1.1"]


def test_a_features_file_without_views_serves_no_solid_change_and_says_so(scorer, tmp_path):
    reference = replace(scorer.features(EXAMPLES / "chair.obj"), views=None)  # as files were
    reference.save(tmp_path / "old.npz")
    with pytest.raises(ValueError, match=r"old\.npz: features without their views"):
        scorer.score(EXAMPLES / "chair_no_leg.obj", tmp_path / "old.npz")
    descriptors_only = Scorer(scorer.config.replace(solid_weight=0.0), threads=2)
    assert descriptors_only.score(EXAMPLES / "chair_no_leg.obj", tmp_path / "old.npz") > 0


def test_background_patches_share_the_blank_view_descriptor(scorer, metric):
    size = metric.config.patch_size
    with torch.no_grad():
        blank = metric.descriptor(metric.detector(torch.zeros(1, 1, size, size))).numpy()
    features = scorer.features(EXAMPLES / "chair.obj")
    assert np.abs(features.empty_descriptor - blank[0]).max() <= 1e-4


def test_a_model_for_another_config_is_refused_with_the_difference():
    shipped = models_dir() / features_file(PipelineConfig.paper())
    with pytest.raises(ModelMismatch, match=r"image_size 256 \(asked 96\)"):
        Scorer(PipelineConfig.paper(image_size=96), model=shipped)
    named = r"built for drkfs-paper's feature graph, scoring asks drkfs-1.1's"
    with pytest.raises(ModelMismatch, match=named):
        Scorer(metric="drkfs-1.1", model=shipped)
    default = models_dir() / features_file(PipelineConfig())  # it serves 1.0 and 1.1: the newest
    named = r"built for drkfs-1.1's feature graph, scoring asks drkfs-paper's"
    with pytest.raises(ModelMismatch, match=named):
        Scorer(metric="drkfs-paper", model=default)
    # the view count, the light on faces seen from behind and the match are not in the graph:
    # the paper's graph serves them
    paper = PipelineConfig.paper(num_views=12, matching="window", back_light=0.0, back_push=0.05)
    Scorer(paper, model=shipped)


def test_a_part_wound_against_the_rest_reads_as_an_inside_only_where_the_file_orients():
    """Two-sided light ignores which way the faces wind. In the shadow, with each face oriented
    by its surface (``winding='geometry'``), neither a mesh wound inside out nor a part wound
    against the rest (the example chair's first leg) moves the score; with the file's winding
    turned as a whole (drkfs-1.0's 'file') the inside-out mesh scores as itself but the part
    renders as an inside and, unpushed, scores above the leg moved."""
    chair = load_mesh(EXAMPLES / "chair.obj")
    flipped = Mesh(chair.vertices, chair.faces[:, ::-1].copy(), "flipped")
    leg_flipped = chair.faces.copy()
    leg_flipped[:12] = leg_flipped[:12, ::-1]
    leg = Mesh(chair.vertices, leg_flipped, "leg flipped")
    shifted = EXAMPLES / "chair_leg_shifted.obj"
    for winding in ("geometry", "file"):
        config = metric_config("drkfs-1.0").replace(winding=winding)
        two_sided = Scorer(config.replace(**TWO_SIDED), threads=2)
        assert two_sided.score(flipped, chair) < 1e-6 and two_sided.score(leg, chair) < 1e-6
        for push in (0.0, 0.05):
            shadowed = Scorer(config.replace(back_light=0.0, back_push=push), threads=2)
            assert shadowed.score(flipped, chair) < 1e-6
            if winding == "geometry":
                assert shadowed.score(leg, chair) < 1e-6
            elif push == 0.0:
                assert shadowed.score(leg, chair) > shadowed.score(shifted, chair)


def test_a_file_wound_against_itself_is_named_in_a_warning_where_the_winding_is_read():
    """Where the config reads a face's outside from the file (drkfs-1.0), a mesh whose
    neighbouring faces run an edge the same way is named in one warning; a consistent file
    (split into a soup of its faces, or with parts meeting at an edge) is not, nor any file
    where the winding is moot (read from the surface, the default, or lit from both sides)."""
    chair = load_mesh(EXAMPLES / "chair.obj")
    flips = np.random.default_rng(0).random(len(chair.faces)) < 0.5
    rewound = Mesh(chair.vertices, np.where(flips[:, None], chair.faces[:, ::-1], chair.faces),
                   "half flipped")  # fmt: skip
    corners = chair.vertices[chair.faces].reshape(-1, 3)
    soup = Mesh(corners, np.arange(len(corners)).reshape(-1, 3), "soup")
    assert (
        opposed_edges(soup.vertices, soup.faces)
        == 0
        < opposed_edges(rewound.vertices, rewound.faces)
    )
    from_file = Scorer(metric="drkfs-1.0", threads=2)
    with pytest.warns(
        WindingWarning, match=r"^half flipped: \d+ of its edges .*--winding geometry"
    ):
        from_file.load(rewound)
    quiet = [
        (from_file, chair), (from_file, soup), (Scorer(threads=2), rewound),
        (Scorer(PipelineConfig(**TWO_SIDED), threads=2), rewound),
    ]  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("error", WindingWarning)
        for scorer, mesh in quiet:
            scorer.load(mesh)
    for name in sets.SHARED_MESHES:  # real meshes, wound consistently, where parts meet too
        mesh = load_mesh(sets.real_mesh(name))
        assert opposed_edges(mesh.vertices, mesh.faces) == 0, name


@pytest.mark.parametrize("name", ["chair", "cow", "woody", "beetle"])
def test_no_winding_of_a_files_faces_scores_above_its_subdivision(name):
    """With each face's outside read from the surface (``winding='geometry'``, the default) no
    winding of a file's faces matters: every face flipped at random, the whole mesh flipped and
    double-sided copies of its faces score below the mesh against its own subdivision (the same
    surface, 4x the faces) + 0.005, either way round."""
    path = EXAMPLES / "chair.obj" if name == "chair" else sets.real_mesh(name)
    mesh = load_mesh(path)
    scorer = Scorer(threads=2)
    subdivided = Mesh(*trimesh.remesh.subdivide(mesh.vertices, mesh.faces), "subdivided")
    bar = max(scorer.score(subdivided, mesh), scorer.score(mesh, subdivided)) + 0.005
    flips = np.random.default_rng(0).random(len(mesh.faces)) < 0.5
    rewound = {
        "half flipped": np.where(flips[:, None], mesh.faces[:, ::-1], mesh.faces),
        "all flipped": mesh.faces[:, ::-1],
        "double-sided": np.concatenate([mesh.faces, mesh.faces[:, ::-1]]),
    }
    for how, faces in rewound.items():
        other = Mesh(mesh.vertices, np.ascontiguousarray(faces), how)
        assert max(scorer.score(other, mesh), scorer.score(mesh, other)) < bar, how


def test_features_made_under_another_light_are_refused_with_the_difference(scorer, tmp_path):
    """The graph describes views however lit, but the views and descriptors of a mesh are its
    renders': a reference described with two-sided light (the default's before openings were
    seen dark) does not serve faces seen from behind in shadow, nor the reverse, and the refusal
    names the flag that does."""
    two_sided = Scorer(scorer.config.replace(**TWO_SIDED), threads=2)
    two_sided.features(EXAMPLES / "chair.obj").save(tmp_path / "lit.npz")
    refused = r"lit\.npz: .*back_light 1(\.0)? \(asked 0(\.0)?\).*score with --two-sided"
    with pytest.raises(ValueError, match=refused):
        scorer.score(EXAMPLES / "chair_no_leg.obj", tmp_path / "lit.npz")
    scorer.features(EXAMPLES / "chair.obj").save(tmp_path / "dark.npz")
    asked = r"dark\.npz: .*scoring asks two-sided light \(--two-sided\): score without it"
    with pytest.raises(ValueError, match=asked):
        two_sided.score(EXAMPLES / "chair_no_leg.obj", tmp_path / "dark.npz")
    shadowed = Scorer(scorer.config.replace(back_push=0.0), threads=2)
    shadowed.features(EXAMPLES / "chair.obj").save(tmp_path / "unpushed.npz")
    with pytest.raises(ValueError, match=r"unpushed\.npz: .*back_push 0(\.0)? \(asked 0\.05\)"):
        scorer.score(EXAMPLES / "chair_no_leg.obj", tmp_path / "unpushed.npz")


def test_both_directions_are_order_free_and_joint_uses_the_reference_frame_for_both():
    """direction 'both' averages A -> B and B -> A of the same two descriptor sets: with 'each'
    the value cannot depend on argument order; with 'joint' both directions are searched in the
    reference's frame, so swapping the arguments swaps only the frame."""
    a, b = EXAMPLES / "chair_no_back.obj", EXAMPLES / "chair.obj"
    config = PipelineConfig(direction="both")
    each = Scorer(config, threads=2, normalization="each")
    assert each.score(a, b) == each.score(b, a) > 0
    joint = Scorer(config, threads=2)
    reference = joint.features(b)
    prediction = joint.features(a, reference.frame)
    one_way = [
        Scorer(config.replace(direction=d), threads=2).match(prediction, reference)
        for d in ("forward", "backward")
    ]
    assert joint.score(a, b) == pytest.approx(sum(one_way) / 2, rel=1e-12)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_turn_by_the_rings_angle_scores_as_the_mesh_itself(scorer, sign):
    # a viewer does not see a 2-degree turn: one mesh's own ring sees it as the other's turned
    # ring sees the unturned mesh (the turn is about the vertical through the frame's centre)
    chair = load_mesh(EXAMPLES / "chair.obj")
    centre, _ = frame_of(chair.vertices)
    turn = rotation_y(sign * PipelineConfig().turn_degrees)
    turned = Mesh((chair.vertices - centre) @ turn.T + centre, chair.faces, "turned")
    one_ring = Scorer(PipelineConfig().one_ring(), threads=2)
    assert scorer.score(turned, chair) < 1e-3 * one_ring.score(turned, chair)
    # what the rings forgive is a turn, not a change: a missing leg still scores
    missing = EXAMPLES / "chair_no_leg.obj"
    assert scorer.score(missing, chair) > 0.5 * one_ring.score(missing, chair)


@pytest.fixture(scope="module")
def turning():
    return Scorer(metric="drkfs-1.2", threads=2)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_drkfs_1_2_turns_a_tilted_mesh_back_onto_its_reference(scorer, turning, axis):
    # a 2-degree turn about any axis (here about the frame's centre) a viewer does not see;
    # the rings forgive one about the vertical alone, the turn onto the reference any
    chair = load_mesh(EXAMPLES / "chair.obj")
    centre, _ = frame_of(chair.vertices)
    tilted = Mesh((chair.vertices - centre) @ rotation(axis, 2.0).T + centre, chair.faces, "tilted")
    assert turning.score(tilted, chair) < 0.2 * scorer.score(tilted, chair)
    # what the turn forgives is a turn, not a change: a missing leg scores as before
    missing = load_mesh(EXAMPLES / "chair_no_leg.obj")
    assert turning.score(missing, chair) == scorer.score(missing, chair) > 0.5


def test_drkfs_1_2_scores_as_the_torch_path_turned_by_the_same_search(turning):
    chair = load_mesh(EXAMPLES / "chair.obj")
    tilted = Mesh(chair.vertices @ rotation(0, 2.0).T, chair.faces, "tilted")
    metric = DRKFS.pretrained(turning.config)
    assert turning.score(tilted, chair) == pytest.approx(
        metric.score_meshes(tilted, chair), rel=1e-3
    )


def test_a_turning_scorers_features_file_carries_the_surface_a_mesh_is_turned_onto(
    scorer, turning, tmp_path
):
    chair = load_mesh(EXAMPLES / "chair.obj")
    tilted = Mesh(chair.vertices @ rotation(2, 2.0).T, chair.faces, "tilted")
    turning.features(chair).save(tmp_path / "chair.npz")
    loaded = MeshFeatures.load(tmp_path / "chair.npz")
    assert len(loaded.surface.points) == turning.config.align_reference_points
    assert turning.score(tilted, loaded) == turning.score(tilted, chair)
    # a file described under no turn holds no surface, and its views alone cannot be turned onto
    scorer.features(chair).save(tmp_path / "plain.npz")
    with pytest.raises(ValueError, match=r"plain\.npz: .*drkfs-1\.1.*drkfs-1\.2.*align_degrees"):
        turning.score(tilted, tmp_path / "plain.npz")
    with np.load(tmp_path / "chair.npz") as saved:  # samples of mismatched shapes
        arrays = {name: saved[name] for name in saved.files}
    np.savez(
        tmp_path / "broken.npz", **{**arrays, "surface_normals": arrays["surface_normals"][1:]}
    )
    with pytest.raises(ValueError, match=r"broken\.npz: incomplete features file \(surface"):
        MeshFeatures.load(tmp_path / "broken.npz")
    views_alone = turning.describe(turning.views(chair, loaded.frame), loaded.frame)
    with pytest.raises(ValueError, match="features of views alone"):
        turning.score(tilted, views_alone)


def test_a_mesh_described_as_compared_is_sampled_when_it_is_later_a_reference():
    turning = Scorer(metric="drkfs-1.2", threads=2)  # an empty cache
    chair, no_leg = load_mesh(EXAMPLES / "chair.obj"), load_mesh(EXAMPLES / "chair_no_leg.obj")
    compared = turning.compared(chair, turning.features(no_leg))  # not turned: the cache's
    assert compared.surface is None  # a compared mesh is not sampled as a reference
    as_reference = turning.features(chair, turning.features(no_leg).frame)
    assert as_reference.descriptors is compared.descriptors and as_reference.surface is not None
