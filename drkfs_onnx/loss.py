"""DR-KFS as a training loss: the loss preset (``PipelineConfig.loss()``) run coarse to fine.

    loss = DrkfsLoss.pretrained()  # an nn.Module: .to("cuda") moves its nets and cameras
    target = loss.target(truth_verts, truth_faces)  # once per ground truth, no autograd
    value = loss(pred_verts, pred_faces, target, progress=step / steps)

A batch is one call: predictions as (B, V, 3) vertices with one (F, 3) face tensor, or meshes
of different sizes (lists, or PyTorch3D-like ``Meshes``; ``render.mesh_batch.MeshBatch``),
against one shared target or a batch of B targets prepared at once (``loss.target(truths_verts,
truths_faces)``); ``batch_reduction`` is 'mean' (default), 'sum' or 'none' ((B,) values).

Early in training (``progress`` below a stage's ``until``) the views are fewer pixels, more
cameras and a softer renderer, so a patch sees a larger part of the shape and a silhouette
reaches further; then the loss preset itself. A soft best match (``SoftMatch``: a softmin over a
patch's candidates whose temperature falls as training goes) is an option for windows of r1 or
more, not the preset: fitting one mesh it ranked first, training networks it did far worse than
the preset (bench/records/fitting.md). ``view_groups`` scores each step from one group of a
stage's cameras, drawn at random: a step that costs about that share of the render and the nets,
and equals the loss on average over the groups.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from .contract.config import PipelineConfig
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
    training (``match.soft_match_distances``)."""

    start: float = 0.1
    end: float = 0.01

    def temperature(self, progress: float) -> float:
        return self.start * (self.end / self.start) ** min(max(progress, 0.0), 1.0)


class StagedTarget(tuple):
    """A ground truth (or a batch of them) prepared for each stage of a ``DrkfsLoss``: one
    ``Target`` per stage; ``to(device)`` moves them all."""

    def to(self, device: torch.device | str) -> StagedTarget:
        return StagedTarget(target.to(device) for target in self)

    @staticmethod
    def stack(targets: list[StagedTarget]) -> StagedTarget:
        """One ground truth each -> a batch of them, stage by stage (``Target.stack``)."""
        return StagedTarget(map(Target.stack, zip(*targets, strict=True)))


class DrkfsLoss(nn.Module):
    """DR-KFS of predictions against prepared ground truths, stage by stage; build it with
    ``pretrained`` (the shipped nets) or ``from_nets``.

    Args:
        metrics: one ``DRKFS`` per stage, at the stage's config.
        stages: each stage's config and the ``progress`` it runs until (the last to 1.0).
        soft: soft best matches whose temperature falls with ``progress``, or None (hard).
        view_groups: each call scores from one of this many groups of each stage's cameras
            (camera k in group k mod ``view_groups``), drawn at random: a cheaper step whose
            mean over the groups is the loss (``DRKFS.score_to``'s ``cameras``); 1, every
            camera each call. It must divide every stage's camera count.
        generator: what draws the groups (a training's own, to repeat its draws); a new one
            seeded 0 when None.

    Shape:
        - target(verts (V, 3), faces (F, 3)) -> ``StagedTarget``, one ``Target`` per stage; a
          batch of B truths (any form ``MeshBatch.of`` takes) -> B targets, one per prediction.
        - forward(verts, faces, target, progress=1.0, batch_reduction='mean'): verts (V, 3) and
          faces (F, 3), or a batch; ``progress`` in [0, 1] is how far training has come
          (past 1: the last stage, for a training run on past its schedule).
        - output: () for one mesh; a batch's () mean or sum, or its (B,) values ('none').
          Differentiable with respect to ``verts``.

    The stages' metrics are a ``ModuleList``, their cameras and match tables buffers:
    ``.to()``, ``.cuda()`` and ``state_dict()`` behave as for any module.
    """

    def __init__(
        self,
        metrics: list[DRKFS],
        stages: tuple[Stage, ...],
        soft: SoftMatch | None,
        view_groups: int = 1,
        generator: torch.Generator | None = None,
    ):
        super().__init__()
        if len(metrics) != len(stages) or stages[-1].until < 1.0:
            raise ValueError("one metric per stage, and the last stage must run to the end (1.0)")
        counts = [s.config.num_views for s in stages]
        if view_groups < 1 or any(count % view_groups for count in counts):
            raise ValueError(
                f"view_groups: a divisor of every stage's camera count ({counts}); "
                f"got {view_groups}"
            )
        self.metrics = nn.ModuleList(metrics)
        self.stages, self.soft, self.view_groups = stages, soft, view_groups
        self.generator = torch.Generator().manual_seed(0) if generator is None else generator

    @classmethod
    def pretrained(
        cls,
        stages: tuple[Stage, ...] = COARSE_TO_FINE,
        soft: SoftMatch | None = None,
        normalization: str = "joint",
        conv_precision: str = "ieee",
        view_groups: int = 1,
    ) -> DrkfsLoss:
        """The shipped nets at each stage's config (``DRKFS.pretrained``); ``conv_precision``
        as ``DRKFS``'s."""
        metrics = [
            DRKFS.pretrained(s.config, normalization=normalization, conv_precision=conv_precision)
            for s in stages
        ]
        return cls(metrics, stages, soft, view_groups)

    @classmethod
    def from_nets(
        cls,
        nets: DRKFS,
        stages: tuple[Stage, ...] = COARSE_TO_FINE,
        soft: SoftMatch | None = None,
        view_groups: int = 1,
    ) -> DrkfsLoss:
        """Copies of ``nets``' detector and HardNet at each stage's config, with its
        normalisation and conv precision: nets of one's own (fine-tuned for the loss, say) in
        place of the shipped ones."""
        options = dict(normalization=nets.normalization, conv_precision=nets.conv_precision)
        metrics = [with_nets(s.config, nets.detector, nets.descriptor, **options) for s in stages]
        return cls(metrics, stages, soft, view_groups)

    def stage(self, progress: float) -> int:
        return next(i for i, s in enumerate(self.stages) if progress < s.until or s.until >= 1.0)

    @torch.no_grad()
    def target(self, verts, faces=None) -> StagedTarget:
        """One ground truth, (V, 3) and (F, 3), to share with every prediction; or a batch of
        them (one per prediction, any form ``MeshBatch.of`` takes), described once."""
        return StagedTarget(metric.target(verts, faces) for metric in self.metrics)

    def forward(
        self,
        verts,
        faces,
        target: StagedTarget | list[Target],
        progress: float = 1.0,
        batch_reduction: str = "mean",
    ) -> torch.Tensor:
        staged = isinstance(target, (list, tuple)) and not isinstance(target, Target)
        if not (staged and len(target) == len(self.stages)
                and all(isinstance(t, Target) for t in target)):  # fmt: skip
            raise ValueError(
                f"target: expected the StagedTarget this loss's target() makes (one Target for "
                f"each of its {len(self.stages)} stages); got {type(target).__name__}"
            )
        index = self.stage(progress)
        temperature = None if self.soft is None else self.soft.temperature(progress)
        metric, cameras = self.metrics[index], None
        if self.view_groups > 1:
            draw = dict(generator=self.generator, device=self.generator.device)
            group = int(torch.randint(self.view_groups, (), **draw))
            cameras = list(range(group, metric.config.num_views, self.view_groups))
        return metric.score_to(verts, faces, target[index], batch_reduction, temperature, cameras)
