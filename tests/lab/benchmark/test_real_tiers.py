"""The real-mesh tiers: each real mesh's variants, labelled as a viewer sees them, and the checks
the benchmark reports on them."""

import numpy as np
import pytest
from conftest import ROOT

from drkfs_lab.benchmark import real_tiers, sets
from drkfs_lab.benchmark.real_tiers import (
    DECIMATED_FACES,
    HELDOUT_MESHES,
    NOISE_EDGES,
    TRAINING_MESHES,
    mean_edge,
    real_variants,
    second_piece,
)
from drkfs_lab.benchmark.run import lever_summary, real_checks, tier_accuracy
from drkfs_lab.benchmark.tiers import smoothed
from drkfs_onnx import load_mesh
from drkfs_onnx.synthetic.variants import salient_tip


def _variants(name: str):
    mesh = load_mesh(sets.real_mesh(name))
    return mesh, {v.name: v for v in real_variants(name, mesh.vertices, mesh.faces,
                                                   np.random.default_rng(0))}  # fmt: skip


def test_the_sides_split_the_real_meshes_once():
    assert set(TRAINING_MESHES).isdisjoint(HELDOUT_MESHES)
    assert {*TRAINING_MESHES, *HELDOUT_MESHES} == set(sets.SHARED_MESHES)


def test_a_mesh_gets_every_tier_and_a_coarse_one_no_decimation(monkeypatch):
    mesh, cow = _variants("cow")
    assert len(mesh.faces) >= DECIMATED_FACES
    tiers = {v.kind for v in cow.values()}
    assert tiers == {"invisible", "surface", "structural"}
    assert {"turned_1", "turned_2", "turned_3", "subdivided"} == {
        n for n, v in cow.items() if v.kind == "invisible"
    }  # half the cow's 5,804 faces shows speckled facets: no decimation to half
    assert len(cow["decimated_heavy"].faces) == pytest.approx(0.1 * len(mesh.faces), rel=0.05)
    coarse, woody = _variants("woody")
    assert len(coarse.faces) < DECIMATED_FACES
    assert not {"decimated_half", "decimated_heavy"} & set(woody)
    monkeypatch.setattr(real_tiers, "HALF_FACES", len(mesh.faces))  # the cow as a dense mesh
    assert _variants("cow")[1]["decimated_half"].kind == "invisible"


def test_the_turn_keeps_the_shape_in_place_and_the_salient_part_is_at_the_furthest_tip():
    mesh, cow = _variants("cow")
    turned = cow["turned_2"].verts
    centre = (mesh.vertices.min(0) + mesh.vertices.max(0)) / 2
    assert np.allclose(
        (turned.min(0) + turned.max(0)) / 2, centre, atol=0.02 * np.ptp(mesh.vertices)
    )
    removed = cow["salient_part_removed"]
    tip = salient_tip(mesh.vertices, mesh.faces)
    kept_centres = removed.verts[removed.faces].mean(1)
    assert np.linalg.norm(kept_centres - tip, axis=1).min() > 0.05 * np.linalg.norm(
        np.ptp(mesh.vertices, 0)
    )
    assert 0 < len(mesh.faces) - len(removed.faces) < 0.1 * len(mesh.faces)


def test_the_variants_relabelled_by_their_renders_carry_their_new_tier():
    _, fandisk = _variants("fandisk")
    assert fandisk["decimated_heavy"].kind == "invisible"
    for name in ("cheburashka", "homer"):
        assert _variants(name)[1]["smoothed"].kind == "invisible"
    assert _variants("cow")[1]["smoothed"].kind == "surface"


