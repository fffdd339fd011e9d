"""bench/records/fitting.md's tables, printed from the committed results of the fitting and network
studies (bench/fit, bench/fit-network), in the order the record holds them."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from drkfs_lab.judging.judges import HIGHER_IS_BETTER, METRICS, SURFACE, VISUAL
from drkfs_lab.judging.rule import brief_share
from drkfs_lab.record_tables import Table, bold, committed, grid
from drkfs_lab.studies.losses import (
    CHAMFER,
    FADED_CONTROL,
    PIXEL,
    SHIPPED,
    pixel_with_chamfer,
    with_both,
    with_chamfer,
    with_pixel,
)
from drkfs_lab.studies.network import FULL as NETWORK
from drkfs_lab.studies.study import landscape_summary

FIT = "bench/fit/results.json"
NETWORK_STUDY = "bench/fit-network/results.json"
# the commit whose network study had the soft form as its only form: the one run that trained
# seed 0's soft form + 3 x Chamfer (its Chamfer and pixel MSE networks and its validation rows
# are the committed study's)
SOFT_FORM_RUN = "0ffd7fe"
# the network study's two forms, as the record names them
FORM_NAMES = {"soft match, window r1, coarse to fine": "soft form", SHIPPED: "plain form"}
DIGITS = {
    "F-score 1%": 3,
    "normal consistency": 3,
    "Chamfer-L1": 4,
    "volumetric IoU": 3,
    "DR-KFS": 0,
    "pixel MSE": 4,
    "PoI-map MSE": 4,
    "silhouette IoU": 3,
    "LFD": 0,
}
# the loss study's judges, one column each, a figure per problem
TUNING_METRICS = ("F-score 1%", "normal consistency", "Chamfer-L1", "silhouette IoU", "LFD")
# the network studies' tables of means: these metrics' columns, the visual cells' last
NETWORK_METRICS = (*SURFACE, "volumetric IoU", "silhouette IoU", "DR-KFS", "LFD")


def _figure(metric: str, value: float, grouped: bool = False) -> str:
    """``value`` of ``metric`` at the record's digits, thousands grouped where asked."""
    return f"{value:{',' if grouped else ''}.{DIGITS[metric]}f}"


def _named(loss: str, form: str, short: str, times: str) -> str:
    """A loss's name with ``form`` written ``short`` and its weights' 'x' written ``times``."""
    return loss.replace(form, short).replace(" x ", times)


def _per_problem(rows: dict, metric: str) -> str:
    """``metric`` of each problem's row (problem -> judged row), 'sofa / cheburashka'."""
    return " / ".join(_figure(metric, row[metric]) for row in rows.values())


def _won(share: dict | None) -> str:
    """A share's wins, or '–' where there is no pair."""
    return "–" if share is None else str(share["wins"])


def _won_of(against_chamfer: dict | None, against_pixel: dict | None) -> str:
    """Visual cells won against Chamfer / pixel MSE, 'of N' after the last count."""
    cells = (against_chamfer or against_pixel)["cells"]
    if against_pixel is None:
        return f"{_won(against_chamfer)} of {cells} / –"
    return f"{_won(against_chamfer)} / {_won(against_pixel)} of {cells}"


def _header(metrics: Sequence[str]) -> list[str]:
    """The columns' headings of ``metrics``: DR-KFS is the judge at the paper preset."""
    return ["DR-KFS (paper)" if m == "DR-KFS" else m for m in metrics]


def _means(means: dict, metrics: Sequence[str]) -> list[str]:
    """A loss's means of ``metrics``, DR-KFS and LFD grouped by thousands."""
    return [_figure(m, means[m], grouped=m in ("DR-KFS", "LFD")) for m in metrics]


def _chosen(study: dict) -> str:
    """The loss a network study's validation chose: its DR-KFS form + w x Chamfer."""
    validation = study["validation"]
    return with_chamfer(validation["form"], validation["chamfer_weight"]).name


