"""The speed-accuracy benchmark: its baselines on known answers, the variant set on disk, the
chart, and the quick run end to end."""

import json
import shutil

import numpy as np
import pytest
import torch
import trimesh
from conftest import ROOT

from drkfs_lab.benchmark import human, peers, sets
from drkfs_lab.benchmark import point_metrics as pm
from drkfs_lab.benchmark.chart import pareto_front, write_chart
from drkfs_lab.benchmark.methods import DEFAULT_NAME, DrkfsOnnx, Placed, drkfs_configs
from drkfs_lab.benchmark.run import TIER_PAIRS, kept_rows, run_bench
from drkfs_lab.benchmark.sets import STABILITY, _box_with_cavity
from drkfs_lab.benchmark.tiers import (
    INVISIBLE,
    STRUCTURAL,
    SURFACE,
    local_edges,
    part_tiers,
    scan_tiers,
)
from drkfs_lab.benchmark.torch_checks import agreement, value_and_gradient
from drkfs_onnx.contract.config import TWO_SIDED, PipelineConfig
from drkfs_onnx.contract.mesh import frame_of, load_mesh, place
from drkfs_onnx.contract.versions import CUSTOM, LATEST, metric_name
from drkfs_onnx.runtime.render import NumpyRenderer
from drkfs_onnx.synthetic.shapes import (
    ALL_FAMILIES,
    FAMILIES,
    Part,
    assemble,
    random_shape,
    subdivide,
)

EXAMPLES = ROOT / "examples"


def _placed(verts, faces):
    return place(verts, frame_of(verts)), faces


def test_nearest_neighbours_are_exact_for_near_and_far_queries():
    rng = np.random.default_rng(0)
    targets = rng.normal(size=(3000, 3))
    queries = np.concatenate([targets[:500] + 1e-3, rng.normal(size=(500, 3)) * 5])
    dist, index = pm._nearest(queries, targets)
    brute = torch.cdist(torch.from_numpy(queries), torch.from_numpy(targets)).min(1)
    np.testing.assert_allclose(dist, brute.values.numpy(), atol=1e-9)
    np.testing.assert_array_equal(index, brute.indices.numpy())


def test_surface_metrics_of_a_surface_against_itself_and_a_shifted_copy():
    verts, faces = _placed(*assemble(random_shape("chair", 0), 1))
    a = pm.sample_surface(verts, faces, 20000, seed=0)
    same = pm.surface_distances(a, pm.sample_surface(verts, faces, 20000, seed=1))
    moved = pm.surface_distances(a, pm.sample_surface(verts + [0.1, 0, 0], faces, 20000, seed=1))
    assert same["fscore"] > 0.97 and same["normal_consistency"] > 0.95
    assert same["chamfer_l1"] < 0.02 < moved["chamfer_l1"] < 0.1
    assert moved["fscore"] < same["fscore"]


def test_occupancy_fills_a_box_and_leaves_its_hidden_cavity_empty():
    box_v, box_f = Part("box", (0, 0, 0), (1.0, 0.6, 0.8)).mesh(2)
    solid = pm.occupancy(box_v, box_f)
    pitch = 2 * pm.VOXEL_EXTENT / pm.VOXELS
    assert solid.sum() * pitch**3 == pytest.approx(0.48, rel=0.1)
    hollow = pm.occupancy(*_box_with_cavity())
    assert pm.iou(solid, hollow) == pytest.approx(1 - 0.06 / 0.48, abs=0.03)
    assert pm.is_watertight(box_v, box_f)
    assert not pm.is_watertight(box_v, box_f[1:])


def test_overlapping_closed_parts_count_once():
    one = Part("a", (0, 0, 0), (1.0, 1.0, 1.0)).mesh()
    two = assemble(
        [Part("a", (0, 0, 0), (1.0, 1.0, 1.0)), Part("b", (0.25, 0, 0), (0.5, 0.5, 0.5))]
    )
    assert pm.iou(pm.occupancy(*one), pm.occupancy(*two)) == 1.0