def test_noise_follows_the_edges_and_a_dense_mesh_gets_more_smoothing():
    """Noise of a tenth of the mean edge on a coarse and a dense mesh; the dense one's smoothing
    takes more iterations, and moves its surface half again as far as the coarse one's count
    would."""
    for name in ("cow", "stanford-bunny"):
        mesh, variants = _variants(name)
        edge = mean_edge(mesh.vertices, mesh.faces)
        noise = np.linalg.norm(variants["noise"].verts - mesh.vertices, axis=1)
        assert np.sqrt(np.mean(noise**2)) == pytest.approx(NOISE_EDGES * edge, rel=0.05)
    bunny = mesh  # the loop's last mesh

    def moved(verts: np.ndarray) -> float:
        return float(np.linalg.norm(verts - bunny.vertices, axis=1).mean())

    as_the_cow = smoothed(bunny.vertices, bunny.faces, 9)  # the cow's iterations
    assert moved(variants["smoothed"].verts) > 1.5 * moved(as_the_cow)


def test_a_second_piece_is_removed_only_where_it_is_a_part():
    beast = load_mesh(sets.real_mesh("beast"))
    assert second_piece(beast.vertices, beast.faces).sum() > 0
    beetle = load_mesh(sets.real_mesh("beetle"))  # its second piece holds 0.5% of the area
    assert second_piece(beetle.vertices, beetle.faces) is None


def test_the_checks_count_meshes_on_each_side():
    bench = sets.BenchSet()
    values, i = {}, 0
    # cow (training): the 2-degree turn below both surface variants, the 3-degree one above the
    # smoothing, the salient part above the turns; homer (held out): the turn above the noise,
    # the salient part below the subdivision
    rows = {
        "cow": {("invisible", "turned_2"): 0.1, ("invisible", "subdivided"): 0.05,
                ("invisible", "turned_3"): 0.25,
                ("surface", "noise"): 0.3, ("surface", "smoothed"): 0.2,
                ("structural", "salient_part_removed"): 0.5},
        "homer": {("invisible", "turned_2"): 0.1, ("invisible", "subdivided"): 0.6,
                  ("surface", "noise"): 0.05, ("surface", "smoothed"): 0.2,
                  ("structural", "salient_part_removed"): 0.5},
    }  # fmt: skip
    for name, row in rows.items():
        base = sets.REAL_PREFIX + name
        for (kind, label), value in row.items():
            bench.comparisons.append(
                sets.Comparison("real", base, label, kind, f"{base}/{label}", base)
            )
            values[i], i = value, i + 1
    checks = real_checks(bench, values)
    assert checks["training"]["turn_below_every_surface"] == {"share": 1.0, "failed": []}
    assert checks["held_out"]["turn_below_every_surface"] == {"share": 0.0, "failed": ["homer"]}
    assert checks["training"]["every_turn_below_every_surface"] == {"share": 0.0, "failed": ["cow"]}
    assert checks["held_out"]["salient_above_every_invisible"]["failed"] == ["homer"]
    accuracy = tier_accuracy(bench, values, "real")
    assert accuracy["training"]["invisible_vs_surface"] == 5 / 6  # the 3-degree turn's miss
    assert accuracy["held_out"]["invisible_vs_surface"] == 0.25  # smoothed above the turn only


def test_a_real_mesh_in_both_tier_groups_is_stored_once_and_every_reference_resolves():
    bench = sets.BenchSet()
    sets.tiers(bench, [], ["woody"])
    sets.real_tiers(bench, ["woody"])
    assert {c.group for c in bench.comparisons} == {"tiers", "real"}
    assert all(c.reference in bench.shapes and c.shape in bench.shapes for c in bench.comparisons)
    assert {c.base for c in bench.comparisons if c.group == "real"} == {"real-woody"}