def _network_row(study: dict, loss: str) -> list[str]:
    """A network's test means and visual cells won against Chamfer / pixel MSE."""
    won = _won_of(study["beats_chamfer"].get(loss), study["beats_pixel_mse"].get(loss))
    return [*_means(study["means"][loss], NETWORK_METRICS), won]


def loss_study_forms(root: Path) -> str:
    """The loss study's forms on the sofa and the cheburashka: judges, mean rank, gradient
    error and monotone descent (as fitted / last stage); the study's choice in bold."""
    study = committed(root, FIT)["loss_study"]
    ranks = study["forms"]["mean_rank"]
    rows = []
    for form in ranks:
        found = study["rows"][form]
        probes = [
            found["landscape"][kind]
            for kind in ("as_fitted", "last_stage")
            if kind in found["landscape"]
        ]
        row = [
            form,
            *(_per_problem(found["problems"], m) for m in TUNING_METRICS if m != "Chamfer-L1"),
            f"{ranks[form]:.2f}",
            " / ".join(f"{p['median_relative_error']:.0%}" for p in probes),
            " / ".join(f"{p['monotone_share']:.0%}" for p in probes),
        ]
        rows.append(bold(row) if form == study["forms"]["chosen"] else row)
    header = [
        "form",
        "F-score (sofa / cheburashka)",
        "normal consistency",
        "silhouette IoU",
        "LFD",
        "mean rank",
        "gradient error, as fitted / last stage",
        "monotone descent",
    ]
    return grid(header, rows, right=7)


def loss_study_weights(root: Path) -> str:
    """The shipped form alone, beside pixel MSE and beside Chamfer at each weight (sofa /
    cheburashka) with each pair's mean rank; the chosen weights' names in bold."""
    study = committed(root, FIT)["loss_study"]
    form = study["form"]
    chosen = {
        with_pixel(form, study["pixel_weight"]["chosen"]).name,
        with_chamfer(form, study["chamfer_weight"]["chosen"]).name,
    }
    ranks = {**study["pixel_weight"]["mean_rank"], **study["chamfer_weight"]["mean_rank"]}
    rows = []
    for loss in (form, *ranks):
        name = _named(loss, form, "the DR-KFS loss", " × ")
        judged = study["rows"][loss]["problems"]
        rows.append(
            [
                bold([name])[0] if loss in chosen else name,
                *(_per_problem(judged, m) for m in TUNING_METRICS),
                f"{ranks[loss]:.2f}" if loss in ranks else "–",
            ]
        )
    header = [
        "loss",
        "F-score",
        "normal consistency",
        "Chamfer-L1",
        "silhouette IoU",
        "LFD",
        "mean rank",
    ]
    return grid(header, rows, right=6)


def loss_nets_fits(root: Path) -> str:
    """The shipped form fitted with the shipped and the fine-tuned nets (sofa / cheburashka):
    judges, gradient error as fitted, monotone descent and mean rank."""
    fits = committed(root, "bench/fit/loss_nets.json")["fits"]
    rows = []
    for nets, judged in fits["rows"].items():
        landscape = {problem: row["landscape"] for problem, row in judged.items()}
        errors = [probe["as_fitted"]["median_relative_error"] for probe in landscape.values()]
        monotone = landscape_summary(landscape)["as_fitted"]["monotone_share"]
        rows.append(
            [
                nets.removesuffix(" nets"),  # the column is "nets"
                *(_per_problem(judged, m) for m in TUNING_METRICS),
                " / ".join(f"{error:.1%}" for error in errors),
                f"{monotone:.0%}",
                f"{fits['mean_rank'][nets]:.1f}",
            ]
        )
    header = [
        "nets",
        "F-score (sofa / cheburashka)",
        "normal consistency",
        "Chamfer-L1",
        "silhouette IoU",
        "LFD",
        "gradient error",
        "monotone descent",
        "mean rank",
    ]
    return grid(header, rows, right=8)


