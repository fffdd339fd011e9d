"""``python bench/fit.py --network``: the paper's setting. A network reconstructs procedural
shapes from a sample of their surface points; it is trained once per loss (Chamfer, pixel MSE,
the DR-KFS loss and its combinations) from the same initial weights on the same batches, and
judged on held-out seeds by metrics no loss computes.

Which DR-KFS form, and at which weight beside Chamfer, is the network's own choice: two fitted
meshes cannot say what a network trained on many shapes needs (with the loss study's first form,
DR-KFS + Chamfer beat the Chamfer network in 49 of 80 test cells; with its second, in 73;
bench/records/fitting.md). So the study trains DR-KFS + w x Chamfer for each of
``NetworkPlan.forms`` (the loss study's two best) and each of ``NetworkPlan.chamfer_weights``, keeps
the pair that beats the Chamfer network on the most visual cells of validation shapes (seeds of
their own, neither trained on nor tested), then trains the chosen form alone and beside pixel MSE,
before any test shape is judged. The candidates it passed over are judged on the test shapes too
(``candidates_on_test``): a report of how much the choice mattered, never an input to it.

The decoder deforms PRIMITIVES icospheres (AtlasNet's idea with closed patches, so the result is
watertight and has a volume): vertex = anchor_k + RADIUS * u + MLP(code, e_k, u) for each unit
sphere vertex u of primitive k, with a learned anchor and embedding e_k per primitive.
"""

from __future__ import annotations

import json
import shutil
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
import trimesh
from torch import nn

from drkfs_lab.benchmark.point_metrics import sample_surface
from drkfs_lab.judging.judges import HIGHER_IS_BETTER, SURFACE, UNSEEN_VIEWS, VISUAL, Judge
from drkfs_lab.judging.rule import brief_share, chamfer_ratios, choose, share
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.geometry import Smoothness
from drkfs_onnx.loss import StagedTarget
from drkfs_onnx.synthetic.shapes import assemble, random_shape

from .gallery import write_gallery
from .losses import CHAMFER, PIXEL, Recipe, Terms, alone, with_chamfer, with_pixel
from .mesh_fit import DrkfsTerm, deterministic_kernels, float_tensor
from .study import (
    column_title,
    machine,
    metric_means,
    resume_key,
    save_mesh,
    slug,
    summary,
)

# seeds of the shapes the network trains on, chooses its Chamfer weight on and is tested on:
# disjoint from the benchmark's (2026-2028), the held-out checks' (3000-3002) and the nets'
# training data (seeds 0-2)
TRAIN_SEED, VALIDATION_SEED, TEST_SEED = 4000, 4400, 4500
INPUT_POINTS = 512  # the network's input: surface points of the shape
PRIMITIVES = 8
SPHERE_LEVEL = 2  # 162 vertices, 320 faces per primitive: 2,560 faces in all
RADIUS = 0.25  # each primitive starts as a sphere of this radius at its anchor
ANCHOR = 0.35  # anchors start at the corners of a cube of this half size
JUDGED = (*SURFACE, "volumetric IoU", *VISUAL)


@dataclass(frozen=True)
class NetworkPlan:
    families: tuple[str, ...]
    train_per_family: int
    test_per_family: int
    steps: int
    batch: int
    learning_rate: float
    smoothness: float  # weight of the primitives' Laplacian smoothness beside losses starting at 1
    # the DR-KFS loss forms the validation shapes choose between: the loss study's two best
    # (bench/fit/results.json, "loss_study"), its choice first; the weight beside pixel MSE and
    # the first weight beside Chamfer are that study's choices, the others the validation's
    forms: tuple[str, ...]
    pixel_weight: float
    chamfer_weights: tuple[float, ...]
    validation_per_family: int
    judge_config: PipelineConfig  # the paper preset, as a judge
    lfd: bool = True  # judge with LFD where it is installed
    unseen_views: int = UNSEEN_VIEWS  # the silhouette judge's cameras
    seed: int = 0

    def fixed(self) -> list[Recipe]:
        """The losses without a DR-KFS form: trained before the validation shapes choose one."""
        return [alone(CHAMFER), alone(PIXEL)]

    def candidates(self) -> list[Recipe]:
        """DR-KFS + w x Chamfer for each form and weight, the loss study's choices first."""
        return [with_chamfer(form, w) for form in self.forms for w in self.chamfer_weights]

    def recipes(self, form: str, chamfer_weight: float) -> list[Recipe]:
        """The five losses judged on the test shapes, at the chosen form and Chamfer weight."""
        return [
            *self.fixed(),
            alone(form),
            with_pixel(form, self.pixel_weight),
            with_chamfer(form, chamfer_weight),
        ]


