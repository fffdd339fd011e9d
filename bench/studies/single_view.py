"""``python bench/single_view.py``: the DR-KFS paper's own experiment (its Tables 3 and 4).
SoftRas' shape generator reconstructs a shape from one image; it is trained once per loss from
the same initial weights on the same batches, and judged on test shapes, from input views no
training sample used, by metrics no loss computes.

The losses, each beside SoftRas' Laplacian and flatten regularisers (``Regularisers``):
SoftRas' multi-view silhouette IoU (the input view and one other, as SoftRas trains), pixel MSE
of the shaded images at the same two views (the paper's ablation), Chamfer-L2 on surface samples
(AtlasNet's and Pixel2Mesh's 3D supervision), the shipped ``DrkfsLoss`` (coarse to fine, shaded
renders) and the same loss on silhouettes (the ablation's first row). Each data term is divided
by its value on the first batch, so that one step size and SoftRas' regulariser weights serve
them all. DR-KFS beside SoftRas' IoU and beside 3 x Chamfer (the README's recipe) are trained at
the first seed; the one that beats DR-KFS alone on validation shapes, if either does, is
trained at every seed, chosen before any test shape is judged.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch

from drkfs_lab.benchmark.point_metrics import sample_surface
from drkfs_lab.judging.judges import HIGHER_IS_BETTER, Judge, better
from drkfs_onnx.contract.config import VIEW_FIELDS, PipelineConfig
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.geometry import chamfer, surface_points
from drkfs_onnx.loss import COARSE_TO_FINE, DrkfsLoss, StagedTarget
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.synthetic.shapes import assemble, random_shape

from .gallery import write_gallery
from .mesh_fit import deterministic_kernels
from .shape_generator import Regularisers, ShapeGenerator
from .study import machine, resume_key, slug
from .views import AZIMUTHS, CHANNELS, IMAGE_SIZE, VIEW_CONFIG, ViewRenderer, render_views

# shape seeds, disjoint from the nets' training data (0-2), the benchmark's (2026-2028), the
# held-out checks' (3000-3002) and the network study's (4000-4503)
TRAIN_SEED, VALIDATION_SEED, TEST_SEED = 5000, 5400, 5500
# input azimuths held out of training: a test shape is reconstructed from one of them
HELD_OUT_AZIMUTHS = (3, 9, 15, 21)
TRAIN_AZIMUTHS = tuple(a for a in range(AZIMUTHS) if a not in HELD_OUT_AZIMUTHS)
# points drawn on each prediction each step, and on each target once: at 2,000 and 5,000 the
# (B, N, M) distances took 3.1 s a step at B = 16 on 2 cores, at these 0.55 s
CHAMFER_SAMPLES, TARGET_SAMPLES = 1000, 2000
TIMED_STEPS = 5  # a loss's timed steps: 2 at DR-KFS's coarse stage, 3 at its fine one

IOU, PIXEL, CHAMFER, DRKFS_SHADED, DRKFS_SILHOUETTE = (
    "silhouette IoU", "pixel MSE", "Chamfer-L2", "DR-KFS", "DR-KFS on silhouettes",
)  # fmt: skip
DRKFS_TUNED = "DR-KFS with nets fine-tuned for the loss"
# the loss's nets fine-tuned on graded series (bench/records/fitting.md), made by
# python bench/loss_nets.py --save-nets bench/single_view/loss_nets.pt
TUNED_NETS = Path(__file__).resolve().parents[1] / "single_view" / "loss_nets.pt"
SOFTRAS = "SoftRas (silhouette IoU)"
# the outside judges: surface ones, and what a viewer sees (LFD, silhouettes of unseen views)
SURFACE = ("Chamfer-L1", "F-score 1%", "volumetric IoU")
VISUAL = ("LFD", "silhouette IoU", "normal consistency")
JUDGED = (*SURFACE, *VISUAL)


class Recipe(NamedTuple):
    name: str
    terms: tuple[tuple[float, str], ...]  # (weight, term)


BASELINES = (
    Recipe(SOFTRAS, ((1.0, IOU),)),
    Recipe(PIXEL, ((1.0, PIXEL),)),
    Recipe(CHAMFER, ((1.0, CHAMFER),)),
)
DRKFS_RECIPES = (
    Recipe(DRKFS_SHADED, ((1.0, DRKFS_SHADED),)),
    Recipe(DRKFS_SILHOUETTE, ((1.0, DRKFS_SILHOUETTE),)),
)
COMBINATIONS = (
    Recipe("DR-KFS + 1 x silhouette IoU", ((1.0, DRKFS_SHADED), (1.0, IOU))),
    Recipe("DR-KFS + 3 x Chamfer-L2", ((1.0, DRKFS_SHADED), (3.0, CHAMFER))),
)
# the matched controls (--controls): each DR-KFS recipe with its DR-KFS term left out, or
# replaced by another image term of the same weight. Every data term is divided by its first
# value, so a term's weight is its share against SoftRas' regularisers: "DR-KFS + 3 x Chamfer"
# gives Chamfer three times the pull it has in "Chamfer-L2", and only a control of the same
# weights tells what DR-KFS adds from what that weight does
RECIPE, RECIPE_IOU = COMBINATIONS[1].name, COMBINATIONS[0].name
CONTROLS = (
    Recipe("3 x Chamfer-L2", ((3.0, CHAMFER),)),
    Recipe("silhouette IoU + 3 x Chamfer-L2", ((1.0, IOU), (3.0, CHAMFER))),
    Recipe("pixel MSE + 3 x Chamfer-L2", ((1.0, PIXEL), (3.0, CHAMFER))),
    Recipe("2 x silhouette IoU", ((2.0, IOU),)),
    Recipe("silhouette IoU + 1 x pixel MSE", ((1.0, IOU), (1.0, PIXEL))),
)
MATCHED = {  # a DR-KFS recipe -> its controls, SoftRas' own loss beside each
    DRKFS_SHADED: (SOFTRAS, PIXEL),
    RECIPE: ("3 x Chamfer-L2", "silhouette IoU + 3 x Chamfer-L2", "pixel MSE + 3 x Chamfer-L2",
             SOFTRAS),
    RECIPE_IOU: (SOFTRAS, "2 x silhouette IoU", "silhouette IoU + 1 x pixel MSE"),
}  # fmt: skip
# the learning curve (--curve): one run of each to the last point at seed 0, judged at every
# point; the recipe's best control is read from OUT/controls.json (by pooled LFD), else this
CURVE_POINTS = (200, 500, 1000, 2000, 3000)
# the staged DR-KFS loss's progress is a step over these (coarse views until 800); the points
# past them go on at its fine stage
CURVE_PLAN_STEPS = 2000
CURVE_SAVE_EVERY = 50  # steps between a curve run's saved training states
CURVE_RECIPES = (SOFTRAS, PIXEL, "3 x Chamfer-L2", DRKFS_SHADED, RECIPE)
CURVE_CONTROL = "silhouette IoU + 3 x Chamfer-L2"
CURVE_STATE = Path.home() / ".cache" / "drkfs-onnx" / "single-view-curve"
# trained only when asked (--steps ... --losses): the strongest attempt's other nets
EXTRA = (
    Recipe(DRKFS_TUNED, ((1.0, DRKFS_TUNED),)),
    Recipe(f"{DRKFS_TUNED} + 3 x Chamfer-L2", ((1.0, DRKFS_TUNED), (3.0, CHAMFER))),
)
# the speed work's cheaper DR-KFS steps, alone and in the recipe (--speed, studies/speed.py):
# from one group of its cameras a step (``DrkfsLoss``'s view_groups), or with HardNet's convs in
# bfloat16 (its conv_precision)
CAMERA_GROUPS = {
    "DR-KFS (half the cameras a step)": 2,
    "DR-KFS (a third of the cameras a step)": 3,
}
BFLOAT16 = "DR-KFS (HardNet in bfloat16)"
CHEAPER = (*CAMERA_GROUPS, BFLOAT16)
CHEAPER_RECIPES = (
    *(Recipe(name, ((1.0, name),)) for name in CHEAPER),
    *(Recipe(f"{name} + 3 x Chamfer-L2", ((1.0, name), (3.0, CHAMFER))) for name in CHEAPER),
)
# the fine-tuning protocol (--finetune, studies/finetune.py): a network trained with SoftRas'
# loss or Chamfer's, trained as long again with its own loss, with DR-KFS beside it, or with
# another image term of DR-KFS's weight beside it (the matched control)
FINETUNE = {
    SOFTRAS: (SOFTRAS, RECIPE_IOU, "silhouette IoU + 1 x pixel MSE"),
    CHAMFER: (CHAMFER, "DR-KFS + 1 x Chamfer-L2", "silhouette IoU + 1 x Chamfer-L2"),
}
# the same with a second DR-KFS arm from each start, the loss's fine-tuned nets in the shipped
# ones' place (--finetune --tuned-nets)
TUNED_RECIPE_IOU = f"{DRKFS_TUNED} + 1 x silhouette IoU"
TUNED_RECIPE_CHAMFER = f"{DRKFS_TUNED} + 1 x Chamfer-L2"
FINETUNE_TUNED = {
    SOFTRAS: (*FINETUNE[SOFTRAS], TUNED_RECIPE_IOU),
    CHAMFER: (*FINETUNE[CHAMFER], TUNED_RECIPE_CHAMFER),
}
FINETUNE_RECIPES = (
    Recipe("DR-KFS + 1 x Chamfer-L2", ((1.0, DRKFS_SHADED), (1.0, CHAMFER))),
    Recipe("silhouette IoU + 1 x Chamfer-L2", ((1.0, IOU), (1.0, CHAMFER))),
    Recipe(TUNED_RECIPE_IOU, ((1.0, DRKFS_TUNED), (1.0, IOU))),
    Recipe(TUNED_RECIPE_CHAMFER, ((1.0, DRKFS_TUNED), (1.0, CHAMFER))),
)


def by_name(name: str) -> Recipe:
    recipes = (
        *BASELINES, *DRKFS_RECIPES, *COMBINATIONS, *CONTROLS, *EXTRA, *FINETUNE_RECIPES,
        *CHEAPER_RECIPES,
    )  # fmt: skip
    for recipe in recipes:
        if recipe.name == name:
            return recipe
    raise ValueError(f"no loss {name!r}; the study's: {', '.join(r.name for r in recipes)}")


@dataclass(frozen=True)
class Plan:
    families: tuple[str, ...]
    train_per_family: int
    validation_per_family: int
    test_per_family: int
    steps: int
    batch: int
    # SoftRas: Adam at 1e-4 for 250,000 steps of 64; scaled to a study of a few hundred steps
    learning_rate: float
    unseen_views: int  # the silhouette judge's cameras
    lfd: bool = True


FULL = Plan(
    families=("airplane", "car", "chair", "lamp"),
    train_per_family=24,
    validation_per_family=2,
    test_per_family=5,
    steps=200,
    batch=16,
    learning_rate=1e-3,
    unseen_views=8,
)
QUICK = replace(
    FULL,
    families=("chair", "lamp"),
    train_per_family=2,
    validation_per_family=1,
    test_per_family=1,
    steps=2,
    batch=4,
    unseen_views=2,
    lfd=False,
)


class Shape(NamedTuple):
    name: str
    family: str
    verts: np.ndarray  # (V, 3) float64, fitting the unit sphere
    faces: np.ndarray  # (F, 3) int64


def make_shapes(plan: Plan, first_seed: int, per_family: int) -> list[Shape]:
    shapes = []
    for family in plan.families:
        for seed in range(first_seed, first_seed + per_family):
            verts, faces = assemble(random_shape(family, seed))
            shapes.append(Shape(f"{family} {seed}", family, place(verts, frame_of(verts)), faces))
    return shapes


def views_of(shapes: list[Shape], cache: Path, renderer: ViewRenderer) -> torch.Tensor:
    """(N, AZIMUTHS, CHANNELS, S, S): each shape's images, rendered once into ``cache``."""
    cached = torch.load(cache, weights_only=True) if cache.exists() else {}
    missing = [s for s in shapes if s.name not in cached]
    for shape in missing:
        cached[shape.name] = render_views(renderer, shape.verts, shape.faces).half()
    if missing:
        cache.parent.mkdir(parents=True, exist_ok=True)
        torch.save(cached, cache)
    return torch.stack([cached[s.name].float() for s in shapes])