def fitting_study_means(root: Path) -> str:
    """The fitting study's means over its six problems per loss, mean rank, seconds a step and
    visual cells won against Chamfer / pixel MSE; the best DR-KFS loss's name in bold."""
    results = committed(root, FIT)
    form = results["loss_study"]["form"]
    control = pixel_with_chamfer(results["loss_study"]["chamfer_weight"]["chosen"]).name
    rows = []
    for loss in results["losses"]:
        name = _named(loss, form, "DR-KFS loss", "·")
        name += " (the control)" if loss == control else ""
        chamfer = results["beats_chamfer"].get(loss)
        pixel = results["beats_pixel_mse"].get(loss)
        rows.append(
            [
                bold([name])[0] if loss == results["summary"]["best_drkfs_loss"] else name,
                *_means(results["means"][loss], METRICS),
                f"{results['mean_rank'][loss]:.2f}",
                f"{results['seconds_per_step']['losses'][loss]:.2f}",
                f"{_won(chamfer)} / {_won(pixel)}",
            ]
        )
    header = [
        "loss",
        "F-score 1%",
        "normal cons.",
        "Chamfer-L1",
        "vol. IoU",
        "DR-KFS (paper)",
        "pixel MSE",
        "PoI-map MSE",
        "silhouette IoU",
        "LFD",
        "mean rank",
        "s a step",
        "visual cells won against Chamfer / pixel MSE",
    ]
    return grid(header, rows, right=12)


def _idea_won(shares: dict | None, label: str) -> str:
    """Visual (surface) cells won against the rival ``label`` in an idea's ``shares``, or '–'
    where there is no such pair."""
    if shares is None or label not in shares:
        return "–"
    return f"{shares[label]['visual']['wins']} ({shares[label]['surface']['wins']})"


def _idea_cell(shares: dict, here: dict | None, label: str, refitted: bool) -> str:
    """An idea's cells won against the rival ``label``: against the committed rival / the
    rival fitted again where it was (``refitted``), '–' where there is no pair."""
    if label not in shares:
        return "–"
    return (
        f"{_idea_won(shares, label)} / {_idea_won(here, label)}"
        if refitted
        else _idea_won(shares, label)
    )


def _idea_name(idea: str, shipped: str) -> str:
    """An idea's row name: the study's own three terms and the faded control named as such."""
    if idea == shipped:
        return "coarse to fine, the shipped form (the study's row)"
    return f"{idea} (no DR-KFS)" if idea == FADED_CONTROL else idea


def every_ideas_best_form(root: Path) -> str:
    """Each idea in all three terms: visual (surface) cells won against each rival, committed /
    refitted, and its mean rank among the committed rows; the faded control in italics."""
    results = committed(root, "bench/fit/ideas.json")
    choice = committed(root, FIT)["loss_study"]
    weights = results["weights"]
    shipped = with_both(choice["form"], weights[PIXEL], weights[CHAMFER]).name
    labels = ("pixel MSE", "the control", "the shipped form's three terms", FADED_CONTROL)
    rows = []
    for idea in (shipped, *results["ideas"]):
        shares, here = results["shares"][idea], results["shares_here"].get(idea)
        # an idea's rows are not fitted again: only the rivals that are no idea were
        cells = [_idea_cell(shares, here, label, label not in results["ideas"]) for label in labels]
        row = [_idea_name(idea, shipped), *cells, f"{results['mean_rank'][idea]:.2f}"]
        rows.append([f"*{cell}*" for cell in row] if idea == FADED_CONTROL else row)
    header = [
        "idea, in all three terms",
        *(f"against {label}" for label in labels),
        f"mean rank of {len(results['mean_rank'])} (committed rivals)",
    ]
    return grid(header, rows, right=5)


