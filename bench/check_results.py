"""The committed results say what the docs quote: each check recomputes a committed number from
the committed rows it came from, or holds the code's choices to the study that made them.

    python bench/check_results.py [--root DIR]

Prints one line a check ("ok", or "FAILED" with the reason) and exits 1 when any failed. These
checks read only committed files (bench/fit, bench/fit-network, bench/single_view,
bench/results, bench/earlier, models/manifest.json, the README, docs/, bench/records/); the
tests run the script (tests/lab/test_check_results.py).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Callable
from pathlib import Path

from drkfs_lab.bench_tables import (
    BATCH_RUNS,
    README_BATCH,
    as_they_come_table,
    batch_table,
    ceiling_table,
    nets_tables,
    readme_table,
    results_table,
    stability_table,
    targets_table,
    test_set_table,
)
from drkfs_lab.benchmark import test_set
from drkfs_lab.benchmark.sets import BenchSet, Comparison
from drkfs_lab.judging.judges import VISUAL
from drkfs_lab.judging.rule import brief_share, chamfer_ratios, share
from drkfs_lab.record_tables import differences, records
from drkfs_lab.score_scale import markdown, scale
from drkfs_lab.studies.finetune import protocol_of, summarise_finetune
from drkfs_lab.studies.losses import CHAMFER, FORMS, PIXEL, SHIPPED, with_chamfer
from drkfs_lab.studies.network import FULL, choose_loss
from drkfs_lab.studies.single_view import (
    DRKFS_SHADED,
    RECIPE,
    RECIPE_IOU,
    SOFTRAS,
    Shape,
    every_pair,
    means,
    summarise,
    summarise_controls,
    validation_choice,
)
from drkfs_lab.studies.speed import summarise_speed
from drkfs_lab.test_set import summary as test_set_summary
from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract.versions import LATEST, VERSIONS, metric_name

ROOT = Path(__file__).resolve().parents[1]


def _json(root: Path, path: str) -> dict:
    return json.loads((root / path).read_text())


def _brief(found: dict) -> dict:
    return {k: found[k] for k in ("wins", "cells", "share")}


def fitting_study_fitted_the_shipped_form(root: Path) -> str | None:
    results = _json(root, "bench/fit/results.json")
    assert results["loss_study"]["form"] == results["summary"]["drkfs_loss_alone"] == SHIPPED
    pinned = re.search(r"torch==([\d.]+)", (root / ".ci" / "run").read_text()).group(1)
    if results["torch"] != f"{pinned}+cpu":  # a note, not a failure: the fits stand as run
        return f"its fits ran on torch {results['torch']}, CI pins {pinned}: a rerun may differ"
    return None


def ideas_recompute_from_their_rows(root: Path) -> None:
    """bench/fit/ideas.json: its study rows are the study's, and its ideas' shares against pixel
    MSE follow from its table, and from pixel MSE fitted again where it ran from ``here``."""
    study = _json(root, "bench/fit/results.json")
    results = _json(root, "bench/fit/ideas.json")
    assert results["torch"] == study["torch"]
    for problem, rows in results["table"].items():
        assert all(rows[name] == study["table"][problem][name] for name in study["losses"])
    ideas = results["ideas"]
    here = {
        p: {**rows, **{i: results["table"][p][i] for i in ideas}}
        for p, rows in results["here"].items()
    }
    for idea in ideas:
        for table, shares in ((results["table"], "shares"), (here, "shares_here")):
            found = results[shares][idea][PIXEL]["visual"]
            assert found == _brief(share(table, idea, PIXEL, VISUAL)), (idea, shares)
    # what the fade's DR-KFS term adds: the fade against the same fade without it
    fade, control = "structure first, pixel MSE last", "the control, pixel MSE last"
    found = results["shares"][fade][control]["visual"]
    assert found == _brief(share(results["table"], fade, control, VISUAL))


def shipped_loss_is_the_network_studys_choice(root: Path) -> None:
    from drkfs_onnx.loss import DrkfsLoss

    chosen = _json(root, "bench/fit-network/results.json")["validation"]["form"]
    loss = DrkfsLoss.pretrained()
    assert chosen == SHIPPED and (loss.stages, loss.soft) == FORMS[SHIPPED]


def network_plan_chooses_between_the_loss_studys_two_best(root: Path) -> None:
    study = _json(root, "bench/fit/results.json")["loss_study"]
    ranks = study["forms"]["mean_rank"]
    assert FULL.forms[0] == study["forms"]["chosen"]
    assert set(FULL.forms) == set(sorted(ranks, key=ranks.get)[:2])
    assert FULL.pixel_weight == study["pixel_weight"]["chosen"]
    assert FULL.chamfer_weights[0] == study["chamfer_weight"]["chosen"]  # the others: validation


def candidates_stand_beside_their_studies(root: Path) -> None:
    """A committed candidate's Chamfer network came out as its study's, its Chamfer and pixel
    MSE rows are the study's, and its shares and ratio recompute from its table."""
    for path in sorted((root / "bench/fit-network/candidates").glob("*.json")):
        results = json.loads(path.read_text())
        study = _json(root, results["study"])
        name = results["candidate"]
        assert results["reproduced"]["exact"] and results["seed"] == study["plan"]["seed"]
        assert name in study["validation"]["shares"] and not results["chosen_by_validation"]
        assert set(results["table"]) == set(study["table"]), path.name
        for shape, rows in results["table"].items():
            for committed in (CHAMFER, PIXEL):
                assert rows[committed] == study["table"][shape][committed], (path.name, shape)
        assert results["beats_chamfer"] == share(results["table"], name, CHAMFER, VISUAL)
        assert results["beats_pixel_mse"] == share(results["table"], name, PIXEL, VISUAL)
        ratio = chamfer_ratios(results["table"], [name])[name]
        assert results["chamfer_l1_over_chamfer_trained"] == ratio, path.name


