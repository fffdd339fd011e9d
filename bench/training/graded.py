"""Nets fine-tuned for the loss: graded series of edits, and an objective that asks the loss's
descriptor distances to grow with the edit at least as fast as pixel MSE's do.

The idea (bench/records/fitting.md, "Nets fine-tuned for the loss"): the scoring nets learn to
ignore mild edits, while a loss must feel every step towards its target. Here one part of a base
shape is shifted, thickened or shrunk away (its last grade: removed), or the whole surface is
roughened, at GRADES strengths, from what a fit's last steps leave to what its first steps face.
Rendered at the loss's config, each patch's squared aligned descriptor distance should grow at least
ELASTICITY times as fast (log over log) as the patch's pixel change, and the loss's score should
grow from one grade to the next. ``bench/loss_nets.py`` measures the shipped and the fine-tuned nets
(bench/records/fitting.md).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
import trimesh

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import frame_of
from drkfs_onnx.match import descriptor_score
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.render.renderer import Renderer
from drkfs_onnx.synthetic.shapes import Part, assemble, random_shape
from drkfs_onnx.synthetic.variants import diagonal, shifted, thickened, without

from .data import views_in_frame
from .metric_losses import LossFn, ranking_loss
from .run import train_steps

# seeds of the bases: disjoint from the nets' other stages (0-2), the fitting problems (3), the
# benchmark (2026-2028), the held-out checks (3000-3002) and the network study (4000+)
TRAIN_SEED, HELDOUT_SEED = 6, 7
TRAIN_SHAPES, HELDOUT_SHAPES = 2, 1  # bases per family
FINE_TUNE_STEPS, FINE_TUNE_RATE = 200, 1e-4  # Adam on the loss's nets
# each series' strengths, weakest first, from what a fit's last steps leave to what its first
# steps face: shift (share of the diagonal), thickening (factor), shrinking (the part's size
# factor; 0: removed), normal noise (share of the diagonal)
GRADES = {
    "shifted": (0.0025, 0.005, 0.01, 0.02, 0.04, 0.08),
    "thickened": (1.025, 1.05, 1.1, 1.2, 1.4, 1.8),
    "shrunk": (0.95, 0.9, 0.8, 0.6, 0.3, 0.0),
    "noisy": (0.00025, 0.0005, 0.001, 0.002, 0.004, 0.008),
}
GROWTH = 1.2  # a patch's pixel change counts as grown when it is at least this much larger
CHANGE_EPS = 1e-3  # mean absolute pixel change below which a patch is unchanged
SCENE_MARGIN = float(np.log(1.2))  # each grade's score >= 1.2x the previous one's
# a patch's squared descriptor distance should grow at least as fast as its squared pixel
# change (pixel MSE's rate): d(g+1) / d(g) >= (change(g+1) / change(g)) ** ELASTICITY
ELASTICITY = 2.0


@dataclass
class GradedViews:
    """N series, each a base and its len(grades) edits of one kind from the config's K cameras.

    images: (N, 1 + G, K, S, S) float32, the base first; kind: (N,) index into GRADES.
    """

    images: torch.Tensor
    kind: torch.Tensor

    def __len__(self) -> int:
        return len(self.images)


def _scaled(parts: list[Part], name: str, factor: float) -> list[Part]:
    """The part ``name`` shrunk (or grown) about its centre; at factor 0, removed."""
    if factor == 0:
        return without(parts, name)
    return [replace(p, size=tuple(factor * s for s in p.size)) if p.name == name else p
            for p in parts]  # fmt: skip


def _series(parts: list[Part], kind: str, rng: np.random.Generator) -> list[tuple]:
    """The base and its graded edits of ``kind``, as (verts, faces), the base first."""
    grades, size = GRADES[kind], diagonal(parts)
    if kind == "noisy":  # a finer surface, so the noise roughens the shading, not the outline
        verts, faces = assemble(parts, 2)
        normals = trimesh.Trimesh(verts, faces, process=False).vertex_normals
        field = rng.normal(size=(len(verts), 1)) * normals * size
        return [(verts, faces)] + [(verts + g * field, faces) for g in grades]
    name = parts[int(rng.integers(len(parts)))].name
    if kind == "shifted":
        direction = rng.normal(size=3)
        direction *= size / np.linalg.norm(direction)
        edited = [shifted(parts, name, tuple(g * direction)) for g in grades]
    elif kind == "thickened":
        edited = [thickened(parts, name, g) for g in grades]
    else:
        edited = [_scaled(parts, name, g) for g in grades]
    return [assemble(p, 1) for p in [parts, *edited]]


@torch.no_grad()
def render_graded_views(
    config: PipelineConfig, families: list[str], shapes_per_family: int, seed: int
) -> GradedViews:
    """``shapes_per_family`` bases of each family (drawn from ``seed``), each with one series of
    every kind in GRADES, every mesh placed in its base's frame as the loss places a fit."""
    rng = np.random.default_rng(seed)
    renderer = Renderer(config)
    images, kinds = [], []
    for family in families:
        for _ in range(shapes_per_family):
            parts = random_shape(family, rng)
            frame = frame_of(assemble(parts, 1)[0])
            for k, kind in enumerate(GRADES):
                meshes = _series(parts, kind, rng)
                images.append(views_in_frame(renderer, meshes, frame))
                kinds.append(k)
    return GradedViews(torch.stack(images), torch.tensor(kinds))


def patch_change(images: torch.Tensor, config: PipelineConfig) -> torch.Tensor:
    """(1 + G, K, S, S) a series' views -> (G, K * P) each edit's mean absolute pixel change
    from the base, per patch of the metric's grid."""
    size, stride = config.patch_size, config.patch_stride
    change = (images[1:] - images[:1]).abs().flatten(0, 1)[:, None]
    return F.avg_pool2d(change, size, stride).reshape(len(images) - 1, -1)