FULL = NetworkPlan(
    families=("chair", "table", "lamp", "airplane"),
    train_per_family=32,
    test_per_family=4,
    steps=2000,
    # one shape a step: a step of the DR-KFS losses costs ~0.5 s a shape on 2 cores, so batch 1
    # keeps the eight 2,000-step trainings and their judging near the 2 h
    batch=1,
    learning_rate=1e-3,
    smoothness=10.0,
    forms=("soft match, window r1, coarse to fine", "window r0 mean, coarse to fine"),
    pixel_weight=0.3,
    chamfer_weights=(1.0, 3.0),
    validation_per_family=4,
    judge_config=PipelineConfig.paper(),
)
QUICK_NETWORK = replace(
    FULL,
    families=("chair", "table"),
    train_per_family=2,
    test_per_family=1,
    validation_per_family=1,
    steps=2,
    judge_config=PipelineConfig.paper(num_views=2, image_size=64),
    lfd=False,
    unseen_views=2,
)


class Shape(NamedTuple):
    name: str
    verts: np.ndarray  # (V, 3) float64 in its normalised frame
    faces: np.ndarray  # (F, 3) int64
    points: torch.Tensor  # (INPUT_POINTS, 3) the network's input


def make_shape(family: str, seed: int) -> Shape:
    verts, faces = assemble(random_shape(family, seed))
    verts = place(verts, frame_of(verts))
    return Shape(
        f"{family} {seed}",
        verts,
        faces,
        float_tensor(sample_surface(verts, faces, INPUT_POINTS, seed).points),
    )


def shapes(plan: NetworkPlan, first_seed: int, per_family: int) -> list[Shape]:
    return [
        make_shape(family, first_seed + i) for family in plan.families for i in range(per_family)
    ]


def primitives() -> tuple[torch.Tensor, torch.Tensor]:
    """The unit icosphere's (Vs, 3) vertices and the (PRIMITIVES * Fs, 3) faces of PRIMITIVES
    copies of it, vertex block after vertex block."""
    sphere = trimesh.creation.icosphere(SPHERE_LEVEL)
    faces = torch.as_tensor(np.asarray(sphere.faces, dtype=np.int64))
    offsets = torch.arange(PRIMITIVES)[:, None, None] * len(sphere.vertices)
    return float_tensor(sphere.vertices), (faces[None] + offsets).reshape(-1, 3)