def network_study(root: Path) -> str:
    """The network study's test means per loss and visual cells won against Chamfer / pixel
    MSE; validation's choice in bold."""
    study = committed(root, NETWORK_STUDY)
    form = study["validation"]["form"]
    rows = []
    for loss in study["plan"]["losses"]:
        row = [_named(loss, form, "DR-KFS loss", " × "), *_network_row(study, loss)]
        rows.append(bold(row) if loss == _chosen(study) else row)
    header = [
        "trained with",
        *_header(NETWORK_METRICS),
        "visual cells won against Chamfer / pixel MSE",
    ]
    return grid(header, rows, right=8)


def _candidate_files(root: Path) -> dict[tuple[str, str], dict]:
    """The committed candidates trained beside a study, by (the study's file, candidate)."""
    found = {}
    for path in sorted((root / "bench/fit-network/candidates").glob("*.json")):
        candidate = json.loads(path.read_text())
        found[candidate["study"], candidate["candidate"]] = candidate
    return found


def _on_test(
    root: Path, path: str, study: dict, name: str, beside: dict[tuple[str, str], dict]
) -> tuple[dict, dict, float]:
    """Candidate ``name``'s test cells won against Chamfer and pixel MSE and its Chamfer-L1
    over Chamfer's, for the network study at ``path``: from the study, else from the candidate
    trained beside it (``beside``, ``_candidate_files``), else (seed 0's soft form + 3 x
    Chamfer) from the soft form's run."""
    if "candidates_on_test" in study:
        found = study["candidates_on_test"]["shares"][name]
        return found["beats_chamfer"], found["beats_pixel_mse"], found["chamfer_l1_ratio"]
    trained = beside.get((path, name))
    if trained is not None:
        ratio = trained["chamfer_l1_over_chamfer_trained"]
        return trained["beats_chamfer"], trained["beats_pixel_mse"], ratio
    if name not in study["plan"]["losses"]:
        study = committed(root, NETWORK_STUDY, SOFT_FORM_RUN)
    return (
        study["beats_chamfer"][name],
        study["beats_pixel_mse"][name],
        study["chamfer_l1_over_chamfer_trained"][name],
    )


def _seed_cells(root: Path, path: str) -> dict[str, tuple[str, dict, dict]]:
    """Each candidate of the network study at ``path`` -> its 'validation / test against
    Chamfer / test against pixel MSE / Chamfer-L1 ratio' cell (in bold for validation's
    choice) and its two test shares."""
    study, beside = committed(root, path), _candidate_files(root)
    chosen = _chosen(study)
    cells = {}
    for candidate in NETWORK.candidates():
        name = candidate.name
        won = brief_share(study["validation"]["table"], name, CHAMFER, VISUAL)["wins"]
        chamfer, pixel, ratio = _on_test(root, path, study, name, beside)
        cell = f"{won} / {chamfer['wins']} / {pixel['wins']} / {ratio:.2f}×"
        cells[name] = (bold([cell])[0] if name == chosen else cell, chamfer, pixel)
    return cells


def _candidate_name(candidate: str, shipped: str) -> str:
    """A candidate as the seeds' tables name it: its form's short name, 'x' as '×', and the
    ``shipped`` loss (the committed study's choice, ``DrkfsLoss.pretrained()``) marked so."""
    marked = " (shipped)" if candidate == shipped else ""
    for form, short in FORM_NAMES.items():
        candidate = candidate.replace(form, short)
    return candidate.replace(" x ", " × ") + marked