def graded_terms(metric: DRKFS, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(1 + G, K, S, S) a series' views -> the loss's score of each edit against the base (G,)
    and each patch's aligned squared descriptor distance (G, K * P)."""
    reference = metric.describe(images[0][:, None])
    described = [metric.describe(edit[:, None]) for edit in images[1:]]
    scores = torch.stack([descriptor_score(d, reference, metric.config) for d in described])
    distances = torch.stack([((d - reference) ** 2).sum(-1) for d in described])
    return scores, distances


def grown_pairs(change: torch.Tensor) -> torch.Tensor:
    """(G, K * P) pixel change -> (G - 1, K * P) bool: where grade g changed the patch visibly
    and grade g + 1 GROWTH times more (a patch that grade g left alone has no rate to ask)."""
    return (change[1:] > GROWTH * change[:-1]) & (change[:-1] > CHANGE_EPS)


def log_growth(values: torch.Tensor) -> torch.Tensor:
    """(G, ...) -> (G - 1, ...) log(values[g + 1] / values[g])."""
    logs = values.clamp_min(1e-12).log()
    return logs[1:] - logs[:-1]


def patch_elasticity(distances: torch.Tensor, change: torch.Tensor) -> torch.Tensor:
    """(G, K * P) distances and pixel changes -> (n,) how fast each patch's distance grew for
    how much its pixels' change grew, log over log, where it grew (``grown_pairs``)."""
    grown = grown_pairs(change)
    return log_growth(distances)[grown] / log_growth(change)[grown]


def series_loss(metric: DRKFS, images: torch.Tensor) -> torch.Tensor:
    """(1 + G, K, S, S) a series' views -> () ``graded_objective`` of its terms."""
    scores, distances = graded_terms(metric, images)
    return graded_objective(scores, distances, patch_change(images, metric.config))


def graded_objective(
    scores: torch.Tensor, distances: torch.Tensor, change: torch.Tensor
) -> torch.Tensor:
    """(G,) scores, (G, K * P) distances and pixel changes -> () each grade's score ranked above
    the previous grade's (SCENE_MARGIN), plus each patch's distance growing at least ELASTICITY
    times as fast as its pixel change, where that grew; both hinges on log ratios, so scaling
    the descriptors cannot win."""
    loss = torch.stack([
        ranking_loss(scores[g : g + 1], scores[g + 1 : g + 2], SCENE_MARGIN)
        for g in range(len(scores) - 1)
    ]).mean()  # fmt: skip
    return loss + patch_hinge(distances, change)


def patch_hinge(distances: torch.Tensor, change: torch.Tensor) -> torch.Tensor:
    """(G, K * P) distances and pixel changes -> () mean over ``grown_pairs`` of
    max(0, ELASTICITY * log-growth of the change - log-growth of the distance); 0 with none."""
    grown = grown_pairs(change)
    if not grown.any():
        return distances.new_zeros(())
    wanted = ELASTICITY * log_growth(change)[grown]
    return (wanted - log_growth(distances)[grown]).clamp_min(0).mean()


def graded_monotone(data: GradedViews, seed: int) -> LossFn:
    """``series_loss`` of one series a step, drawn from ``seed`` and the step."""

    def loss_fn(metric: DRKFS, step: int) -> torch.Tensor:
        rng = np.random.default_rng([seed, 6, step])
        return series_loss(metric, data.images[int(rng.integers(len(data)))])

    return loss_fn


def fine_tune(data: GradedViews, steps: int, checkpoint: Path) -> DRKFS:
    """The loss's shipped nets (``PipelineConfig.loss()``) after ``steps`` of ``graded_monotone``
    on ``data``, resumable from ``checkpoint``."""
    metric = DRKFS.pretrained(PipelineConfig.loss())
    metric.detector.requires_grad_(True)
    metric.descriptor.requires_grad_(True)
    loss_fn = graded_monotone(data, TRAIN_SEED)
    train_steps(metric, loss_fn, steps, FINE_TUNE_RATE, checkpoint, 20)
    return metric.requires_grad_(False)


@torch.no_grad()
def grade_stats(metric: DRKFS, data: GradedViews) -> dict:
    """How ``metric``'s loss grows along the series, overall and per kind: the share of
    consecutive grades whose score grows, the share of patches whose distance grows where their
    pixels changed more, the median and 10th percentile of ``patch_elasticity``, and the mean
    ``series_loss`` (the fine-tuning objective)."""
    found = {kind: {"scene": [], "patch": [], "elasticity": [], "loss": []} for kind in GRADES}
    for images, k in zip(data.images, data.kind.tolist(), strict=True):
        scores, distances = graded_terms(metric, images)
        change = patch_change(images, metric.config)
        kind = found[list(GRADES)[k]]
        kind["scene"].append(scores[1:] > scores[:-1])
        kind["patch"].append((distances[1:] > distances[:-1])[grown_pairs(change)])
        kind["elasticity"].append(patch_elasticity(distances, change))
        kind["loss"].append(float(graded_objective(scores, distances, change)))

    def stats(scene: list, patch: list, elasticity: list, loss: list) -> dict:
        elastic = torch.cat(elasticity)
        return {
            "scene_grows": float(torch.cat(scene).float().mean()),
            "patch_grows": float(torch.cat(patch).float().mean()),
            "elasticity_median": float(elastic.median()),
            "elasticity_q10": float(elastic.quantile(0.1)),
            "patches": len(elastic),
            "objective": float(np.mean(loss)),
        }

    everything = {part: [x for f in found.values() for x in f[part]] for part in found["noisy"]}
    return {"all": stats(**everything), **{kind: stats(**f) for kind, f in found.items()}}