def network_studies_shares_recompute(root: Path) -> None:
    """Per seed: the summary's loss is validation's choice (the rule drkfs choose-loss applies
    picks it again), and its shares, its Chamfer-L1 ratio and every passed-over candidate's
    shares (where the run kept them) recompute from the committed tables."""
    folder = root / "bench/fit-network"
    for path in [folder / "results.json", *sorted(folder.glob("seed*.json"))]:
        results = json.loads(path.read_text())
        table, done, choice = results["table"], results["summary"], results["validation"]
        best = with_chamfer(choice["form"], choice["chamfer_weight"]).name
        assert done["best_drkfs_loss"] == best, path.name
        again = choose_loss(FULL, choice["table"])
        assert (again["form"], again["chamfer_weight"]) == (
            choice["form"],
            choice["chamfer_weight"],
        ), path.name
        assert done["share_beats_chamfer"] == share(table, best, CHAMFER, VISUAL)["share"]
        assert done["share_beats_pixel_mse"] == share(table, best, PIXEL, VISUAL)["share"]
        assert done["chamfer_l1_ratio"] == chamfer_ratios(table, [best])[best], path.name
        if "candidates_on_test" in results:  # runs before it judged only validation's choice
            others = results["candidates_on_test"]
            merged = {shape: {**rows, **others["table"][shape]} for shape, rows in table.items()}
            assert set(others["shares"]) == set(choice["shares"]), path.name
            for name, got in others["shares"].items():
                for key, against in (("beats_chamfer", CHAMFER), ("beats_pixel_mse", PIXEL)):
                    assert got[key] == brief_share(merged, name, against, VISUAL), (path, name)


def single_view_study_recomputes(root: Path) -> None:
    """The single-view study's means, shares and goal recompute from its per-seed tables, and
    its combination is validation's choice."""
    results = _json(root, "bench/single_view/results.json")
    tables = {int(seed.split()[1]): table for seed, table in results["tables"].items()}
    # summarise reads the test shapes' names and families ("chair 5500"): the tables' own
    test_set = [Shape(n, n.split()[0], None, None) for n in next(iter(tables.values()))]
    again = summarise(tables, test_set, results["plan"]["losses"])
    for key in ("means", "shares", "goal"):
        assert again[key] == results[key], f"results.json's {key} do not recompute"
    validation = results["validation"]
    if validation.get("table"):
        assert validation_choice(validation["table"])["chosen"] == validation["chosen"]


def _test_set(table: dict) -> list[Shape]:
    """The test shapes of a table keyed by their names ("chair 5500")."""
    return [Shape(n, n.split()[0], None, None) for n in table]