class Batch(NamedTuple):
    shapes: torch.Tensor  # (B,) indices into the training shapes
    inputs: torch.Tensor  # (B,) the input image's azimuth
    others: torch.Tensor  # (B,) a second azimuth the image losses also see


def draw_batch(rng: np.random.Generator, count: int, size: int) -> Batch:
    shapes = rng.choice(count, size=size, replace=False)
    azimuths = np.asarray(TRAIN_AZIMUTHS)[rng.integers(0, len(TRAIN_AZIMUTHS), size=(2, size))]
    return Batch(*(torch.as_tensor(a) for a in (shapes, *azimuths)))


class SilhouetteDRKFS(DRKFS):
    """DR-KFS whose nets see the silhouettes: the ablation's first row."""

    render_mode = "silhouette"


def iou_loss(rendered: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """SoftRas' 1 - soft IoU of each image (N, S, S), averaged."""
    overlap = (rendered * truth).sum((-1, -2))
    union = (rendered + truth - rendered * truth).sum((-1, -2)).clamp_min(1e-6)
    return (1 - overlap / union).mean()


class Terms:
    """The loss terms on the training shapes: ``value(term, verts (B, V, 3), batch, progress)``
    -> () the batch's mean. Targets are prepared once, when a term is first asked for."""

    def __init__(self, shapes: list[Shape], views: torch.Tensor, faces: torch.Tensor, seed: int):
        self.shapes, self.views, self.faces = shapes, views, faces
        self.renderer = ViewRenderer().to(faces.device)
        self.generator = torch.Generator(faces.device.type).manual_seed(seed)
        self.prepared: dict[str, object] = {}

    def value(self, term: str, verts: torch.Tensor, batch: Batch, progress: float):
        if term in (IOU, PIXEL):
            azimuths = torch.cat([batch.inputs, batch.others])
            shapes = torch.cat([batch.shapes, batch.shapes])
            channel = 1 if term == IOU else 0
            truth = self.views[shapes, azimuths, channel].to(verts.device)
            mode = "silhouette" if term == IOU else "shaded"
            rendered = self.renderer(torch.cat([verts, verts]), self.faces, azimuths, mode)
            return iou_loss(rendered, truth) if term == IOU else ((rendered - truth) ** 2).mean()
        prepared = self.prepare(term)
        if term == CHAMFER:
            points = surface_points(verts, self.faces, CHAMFER_SAMPLES, self.generator)
            return chamfer(points, prepared[batch.shapes.to(verts.device)])
        loss, targets = prepared
        target = StagedTarget.stack([targets[i] for i in batch.shapes.tolist()])
        return loss(verts, self.faces, target, progress)

    def prepare(self, term: str):
        if term not in self.prepared:
            device = self.faces.device
            if term == CHAMFER:
                self.prepared[term] = torch.stack([
                    torch.as_tensor(sample_surface(s.verts, s.faces, TARGET_SAMPLES).points,
                                    dtype=torch.float32)
                    for s in self.shapes
                ]).to(device)  # fmt: skip
            else:
                if term == DRKFS_TUNED:
                    loss = DrkfsLoss.from_nets(tuned_nets())
                else:
                    # the groups are drawn by the training's generator: a seed repeats them
                    kind = SilhouetteDRKFS if term == DRKFS_SILHOUETTE else DRKFS
                    precision = "bfloat16" if term == BFLOAT16 else "ieee"
                    metrics = [kind.pretrained(stage.config, conv_precision=precision)
                               for stage in COARSE_TO_FINE]  # fmt: skip
                    groups = CAMERA_GROUPS.get(term, 1)
                    loss = DrkfsLoss(metrics, COARSE_TO_FINE, None, groups, self.generator)
                loss = loss.to(device)
                targets = [
                    loss.target(torch.as_tensor(s.verts, dtype=torch.float32, device=device),
                                torch.as_tensor(s.faces, device=device))
                    for s in self.shapes
                ]  # fmt: skip
                self.prepared[term] = (loss, targets)
        return self.prepared[term]


def tuned_nets() -> DRKFS:
    """The loss's nets fine-tuned for it (``TUNED_NETS``), as a ``DRKFS`` at the loss preset."""
    if not TUNED_NETS.is_file():
        raise ValueError(
            f"{TUNED_NETS}: no fine-tuned nets; make them with python bench/loss_nets.py "
            f"--save-nets {TUNED_NETS}"
        )
    nets = DRKFS(PipelineConfig.loss())
    nets.load_state_dict(torch.load(TUNED_NETS, weights_only=True))
    return nets


@deterministic_kernels()
def train(
    plan: Plan,
    recipe: Recipe,
    seed: int,
    views: torch.Tensor,
    terms: Terms,
    progress,
    resume: dict | None = None,
    until: int | None = None,
    start: dict | None = None,
) -> dict:
    """One generator trained with ``recipe`` -> {"model", "history", "seconds_per_step",
    "state"}. Every recipe at a seed starts from the same weights and sees the same batches.
    ``until`` stops at that step (default: the plan's last), with the staged loss's progress
    still counted against the plan's steps; ``resume`` goes on from an earlier call's "state"
    as if the two calls were one; ``start``: a trained generator's weights to start from
    instead of the seed's (a fine-tuning, with a fresh optimiser)."""
    device = terms.faces.device
    torch.manual_seed(seed)
    model = ShapeGenerator(CHANNELS, IMAGE_SIZE).to(device)
    if start is not None:
        model.load_state_dict(start)
    regularisers = Regularisers(model.template(), model.faces).to(device)
    weights = torch.tensor([w for w, _ in recipe.terms], device=device)
    rng = np.random.default_rng(seed)
    terms.generator.manual_seed(seed)
    optimizer = torch.optim.Adam(model.parameters(), lr=plan.learning_rate)
    scales, history, first, seconds = None, [], 0, 0.0
    if resume is not None:
        model.load_state_dict(resume["model"])
        optimizer.load_state_dict(resume["optimizer"])
        rng.bit_generator.state = resume["rng"]
        terms.generator.set_state(resume["generator"])
        scales, history = resume["scales"], list(resume["history"])
        first, seconds = len(history), resume["seconds"]
    last = plan.steps if until is None else until
    start = time.perf_counter()
    for step in range(first, last):
        batch = draw_batch(rng, len(views), plan.batch)
        verts = model(views[batch.shapes, batch.inputs].to(device))
        values = torch.stack(
            [terms.value(t, verts, batch, step / plan.steps) for _, t in recipe.terms]
        )
        if scales is None:
            scales = values.detach().clamp_min(1e-12)
        objective = (weights * values / scales).sum()
        optimizer.zero_grad()
        (objective + regularisers(verts)).backward()
        optimizer.step()
        history.append(float(objective.detach()))
        if step % max(1, plan.steps // 10) == 0:
            progress(f"seed {seed}, {recipe.name}: step {step} objective {history[-1]:.4f}")
    seconds += time.perf_counter() - start
    state = {"model": model.state_dict(), "optimizer": optimizer.state_dict(),
             "rng": rng.bit_generator.state, "generator": terms.generator.get_state(),
             "scales": scales, "history": history, "seconds": seconds}  # fmt: skip
    return {"model": model.eval(), "history": history,
            "seconds_per_step": seconds / max(len(history), 1), "state": state}  # fmt: skip


class Networks:
    """Trained generators as OUT/networks/seed<S>/<loss>.pt (float16 weights, the ``resume_key``
    they were trained under, their objective's history and seconds a step): a stopped study
    resumes where it stopped, and every network is judged from its saved weights, so a resumed
    study judges what a straight one does."""

    def __init__(self, folder: Path, plan: Plan, device: torch.device):
        self.key = f"{resume_key(plan)}; views {VIEW_CONFIG.to_json()}"
        self.folder, self.device = folder, device

    def matches(self, key: str) -> bool:
        """Whether a network saved under ``key`` was trained as this store's would be: the same
        plan, torch and threads, and the same views (a config field added since reads as the
        value such records were made with; fields the views do not depend on are moot)."""
        plan, _, views = key.partition("; views ")
        ours, _, our_views = self.key.partition("; views ")
        saved, now = (PipelineConfig.from_json(v) for v in (views, our_views))
        return plan == ours and all(getattr(saved, f) == getattr(now, f) for f in VIEW_FIELDS)

    def path(self, seed: int, name: str) -> Path:
        return self.folder / f"seed{seed}" / f"{slug(name)}.pt"

    def get(self, seed: int, name: str, any_key: bool = False) -> dict | None:
        path = self.path(seed, name)
        saved = torch.load(path, weights_only=True) if path.exists() else None
        if saved is None or not (any_key or self.matches(saved["key"])):
            return None
        model = ShapeGenerator(CHANNELS, IMAGE_SIZE)
        model.load_state_dict({k: v.float() if v.is_floating_point() else v
                               for k, v in saved["state"].items()})  # fmt: skip
        return {**saved, "model": model.to(self.device).eval()}

    def trained(
        self, seed: int, name: str, plan: Plan, views: torch.Tensor, terms: Terms, progress
    ) -> dict:
        """The saved network of loss ``name`` at ``seed`` (as ``get``), trained on ``views``
        and saved first where there is none."""
        if self.get(seed, name) is None:
            self.put(seed, name, train(plan, by_name(name), seed, views, terms, progress))
        return self.get(seed, name)

    def put(self, seed: int, name: str, result: dict) -> None:
        path = self.path(seed, name)
        path.parent.mkdir(parents=True, exist_ok=True)
        state = {k: v.half() if v.is_floating_point() else v
                 for k, v in result["model"].state_dict().items()}  # fmt: skip
        saved = {"key": self.key, "state": state, "history": result["history"],
                 "seconds_per_step": result["seconds_per_step"]}  # fmt: skip
        scratch = path.with_suffix(".tmp")  # a kill mid-write leaves no .pt
        torch.save(saved, scratch)
        scratch.replace(path)


@torch.no_grad()
def reconstruct(model: ShapeGenerator, views: torch.Tensor, azimuths: list[int]) -> np.ndarray:
    """(N, V, 3) float64: shape i reconstructed from its view at ``azimuths[i]``."""
    device = next(model.parameters()).device
    images = views[torch.arange(len(views)), torch.as_tensor(azimuths)].to(device)
    return model(images).double().cpu().numpy()


def input_azimuths(shapes: list[Shape]) -> list[int]:
    """Each judged shape's input view, a held-out azimuth, turning with the shape's index."""
    return [HELD_OUT_AZIMUTHS[i % len(HELD_OUT_AZIMUTHS)] for i in range(len(shapes))]


def judge_all(judge: Judge, models: dict, shapes, views, targets: dict, progress) -> dict:
    """shape -> loss -> judged row, each model's reconstruction from the shape's input view.
    ``targets`` (shape name -> the judge's prepared truth) keeps each truth prepared once
    across calls: LFD describes a mesh in seconds."""
    azimuths = input_azimuths(shapes)
    faces = next(iter(models.values())).faces.cpu().numpy()
    predictions = {n: reconstruct(m, views, azimuths) for n, m in models.items()}
    table = {}
    for i, shape in enumerate(shapes):
        if shape.name not in targets:
            targets[shape.name] = judge.prepare(shape.verts, shape.faces)
        table[shape.name] = {
            name: judge.compare(judge.prepare(verts[i], faces), targets[shape.name])
            for name, verts in predictions.items()
        }
        progress(f"{shape.name}: " + "; ".join(
            f"{n} LFD {r['LFD'] if r['LFD'] is None else round(r['LFD'])} "
            f"sil {r['silhouette IoU']:.3f}" for n, r in table[shape.name].items()))  # fmt: skip
    return table


@contextmanager
def seed_judging(plan: Plan, threads: int, shapes, views, progress) -> Iterator[tuple]:
    """One judge of ``shapes`` whose prepared truths serve every call inside: (its LFD note,
    ``tables(seeds, models_at)`` -> seed -> ``judge_all``'s table of the networks
    ``models_at(seed)``, name -> generator)."""
    judge = Judge(PipelineConfig(), threads, plan.unseen_views, plan.lfd, image_judges=False)
    truths: dict = {}

    def tables(seeds, models_at) -> dict[int, dict]:
        return {s: judge_all(judge, models_at(s), shapes, views, truths, progress) for s in seeds}

    try:
        yield judge.lfd_note, tables
    finally:
        judge.close()


def judge_seeds(
    plan: Plan, threads: int, seeds, models_at, shapes, views, progress
) -> tuple[dict[int, dict], str]:
    """seed -> ``judge_all``'s table of the networks ``models_at(seed)`` (name -> generator) on
    ``shapes``, by one judge (``seed_judging``); and its LFD note."""
    with seed_judging(plan, threads, shapes, views, progress) as (lfd, tables):
        return tables(seeds, models_at), lfd


def means(tables: list[dict], shapes: list[Shape], names: list[str]) -> dict:
    """family (and 'mean') -> loss -> judge -> the mean over shapes and the tables' seeds."""
    families = sorted({s.family for s in shapes}) + ["mean"]
    out = {}
    for family in families:
        rows = [t[s.name] for t in tables for s in shapes if family in ("mean", s.family)]
        out[family] = {n: {m: _mean([r[n][m] for r in rows]) for m in JUDGED} for n in names}
    return out


def _mean(values: list) -> float | None:
    kept = [v for v in values if v is not None]
    return float(np.mean(kept)) if kept else None


def shares(tables: list[dict], challenger: str, against: str) -> dict:
    """judge -> the share of (seed, shape) cells where ``challenger``'s reconstruction is
    closer than ``against``'s, and 'all visual': of the cells where it is closer by every
    visual judge at once."""
    out = {}
    for metric in JUDGED:
        cells = [
            better(metric, rows[challenger][metric], rows[against][metric])
            for t in tables for rows in t.values()
            if rows[challenger][metric] is not None and rows[against][metric] is not None
        ]  # fmt: skip
        out[metric] = {"wins": int(sum(cells)), "cells": len(cells),
                       "share": sum(cells) / len(cells) if cells else None}  # fmt: skip
    return out


def goal(tables: list[dict], chamfer_l1: dict[str, float | None]) -> dict:
    """The issue's bar: DR-KFS's network closer than SoftRas' and pixel MSE's by LFD and by
    unseen-view silhouette IoU on >= 75% of test shapes pooled over seeds, at a Chamfer-L1
    (``chamfer_l1``: loss -> pooled mean) no worse than 1.1 x the best baseline's."""
    baselines = [b.name for b in BASELINES]
    return bar(tables, DRKFS_SHADED, (SOFTRAS, PIXEL), chamfer_l1, baselines, "baseline", 1.1)


def bar(
    tables: list[dict],
    challenger: str,
    against: tuple[str, ...],
    chamfer_l1: dict[str, float | None],
    pool: list[str],
    pooled_as: str,
    ceiling: float,
) -> dict:
    """``challenger`` closer than each of ``against`` by LFD and by unseen-view silhouette IoU
    on >= 75% of the cells of ``tables``, at a pooled Chamfer-L1 no more than ``ceiling`` times
    the best of ``pool``'s -> each share, the ratio and whether all held ("met")."""
    found: dict = {}
    for other in against:
        won = shares(tables, challenger, other)
        found[f"beats {other}"] = {m: won[m]["share"] for m in ("LFD", "silhouette IoU")}
    ratio = f"chamfer_l1_over_best_{pooled_as}"
    found[ratio] = chamfer_l1[challenger] / min(chamfer_l1[n] for n in pool)
    shares_met = all(
        v is not None and v >= 0.75 for k, row in found.items() if k.startswith("beats")
        for v in row.values()
    )  # fmt: skip
    found["met"] = shares_met and found[ratio] <= ceiling
    return found


def study_sets(plan: Plan, test_seed: int = TEST_SEED) -> tuple[list[Shape], ...]:
    return (
        make_shapes(plan, TRAIN_SEED, plan.train_per_family),
        make_shapes(plan, VALIDATION_SEED, plan.validation_per_family),
        make_shapes(plan, test_seed, plan.test_per_family),
    )


def validation_choice(table: dict) -> dict:
    """Of DR-KFS alone and its combinations, the one whose network beats SoftRas' on the most
    visual cells of the validation ``table`` (a tie keeps DR-KFS alone)."""
    candidates = [DRKFS_SHADED, *(r.name for r in COMBINATIONS)]
    won = {}
    for name in candidates:
        cells = shares([table], name, SOFTRAS)
        wins = sum(cells[m]["wins"] for m in VISUAL)
        won[name] = wins / max(sum(cells[m]["cells"] for m in VISUAL), 1)
    return {"shares_of_visual_cells_beating_softras": won, "chosen": max(candidates, key=won.get)}


def summarise(tables: dict[int, dict], test_set: list[Shape], names: list[str]) -> dict:
    """Per seed and pooled: the paper-form means, and each DR-KFS network's shares against
    each baseline; the issue's goal on the pooled shares."""
    pooled = list(tables.values())
    drkfs = [n for n in names if n.startswith("DR-KFS")]
    baselines = [b.name for b in BASELINES]
    pooled_means = means(pooled, test_set, names)
    return {
        "means": {"pooled": pooled_means,
                  **{f"seed {s}": means([t], test_set, names) for s, t in tables.items()}},
        "shares": {
            "pooled": {d: {b: shares(pooled, d, b) for b in baselines} for d in drkfs},
            **{f"seed {s}": {d: {b: shares([t], d, b) for b in baselines} for d in drkfs}
               for s, t in tables.items()},
        },
        "goal": goal(pooled, {n: pooled_means["mean"][n]["Chamfer-L1"] for n in names}),
    }  # fmt: skip


def run_single_view(
    out: Path,
    quick: bool = False,
    seeds: tuple[int, ...] = (0, 1, 2),
    device: str = "cpu",
    threads: int = 2,
    progress=print,
) -> dict:
    """Train every loss's generator at each seed (resuming from OUT/networks), choose the
    combination on validation shapes, judge the test shapes -> results (OUT/results.json,
    OUT/gallery.png)."""
    start = time.perf_counter()
    plan = QUICK if quick else FULL
    dev = torch.device(device)
    train_set, validation_set, test_set = study_sets(plan)
    renderer = ViewRenderer()
    cache = out / "data" / "views.pt"
    sets = {"train": train_set, "validation": validation_set, "test": test_set}
    views = {name: views_of(shapes, cache, renderer) for name, shapes in sets.items()}
    networks = Networks(out / "networks", plan, dev)
    terms = Terms(train_set, views["train"], ShapeGenerator(CHANNELS, IMAGE_SIZE).faces.to(dev), 0)
    resumed, seconds = [], {}

    def trained(seed: int, recipe: Recipe) -> ShapeGenerator:
        saved = networks.get(seed, recipe.name)
        if saved is None:
            networks.put(
                seed, recipe.name, train(plan, recipe, seed, views["train"], terms, progress)
            )
            saved = networks.get(seed, recipe.name)
        else:
            resumed.append(f"seed {seed}: {recipe.name}")
        seconds.setdefault(recipe.name, {})[f"seed {seed}"] = saved["seconds_per_step"]
        return saved["model"]

    # the paper's comparison at every seed; the combinations at the first, one chosen on
    # validation shapes and trained at every seed; judged and written; then the ablation (DR-KFS
    # on silhouettes), judged and written again: the comparison and its strongest attempt first
    for seed in seeds:
        for recipe in (*BASELINES, DRKFS_RECIPES[0]):
            trained(seed, recipe)
    recipes = [*BASELINES, DRKFS_RECIPES[0]]
    judge = Judge(PipelineConfig(), threads, plan.unseen_views, plan.lfd, image_judges=False)
    truths: dict = {}  # every shape's prepared truth, validation's and test's

    def judged(names: list[str]) -> dict[int, dict]:
        return {
            seed: judge_all(judge, {n: trained(seed, by_name(n)) for n in names}, test_set,
                            views["test"], truths, progress)
            for seed in seeds
        }  # fmt: skip

    def write(tables: dict, validation: dict) -> dict:
        names = [r.name for r in recipes]
        results = {
            "command": f"python bench/single_view.py{' --quick' if quick else ''} --seeds "
            f"{','.join(map(str, seeds))} --device {device} --out {out}",
            "quick": quick,
            **machine(),
            "device": device if dev.type == "cpu" else torch.cuda.get_device_name(dev),
            "lfd": judge.lfd_note,
            "plan": {
                **asdict(plan),
                "seeds": list(seeds),
                "losses": names,
                "train_seeds": [TRAIN_SEED, TRAIN_SEED + plan.train_per_family - 1],
                "validation_seeds": [
                    VALIDATION_SEED,
                    VALIDATION_SEED + plan.validation_per_family - 1,
                ],
                "test_seeds": [TEST_SEED, TEST_SEED + plan.test_per_family - 1],
                "input_azimuths_trained": list(TRAIN_AZIMUTHS),
                "input_azimuths_tested": list(HELD_OUT_AZIMUTHS),
                "parameters": sum(
                    p.numel() for p in ShapeGenerator(CHANNELS, IMAGE_SIZE).parameters()
                ),
            },  # fmt: skip
            "judged": list(JUDGED),
            "visual": list(VISUAL),
            "higher_is_better": sorted(HIGHER_IS_BETTER & set(JUDGED)),
            "validation": validation,
            "tables": {f"seed {s}": t for s, t in tables.items()},
            **summarise(tables, test_set, names),
            "seconds_per_step": {"timed": timing, "trainings": seconds},
            "networks_resumed": resumed,
            "seconds_total": time.perf_counter() - start,
        }
        out.mkdir(parents=True, exist_ok=True)
        (out / "results.json").write_text(json.dumps(results, indent=1))
        draw_gallery(out, plan, networks, seeds[0], names, test_set, views["test"])
        return results

    # each loss's seconds a step, timed apart from the trainings (which shared the cores with
    # whatever else ran)
    timing = {
        r.name: timed(plan, r, views["train"], terms, progress)
        for r in (*BASELINES, *DRKFS_RECIPES, *COMBINATIONS)
    }
    try:
        first = seeds[0]
        candidates = [BASELINES[0], DRKFS_RECIPES[0], *COMBINATIONS]
        progress("validation shapes:")
        validation = judge_all(
            judge, {r.name: trained(first, r) for r in candidates}, validation_set,
            views["validation"], truths, progress,
        )  # fmt: skip
        choice = {**validation_choice(validation), "table": validation}
        progress(f"validation chose {choice['chosen']}")
        recipes += [r for r in COMBINATIONS if r.name == choice["chosen"]]
        tables = judged([r.name for r in recipes])
        write(tables, choice)
        recipes.append(DRKFS_RECIPES[1])
        for seed, rows in judged([DRKFS_RECIPES[1].name]).items():
            for shape, row in rows.items():
                tables[seed][shape].update(row)
        return write(tables, choice)
    finally:
        judge.close()


def timed(plan: Plan, recipe: Recipe, views: torch.Tensor, terms: Terms, progress) -> float:
    """A loss's seconds a step: TIMED_STEPS steps from seed 0's start, coarse and fine stages
    both, after two steps, one at each stage, that pay the first compile of each stage's
    rasteriser equations (which the timed steps' first fine one paid before)."""
    train(replace(plan, steps=2), recipe, 0, views, terms, progress)
    return train(replace(plan, steps=TIMED_STEPS), recipe, 0, views, terms, progress)[
        "seconds_per_step"
    ]


def judge_saved(out: Path, test_seed: int, threads: int = 2, progress=print) -> dict:
    """The networks a finished study saved under OUT, and those of its matched controls where
    they ran (OUT/controls.json), judged on test shapes of seeds from ``test_seed`` on (as many
    a family as the study's plan) -> OUT/test-seeds-<seed>.json."""
    start = time.perf_counter()
    study = json.loads((out / "results.json").read_text())
    plan = QUICK if study["quick"] else FULL
    _, _, test_set = study_sets(plan, test_seed)
    views = views_of(test_set, out / "data" / "views.pt", ViewRenderer())
    names, ran_file = study["plan"]["losses"], out / "controls.json"
    ran = json.loads(ran_file.read_text()) if ran_file.exists() else None
    cpu = torch.device("cpu")

    def saved(folder: str, losses: list[str]):
        store = Networks(out / folder, plan, cpu)
        return lambda seed: {n: store.get(seed, n, any_key=True)["model"] for n in losses}

    # one judge for both: each test shape's truth prepared once (LFD describes it in seconds)
    with seed_judging(plan, threads, test_set, views, progress) as (lfd, tables_of):
        tables = tables_of(study["plan"]["seeds"], saved("networks", names))
        if ran is not None:
            control_tables = tables_of(ran["seeds"], saved(CONTROLS_NETWORKS, ran["recipes"]))
    results = {
        "command": f"python bench/single_view.py --out {out} --test-seeds {test_seed}",
        **machine(),
        "test_seeds": [test_seed, test_seed + plan.test_per_family - 1],
        "lfd": lfd,
        "tables": {f"seed {s}": t for s, t in tables.items()},
        **summarise(tables, test_set, names),
    }
    if ran is not None:
        results["controls"] = {
            "recipes": ran["recipes"],
            "tables": {f"seed {s}": t for s, t in control_tables.items()},
            **summarise_controls(control_tables, test_set),
        }
    results["seconds_total"] = time.perf_counter() - start
    (out / f"test-seeds-{test_seed}.json").write_text(json.dumps(results, indent=1))
    return results


def training_data(out: Path, plan: Plan, device: torch.device):
    """The plan's test shapes, the train and test shapes' views (cached in OUT/data) and the
    loss terms on the training shapes -> (test_set, views, terms)."""
    train_set, _, test_set = study_sets(plan)
    cache, renderer = out / "data" / "views.pt", ViewRenderer()
    views = {name: views_of(shapes, cache, renderer)
             for name, shapes in (("train", train_set), ("test", test_set))}  # fmt: skip
    faces = ShapeGenerator(CHANNELS, IMAGE_SIZE).faces.to(device)
    return test_set, views, Terms(train_set, views["train"], faces, 0)


def run_longer(
    out: Path,
    steps: int,
    names: list[str],
    seed: int = 0,
    quick: bool = False,
    device: str = "cpu",
    threads: int = 2,
    progress=print,
) -> dict:
    """Whether more steps close a loss's gap, or how a loss the study leaves out does:
    ``names``' generators trained at ``seed`` for ``steps`` steps (OUT/networks-<steps>-steps,
    resumable), judged on the study's test shapes beside the study's networks of the same
    losses and of SoftRas', DR-KFS' and the recipe's (OUT/networks) ->
    OUT/longer-<steps>-steps-seed<seed>.json, which names each network's folder, loss and
    sha256 for ``judge_longer``."""
    study_plan = QUICK if quick else FULL
    plan = replace(study_plan, steps=steps)
    dev = torch.device(device)
    test_set, views, terms = training_data(out, plan, dev)
    longer = Networks(out / f"networks-{steps}-steps", plan, dev)
    stored, models, seconds = {}, {}, {}  # row -> (its store, its loss); row -> generator
    for name in names:
        saved = longer.trained(seed, name, plan, views["train"], terms, progress)
        row = f"{name}, {steps} steps"
        stored[row], models[row] = (longer, name), saved["model"]
        seconds[name] = saved["seconds_per_step"]
    # beside them the study's networks of the same losses, and of SoftRas', DR-KFS' and the recipe
    study = Networks(out / "networks", study_plan, dev)
    for name in dict.fromkeys([*names, SOFTRAS, DRKFS_SHADED, RECIPE]):
        row = f"{name}, {study_plan.steps} steps"
        saved = None if row in stored else study.get(seed, name)
        if saved is not None:
            stored[row], models[row] = (study, name), saved["model"]
    judge = Judge(PipelineConfig(), threads, plan.unseen_views, plan.lfd, image_judges=False)
    try:
        table = judge_all(judge, models, test_set, views["test"], {}, progress)
    finally:
        judge.close()
    results = {
        "command": f"python bench/single_view.py{' --quick' if quick else ''} --out {out} "
        f"--steps {steps} --seeds {seed} --losses '{','.join(names)}'",
        **machine(),
        "lfd": judge.lfd_note,
        "quick": quick,
        "seed": seed,
        "steps": [study_plan.steps, steps],
        "seconds_per_step": seconds,
        "networks": {
            row: {
                "folder": store.folder.name,
                "loss": name,
                "sha256": sha256_of(store.path(seed, name)),
            }
            for row, (store, name) in stored.items()
        },  # fmt: skip
        "table": table,
        **every_pair([table], test_set, list(models)),
    }
    return write_json(out / f"longer-{steps}-steps-seed{seed}.json", results)


def every_pair(tables: list[dict], test_set: list[Shape], rows: list[str]) -> dict:
    """The means of ``rows`` over ``tables``' cells, and each row's shares against each other."""
    return {
        "means": means(tables, test_set, rows),
        "shares": {c: {a: shares(tables, c, a) for a in rows if a != c} for c in rows},
    }


def judge_longer(
    out: Path, steps: int, seeds: tuple[int, ...], test_seed: int, threads: int = 2, progress=print
) -> dict:
    """The networks each --steps run OUT/longer-<steps>-steps-seed<S>.json of ``seeds`` judged,
    judged again on test shapes of seeds from ``test_seed`` on (as many a family as the runs'
    plan) -> OUT/longer-<steps>-steps-test-seeds-<seed>.json: each seed's table, and every
    row's means and shares pooled over the seeds. ``SavedRunError`` where a run is missing,
    names no digests or judged other rows or another plan than the first seed's, or where a
    network is missing or not the one its run judged."""
    began = time.perf_counter()
    seeds = tuple(dict.fromkeys(seeds))
    paths = {seed: out / f"longer-{steps}-steps-seed{seed}.json" for seed in seeds}
    runs = {seed: saved_run(path, f"`python bench/single_view.py --out {out} --steps {steps} "
                                  f"--seeds {seed} --losses <losses>`")
            for seed, path in paths.items()}  # fmt: skip
    first = runs[seeds[0]]
    for seed, run in runs.items():
        if (run["quick"], list(run["networks"])) != (first["quick"], list(first["networks"])):
            raise SavedRunError(
                f"{paths[seed]} judged other networks than {paths[seeds[0]].name}: "
                "judge seeds whose runs trained the same losses"
            )
    plan, cpu = (QUICK if first["quick"] else FULL), torch.device("cpu")

    # a store of either folder under the study's plan: its networks are loaded by their
    # digests, whatever plan their key names (``get(any_key=True)``)
    def stored(seed: int) -> dict[str, tuple[Networks, str]]:  # row -> (its store, its loss)
        return {row: (Networks(out / n["folder"], plan, cpu), n["loss"])
                for row, n in runs[seed]["networks"].items()}  # fmt: skip

    digests = {
        f"seed {seed}": {
            row: checked(paths[seed], store.path(seed, name), runs[seed]["networks"][row]["sha256"])
            for row, (store, name) in stored(seed).items()
        }
        for seed in seeds
    }
    _, _, test_set = study_sets(plan, test_seed)
    views = views_of(test_set, out / "data" / "views.pt", ViewRenderer())

    def models_at(seed: int) -> dict:
        return {row: store.get(seed, name, any_key=True)["model"]
                for row, (store, name) in stored(seed).items()}  # fmt: skip

    tables, lfd = judge_seeds(plan, threads, seeds, models_at, test_set, views, progress)
    results = {
        "command": f"python bench/single_view.py --out {out} --steps {steps} "
        f"--seeds {','.join(map(str, seeds))} --test-seeds {test_seed}",
        **machine(),
        "lfd": lfd,
        "seeds": list(seeds),
        "steps": first["steps"],
        "test_seeds": [test_seed, test_seed + plan.test_per_family - 1],
        "networks": digests,
        "tables": {f"seed {s}": t for s, t in tables.items()},
        **every_pair(list(tables.values()), test_set, list(first["networks"])),
        "seconds_total": time.perf_counter() - began,
    }
    return write_json(out / f"longer-{steps}-steps-test-seeds-{test_seed}.json", results)


def controls_goal(tables: list[dict], chamfer_l1: dict[str, float | None], recipe: str) -> dict:
    """The issue's bar for one DR-KFS recipe: closer than each of its matched controls and than
    SoftRas' loss by LFD and by unseen-view silhouette IoU on >= 75% of the test cells pooled
    over seeds, at a Chamfer-L1 (``chamfer_l1``: loss -> pooled mean) no worse than the best
    control's."""
    controls = MATCHED[recipe]
    return bar(tables, recipe, controls, chamfer_l1, list(controls), "control", 1.0)


def summarise_controls(tables: dict[int, dict], test_set: list[Shape]) -> dict:
    """Means of every recipe and control; each DR-KFS recipe's shares against each of its
    controls, per seed and pooled; the goal per DR-KFS recipe."""
    names = list(dict.fromkeys(n for d, cs in MATCHED.items() for n in (d, *cs)))
    pooled = list(tables.values())
    pooled_means = means(pooled, test_set, names)
    chamfer_l1 = {n: pooled_means["mean"][n]["Chamfer-L1"] for n in names}
    per = {"pooled": pooled, **{f"seed {s}": [t] for s, t in tables.items()}}
    return {
        "means": {"pooled": pooled_means,
                  **{f"seed {s}": means([t], test_set, names) for s, t in tables.items()}},
        "shares": {key: {d: {c: shares(ts, d, c) for c in cs} for d, cs in MATCHED.items()}
                   for key, ts in per.items()},
        "goal": {d: controls_goal(pooled, chamfer_l1, d) for d in MATCHED},
    }  # fmt: skip


# The controls' networks, every recipe of ``MATCHED`` trained in one folder by one version of the
# code: the soft rasteriser's float rounding has moved since the study's own networks were
# trained, and from the same weights and batches a network's objective drifts from its
# rounding's by 1e-7 at the third step to 1e-2 by the thirtieth: a recipe trained then and its
# control trained now would not be matched (bench/records/single_view.md, "Matched controls").
CONTROLS_NETWORKS = "networks-controls"


def run_controls(
    out: Path,
    seeds: tuple[int, ...] = (0, 1, 2),
    quick: bool = False,
    device: str = "cpu",
    threads: int = 2,
    progress=print,
) -> dict:
    """Each DR-KFS recipe and its matched controls (``MATCHED``) trained at every seed for the
    study's steps (OUT/networks-controls, resumable) and judged on its test shapes ->
    OUT/controls.json."""
    start = time.perf_counter()
    plan = QUICK if quick else FULL
    dev = torch.device(device)
    test_set, views, terms = training_data(out, plan, dev)
    networks = Networks(out / CONTROLS_NETWORKS, plan, dev)
    names = list(dict.fromkeys(n for d, cs in MATCHED.items() for n in (d, *cs)))
    seconds: dict = {}
    for seed in seeds:
        for name in names:
            saved = networks.trained(seed, name, plan, views["train"], terms, progress)
            seconds.setdefault(name, {})[f"seed {seed}"] = saved["seconds_per_step"]
    tables, lfd = judge_seeds(
        plan, threads, seeds, lambda seed: {n: networks.get(seed, n)["model"] for n in names},
        test_set, views["test"], progress,
    )  # fmt: skip
    results = {
        **run_header("--controls", quick, seeds, dev, out, lfd),
        "steps": plan.steps,
        "matched": {d: list(cs) for d, cs in MATCHED.items()},
        "recipes": {n: [list(t) for t in by_name(n).terms] for n in names},
        "tables": {f"seed {s}": t for s, t in tables.items()},
        **summarise_controls(tables, test_set),
        "seconds_per_step": seconds,
        "seconds_total": time.perf_counter() - start,
    }
    return write_json(out / "controls.json", results)


def run_header(
    flag: str, quick: bool, seeds: tuple[int, ...], dev: torch.device, out: Path, lfd: str
) -> dict:
    """What every seeded run's JSON opens with: its command, the machine and device, the LFD
    judge it had (``Judge.lfd_note``) and its seeds."""
    return {
        "command": f"python bench/single_view.py{' --quick' if quick else ''} {flag} "
        f"--seeds {','.join(map(str, seeds))} --device {dev.type} --out {out}",
        **machine(),
        "device": "cpu" if dev.type == "cpu" else torch.cuda.get_device_name(dev),
        "lfd": lfd,
        "seeds": list(seeds),
    }


def write_json(path: Path, results: dict) -> dict:
    """``results`` written to ``path`` (its folder made), and returned."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=1))
    return results


class SavedRunError(ValueError):
    """A run's JSON or networks missing from OUT, or not each other's."""


def sha256_of(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def saved_run(path: Path, again: str) -> dict:
    """The run ``path`` (its JSON), which names the sha256 of each network it judged;
    ``SavedRunError`` where it is missing or names none (``again``: the command that makes it,
    where the run does not name its own)."""
    if not path.is_file():
        raise SavedRunError(f"{path}: no run to judge again; {again} makes it")
    run = json.loads(path.read_text())
    if "networks" not in run:
        again = f"`{run['command']}`" if "command" in run else again
        raise SavedRunError(
            f"{path} names no digest of its networks, so those beside it may be others; "
            f"{again} judges them and names them"
        )
    return run


def checked(run: Path, network: Path, digest: str) -> str:
    """``network``'s sha256, where it is the one the run ``run`` judged (``digest``);
    ``SavedRunError`` where it is missing or another."""
    found = sha256_of(network) if network.is_file() else None
    if found is None or found != digest:
        raise SavedRunError(f"{network}: not the network {run.name} judged")
    return found


def curve_control(out: Path) -> str:
    """The recipe's matched control closest by pooled LFD in OUT/controls.json, else
    ``CURVE_CONTROL``."""
    path = out / "controls.json"
    if not path.is_file():
        return CURVE_CONTROL
    pooled = json.loads(path.read_text())["means"]["pooled"]["mean"]
    controls = [c for c in MATCHED[RECIPE] if c != SOFTRAS and pooled[c]["LFD"] is not None]
    return min(controls, key=lambda c: pooled[c]["LFD"]) if controls else CURVE_CONTROL


def run_curve(
    out: Path,
    until: int = CURVE_POINTS[-1],
    seed: int = 0,
    state: Path = CURVE_STATE,
    quick: bool = False,
    device: str = "cpu",
    threads: int = 2,
    progress=print,
) -> dict:
    """The learning curve: each of ``CURVE_RECIPES`` and the recipe's best control trained in
    one run to the last of ``CURVE_POINTS`` (at most ``until``; the staged loss's progress over
    ``CURVE_PLAN_STEPS``), judged on the study's test shapes at each point -> OUT/curve.json and
    OUT/curve.png, rewritten after every point. Each
    run's training state and its network at each point are kept in ``state`` (outside the
    repository: 15 MB a state), so a stopped curve goes on where it stopped, bit for bit as a
    straight run, in this session or a later one on the same machine."""
    study_plan = QUICK if quick else FULL
    # quick: a point past the staged loss's steps too
    points, staged = (
        ([1, 2, 3], 2) if quick else ([p for p in CURVE_POINTS if p <= until], CURVE_PLAN_STEPS)
    )
    plan = replace(study_plan, steps=staged)
    dev = torch.device(device)
    test_set, views, terms = training_data(out, plan, dev)
    names = [*CURVE_RECIPES, curve_control(out)]
    key = f"{resume_key(plan)}; views {VIEW_CONFIG.to_json()}"
    judge = Judge(PipelineConfig(), threads, plan.unseen_views, plan.lfd, image_judges=False)
    path = out / "curve.json"
    done = json.loads(path.read_text()) if path.is_file() else {}
    rows = done.get("points", {}) if done.get("key") == key else {}
    truths: dict = {}
    try:
        for point in points:
            networks = Networks(state / f"networks-{point}-steps", plan, dev)
            for name in names:
                if networks.get(seed, name) is None:
                    saved = state / "states" / f"seed{seed}" / f"{slug(name)}.pt"
                    resume = torch.load(saved, weights_only=False) if saved.is_file() else None
                    if resume is not None and (
                        resume["key"] != key or len(resume["history"]) > point
                    ):
                        resume = None  # another plan's, or past this point: train afresh
                    # saved every CURVE_SAVE_EVERY steps: a stop loses at most that many
                    while True:
                        done_steps = len(resume["history"]) if resume else 0
                        stop = min(point, done_steps + CURVE_SAVE_EVERY)
                        recipe = by_name(name)
                        trained = train(plan, recipe, seed, views["train"], terms, progress,
                                        resume, until=stop)  # fmt: skip
                        resume = {**trained["state"], "key": key}
                        saved.parent.mkdir(parents=True, exist_ok=True)
                        torch.save(resume, saved.with_suffix(".tmp"))
                        saved.with_suffix(".tmp").replace(saved)
                        if len(trained["history"]) >= point:
                            break
                    networks.put(seed, name, trained)
            if str(point) in rows and set(rows[str(point)]["means"]) >= set(names):
                continue
            models = {n: networks.get(seed, n)["model"] for n in names}
            table = judge_all(judge, models, test_set, views["test"], truths, progress)
            rows[str(point)] = {
                "table": table,
                "means": means([table], test_set, names)["mean"],
                "seconds_per_step": {n: networks.get(seed, n)["seconds_per_step"] for n in names},
            }
            results = {
                "command": f"python bench/single_view.py{' --quick' if quick else ''} --curve "
                f"--until {until} --seeds {seed} --device {device} --out {out}",
                **machine(),
                "device": device if dev.type == "cpu" else torch.cuda.get_device_name(dev),
                "lfd": judge.lfd_note,
                "key": key,
                "seed": seed,
                "losses": names,
                "schedule": f"one run, judged at each point; the staged DR-KFS loss's "
                f"progress is the step over {plan.steps} steps, its fine stage past them",
                "points": dict(sorted(rows.items(), key=lambda kv: int(kv[0]))),
            }
            out.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(results, indent=1))
            draw_curve(out / "curve.png", results)
    finally:
        judge.close()
    return json.loads(path.read_text())


def draw_curve(path: Path, results: dict) -> None:
    """Each judge against steps (log scale), one line per loss."""
    from matplotlib.figure import Figure

    judges = ("LFD", "silhouette IoU", "Chamfer-L1", "F-score 1%")
    figure = Figure(figsize=(14, 3.6))
    steps = [int(p) for p in results["points"]]
    for i, metric in enumerate(judges):
        axes = figure.add_subplot(1, len(judges), i + 1)
        for name in results["losses"]:
            values = [results["points"][str(p)]["means"][name][metric] for p in steps]
            if any(v is not None for v in values):
                axes.plot(steps, values, marker="o", label=name)
        axes.set_xscale("log")
        # the judged points as plain numbers, without log scale's minor labels between them
        axes.set_xticks(steps, [f"{s:,}" for s in steps], fontsize=7)
        axes.minorticks_off()
        axes.set_xlabel("training steps")
        title = "unseen silhouette IoU" if metric == "silhouette IoU" else metric
        arrow = "higher is better" if metric in HIGHER_IS_BETTER else "lower is better"
        axes.set_title(f"{title} ({arrow})", fontsize=9)
    figure.axes[0].legend(fontsize=7)
    figure.tight_layout()
    figure.savefig(path, dpi=90)


def draw_gallery(out, plan, networks, seed, names, test_set, views) -> None:
    """OUT/gallery.png: the first test shape of each family, its input image (grey above
    alpha), each loss's reconstruction at ``seed`` and the truth, from the gallery's cameras."""
    picked = [i for i, s in enumerate(test_set) if i % plan.test_per_family == 0]
    azimuths = input_azimuths(test_set)
    faces = ShapeGenerator(CHANNELS, IMAGE_SIZE).faces.numpy()
    predictions = {n: reconstruct(networks.get(seed, n)["model"], views, azimuths) for n in names}
    rows = []
    for i in picked:
        image = views[i, azimuths[i]].reshape(-1, views.shape[-1]).numpy()
        meshes = [(predictions[n][i], faces) for n in names]
        rows.append((test_set[i].name, [image, *meshes, (test_set[i].verts, test_set[i].faces)]))
    write_gallery(out / "gallery.png", ["INPUT", *names, "TRUTH"], rows)


COLUMNS = (  # the paper's table's order: CD, F-score, NC, IoU, LFD; then unseen silhouettes
    ("Chamfer-L1", "CD-L1 ×100", 100.0, 2),
    ("F-score 1%", "F-score 1% ×100", 100.0, 1),
    ("normal consistency", "NC", 1.0, 3),
    ("volumetric IoU", "vol. IoU", 1.0, 3),
    ("LFD", "LFD", 1.0, 0),
    ("silhouette IoU", "unseen sil. IoU", 1.0, 3),
)


def table_cell(value: float | None, scale: float, digits: int) -> str:
    return "n/a" if value is None else f"{value * scale:,.{digits}f}"


def means_table(pooled: dict, first: str) -> list[str]:
    """The rows of a table of each network's pooled means (loss -> judge -> mean), in
    ``COLUMNS``' order, under a first column headed ``first``."""
    lines = [f"| {first} | " + " | ".join(c[1] for c in COLUMNS) + " |",
             "|---|" + "---:|" * len(COLUMNS)]  # fmt: skip
    for name, row in pooled.items():
        lines.append(f"| {name} | " + " | ".join(table_cell(row[m], s, d) for m, _, s, d in COLUMNS)
                     + " |")  # fmt: skip
    return lines


def wins_table(shares_by: dict, first: str) -> list[str]:
    """The rows of a table of each "challenger | against" pair's cells closer, pooled and (LFD,
    unseen silhouettes) per seed, from {"pooled" or "seed S": {pair: judge -> share}}."""
    judged = ("LFD", "silhouette IoU", "Chamfer-L1", "F-score 1%")
    seeds = [k for k in shares_by if k != "pooled"]
    lines = [f"| {first} | closer than | " + " | ".join(judged) + " | LFD by seed | "
             "unseen sil. by seed |", "|---|---|" + "---:|" * (len(judged) + 2)]  # fmt: skip
    for pair, row in shares_by["pooled"].items():
        challenger, against = pair.split(" | ")
        cells = " | ".join(f"{row[m]['wins']}/{row[m]['cells']}" for m in judged)
        by_seed = [" / ".join(str(shares_by[k][pair][m]["wins"]) for k in seeds)
                   for m in judged[:2]]  # fmt: skip
        lines.append(f"| {challenger} | {against} | {cells} | {' | '.join(by_seed)} |")
    return lines


def steps_markdown(run: dict) -> str:
    """bench/records/single_view.md's table of one --steps run (OUT/longer-<steps>-steps-
    seed<S>.json) or of its networks judged on other test shapes (``judge_longer``): each
    network's means over the test shapes, a loss's rows together, fewer steps first."""
    judged = [c for c in COLUMNS if c[0] not in ("normal consistency", "volumetric IoU")]
    rows = run["means"]["mean"]
    losses = list(dict.fromkeys(name.rsplit(", ", 1)[0] for name in rows))
    order = sorted(rows, key=lambda n: (losses.index(n.rsplit(", ", 1)[0]), int(n.split()[-2])))
    seeds = ", ".join(map(str, run.get("seeds", [run.get("seed")])))
    shapes = len(next(iter(run["tables"].values())) if "tables" in run else run["table"])
    other = f" from seed {run['test_seeds'][0]}" if "test_seeds" in run else ""
    head = f"| seed {seeds}, {shapes} test shapes{other} | "
    lines = [head + " | ".join(c[1] for c in judged) + " |", "|---|" + "---:|" * len(judged)]
    for name in order:
        cells = " | ".join(table_cell(rows[name][m], s, d) for m, _, s, d in judged)
        lines.append(f"| {name} | {cells} |")
    return "\n".join(lines) + "\n"


def tuned_nets_markdown(results: dict) -> str:
    """bench/records/single_view.md's tables of the nets fine-tuned for the loss at the
    study's steps, from ``results`` with their "steps" and each seed's "tables" (the --steps
    runs of ``EXTRA``, ``pooled_runs``, or their networks judged on other test shapes,
    OUT/longer-200-steps-test-seeds-<seed>.json): every network's means pooled over the seeds,
    and each tuned loss's cells closer than the same loss with the shipped nets and than
    SoftRas', pooled and per seed."""
    steps = results["steps"][1]

    def at(name: str) -> str:  # the runs' row names
        return f"{name}, {steps} steps"

    tuned = [r.name for r in EXTRA]
    shipped = {tuned[0]: DRKFS_SHADED, tuned[1]: RECIPE}
    rows = [at(n) for n in (SOFTRAS, DRKFS_SHADED, tuned[0], RECIPE, tuned[1])]
    tables = results["tables"]
    shapes = [Shape(n, n.split()[0], None, None) for n in next(iter(tables.values()))]
    pairs = [(at(n), at(against)) for n in tuned for against in (shipped[n], SOFTRAS)]
    per = {"pooled": list(tables.values()), **{key: [t] for key, t in tables.items()}}
    wins = {key: {f"{c} | {a}": shares(ts, c, a) for c, a in pairs} for key, ts in per.items()}
    pooled = means(per["pooled"], shapes, rows)["mean"]
    blocks = (means_table(pooled, "network"), wins_table(wins, "network"))
    return "\n\n".join("\n".join(block) for block in blocks) + "\n"


def pooled_runs(runs: list[dict]) -> dict:
    """The --steps runs (OUT/longer-<steps>-steps-seed<S>.json, one a seed) as one
    run's "steps" and "tables" (seed -> table)."""
    return {"steps": runs[0]["steps"], "tables": {f"seed {r['seed']}": r["table"] for r in runs}}


def markdown(results: dict) -> str:
    """bench/records/single_view.md's tables from a results.json: the paper's form pooled over
    seeds, per family and per seed, and the shares of test shapes where each DR-KFS network is
    closer than each baseline (bench/check_results.py checks the docs hold them)."""
    names = results["plan"]["losses"]
    header = "| loss | " + " | ".join(c[1] for c in COLUMNS) + " |"
    rule = "|---|" + "---:|" * len(COLUMNS)
    blocks = []
    means = results["means"]
    pooled = means["pooled"]
    for title, rows in (
        ("pooled over seeds, all families", [(n, pooled["mean"][n]) for n in names]),
        *(
            (f"pooled over seeds, {family}", [(n, pooled[family][n]) for n in names])
            for family in pooled if family != "mean"
        ),
        *(
            (f"{seed}, all families", [(n, means[seed]["mean"][n]) for n in names])
            for seed in results["tables"]
        ),
    ):  # fmt: skip
        lines = [f"**{title}**", "", header, rule]
        for name, row in rows:
            cells = " | ".join(table_cell(row[m], s, d) for m, _, s, d in COLUMNS)
            lines.append(f"| {name} | {cells} |")
        blocks.append("\n".join(lines))
    share_lines = [
        "| DR-KFS network | against | " + " | ".join(c[1] for c in COLUMNS) + " |",
        "|---|---|" + "---:|" * len(COLUMNS),
    ]
    for drkfs, against in results["shares"]["pooled"].items():
        for baseline, row in against.items():
            cells = " | ".join(
                "n/a" if row[m]["share"] is None else f"{row[m]['wins']}/{row[m]['cells']}"
                for m, *_ in COLUMNS
            )
            share_lines.append(f"| {drkfs} | {baseline} | {cells} |")
    blocks.append("\n".join(share_lines))
    return "\n\n".join(blocks) + "\n"


def _pooled_means(pooled: dict, names: list[str]) -> list[str]:
    """A markdown table's lines: each loss's means (``COLUMNS``) pooled over the seeds."""
    lines = ["| loss | " + " | ".join(c[1] for c in COLUMNS) + " |",
             "|---|" + "---:|" * len(COLUMNS)]  # fmt: skip
    for name in names:
        lines.append(f"| {name} | " + " | ".join(table_cell(pooled[name][m], s, d)
                                                   for m, _, s, d in COLUMNS) + " |")  # fmt: skip
    return lines


def test_seeds_markdown(results: dict) -> str:
    """bench/records/single_view.md's tables of the saved networks judged on other test shapes
    (OUT/test-seeds-<seed>.json): the study's losses' pooled means and each DR-KFS network's
    cells closer than each baseline; then the controls' tables (``controls_markdown``) where
    they were judged (bench/check_results.py checks the docs hold them)."""
    pooled = results["means"]["pooled"]["mean"]
    lines = _pooled_means(pooled, list(pooled))
    judged = ("LFD", "silhouette IoU", "Chamfer-L1")
    wins = ["| DR-KFS network | against | " + " | ".join(judged) + " |",
            "|---|---|" + "---:|" * len(judged)]  # fmt: skip
    for network, against in results["shares"]["pooled"].items():
        for baseline, row in against.items():
            cells = " | ".join(f"{row[m]['wins']}/{row[m]['cells']}" for m in judged)
            wins.append(f"| {network} | {baseline} | {cells} |")
    study = "\n\n".join("\n".join(block) for block in (lines, wins)) + "\n"
    return study + ("\n" + controls_markdown(results["controls"]) if "controls" in results else "")


def controls_markdown(results: dict) -> str:
    """bench/records/single_view.md's tables of the matched controls (OUT/controls.json): each
    recipe's and control's pooled means; each DR-KFS recipe's test cells closer than each of its
    controls, pooled and (LFD, unseen silhouettes) per seed; the goal (bench/check_results.py
    checks the docs hold them)."""
    lines = _pooled_means(results["means"]["pooled"]["mean"], list(results["recipes"]))
    judged = ("LFD", "silhouette IoU", "Chamfer-L1", "F-score 1%")
    seeds = [k for k in results["shares"] if k != "pooled"]
    wins = ["| DR-KFS recipe | against | " + " | ".join(judged) + " | LFD by seed | unseen sil."
            " by seed |", "|---|---|" + "---:|" * (len(judged) + 2)]  # fmt: skip
    for recipe, against in results["shares"]["pooled"].items():
        for control, row in against.items():
            cells = " | ".join(f"{row[m]['wins']}/{row[m]['cells']}" for m in judged)
            by_seed = [" / ".join(str(results["shares"][k][recipe][control][m]["wins"])
                                  for k in seeds) for m in judged[:2]]  # fmt: skip
            wins.append(f"| {recipe} | {control} | {cells} | {' | '.join(by_seed)} |")
    goal = ["| DR-KFS recipe | Chamfer-L1 over the best control's | goal met |", "|---|---:|---|"]
    for recipe, found in results["goal"].items():
        ratio = found["chamfer_l1_over_best_control"]
        goal.append(f"| {recipe} | {ratio:.3f} | {'yes' if found['met'] else 'no'} |")
    return "\n\n".join("\n".join(block) for block in (lines, wins, goal)) + "\n"


def curve_markdown(results: dict) -> str:
    """bench/records/single_view.md's learning-curve table (OUT/curve.json): each loss's pooled LFD,
    unseen silhouette IoU, Chamfer-L1 and F-score at every judged point."""
    judged = (("LFD", 1.0, 0), ("silhouette IoU", 1.0, 3), ("Chamfer-L1", 100.0, 2),
              ("F-score 1%", 100.0, 1))  # fmt: skip
    points = list(results["points"])
    head = " | ".join(f"{m} @ {p}" for m, *_ in judged for p in points)
    lines = [f"| loss | {head} |", "|---|" + "---:|" * (len(judged) * len(points))]
    for name in results["losses"]:
        cells = " | ".join(table_cell(results["points"][p]["means"][name][m], s, d)
                           for m, s, d in judged for p in points)  # fmt: skip
        lines.append(f"| {name} | {cells} |")
    return "\n".join(lines) + "\n"
