"""The losses a template is fitted with, and the loop that fits it.

Every loss sees only the predicted vertices; the target is prepared once when the loss is
built. An ``Objective`` divides each term by its value at the template, so one smoothness
weight and one learning rate serve losses whose raw scales differ by orders of magnitude.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import torch

from drkfs_lab.benchmark.point_metrics import sample_surface
from drkfs_onnx.geometry import Smoothness, chamfer, surface_points
from drkfs_onnx.loss import DrkfsLoss
from drkfs_onnx.metric import DRKFS

CHAMFER_SAMPLES = 2000  # points drawn on the prediction each step
TARGET_SAMPLES = 5000  # points on the target, drawn once


def float_tensor(array: np.ndarray) -> torch.Tensor:
    return torch.as_tensor(np.asarray(array, dtype=np.float32))


@contextmanager
def deterministic_kernels() -> Iterator[None]:
    """Run the block on torch's deterministic kernels, then restore the caller's setting.

    Why: the backward of indexing a CPU tensor (``verts[faces]``) accumulates its float sums in
    an order that follows thread timing, so the same training ends elsewhere from run to run,
    most of all on a busy machine (bench/records/fitting.md, "This run is the first that
    reproduces")."""
    enabled = torch.are_deterministic_algorithms_enabled()
    warn_only = torch.is_deterministic_algorithms_warn_only_enabled()
    torch.use_deterministic_algorithms(True)
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(enabled, warn_only=warn_only)


class DrkfsTerm:
    """A DR-KFS loss form (``loss.DrkfsLoss``: its stages and match) of the prediction against
    the target, prepared once; ``at(progress)`` says how far the fit has come."""

    def __init__(self, loss: DrkfsLoss, target_verts: np.ndarray, target_faces: np.ndarray, faces):
        self.loss, self.faces, self.progress = loss, faces, 0.0
        self.target = loss.target(float_tensor(target_verts), torch.as_tensor(target_faces))

    def at(self, progress: float) -> None:
        self.progress = progress

    def __call__(self, verts: torch.Tensor) -> torch.Tensor:
        return self.loss(verts, self.faces, self.target, self.progress)


class ChamferLoss:
    """Squared Chamfer distance between fresh samples of the prediction and fixed target ones."""

    def __init__(self, target_verts: np.ndarray, target_faces: np.ndarray, faces, seed: int = 0):
        self.faces = faces
        samples = sample_surface(target_verts, target_faces, TARGET_SAMPLES)
        self.targets = float_tensor(samples.points)
        self.generator = torch.Generator().manual_seed(seed)

    def __call__(self, verts: torch.Tensor) -> torch.Tensor:
        points = surface_points(verts, self.faces, CHAMFER_SAMPLES, self.generator)
        return chamfer(points, self.targets)


class PixelLoss:
    """Mean squared difference of the metric's own renders (same cameras, light, rasteriser)."""

    def __init__(self, metric: DRKFS, target_verts: np.ndarray, target_faces: np.ndarray, faces):
        self.metric, self.faces = metric, faces
        with torch.no_grad():
            self.target = metric.render(float_tensor(target_verts), torch.as_tensor(target_faces))

    def __call__(self, verts: torch.Tensor) -> torch.Tensor:
        return ((self.metric.render(verts, self.faces) - self.target) ** 2).mean()


@dataclass(frozen=True)
class Fade:
    """A weight that falls linearly from 1 at ``start`` to 0 at ``end`` (shares of the fit)."""

    start: float
    end: float

    def factor(self, progress: float) -> float:
        return float(np.clip((self.end - progress) / (self.end - self.start), 0.0, 1.0))


class Objective:
    """sum_i fade_i * weight_i * loss_i(verts) / loss_i(template): each term starts at its
    weight (a staged term at its first stage; its later stages keep that scale); a term with a
    ``Fade`` falls to 0 over the fit and is not computed once it is 0."""

    def __init__(
        self,
        terms: list[tuple[float, object]],
        template: torch.Tensor,
        fades: list[Fade | None] | None = None,
    ):
        self.terms = terms
        self.fades = fades or [None] * len(terms)
        self.at(0.0)
        with torch.no_grad():
            self.scales = [max(float(loss(template)), 1e-12) for _, loss in terms]

    def at(self, progress: float) -> None:
        """Tell the terms that change with training (``DrkfsTerm``) how far the fit has come."""
        self.factors = [1.0 if fade is None else fade.factor(progress) for fade in self.fades]
        for _, loss in self.terms:
            if isinstance(loss, DrkfsTerm):
                loss.at(progress)

    def __call__(self, verts: torch.Tensor) -> torch.Tensor:
        parts = [
            f * w * loss(verts) / s
            for (w, loss), s, f in zip(self.terms, self.scales, self.factors, strict=True)
            if f > 0.0
        ]
        return torch.stack(parts).sum()


@dataclass(frozen=True)
class FitSettings:
    steps: int = 100
    learning_rate: float = 0.005  # Adam, in units of the target's normalised frame (radius 1)
    smoothness: float = 100.0  # weight of Smoothness beside an objective that starts at 1


@dataclass
class FitResult:
    verts: np.ndarray  # (V, 3) float64, the fitted template
    objective: list[float]  # the objective (without smoothness) at every step
    seconds_per_step: float


Watch = Callable[[int, torch.Tensor, torch.Tensor], None]


@deterministic_kernels()
def fit_mesh(
    objective: Objective,
    template: torch.Tensor,
    faces: torch.Tensor,
    settings: FitSettings,
    watch: Watch | None = None,
    total_steps: int | None = None,
) -> FitResult:
    """Optimise per-vertex offsets of ``template`` (V, 3) with Adam; the loss each step is
    objective + smoothness * Smoothness. ``watch(step, verts (V, 3), delta (V, 3))`` sees each
    step's starting vertices and the move the optimiser made from them. A staged objective is
    told each step's progress, step / ``total_steps`` (default: the settings' steps; the first
    steps of a longer fit pass its length). It runs on deterministic kernels, so a rerun ends
    on the same vertices."""
    smooth = Smoothness(template, faces)
    offsets = torch.zeros_like(template, requires_grad=True)
    optimizer = torch.optim.Adam([offsets], lr=settings.learning_rate)
    history = []
    start = time.perf_counter()
    for step in range(settings.steps):
        objective.at(step / (total_steps or settings.steps))
        verts = template + offsets
        value = objective(verts)
        loss = value + settings.smoothness * smooth(verts)
        optimizer.zero_grad()
        loss.backward()
        before = offsets.detach().clone()
        optimizer.step()
        history.append(float(value.detach()))
        if watch is not None:
            watch(step, template + before, offsets.detach() - before)
    seconds = (time.perf_counter() - start) / max(settings.steps, 1)
    verts = (template + offsets).detach().numpy().astype(np.float64)
    return FitResult(verts, history, seconds)