def test_a_scans_tiers_change_it_by_their_measure(real_meshes):
    mesh = load_mesh(real_meshes / "cow.obj")
    variants = scan_tiers(mesh.vertices, mesh.faces, np.random.default_rng(0))
    assert [v.name for v in variants] == [*STRUCTURAL, *INVISIBLE, *SURFACE]
    assert [v.kind for v in variants] == ["structural"] * 2 + ["invisible"] * 5 + ["surface"] * 3
    kinds = {v.name: v for v in variants}
    assert len(kinds["part_removed"].faces) < len(mesh.faces)
    assert len(kinds["retessellated"].faces) == len(kinds["noise"].faces) == 4 * len(mesh.faces)
    size = np.linalg.norm(np.ptp(mesh.vertices, axis=0))
    moved = np.linalg.norm(kinds["part_shifted"].verts - mesh.vertices, axis=1)
    assert 0 < moved.max() <= 0.01 * size + 1e-9 and (moved == 0).mean() > 0.5
    jitter = np.linalg.norm(kinds["jittered"].verts - mesh.vertices, axis=1)
    assert np.median(jitter / local_edges(mesh.vertices, mesh.faces)) < 0.1  # sub-triangle
    assert len(kinds["simplified"].faces) == pytest.approx(0.15 * len(mesh.faces), rel=0.05)
    fine = kinds["retessellated"]
    noise = np.linalg.norm(kinds["noise"].verts - fine.verts, axis=1)
    assert np.median(noise / local_edges(fine.verts, fine.faces)) > 0.1  # visible, not tiny


def test_the_invisible_turn_is_a_turn_about_the_shape_wherever_its_files_origin_lies(
    real_meshes,
):
    mesh = load_mesh(real_meshes / "homer.obj")  # its origin lies 0.7 diagonals away
    verts = np.asarray(mesh.vertices)
    (turn,) = [
        v for v in scan_tiers(verts, mesh.faces, np.random.default_rng(0)) if v.name == "rotated"
    ]
    size = np.linalg.norm(np.ptp(verts, axis=0))
    centre = (verts.min(0) + verts.max(0)) / 2
    # no shift: the box's centre stays within what a turn of its corners moves it (0.4% of the
    # size here); about the origin it would move by 2.4%
    assert np.abs((turn.verts.min(0) + turn.verts.max(0)) / 2 - centre).max() < 0.01 * size
    # and a 2-degree turn: no vertex moves further than the arc at the box's farthest corner
    arc = np.radians(2.0) * np.linalg.norm(verts - centre, axis=1).max()
    moved = np.linalg.norm(turn.verts - verts, axis=1)
    assert moved.max() <= arc + 1e-9 and np.allclose(turn.verts[:, 1], verts[:, 1])


def test_a_part_shapes_tiers_keep_its_tessellation_but_where_the_tier_changes_it():
    parts = random_shape("chair", 0)
    verts, faces = assemble(parts, 1)
    variants = {v.name: v for v in part_tiers(parts, np.random.default_rng(0))}
    assert set(variants) == {*STRUCTURAL, *INVISIBLE, "noise", "smoothed"}
    assert np.array_equal(variants["jittered"].faces, faces)
    assert np.abs(variants["rotated"].verts - verts).max() < 0.05
    assert len(variants["noise"].faces) == 64 * len(faces)  # the fine tessellation
    assert len(variants["part_removed"].faces) < len(faces)


def test_retrieval_spans_every_family_and_the_tiers_only_the_trained_ones():
    bench = sets.BenchSet()
    sets.retrieval(bench, list(ALL_FAMILIES), sets.RETRIEVAL_PER_FAMILY)
    assert len(bench.retrieval) >= 100 and len(set(bench.retrieval.values())) >= 20
    assert set(FAMILIES) < set(ALL_FAMILIES)


def test_pareto_front_keeps_only_unbeaten_points_fastest_first():
    points = {"slow_best": (10.0, 0.9), "fast_ok": (0.1, 0.6), "beaten": (1.0, 0.5),
              "tie_slower": (0.2, 0.6), "no_accuracy": (0.01, None)}  # fmt: skip
    assert pareto_front(points) == ["fast_ok", "slow_best"]