def single_view_controls_recompute(root: Path) -> None:
    """The matched controls' means, shares and goal recompute from their per-seed tables."""
    results = _json(root, "bench/single_view/controls.json")
    tables = {int(seed.split()[1]): table for seed, table in results["tables"].items()}
    again = summarise_controls(tables, _test_set(next(iter(tables.values()))))
    for key in ("means", "shares", "goal"):
        assert again[key] == results[key], f"controls.json's {key} do not recompute"


def single_view_other_test_seeds_recompute(root: Path) -> None:
    """The saved networks judged on other test shapes: the study's losses' and (where judged)
    the controls' means, shares and goals recompute from their per-seed tables."""
    results = _json(root, "bench/single_view/test-seeds-6000.json")

    def by_seed(part: dict) -> dict[int, dict]:
        return {int(seed.split()[1]): table for seed, table in part["tables"].items()}

    study = by_seed(results)
    first = next(iter(study.values()))  # shape -> loss -> judge
    shapes, losses = _test_set(first), list(next(iter(first.values())))
    recomputed = [(results, summarise(study, shapes, losses))]
    if (root / "bench/single_view/controls.json").exists():  # then they are judged too
        assert "controls" in results, "test-seeds-6000.json lacks the controls' networks"
        recomputed.append(
            (results["controls"], summarise_controls(by_seed(results["controls"]), shapes))
        )
    for part, again in recomputed:
        for key in ("means", "shares", "goal"):
            assert again[key] == part[key], f"test-seeds-6000.json's {key} do not recompute"


def single_view_finetuning_recomputes(root: Path) -> None:
    """The fine-tuning protocol's means and shares recompute from its per-seed tables, in
    each of its runs (finetune*.json) by the protocol that run names."""
    for path in sorted((root / "bench/single_view").glob("finetune*.json")):
        results = _json(root, str(path.relative_to(root)))
        tables = {int(seed.split()[1]): table for seed, table in results["tables"].items()}
        test_set = _test_set(next(iter(tables.values())))
        again = summarise_finetune(tables, test_set, protocol_of(results))
        for key in ("means", "shares"):
            assert again[key] == results[key], f"{path.name}'s {key} do not recompute"


def single_view_curve_recomputes(root: Path) -> None:
    """Each judged point of the learning curve's means recompute from its table."""
    results = _json(root, "bench/single_view/curve.json")
    for point, found in results["points"].items():
        again = means([found["table"]], _test_set(found["table"]), results["losses"])["mean"]
        assert again == found["means"], f"curve.json's means at {point} steps do not recompute"


def single_view_steps_runs_recompute(root: Path) -> None:
    """Each --steps run's means and shares recompute from its table, and those of its networks
    judged on other test shapes (longer-*-test-seeds-*.json) from their per-seed tables."""
    for path in sorted((root / "bench/single_view").glob("longer-*.json")):
        results = _json(root, str(path.relative_to(root)))
        tables = list(results["tables"].values()) if "tables" in results else [results["table"]]
        rows = list(results["means"]["mean"])
        again = every_pair(tables, _test_set(tables[0]), rows)
        for key in ("means", "shares"):
            assert again[key] == results[key], f"{path.name}'s {key} do not recompute"


def single_view_speed_recomputes(root: Path) -> None:
    """Each speed run's validation means and shares recompute from its per-seed tables."""
    for path in sorted((root / "bench/single_view").glob("speed*.json")):
        results = json.loads(path.read_text())
        tables = {int(seed.split()[1]): table for seed, table in results["tables"].items()}
        again = summarise_speed(tables, _test_set(next(iter(tables.values()))), results["losses"])
        for key in ("means", "shares"):
            assert again[key] == results[key], f"{path.name}'s {key} do not recompute"


def readme_score_scale_is_the_benchmarks(root: Path) -> None:
    """The README's table of what a score means is bench/score_scale.py's, from the committed
    benchmark."""
    table = markdown(scale(_json(root, "bench/results/results.json")))
    assert table in (root / "README.md").read_text(), "README's score scale table differs"


def benchmark_tables_are_the_benchmarks(root: Path) -> None:
    """The README's and docs/benchmark.md's tables of the methods are bench/bench_tables.py's,
    from the committed benchmark."""
    results = _json(root, "bench/results/results.json")
    assert readme_table(results) in (root / "README.md").read_text(), "README's table differs"
    doc = (root / "docs/benchmark.md").read_text()
    for table in (results_table, targets_table, ceiling_table, stability_table):
        assert table(results) in doc, f"docs/benchmark.md's {table.__name__} differs"
    section = _json(root, "bench/results/as_they_come.json")
    assert as_they_come_table(section) in doc, "docs/benchmark.md's meshes as they come differ"


