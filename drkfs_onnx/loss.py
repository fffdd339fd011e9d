"""DR-KFS as a training loss: the loss preset (``PipelineConfig.loss()``) run coarse to fine.

    loss = DrkfsLoss.pretrained()  # .to("cuda") moves its nets to a GPU
    target = loss.target(truth_verts, truth_faces)  # once per ground truth, no autograd
    value = loss(pred_verts, pred_faces, target, progress=step / steps)

Early in training (``progress`` below a stage's ``until``) the views are fewer pixels, more
cameras and a softer renderer, so a patch sees a larger part of the shape and a silhouette
reaches further; then the loss preset itself. A soft best match (``SoftMatch``: a softmin over a
patch's candidates whose temperature falls as training goes) is an option for windows of r1 or
more, not the preset: fitting one mesh it ranked first, training networks it did far worse than
the preset (docs/fitting.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from .config import PipelineConfig
from .matching import match_score
from .metric import DRKFS, Target, with_nets


@dataclass(frozen=True)
class Stage:
    """A config the loss runs at until ``until`` (a share of training, in (0, 1])."""

    config: PipelineConfig
    until: float


# 64 px views (3 x 3 patches each), 12 cameras and a renderer 10x softer, for the first 40% of
# training; then the loss preset
COARSE_TO_FINE = (
    Stage(PipelineConfig.loss(num_views=12, image_size=64, sigma=1e-3, gamma=0.3), 0.4),
    Stage(PipelineConfig.loss(), 1.0),
)


@dataclass(frozen=True)
class SoftMatch:
    """A soft best match whose temperature falls geometrically from ``start`` to ``end`` over
    training (``matching.soft_match_distances``)."""

    start: float = 0.1
    end: float = 0.01

    def temperature(self, progress: float) -> float:
        return self.start * (self.end / self.start) ** min(max(progress, 0.0), 1.0)


class DrkfsLoss:
    """DR-KFS of a prediction against a prepared ground truth, stage by stage.

    ``target(verts (V, 3), faces (F, 3)) -> [Target]`` (one per stage) and ``__call__(verts,
    faces, target, progress) -> ()``, differentiable with respect to ``verts``; ``progress`` in
    [0, 1] is how far training has come (1: the last stage). ``to(device)`` moves the nets, as
    ``nn.Module.to`` does; a target lives on the device of the mesh it was prepared from.
    """

    def __init__(self, metrics: list[DRKFS], stages: tuple[Stage, ...], soft: SoftMatch | None):
        if len(metrics) != len(stages) or stages[-1].until < 1.0:
            raise ValueError("one metric per stage, and the last stage must run to the end (1.0)")
        self.metrics, self.stages, self.soft = metrics, stages, soft

    @classmethod
    def pretrained(
        cls,
        stages: tuple[Stage, ...] = COARSE_TO_FINE,
        soft: SoftMatch | None = None,
        normalization: str = "joint",
    ) -> DrkfsLoss:
        """The shipped nets at each stage's config (``DRKFS.pretrained``)."""
        metrics = [DRKFS.pretrained(s.config, normalization=normalization) for s in stages]
        return cls(metrics, stages, soft)

    @classmethod
    def from_nets(
        cls,
        nets: DRKFS,
        stages: tuple[Stage, ...] = COARSE_TO_FINE,
        soft: SoftMatch | None = None,
    ) -> DrkfsLoss:
        """Copies of ``nets``' detector and HardNet at each stage's config: nets of one's own
        (fine-tuned for the loss, say) in place of the shipped ones."""
        metrics = [with_nets(s.config, nets.detector, nets.descriptor) for s in stages]
        return cls(metrics, stages, soft)

    def to(self, device: torch.device | str) -> DrkfsLoss:
        for metric in self.metrics:
            metric.to(device)
        return self

    def stage(self, progress: float) -> int:
        return next(i for i, s in enumerate(self.stages) if progress < s.until or s.until >= 1.0)

    @torch.no_grad()
    def target(self, verts: torch.Tensor, faces: torch.Tensor) -> list[Target]:
        return [metric.target(verts, faces) for metric in self.metrics]

    def __call__(
        self, verts: torch.Tensor, faces: torch.Tensor, target: list[Target], progress: float = 1.0
    ) -> torch.Tensor:
        index = self.stage(progress)
        metric, prepared = self.metrics[index], target[index]
        features = metric.features_to(verts, faces, prepared)
        temperature = None if self.soft is None else self.soft.temperature(progress)
        return match_score(features, prepared.features, metric.config, temperature)