def _png(path):
    from matplotlib.image import imread

    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    return (imread(path)[..., :3] * 255).round().astype(int)


def test_chart_draws_every_kind_of_method_the_front_and_the_presets(tmp_path):
    from matplotlib.colors import to_rgb

    points = {"DR-KFS": (1.5, 0.8), "Chamfer-L1": (0.5, 0.7), "pixel MSE": (0.7, 0.6)}
    path = write_chart(tmp_path / "chart.png", points, pareto_front(points), {"DR-KFS": "default"})
    pixels = _png(path)
    assert pixels.shape[:2] == (704, 1100)  # 10 x 6.4 inches at 110 dpi
    colours = {tuple(c) for c in pixels.reshape(-1, 3)}
    for name in ("tab:blue", "tab:grey", "tab:red"):  # DR-KFS, other methods, the front
        assert tuple(round(255 * v) for v in to_rgb(name)) in colours, name
    unmarked = write_chart(tmp_path / "unmarked.png", points, pareto_front(points))
    assert (_png(unmarked) != pixels).any()  # the preset is marked
    without = write_chart(tmp_path / "plain.png", {"pixel MSE": (0.7, 0.6)}, [])
    plain = {tuple(c) for c in _png(without).reshape(-1, 3)}
    assert tuple(round(255 * v) for v in to_rgb("tab:blue")) not in plain


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """The quick bench without the LFD peer even where it is installed: it would double the
    run, and ``test_lfd_sees_the_missing_leg_and_not_the_retessellation`` checks it."""
    out = tmp_path_factory.mktemp("bench")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("drkfs_lab.benchmark.run.find_lfd", lambda: "left out of the tests")
        return out, run_bench(out, quick=True, progress=lambda line: None)


def test_quick_bench_writes_results_chart_and_the_variant_set(quick):
    out, results = quick
    assert json.loads((out / "results.json").read_text())["quick"] is True
    # each DR-KFS row names the metric version of its config (custom where a setting differs)
    rows = [m for m in results["methods"].values() if "config" in m]
    assert all(m["metric"] == metric_name(PipelineConfig.from_dict(m["config"])) for m in rows)
    assert results["methods"]["DR-KFS"]["metric"] == LATEST
    assert results["methods"]["DR-KFS paper"]["metric"] == CUSTOM  # capped by the quick set
    full = drkfs_configs()
    assert metric_name(full["DR-KFS"]) == LATEST
    assert metric_name(full["DR-KFS paper"]) == "drkfs-paper"
    assert _png(out / "speed_accuracy.png").shape[:2] == (704, 1100)
    index = json.loads((out / "set" / "index.json").read_text())
    for key, name in index["files"].items():
        assert len(trimesh.load(out / "set" / name, process=False).faces) > 0, key
    assert {c["group"] for c in index["comparisons"]} == {"tiers", "real", "bars", "stability"}
    # the quick set's real tiers: woody, on the training side
    real = results["methods"]["DR-KFS"]["real_tiers"]
    assert real["training"]["invisible_vs_structural"] is not None
    assert real["held_out"]["invisible_vs_structural"] is None
    assert real["checks"]["training"]["turn_below_every_surface"]["share"] in (0.0, 1.0)
    # every method off the front is beaten on both axes by one on it
    point = {
        n: (m["seconds_per_pair"], m["tiers"]["invisible_vs_structural"])
        for n, m in results["methods"].items()
    }
    front = results["pareto_front"]
    for name, (seconds, accuracy) in point.items():
        if name not in front and accuracy is not None:
            assert any(point[f][0] <= seconds and point[f][1] >= accuracy for f in front), name