def training_tables_are_the_manifests(root: Path) -> None:
    """docs/training.md's tables of the detectors and HardNet widths are
    bench/bench_tables.py's, from the shipped nets' manifest (models/manifest.json)."""
    tables = nets_tables(_json(root, "models/manifest.json"))
    assert tables in (root / "docs/training.md").read_text(), "docs/training.md's nets differ"


def _version_rows(run: dict) -> list[tuple[str, dict]]:
    """The rows of a committed run (a benchmark's methods, a lever run's levers) whose config
    is a named version, with their values by pair: (version, values)."""
    rows = run.get("methods") or run.get("levers") or {}
    found = []
    for name, row in rows.items():
        try:
            version = metric_name(PipelineConfig.from_dict(row["config"]))
        except (KeyError, ValueError):  # no config, or one with a setting since removed
            continue
        if version in VERSIONS:
            found.append((version, run["values"][name]))
    return found


def each_version_scores_as_its_committed_runs(root: Path) -> str:
    """Each named version's scores of bench/version_sample.py's sample are those of every
    committed run that scored that version: the benchmark's DR-KFS rows and the lever runs'
    rows whose config is a named version, on each pair of the sample the run scored (and every
    such run scored some)."""
    sample = _json(root, "bench/results/version_sample.json")["versions"]
    held = {}
    for path in sorted((root / "bench/results").glob("*.json")):
        for version, values in _version_rows(json.loads(path.read_text())):
            assert version in sample, f"{path.name} scores {version}, which the sample lacks"
            pairs = [key for key in sample[version] if key in values]
            assert pairs, f"{path.name} scores {version} on none of the sample's pairs"
            for key in pairs:
                assert math.isclose(sample[version][key], values[key], rel_tol=1e-6), (
                    f"{version} {key}: {sample[version][key]} vs {values[key]} in {path.name}"
                )
            held.setdefault(version, []).append(path.stem)
    assert "results" in held.get(LATEST, []), "the benchmark does not score the newest version"
    return "; ".join(f"{v} in {', '.join(runs)}" for v, runs in sorted(held.items()))


def test_set_is_scored_at_each_release(root: Path) -> str:
    """bench/results/test_set.json holds the newest version's release, scored on the frozen set
    (its digest), each method's shares recompute from its values, docs/benchmark.md holds the
    table and the README the newest version's synthetic shares."""
    results = _json(root, "bench/results/test_set.json")
    assert results["set"]["digest"] == test_set.DIGEST, "scored on another test set"
    assert LATEST in results["releases"], f"{LATEST} is not scored on the test set"
    labels = results["set"]["labels"]
    keys = list(labels)
    bench = BenchSet(comparisons=[
        Comparison(group, key.rsplit("/", 1)[0], key.rsplit("/", 1)[1], kind, key, "")
        for key, (group, kind) in labels.items()
    ])  # fmt: skip
    for release, entry in results["releases"].items():
        for method, row in entry["methods"].items():
            values = {i: entry["values"][method][key] for i, key in enumerate(keys)}
            committed = {name: value for name, value in row.items() if name != "seconds_per_pair"}
            assert test_set_summary(bench, values) == committed, f"{release} {method}"
    doc = (root / "docs/benchmark.md").read_text()
    assert test_set_table(results) in doc, "docs/benchmark.md's test set table differs"
    shares = results["releases"][LATEST]["methods"][LATEST][test_set.TIERS_GROUP]
    quoted = " / ".join(f"{shares[pair]:.3f}" for pair in (
        "invisible_vs_structural", "invisible_vs_surface", "surface_vs_structural"))  # fmt: skip
    readme = " ".join((root / "README.md").read_text().split())
    assert f"{quoted} on new synthetic shapes" in readme, "the README's test set figures differ"
    return f"releases {', '.join(results['releases'])}"


def readme_batch_table_is_torch_batchs(root: Path) -> None:
    """The README's table of the loss on a batch is bench/bench_tables.py's, and its TF32
    figure the GPU run's, from bench/torch_batch.py's committed runs."""
    runs = [_json(root, f"bench/results/{name}") for name in BATCH_RUNS]
    readme = (root / "README.md").read_text()
    assert batch_table(runs) in readme, "README's batch table differs"
    gpu_rows = next(run["rows"] for run in runs if run["machine"]["gpu"])
    gpu = next(row for row in gpu_rows if row["batch"] == README_BATCH)
    tf32 = f'(`conv_precision="tf32"`: {gpu["batched_tf32"]["seconds"] * 1e3:.0f} ms)'
    assert tf32 in readme, "README's TF32 figure differs"