def six_seeds(root: Path) -> str:
    """Per candidate and seed the validation and test cells won and the Chamfer-L1 ratio
    (validation's choice in bold), and its test cells pooled over the seeds."""
    paths = [NETWORK_STUDY, *(f"bench/fit-network/seed{n}.json" for n in range(1, 6))]
    seeds = [_seed_cells(root, path) for path in paths]
    shipped = _chosen(committed(root, NETWORK_STUDY))
    rows = []
    for candidate in NETWORK.candidates():
        found = [seed[candidate.name] for seed in seeds]
        against_chamfer = sum(chamfer["wins"] for _, chamfer, _ in found)
        against_pixel = sum(pixel["wins"] for _, _, pixel in found)
        pooled = f"{against_chamfer} / {against_pixel}"
        if not rows:  # the first row says what the counts are of
            pooled += f" of {sum(chamfer['cells'] for _, chamfer, _ in found)}"
        cells = [cell for cell, _, _ in found]
        rows.append([_candidate_name(candidate.name, shipped), *cells, pooled])
    header = [
        "DR-KFS form + w × Chamfer",
        *(f"seed {committed(root, path)['plan']['seed']}" for path in paths),
        "test, six seeds: Chamfer / pixel MSE",
    ]
    return grid(header, rows, right=1)


def seed_zero_again(root: Path) -> str:
    """Seed 0's cells as in ``six_seeds``, committed and run again on the batched loss."""
    first = _seed_cells(root, NETWORK_STUDY)
    again = _seed_cells(root, "bench/fit-network/seed0-rerun.json")
    shipped = _chosen(committed(root, NETWORK_STUDY))
    rows = [
        [_candidate_name(c.name, shipped), first[c.name][0], again[c.name][0]]
        for c in NETWORK.candidates()
    ]
    return grid(["DR-KFS form + w × Chamfer", "seed 0, committed", "seed 0, again"], rows)


def soft_form_trained(root: Path) -> str:
    """The network study's run with the soft form as its only form (commit 0ffd7fe): the test
    means of the losses holding it, and their visual cells won against Chamfer / pixel MSE."""
    study = committed(root, NETWORK_STUDY, SOFT_FORM_RUN)
    form = study["plan"]["form"]
    rows = [
        [_named(loss, form, "soft form", " × "), *_network_row(study, loss)]
        for loss in study["plan"]["losses"]
        if form in loss
    ]
    header = [
        "trained with",
        *_header(NETWORK_METRICS),
        "visual cells won against Chamfer / pixel MSE",
    ]
    return grid(header, rows, right=8)


def _best(values: dict[str, float], higher: bool) -> str:
    """The key of the best of ``values``."""
    return (max if higher else min)(values, key=values.get)


def three_terms_trained(root: Path) -> str:
    """The network study's losses with all three terms and the control: test means and mean
    rank of the seven, the best of each column in bold, and validation's choice's name."""
    results = committed(root, "bench/fit-network/combinations.json")
    study = committed(root, NETWORK_STUDY)
    form = study["validation"]["form"]
    control = pixel_with_chamfer(study["validation"]["chamfer_weight"]).name
    metrics = [m for m in NETWORK_METRICS if m != "DR-KFS"]
    columns = {m: {loss: results["means"][loss][m] for loss in results["losses"]} for m in metrics}
    best = {m: _best(found, m in HIGHER_IS_BETTER) for m, found in columns.items()}
    best_rank = _best(results["mean_rank"], higher=False)
    rows = []
    for loss in results["losses"]:
        name = _named(loss, form, "DR-KFS loss", " × ")
        name += " (the control)" if loss == control else ""
        means = _means(results["means"][loss], metrics)
        rank = f"{results['mean_rank'][loss]:.2f}"
        rows.append(
            [
                f"**{name}**" if loss == _chosen(study) else name,
                *(
                    f"**{c}**" if best[m] == loss else c
                    for m, c in zip(metrics, means, strict=True)
                ),
                f"**{rank}**" if loss == best_rank else rank,
            ]
        )
    header = ["trained with", *_header(metrics), f"mean rank of {len(results['losses'])}"]
    return grid(header, rows, right=7)


TABLES: list[Table] = [
    loss_study_forms,
    loss_study_weights,
    loss_nets_fits,
    fitting_study_means,
    every_ideas_best_form,
    network_study,
    six_seeds,
    seed_zero_again,
    soft_form_trained,
    three_terms_trained,
]