def test_quick_bench_scores_every_method_on_the_same_rows(quick):
    _, results = quick
    names = set(results["methods"])
    assert {"DR-KFS torch", "DR-KFS", "DR-KFS paper", "Chamfer-L1", "volumetric IoU"} <= names
    assert results["methods"]["DR-KFS"]["default"] is True
    assert results["methods"]["DR-KFS paper"]["preset"] == "paper"
    assert sum(row.get("default", False) for row in results["methods"].values()) == 1
    rows = {name: set(values) for name, values in results["values"].items()}
    assert all(r == rows["Chamfer-L1"] for r in rows.values())
    methods = results["methods"]
    judged = methods["DR-KFS"]["tiers"]["pairs"]
    assert min(judged.values()) > 0 and methods["Chamfer-L1"]["tiers"]["pairs"] == judged
    for name, row in methods.items():
        for pair, count in row["tiers"]["pairs"].items():
            wins = row["tiers"][pair] * count
            assert wins == pytest.approx(round(wins)), (name, pair)  # a share of whole pairs
            assert row["tiers"]["synthetic"][pair] == row["tiers"][pair]  # no shared mesh here
            missed = row["tiers"]["misses"][pair]  # the wrong-way variant pairs, by name
            assert sum(missed.values()) == pytest.approx(count - wins), (name, pair)
            lower, higher = TIER_PAIRS[pair]
            kinds = {"invisible": INVISIBLE, "surface": SURFACE, "structural": STRUCTURAL}
            for named in missed:
                low, high = named.split(" < ")
                assert low in kinds[lower] and high in kinds[higher], named
        assert row["tiers"]["shared"]["invisible_vs_structural"] is None
        assert row["seconds_per_pair"] >= row["seconds_per_cached_pair"], name
        assert row["retrieval"]["queries"] > 0, name
        assert row["human"] is None  # no --human folder
    median = methods["DR-KFS"]["tiers"]["median"]  # the metric's point, even on the quick set
    assert median["invisible"] < median["surface"] < median["structural"]


def test_quick_bench_torch_and_onnx_agree(quick):
    _, results = quick
    onnx, torch_ = results["values"]["DR-KFS"], results["values"]["DR-KFS torch"]
    scale = max(torch_.values())  # near-zero scores differ by float rounding of that scale
    for key, value in onnx.items():
        assert value == pytest.approx(torch_[key], rel=2e-3, abs=2e-3 * scale), key


def test_a_devices_step_is_compared_with_the_cpus_by_value_and_gradient_direction():
    verts = torch.tensor([[1.0, -2.0, 0.5]])
    step = value_and_gradient(lambda v: (v**2).sum(), verts, "cpu")
    value, gradient = step()
    assert value == 5.25 and torch.equal(gradient, 2 * verts)
    assert verts.grad is None  # the caller's tensor is left alone, so the step can repeat
    assert agreement((value, gradient), step()) == {
        "value_relative_difference": 0.0,
        "gradient_cosine": pytest.approx(1.0),
    }
    off = agreement((value, gradient), (1.01 * value, -3 * gradient))
    assert off["value_relative_difference"] == pytest.approx(0.01)
    assert off["gradient_cosine"] == pytest.approx(-1.0)  # direction only, not length


def test_quick_bench_stability_rows_and_torch_checks(quick):
    _, results = quick
    table = results["stability"]["DR-KFS"]
    assert set(table) == set(STABILITY) - {"over_200k_faces"}
    assert table["hidden_cavity"]["value"] == 0.0  # the known blind spot: no camera sees it
    assert table["hidden_cavity"]["passed"] is False
    assert table["duplicated_faces"]["passed"] and table["retessellated"]["passed"]
    assert results["stability"]["volumetric IoU"]["hidden_cavity"]["passed"] is True
    checks = results["torch_stability"]
    assert all(
        row["gradient_finite"] and row["self_score"] == 0.0 for row in checks["cases"].values()
    )
    scores = checks["slide"]["scores"]
    assert scores[0] == 0.0 and scores[-1] == max(scores) > 0  # a slid leg scores, most at 5%


def test_quick_bench_score_rises_without_a_jump_as_a_leg_slides(quick):
    # no step of the slide more than 3 times the mean step, the default as shipped (4 views of
    # 192 px failed this: their largest step was 3.3 times the mean)
    _, results = quick
    slide = results["torch_stability"]["slide"]
    assert slide["passed"] and slide["max_over_mean_step"] <= slide["limit"] == 3
    assert slide["scores"][-1] == max(slide["scores"]) > 0
    assert drkfs_configs(quick=True)[DEFAULT_NAME] == PipelineConfig()  # as shipped