def readme_as_a_loss_is_the_single_view_studys(root: Path) -> None:
    """The README's "As a loss" figures are the single-view study's committed runs': the learning
    curve's LFD at 2,000 and 3,000 steps, the recipe's cells against its silhouette-IoU control,
    and the fine-tuning protocol's cells in both its runs (finetune.json and its replicate
    beside the loss's nets, finetune-tuned-nets.json) and the replicate's networks on other test
    shapes (finetune-tuned-nets-test-seeds-6000.json)."""
    curve = _json(root, "bench/single_view/curve.json")["points"]
    controls = _json(root, "bench/single_view/controls.json")["shares"]["pooled"]
    runs = [
        _json(root, f"bench/single_view/{name}.json")["shares"]["pooled"]
        for name in ("finetune", "finetune-tuned-nets", "finetune-tuned-nets-test-seeds-6000")
    ]

    def lfd(point: str, name: str) -> str:
        return f"{curve[point]['means'][name]['LFD']:,.0f}"

    def arm(then: str) -> str:
        return f"{SOFTRAS}, then {then}"

    def wins(against: str, judge: str) -> list[int]:  # each run's cells
        found = [run[f"{arm(RECIPE_IOU)} | {arm(against)}"][judge] for run in runs]
        assert len({f["cells"] for f in found}) == 1, "the fine-tuning runs judge other cells"
        return [f["wins"] for f in found]

    cells = runs[0][f"{arm(RECIPE_IOU)} | {arm(SOFTRAS)}"]["LFD"]["cells"]

    against_iou = controls[RECIPE]["silhouette IoU + 3 x Chamfer-L2"]["LFD"]
    mse = "silhouette IoU + 1 x pixel MSE"
    sl, sc = wins(SOFTRAS, "LFD"), wins(SOFTRAS, "Chamfer-L1")
    ml, ms = wins(mse, "LFD"), wins(mse, "silhouette IoU")
    readme = (root / "README.md").read_text()
    for figure in (
        f"(LFD {lfd('2000', DRKFS_SHADED)} against {lfd('2000', SOFTRAS)})",
        f"({lfd('3000', DRKFS_SHADED)} against {lfd('3000', SOFTRAS)})",
        f"({against_iou['wins']} of {against_iou['cells']} test cells",
        f"on {sl[0]} and {sl[1]} of {cells} cells by LFD in two runs on two CPUs ({sl[2]} on "
        f"other test shapes), {sc[0]} and {sc[1]} by Chamfer-L1 ({sc[2]}), and IoU + 1 × pixel "
        f"MSE on {ml[0]} and {ml[1]} by LFD ({ml[2]}), by unseen silhouettes on only "
        f"{', '.join(map(str, ms))}.",
    ):
        assert figure in readme.replace("\n", " "), f"README's 'As a loss' differs at {figure!r}"