@pytest.mark.slow  # scores all 92 real variants (about 30 s on 2 cores)
def test_the_parts_split_each_score_into_its_two_terms_and_name_every_misordered_pair(tmp_path):
    import json
    import subprocess
    import sys

    root = ROOT
    out = tmp_path / "parts.json"
    done = subprocess.run(
        [sys.executable, "bench/real_tiers.py", "--parts", str(out), "--threads", "2"],
        cwd=root, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    found = json.loads(out.read_text())
    parts, misses = found["variants"], found["misses"]
    committed = json.loads((root / "bench/results/real_tiers.json").read_text())
    assert set(parts) == set(committed["labels"])
    for key, part in parts.items():
        assert part["kind"] == committed["labels"][key]
        assert part["descriptors"] >= 0 and part["solid_change"] >= 0
        assert part["descriptors"] + part["solid_change"] == pytest.approx(part["score"])
        # the default's score, as the real tiers' run scored it
        assert part["score"] == pytest.approx(committed["values"]["DR-KFS"][key], rel=1e-6)
    listed = {(m["below"], m["above"]) for side in misses.values() for m in side}
    assert listed  # the default misorders some pairs (bench/records/real_tiers.md, "Left open")
    for upper, lower in ((u, w) for u in parts for w in parts):
        if upper.split("/")[0] != lower.split("/")[0] or parts[upper]["kind"] != "structural":
            continue
        wrong = parts[lower]["kind"] != "structural" and (
            parts[upper]["score"] <= parts[lower]["score"]
        )
        assert ((upper, lower) in listed) == wrong


@pytest.mark.slow  # three runs of the script, each importing the lab (about 15 s on 2 cores)
def test_the_shares_recomputed_without_some_variants_leave_out_exactly_their_pairs(tmp_path):
    import json
    import subprocess
    import sys

    root = ROOT
    committed = json.loads((root / "bench/results/real_tiers.json").read_text())

    def shares(left_out: str) -> subprocess.CompletedProcess:
        out = tmp_path / "shares.json"
        return subprocess.run(
            [sys.executable, "bench/real_tiers.py", "--shares-from",
             "bench/results/real_tiers.json", "--leave-out", left_out, "--out", str(out)],
            cwd=root, capture_output=True, text=True, timeout=300,
        )  # fmt: skip

    assert shares("").returncode == 0
    found = json.loads((tmp_path / "shares.json").read_text())["methods"]["DR-KFS"]
    for side in ("training", "held_out"):
        assert found[side] == committed["methods"]["DR-KFS"][side]
    assert shares("cheburashka/noise").returncode == 0
    without = json.loads((tmp_path / "shares.json").read_text())["methods"]["DR-KFS"]
    structural = sum(
        kind == "structural" and key.startswith("real-cheburashka/")
        for key, kind in committed["labels"].items()
    )
    assert without["pairs"]["surface_vs_structural"] == (
        found["pairs"]["surface_vs_structural"] - structural
    )
    wrong = shares("cheburashka/no-such-variant")
    assert wrong.returncode != 0 and "cheburashka/no-such-variant" in wrong.stderr


def test_meshes_from_outside_the_repository_form_a_third_side_with_their_own_labels(tmp_path):
    from drkfs_lab.benchmark.real_tiers import parse_relabels
    from drkfs_lab.benchmark.run import real_sides

    other = tmp_path / "other"
    other.mkdir()
    (other / "gingerbread.obj").write_bytes(sets.real_mesh("woody").read_bytes())
    relabelled = parse_relabels("gingerbread/smoothed=invisible")
    assert relabelled == {("gingerbread", "smoothed"): "invisible"}
    bench = sets.BenchSet()
    sets.real_tiers(bench, ["cow", "homer"])
    assert sets.other_tiers(bench, other, relabelled) == ["gingerbread"]
    kinds = {c.label: c.kind for c in bench.comparisons if c.base == "real-gingerbread"}
    assert kinds["smoothed"] == "invisible" and kinds["noise"] == "surface"
    # the repository's meshes keep the recipe's labels: a relabel names its mesh
    assert {c.label: c.kind for c in bench.comparisons if c.base == "real-cow"}["smoothed"] == (
        "surface"
    )
    bases = sorted({c.base for c in bench.comparisons})
    assert real_sides(bases) == {
        "training": ["real-cow"], "held_out": ["real-homer"], "other": ["real-gingerbread"],
    }  # fmt: skip
    assert real_sides(["real-cow", "real-homer"]) == {
        "training": ["real-cow"], "held_out": ["real-homer"],
    }  # no third side unless one is scored  # fmt: skip
    # the third side's scores count on it alone: its surface variants misordered, no other's
    values = {i: float(c.kind != "invisible") * (0.5 if c.base == "real-gingerbread" else 1)
              for i, c in enumerate(bench.comparisons)}  # fmt: skip
    values |= {i: 0.0 for i, c in enumerate(bench.comparisons)
               if c.base == "real-gingerbread" and c.kind == "surface"}  # fmt: skip
    shares = lever_summary(bench, values)["real"]
    assert shares["other"]["invisible_vs_surface"] == 0.0
    assert shares["training"]["invisible_vs_surface"] == 1.0
    assert shares["held_out"]["invisible_vs_surface"] == 1.0
    assert set(real_checks(bench, values)) == {"training", "held_out", "other"}


def test_a_third_side_refuses_a_repository_meshs_name_and_a_malformed_relabel(tmp_path):
    from drkfs_lab.benchmark.real_tiers import parse_relabels

    (tmp_path / "cow.obj").write_bytes(sets.real_mesh("cow").read_bytes())
    with pytest.raises(ValueError, match="cow named as the repository's meshes"):
        sets.other_tiers(sets.BenchSet(), tmp_path, {})
    with pytest.raises(ValueError, match="no .obj meshes"):
        sets.other_tiers(sets.BenchSet(), tmp_path / "nothing", {})
    for bad in ("cow/noise", "cow=invisible", "cow/noise=hidden", "cow/noise/x=surface"):
        with pytest.raises(ValueError, match="a relabel is mesh/variant=tier"):
            parse_relabels(bad)
    with pytest.raises(ValueError, match="relabelled twice"):
        parse_relabels("cow/noise=surface,cow/noise=invisible")
    (tmp_path / "cow.obj").rename(tmp_path / "cattle.obj")
    with pytest.raises(ValueError, match="no such variant to relabel: cattle/smoothd"):
        sets.other_tiers(sets.BenchSet(), tmp_path, parse_relabels("cattle/smoothd=invisible"))


def test_the_third_sides_meshes_are_written_welded_from_a_clone(tmp_path):
    import subprocess
    import sys
    import zipfile

    import trimesh

    root = ROOT
    data = tmp_path / "clone" / "data"
    data.mkdir(parents=True)
    cow = load_mesh(sets.real_mesh("cow"))
    # texture seams everywhere: every face its own three vertices, each its own texture point
    corners = np.arange(3 * len(cow.faces)).reshape(-1, 3)
    uv = np.random.default_rng(0).random((corners.size, 2))
    split = trimesh.Trimesh(cow.vertices[cow.faces].reshape(-1, 3), corners, process=False,
                            visual=trimesh.visual.TextureVisuals(uv=uv))  # fmt: skip
    for name in ("nefertiti", "ogre", "spot", "suzanne", "teapot"):
        split.export(data / f"{name}.obj")
    with zipfile.ZipFile(data / "horse.zip", "w") as archive:
        archive.writestr("horse.ply", trimesh.exchange.ply.export_ply(split))
    out = tmp_path / "meshes"
    done = subprocess.run(
        [sys.executable, "bench/other_meshes.py", "--clone", str(tmp_path / "clone"),
         "--out", str(out)], cwd=root, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    for name in ("horse", "nefertiti", "ogre", "spot", "suzanne", "teapot"):
        welded = load_mesh(out / f"{name}.obj")
        assert len(welded.vertices) == len(cow.vertices) and len(welded.faces) == len(cow.faces)
    (data / "spot.obj").unlink()
    done = subprocess.run(
        [sys.executable, "bench/other_meshes.py", "--clone", str(tmp_path / "clone"),
         "--out", str(out)], cwd=root, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode != 0 and "not in this clone: data/spot.obj" in done.stderr