def test_retessellating_a_mesh_keeps_its_occupancy():
    verts, faces = _placed(*Part("c", (0, 0, 0), (1, 1, 1), "cylinder").mesh(1))
    fine = subdivide(verts, faces)
    assert pm.iou(pm.occupancy(verts, faces), pm.occupancy(*fine)) == 1.0


def test_missing_graphs_are_exported_once_before_the_bench_scores(tmp_path, monkeypatch):
    """With no shipped graphs (weights retrained, not exported), ``drkfs export``'s function runs
    once and every DR-KFS method reads its graph from the run's folder."""
    import shutil

    from drkfs_lab.benchmark import methods
    from drkfs_onnx.contract.model_files import models_dir
    from drkfs_onnx.export import onnx_files

    shipped, calls = models_dir(), []

    def export_shipped(folder):  # copies stand in for fresh exports of the same weights
        calls.append(folder)
        folder.mkdir(parents=True, exist_ok=True)
        for graph in shipped.glob("*.onnx"):
            shutil.copy(graph, folder / graph.name)

    monkeypatch.setattr(onnx_files, "export_shipped", export_shipped)
    monkeypatch.setattr(methods, "models_dir", lambda: tmp_path / "empty")
    built = methods.build_methods(tmp_path / "run", threads=1, quick=True)
    assert calls == [tmp_path / "run"]
    onnx = [m for m in built if isinstance(m, methods.DrkfsOnnx)]
    assert onnx and all(
        m.scorer.features_graph.source.startswith(str(tmp_path / "run")) for m in onnx
    )


def test_configs_that_differ_only_in_their_match_describe_a_mesh_once(monkeypatch):
    """The structure preset has the default's nets and cameras: it takes the default's
    descriptors of a mesh, charged what they cost; other nets describe it anew. (Without the
    turn onto the reference, whose surface samples each config times on its own.)"""
    verts, faces = assemble(FAMILIES["chair"](np.random.default_rng(0)), 1)
    placed = Placed("chair", place(verts, frame_of(verts)), faces)
    default, structure, previous = (
        DrkfsOnnx(name, config, None, threads=1)
        for name, config in [
            ("default", PipelineConfig(align_degrees=0.0)),
            ("structure", PipelineConfig.structure(align_degrees=0.0)),
            ("previous", PipelineConfig.structure(nets="correspondence", align_degrees=0.0)),
        ]
    )
    described = []
    for method in (default, structure, previous):
        describe = method.scorer.describe
        monkeypatch.setattr(
            method.scorer,
            "describe",
            lambda images, f=describe, m=method: described.append(m) or f(images),
        )
    ((_, features, _), seconds), ((_, shared, _), charged) = (
        default.prepare(placed),
        structure.prepare(placed),
    )
    assert shared is features and charged == seconds
    (_, own, _), _ = previous.prepare(placed)
    assert described == [default, previous] and own.config != features.config


def test_views_are_shared_only_between_configs_that_render_alike():
    """Two levers that differ in the match share a mesh's renders; one that lights faces seen
    from behind otherwise, or pushes them back otherwise, renders its own."""
    verts, faces = assemble(FAMILIES["chair"](np.random.default_rng(0)), 1)
    placed = Placed("chair", place(verts, frame_of(verts)), faces)
    config = PipelineConfig(num_views=2, image_size=64, **TWO_SIDED)
    views, _ = placed.views(NumpyRenderer(config))
    assert placed.views(NumpyRenderer(config.replace(temperature=0.5)))[0] is views
    shadowed, _ = placed.views(NumpyRenderer(config.replace(back_light=0.0)))
    assert shadowed is not views and not np.array_equal(shadowed, views)
    pushed, _ = placed.views(NumpyRenderer(config.replace(back_light=0.0, back_push=0.1)))
    assert pushed is not shadowed and not np.array_equal(pushed, shadowed)