def architecture_numbers_are_the_configs(root: Path) -> None:
    """docs/architecture.md's equation and stage table give the newest version's settings
    (and the paper preset's and the loss's beside them) as ``PipelineConfig`` has them."""
    c, paper, loss = PipelineConfig(), PipelineConfig.paper(), PipelineConfig.loss()
    kept = 1 - c.turned_part_share
    figures = (
        # the equation
        f"the K = {c.num_views}\ncameras of two rings",
        f"turned {c.turn_degrees:g}° about the vertical",
        f"each view's {round(c.patches_per_view**0.5)} × {round(c.patches_per_view**0.5)} patches",
        f"m(P_ij) + {c.solid_weight:g} · S_ij",
        f"t = {c.temperature:g}",
        f"{kept:g} · P_00 + {c.turned_part_share:g} · P_11",
        f"m(P) = P − {1 - c.moderate_slope:g} · clip(P − {c.moderate_from:g}, 0, "
        f"{c.moderate_to - c.moderate_from:g})",
        f"slope of {c.moderate_slope:g} between {c.moderate_from:g} and {c.moderate_to:g}",
        f"{c.solid_block} × {c.solid_block} block",
        f"{paper.num_views} views of {paper.image_size} px",
        # the stage table
        f"| {c.num_views} (paper: {paper.num_views}; the nets' training and the loss: "
        f"{loss.num_views})",
        f"at distance {c.camera_distance:g}; {c.image_size} px (paper: {paper.image_size}; "
        f"training and loss: {loss.image_size})",
        f"{c.fov_degrees:g}° pinhole",
        f"(ambient {c.ambient:g}, diffuse {c.diffuse:g},",
        f"`back_push` {c.back_push:g}",
        f"N=M={c.detector_n}, {c.detector_kernel}×{c.detector_kernel}",
        f"{c.patch_size}×{c.patch_size} at stride {c.patch_stride} → {c.patches_per_view} per "
        f"view at {c.image_size} px",
        f"width multiplier {c.descriptor_width:g}",
        f"eps {c.patch_norm_eps:.0e}".replace("e-0", "e-"),
        f"at temperature {c.temperature:g}",
        f"{c.solid_weight:g} × the mean over the views",
        f"raised to the power {c.solid_inner_power:g}",
        f"takes {c.turned_part_share:g} of its descriptors' part",
    )
    flat = " ".join((root / "docs/architecture.md").read_text().split())
    for figure in figures:  # each ends where its number ends: 0.1 is not found in 0.15
        found = re.search(re.escape(" ".join(figure.split())) + r"(?!\d)", flat)
        assert found, f"docs/architecture.md differs at {figure!r}"


def records_hold_their_printed_tables(root: Path) -> None:
    """Every table of every record (bench/records/, its README aside) is the one printed from
    the JSON it reports (bench/record_tables/), in the record's order, none typed beside them."""
    found = [line for name in records(root) for line in differences(name, root)]
    assert not found, "; ".join(found)


def readme_versions_table_names_every_version(root: Path) -> str:
    """The README's table of metric versions names every version of
    drkfs_onnx/contract/versions.py once, and each row's constructor makes its version."""
    readme = (root / "README.md").read_text()
    block = readme[readme.index("| version | config |") :].split("\n\n", 1)[0]
    rows = [line.split(" | ") for line in block.splitlines()[2:]]
    versions_by_row = [re.findall(r"`(drkfs[^`]*)`", row[0]) for row in rows]
    named = [name for versions in versions_by_row for name in versions]
    assert sorted(named) == sorted(VERSIONS), (
        f"README's versions {named}, the code's {list(VERSIONS)}"
    )
    for row, versions in zip(rows, versions_by_row, strict=True):
        made = re.fullmatch(r"`PipelineConfig(\.\w+)?\(\)`", row[1].strip())
        if made and versions:
            config = getattr(PipelineConfig, made[1][1:])() if made[1] else PipelineConfig()
            assert metric_name(config) == versions[0], f"README: {row[1]} is not {versions[0]}"
    return f"{len(named)} versions"


CHECKS: list[Callable[[Path], str | None]] = [
    fitting_study_fitted_the_shipped_form,
    ideas_recompute_from_their_rows,
    shipped_loss_is_the_network_studys_choice,
    network_plan_chooses_between_the_loss_studys_two_best,
    candidates_stand_beside_their_studies,
    network_studies_shares_recompute,
    single_view_study_recomputes,
    single_view_controls_recompute,
    single_view_other_test_seeds_recompute,
    single_view_finetuning_recomputes,
    single_view_curve_recomputes,
    single_view_steps_runs_recompute,
    single_view_speed_recomputes,
    readme_score_scale_is_the_benchmarks,
    readme_batch_table_is_torch_batchs,
    readme_as_a_loss_is_the_single_view_studys,
    readme_versions_table_names_every_version,
    architecture_numbers_are_the_configs,
    benchmark_tables_are_the_benchmarks,
    training_tables_are_the_manifests,
    each_version_scores_as_its_committed_runs,
    test_set_is_scored_at_each_release,
    records_hold_their_printed_tables,
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=ROOT, help="the repository to check")
    args = parser.parse_args()
    failed = 0
    for check in CHECKS:
        name = check.__name__.replace("_", " ")
        try:
            note = check(args.root)
        except (AssertionError, KeyError, FileNotFoundError, ValueError) as exc:
            failed += 1
            print(f"FAILED {name}: {type(exc).__name__} {exc}")
            continue
        print(f"ok {name}" + (f" (note: {note})" if note else ""))
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