class Reconstructor(nn.Module):
    """Points -> the vertices of PRIMITIVES deformed icospheres.

    ``forward(points (B, N, 3)) -> (B, PRIMITIVES * Vs, 3)``; ``faces`` (PRIMITIVES * Fs, 3) is
    fixed. The encoder is a PointNet (shared MLP, max pool).
    """

    def __init__(self, code: int = 128, hidden: int = 128, embedding: int = 16):
        super().__init__()
        self.encoder = nn.Sequential(
            nn.Linear(3, 64), nn.ReLU(), nn.Linear(64, 128), nn.ReLU(), nn.Linear(128, code)
        )
        unit, faces = primitives()
        corners = torch.tensor([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        self.anchors = nn.Parameter(ANCHOR * corners[:PRIMITIVES].float())
        self.embedding = nn.Parameter(0.1 * torch.randn(PRIMITIVES, embedding))
        self.decoder = nn.Sequential(
            nn.Linear(code + embedding + 3, hidden),
            nn.ReLU(),
            nn.Linear(hidden, hidden),
            nn.ReLU(),
            nn.Linear(hidden, 3),
        )
        last = self.decoder[-1]
        nn.init.normal_(last.weight, std=1e-3)  # start from the spheres themselves
        nn.init.zeros_(last.bias)
        self.register_buffer("unit", unit, persistent=False)
        self.register_buffer("faces", faces, persistent=False)

    def spheres(self) -> torch.Tensor:
        """(PRIMITIVES * Vs, 3): the primitives before any deformation."""
        return (self.anchors[:, None] + RADIUS * self.unit).reshape(-1, 3)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        code = self.encoder(points).amax(dim=1)  # (B, code)
        b, k, v = len(code), PRIMITIVES, len(self.unit)
        inputs = torch.cat(
            [
                code[:, None, None].expand(b, k, v, -1),
                self.embedding[None, :, None].expand(b, k, v, -1),
                self.unit[None, None].expand(b, k, v, -1),
            ],
            dim=-1,
        )
        verts = self.anchors[None, :, None] + RADIUS * self.unit + self.decoder(inputs)
        return verts.reshape(b, k * v, 3)


def loss_step_case() -> tuple[torch.Tensor, torch.Tensor, tuple[torch.Tensor, torch.Tensor], str]:
    """The case a loss step is timed and checked on: a fresh network's prediction (8 spheres,
    2,560 faces, nudged off them as training soon moves it) and the first training chair ->
    (prediction (V, 3), its faces (F, 3), the chair's (verts, faces), the chair's name)."""
    torch.manual_seed(0)
    shape = make_shape("chair", TRAIN_SEED)
    model = Reconstructor()
    with torch.no_grad():
        prediction = model(shape.points[None])[0]
        prediction += 0.02 * torch.randn(prediction.shape)
    truth = float_tensor(shape.verts), torch.as_tensor(shape.faces)
    return prediction, model.faces, truth, shape.name


def targets(recipe: Recipe, train: list[Shape], faces: torch.Tensor, terms: Terms) -> list:
    """Each training shape's (weight, term) pairs of ``recipe``, its targets prepared once."""
    if recipe.fade is not None:  # the networks' loop weighs terms without fades
        raise ValueError(f"{recipe.name}: the network study does not fade terms")
    return [[(w, terms.term(t, s.verts, s.faces, faces)) for w, t in recipe.terms] for s in train]


def term_mean(terms: list, predicted: torch.Tensor, progress: float) -> torch.Tensor:
    """The mean over a batch of one term, each prediction (B, V, 3) against its own shape's:
    a DR-KFS term in one call of its loss for the whole batch, the others shape by shape."""
    if isinstance(terms[0], DrkfsTerm):
        target = StagedTarget.stack([term.target for term in terms])
        return terms[0].loss(predicted, terms[0].faces, target, progress)
    return torch.stack([term(verts) for term, verts in zip(terms, predicted, strict=True)]).mean()


@deterministic_kernels()
def train(plan: NetworkPlan, recipe: Recipe, points: torch.Tensor, shape_terms: list, progress):
    """One network trained with ``recipe`` on the training shapes' input ``points`` (S, N, 3)
    -> {"model", "history", "seconds_per_step"}. Every recipe starts from the same weights and
    sees the same batches (and the same Chamfer draws); each term is divided by its mean over
    the first batch, so one smoothness weight and one step size serve them all. It runs on
    deterministic kernels, so a rerun ends with the same weights however busy the machine."""
    torch.manual_seed(plan.seed)
    model = Reconstructor()
    smooth = Smoothness(model.spheres().detach(), model.faces)
    weights = torch.tensor([w for w, _ in recipe.terms])
    rng = np.random.default_rng(plan.seed)
    optimizer = torch.optim.Adam(model.parameters(), lr=plan.learning_rate)
    scales, history = None, []
    start = time.perf_counter()
    for step in range(plan.steps):
        batch = rng.choice(len(points), size=plan.batch, replace=False)
        predicted = model(points[batch])
        values = torch.stack(
            [
                term_mean([shape_terms[i][slot][1] for i in batch], predicted, step / plan.steps)
                for slot in range(len(recipe.terms))
            ]
        )  # (terms,)
        if scales is None:
            scales = values.detach().clamp_min(1e-12)
        objective = (weights * values / scales).sum()
        regulariser = torch.stack([smooth(v) for v in predicted]).mean()
        optimizer.zero_grad()
        (objective + plan.smoothness * regulariser).backward()
        optimizer.step()
        history.append(float(objective.detach()))
        if step % max(1, plan.steps // 10) == 0:
            progress(f"{recipe.name}: step {step} objective {history[-1]:.4f}")
    seconds = (time.perf_counter() - start) / max(plan.steps, 1)
    return {"model": model, "history": history, "seconds_per_step": seconds}


class Trainings:
    """Finished trainings kept as OUT/checkpoint/<loss>.pt with the ``resume_key`` (plan, torch
    build, threads) they were trained under, so a stopped study resumes where it stopped
    (``train`` seeds each training itself, so a resumed network equals the one a straight run
    trains); a finished study removes them."""

    def __init__(self, folder: Path, plan: NetworkPlan):
        self.folder, self.key = folder, resume_key(plan)

    def get(self, recipe: Recipe) -> dict | None:
        path = self.folder / f"{slug(recipe.name)}.pt"
        saved = torch.load(path, weights_only=True) if path.exists() else None
        if saved is None or saved.get("key") != self.key:
            return None
        model = Reconstructor()
        model.load_state_dict(saved["state"])
        return {"model": model, "history": saved["history"], "seconds_per_step": saved["seconds"]}

    def put(self, recipe: Recipe, result: dict) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        saved = {"key": self.key, "state": result["model"].state_dict(),
                 "history": result["history"], "seconds": result["seconds_per_step"]}  # fmt: skip
        scratch = self.folder / f"{slug(recipe.name)}.tmp"  # a kill mid-write leaves no .pt
        torch.save(saved, scratch)
        scratch.replace(scratch.with_suffix(".pt"))

    def remove(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)


def judge_networks(
    trained: dict,
    test_set: list[Shape],
    faces: np.ndarray,
    judge: Judge,
    out: Path | None,
    progress,
) -> tuple[dict, dict]:
    """Each trained network's reconstruction of each shape, judged against the shape and, where
    ``out`` is given, saved as OUT/meshes/<shape>/<loss>.ply -> (table: shape -> loss -> judged
    row, meshes: the saved files relative to OUT)."""
    table, meshes = {}, {}
    for shape in test_set:
        target = judge.prepare(shape.verts, shape.faces)
        rows, saved = {}, {}
        folder = out / "meshes" / slug(shape.name) if out else None
        if folder:
            saved["target"] = save_mesh(folder / "target.ply", shape.verts, shape.faces)
        for name, result in trained.items():
            with torch.no_grad():
                verts = result["model"](shape.points[None])[0].double().numpy()
            rows[name] = judge.compare(judge.prepare(verts, faces), target)
            if folder:
                saved[name] = save_mesh(folder / f"{slug(name)}.ply", verts, faces)
        table[shape.name], meshes[shape.name] = rows, saved
        progress(
            f"{shape.name}: " + "; ".join(f"{k} {v['F-score 1%']:.3f}" for k, v in rows.items())
        )
    return table, meshes


def choose_loss(plan: NetworkPlan, table: dict) -> dict:
    """The candidate (form, Chamfer weight) whose network beats the Chamfer network on the most
    visual cells of the validation ``table`` (a tie goes to the earlier candidate: the loss
    study's choices first) -> {"shares", "chamfer_l1_ratio", "form", "chamfer_weight"}."""
    candidates = {r.name: r for r in plan.candidates()}
    choice = choose(table, list(candidates), CHAMFER)
    (_, form), (weight, _) = candidates[choice["chosen"]].terms
    return {
        "shares": {name: won["share"] for name, won in choice["shares"].items()},
        "chamfer_l1_ratio": choice["chamfer_l1_ratio"],
        "form": form,
        "chamfer_weight": weight,
    }


def candidates_on_test(plan: NetworkPlan, table: dict) -> dict:
    """Each candidate's visual cells won against the Chamfer and pixel MSE networks on the test
    ``table`` (shape -> loss -> judged row, every candidate in it), and its Chamfer-L1 ratio: not
    a choice (validation made it), but how much the choice mattered on the shapes judged."""
    names = [r.name for r in plan.candidates()]
    ratios = chamfer_ratios(table, names)
    return {
        n: {
            "beats_chamfer": brief_share(table, n, CHAMFER, VISUAL),
            "beats_pixel_mse": brief_share(table, n, PIXEL, VISUAL),
            "chamfer_l1_ratio": ratios[n],
        }
        for n in names
    }


def reproduction(new: dict, committed: dict) -> dict:
    """The largest absolute difference between two tables' judged values (shape -> judged row),
    cell by cell."""
    gaps = [
        abs(row[m] - committed[shape][m])
        for shape, row in new.items()
        for m in JUDGED
        if row.get(m) is not None and committed[shape].get(m) is not None
    ]
    return {"cells": len(gaps), "max_abs_difference": max(gaps), "exact": max(gaps) == 0.0}


def retrained_beside(
    study: dict, recipes: list[Recipe], quick: bool, threads: int, out: Path | None, progress
) -> dict:
    """``recipes`` trained as a committed network study (``study``, its results.json) trained its
    own networks, judged on its test shapes beside them. ``train`` seeds the initial weights, the
    batches and the Chamfer draws from the plan and its seed, so the Chamfer network is trained
    again as the proof: at the same thread count and torch build its judged rows must equal the
    committed ones (``reproduced``), and then the committed rows stand beside the new ones.
    The new networks' reconstructions are saved under OUT/meshes/<shape>/ where ``out`` is given
    -> {"lfd", "reproduced", "table": the committed rows with the new networks', "meshes" (none
    without ``out``), "seconds_per_step"}."""
    plan = replace(QUICK_NETWORK if quick else FULL, seed=study["plan"]["seed"])
    train_set = shapes(plan, TRAIN_SEED, plan.train_per_family)
    test_set = shapes(plan, TEST_SEED, plan.test_per_family)
    _, faces = primitives()
    points = torch.stack([s.points for s in train_set])
    terms = Terms()
    trained = {
        r.name: train(plan, r, points, targets(r, train_set, faces, terms), progress)
        for r in (alone(CHAMFER), *recipes)
    }
    judge = Judge(plan.judge_config, threads, plan.unseen_views, plan.lfd)
    try:
        new, meshes = judge_networks(trained, test_set, faces.numpy(), judge, out, progress)
    finally:
        judge.close()
    committed = study["table"]
    names = [r.name for r in recipes]
    return {
        "lfd": judge.lfd_note,
        "reproduced": reproduction(
            {s: rows[CHAMFER] for s, rows in new.items()},
            {s: rows[CHAMFER] for s, rows in committed.items()},
        ),
        "table": {s: {**committed[s], **{n: rows[n] for n in names}} for s, rows in new.items()},
        "meshes": {s: {n: m[n] for n in names} for s, m in meshes.items()} if out else {},
        "seconds_per_step": {n: r["seconds_per_step"] for n, r in trained.items()},
    }


def run_network_study(
    out: Path, quick: bool, threads: int = 2, progress=print, seed: int = 0
) -> dict:
    """The study at the plan's size; ``seed`` draws every network's initial weights and batch
    order (the shapes, validation and test sets stay the plan's), so runs at several seeds show
    how far one run's shares can be trusted."""
    start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    plan = replace(QUICK_NETWORK if quick else FULL, seed=seed)
    train_set = shapes(plan, TRAIN_SEED, plan.train_per_family)
    validation_set = shapes(plan, VALIDATION_SEED, plan.validation_per_family)
    test_set = shapes(plan, TEST_SEED, plan.test_per_family)
    _, faces = primitives()
    points = torch.stack([s.points for s in train_set])
    terms, checkpoint = Terms(), Trainings(out / "checkpoint", plan)
    trained, resumed = {}, []

    def train_all(recipes: list[Recipe]) -> None:
        for recipe in recipes:
            result = checkpoint.get(recipe)
            if result is None:
                shape_terms = targets(recipe, train_set, faces, terms)
                result = train(plan, recipe, points, shape_terms, progress)
                checkpoint.put(recipe, result)
            else:
                resumed.append(recipe.name)
            trained[recipe.name] = result

    train_all([*plan.fixed(), *plan.candidates()])
    judge = Judge(plan.judge_config, threads, plan.unseen_views, plan.lfd)
    try:
        judging = {r.name: trained[r.name] for r in [alone(CHAMFER), *plan.candidates()]}
        progress("validation shapes:")
        validation_table, _ = judge_networks(
            judging, validation_set, faces.numpy(), judge, None, progress
        )
        choice = choose_loss(plan, validation_table)
        form = choice["form"]
        recipes = plan.recipes(form, choice["chamfer_weight"])
        progress(f"validation chose {form} at Chamfer weight {choice['chamfer_weight']:g}")
        train_all([r for r in recipes if r.name not in trained])
        progress("test shapes:")
        table, meshes = judge_networks(
            {r.name: trained[r.name] for r in recipes},
            test_set, faces.numpy(), judge, out, progress,
        )  # fmt: skip
        # the candidates validation passed over, judged on the same test shapes (not saved)
        others = {r.name: trained[r.name] for r in plan.candidates() if r not in recipes}
        progress("test shapes, the other candidates:")
        others_table, _ = judge_networks(others, test_set, faces.numpy(), judge, None, progress)
    finally:
        judge.close()
    names = [r.name for r in recipes]
    results = {
        "command": f"python bench/fit.py --network{' --quick' if quick else ''}"
        + (f" --seed {seed}" if seed else "")
        + f" --out {out}",
        "quick": quick,
        **machine(),
        "device": "cpu",
        "lfd": judge.lfd_note,
        "plan": {
            **{k: v for k, v in asdict(plan).items() if k != "judge_config"},
            "judge_config": plan.judge_config.to_dict(),
            "losses": names,
            "train_seeds": [TRAIN_SEED, TRAIN_SEED + plan.train_per_family - 1],
            "validation_seeds": [VALIDATION_SEED, VALIDATION_SEED + plan.validation_per_family - 1],
            "test_seeds": [TEST_SEED, TEST_SEED + plan.test_per_family - 1],
            "network": f"PointNet encoder ({INPUT_POINTS} points) -> {PRIMITIVES} deformed "
            f"icospheres (level {SPHERE_LEVEL})",
            "parameters": sum(p.numel() for p in trained[names[0]]["model"].parameters()),
        },
        "judged": list(JUDGED),
        "visual": list(VISUAL),
        "higher_is_better": sorted(HIGHER_IS_BETTER & set(JUDGED)),
        "validation": {**choice, "table": validation_table},
        "table": table,
        "candidates_on_test": {
            "table": others_table,
            "shares": candidates_on_test(
                plan, {s: {**rows, **others_table[s]} for s, rows in table.items()}
            ),
        },
        "meshes": meshes,
        "training": {
            name: {
                "objective_first": r["history"][0],
                "objective_last": r["history"][-1],
                "seconds_per_step": r["seconds_per_step"],
            }
            for name, r in trained.items()
        },  # every network trained, the candidate not chosen included
        "beats_chamfer": {n: share(table, n, CHAMFER, VISUAL) for n in names[1:]},
        "beats_pixel_mse": {n: share(table, n, PIXEL, VISUAL) for n in names if n != PIXEL},
        "chamfer_l1_over_chamfer_trained": chamfer_ratios(table, names),
        "means": metric_means(table, names),
        "summary": summary(table, recipes, form),
    }
    results["networks_resumed"] = resumed  # from a checkpoint: seconds_total does not count them
    results["seconds_total"] = time.perf_counter() - start
    (out / "results.json").write_text(json.dumps(results, indent=1))
    draw_gallery(out)
    checkpoint.remove()
    return results


def draw_gallery(out: Path) -> None:
    """OUT/gallery.png from a finished network study's results.json and saved meshes: per test
    shape the target and each network's reconstruction, from the same two cameras."""
    results = json.loads((out / "results.json").read_text())
    losses = results["plan"]["losses"]
    rows = []
    for shape, saved in results["meshes"].items():
        loaded = [trimesh.load(out / saved[n], process=False) for n in ("target", *losses)]
        rows.append((shape, [(np.asarray(m.vertices), np.asarray(m.faces)) for m in loaded]))
    form = results["validation"]["form"]
    write_gallery(out / "gallery.png", ["TARGET", *(column_title(n, form) for n in losses)], rows)