def _geometric_folder(folder, faces: dict[str, dict[str, float]]):
    """A Geo-metric-like folder: each face's stimuli (the example chair, shifted per level) and
    a JODPerMesh.csv with the given JOD per level in every setting."""
    chair = load_mesh(EXAMPLES / "chair.obj")
    lines = ["basemesh,dst_type,setting,magnitude,JOD," + ",".join(human.DATASET_METRICS)]
    for face, jods in faces.items():
        for shift, (level, value) in enumerate(jods.items()):
            path = human.stimulus(folder, face, level)
            path.parent.mkdir(parents=True, exist_ok=True)
            trimesh.Trimesh(chair.vertices + [0.01 * shift, 0, 0], chair.faces).export(path)
            metrics = ",".join([str(-value)] * len(human.DATASET_METRICS))  # worse: larger
            lines += [f"{face},Simp,{s},Simp_{level},{value},{metrics}" for s in human.SETTINGS]
    (folder / human.JOD_FILE).parent.mkdir(parents=True)
    (folder / human.JOD_FILE).write_text("\n".join(lines) + "\n")
    return folder


def test_human_agreement_is_spearman_against_the_jod_difference_per_setting(tmp_path):
    jods = {f"F{i}": {"p12.50": -0.5, "p06.25": -1.0 - i, "p03.12": -2.0 - 2 * i} for i in range(4)}
    bench = sets.BenchSet()
    differences = human.add_human(bench, _geometric_folder(tmp_path, jods))
    assert len(bench.comparisons) == 8 and set(bench.sources) == set(bench.shapes)
    worse = {
        i: -differences[(c.base, c.kind, "far_normal")] for i, c in enumerate(bench.comparisons)
    }
    agreement = human.human_agreement(bench, worse, differences)
    assert [agreement[s] for s in human.SETTINGS] == pytest.approx([-1.0] * 4)
    assert agreement["within_level"]["p03.12"]["close_flipped"] == pytest.approx(-1.0)
    assert human.human_agreement(bench, {}, differences) is None
    reference = human.dataset_agreement(bench, tmp_path, differences)
    assert reference["MSDM2"]["close_normal"] == pytest.approx(-1.0)
    index = json.loads(bench.write(tmp_path / "set").read_text())  # stimuli named, not copied
    assert set(index["files"].values()) == {str(p) for p in bench.sources.values()}


def test_human_ceiling_is_what_separating_the_levels_alone_can_reach(tmp_path):
    # people tell the levels apart and nothing else: a perfect level separator reaches the
    # rank correlation of a two-valued variable with 8 ranks, and no luck does better
    tied = {f"F{i}": {"p12.50": 0.0, "p06.25": -1.0, "p03.12": -2.0} for i in range(4)}
    bench = sets.BenchSet()
    ceiling = human.agreement_ceiling(
        bench, human.add_human(bench, _geometric_folder(tmp_path / "a", tied))
    )
    best = -np.sqrt(3 * 8**2 / (4 * (8**2 - 1)))
    assert ceiling["far_normal"]["levels_only"] == pytest.approx(best)
    assert ceiling["far_normal"]["levels_only_lucky"] == pytest.approx(best)
    # faces ordered within a level the same way in every setting: people agree with themselves,
    # and a scorer blind within a level falls short of -1 by luck
    ordered = {
        f"F{i}": {"p12.50": -0.5, "p06.25": -1.0 - i, "p03.12": -2.0 - 2 * i} for i in range(4)
    }
    bench = sets.BenchSet()
    ceiling = human.agreement_ceiling(
        bench, human.add_human(bench, _geometric_folder(tmp_path / "b", ordered))
    )
    for setting in human.SETTINGS:
        found = ceiling[setting]
        assert found["people_within_level"] == pytest.approx(1.0)
        assert -1.0 < found["levels_only_lucky"] < found["levels_only"] < 0.0


def test_a_folder_without_the_stimuli_is_named(tmp_path):
    with pytest.raises(ValueError, match="JODPerMesh.csv"):
        human.faces_in(tmp_path)
    (tmp_path / human.JOD_FILE).parent.mkdir(parents=True)
    (tmp_path / human.JOD_FILE).write_text("basemesh\n")
    with pytest.raises(ValueError, match="b4f5cc9"):
        human.faces_in(tmp_path)


def test_lfd_is_skipped_with_its_reason_where_it_is_not_installed(tmp_path):
    assert "not installed" in peers.find_lfd(tmp_path)


@pytest.mark.skipif(isinstance(peers.find_lfd(), str), reason="LFD peer not installed here")
def test_lfd_sees_the_missing_leg_and_not_the_retessellation():
    lfd = peers.LightField(*peers.find_lfd())
    try:
        chair = load_mesh(EXAMPLES / "chair.obj")
        frame = frame_of(chair.vertices)
        prepared = {
            name: lfd.prepare(Placed(name, place(mesh.vertices, frame), mesh.faces))[0]
            for name, mesh in (("chair", chair),
                               *((n, load_mesh(EXAMPLES / f"chair_{n}.obj"))
                                 for n in ("no_leg", "retessellated")))
        }  # fmt: skip
        assert lfd.compare(prepared["chair"], prepared["chair"]) == (0.0,)
        assert lfd.compare(prepared["chair"], prepared["retessellated"]) == (0.0,)
        (missing,) = lfd.compare(prepared["chair"], prepared["no_leg"])
        assert missing > 0 and lfd.compare(prepared["no_leg"], prepared["chair"]) == (missing,)
    finally:
        lfd.close()


@pytest.mark.skipif(shutil.which("Xvfb") is None, reason="no Xvfb here")
def test_a_mesh_lfd_cannot_describe_leaves_its_pairs_unscored_and_is_named(tmp_path):
    program = tmp_path / "Executable"
    program.mkdir()
    (program / "3DAlignment").write_text("#!/bin/sh\nexit 1\n")
    (program / "3DAlignment").chmod(0o755)
    lfd = peers.LightField(program, program / "Distance")
    try:
        chair = load_mesh(EXAMPLES / "chair.obj")
        described, _ = lfd.prepare(Placed("chair", chair.vertices, chair.faces))
        assert described is None and lfd.failed == ["chair"]
        assert lfd.compare(described, described) == (None,)
    finally:
        lfd.close()


def test_the_image_methods_render_a_mesh_alone_when_no_other_method_shares_their_views():
    """Pixel and PoI-map MSE take the paper preset's renders; scored without the paper preset
    (a run of a few methods), each renders them itself, with its own threads."""
    from drkfs_lab.benchmark import methods

    verts, faces = assemble(FAMILIES["chair"](np.random.default_rng(0)), 1)
    built = methods.build_methods(methods.models_dir(), threads=2, quick=True)
    for method in (m for m in built if isinstance(m, methods.ImageMSE)):
        placed = Placed("chair", place(verts, frame_of(verts)), faces)
        prepared, seconds = method.prepare(placed)
        assert method.renderer.threads == 2 and seconds > 0
        assert method.compare(prepared, prepared) == (0.0,)


def test_an_earlier_runs_rows_are_kept_for_the_same_pairs_but_never_the_defaults():
    earlier = {
        "command": "python bench/as_they_come.py --out x.json",
        "labels": {"cow/noise": "surface"},
        "peers": {"LFD": "light-field-distance 0.0.9"},
        "methods": {DEFAULT_NAME: {"held_out": 1.0}, "LFD": {"held_out": 0.5}},
        "values": {DEFAULT_NAME: {"cow/noise": 0.1}, "LFD": {"cow/noise": 300.0}},
    }
    kept, rows, values = kept_rows(earlier, {"cow/noise": "surface"}, [DEFAULT_NAME])
    assert kept == {
        "command": "python bench/as_they_come.py --out x.json",
        "methods": ["LFD"],
        "peers": {"LFD": "light-field-distance 0.0.9"},
    }
    assert rows == {"LFD": {"held_out": 0.5}} and values == {"LFD": {"cow/noise": 300.0}}
    with pytest.raises(ValueError, match="scored other pairs"):
        kept_rows(earlier, {"cow/hole": "surface"}, [DEFAULT_NAME])
    with pytest.raises(ValueError, match=f"rows of {DEFAULT_NAME} follow the default"):
        kept_rows(earlier, {"cow/noise": "surface"}, ["LFD"])
