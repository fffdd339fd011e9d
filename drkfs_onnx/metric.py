"""DR-KFS as a differentiable torch module: mesh -> views -> PoI maps -> patches -> descriptors
-> best matches -> score."""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import nn

from . import match_rules
from .config import PipelineConfig
from .detector import PoIDetector
from .hardnet import HardNet
from .matching import best_match_distances, match_score
from .mesh import Mesh, check_normalization, normalize_pair, place_by, reference_frame
from .patches import nonempty_patches, select_patches
from .render import Renderer
from .weights import RANDOM_SEED, load_shipped_state


class MissingWeights(ValueError):
    """No shipped weights serve the asked config."""


class Target(NamedTuple):
    """A reference mesh prepared once: the frame predictions are placed in, and its (N, D)
    descriptors."""

    frame: tuple[torch.Tensor, torch.Tensor] | None
    features: torch.Tensor


class DRKFS(nn.Module):
    """The DR-KFS visual distance between two triangle meshes.

    ``forward(verts_a (Va, 3), faces_a (Fa, 3), verts_b (Vb, 3), faces_b (Fb, 3)) -> ()`` is
    differentiable with respect to both vertex tensors. B is the reference: with
    ``normalization='joint'`` both meshes are placed by B's bounding box, whichever directions
    the config's match searches. The config holds every setting of the score (matching,
    reduction, direction); ``PipelineConfig.paper()`` is the paper's recipe.

    As a training loss against a fixed ground truth, prepare it once with ``target`` and call
    ``score_to(verts, faces, target)`` each step: the truth is rendered and described once.

    The detector and descriptor are frozen and always run in evaluation mode; use
    ``DRKFS.pretrained()`` for the shipped weights.
    """

    def __init__(self, config: PipelineConfig | None = None, normalization: str = "joint"):
        super().__init__()
        self.config = config or PipelineConfig()
        self.normalization = check_normalization(normalization)
        self.renderer = Renderer(self.config)
        self.detector = PoIDetector(self.config)
        # channels-last convs run ~1.4x faster on CPU for HardNet's many small patches
        self.descriptor = HardNet(self.config).to(memory_format=torch.channels_last)
        self.requires_grad_(False)
        self.train(False)

    @classmethod
    def pretrained(
        cls, config: PipelineConfig | None = None, random_weights: bool = False, **options
    ) -> DRKFS:
        """The metric with the weights shipped in ``models/``, sha256-checked against the
        manifest (a mismatch raises ValueError).

        Weights trained at another view count, image size, renderer softness (sigma, gamma) or
        match serve a config that differs only there (the nets are the same). Without shipped
        weights for the config this raises ``MissingWeights``, unless ``random_weights=True``
        asks for nets initialised from torch.manual_seed(RANDOM_SEED): deterministic, but
        random.
        """
        config = config or PipelineConfig()
        state = load_shipped_state(config, any_rendering=True)
        if state is None:
            if not random_weights:
                nets = config.features_part()
                raise MissingWeights(
                    f"no trained weights in models/ for {nets.nets} nets at width "
                    f"{nets.descriptor_width:g}, detector {nets.detector_n}x{nets.detector_m} "
                    f"{nets.detector_kernel}x{nets.detector_kernel}, descriptor dim "
                    f"{nets.descriptor_dim}: train them (drkfs train --out models), or pass "
                    "random_weights=True for seeded random nets"
                )
            with torch.random.fork_rng():
                torch.manual_seed(RANDOM_SEED)
                return cls(config, **options)
        metric = cls(config, **options)
        metric.load_state_dict(state)
        return metric

    def train(self, mode: bool = True) -> DRKFS:
        """The feature nets stay in evaluation mode: the metric is a fixed function."""
        super().train(mode)
        self.detector.eval()
        self.descriptor.eval()
        return self

    def render(self, verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
        """(V, 3), (F, 3) -> (K, 1, S, S) grey views."""
        return self.renderer.render(verts, faces).unsqueeze(1)

    def describe(self, images: torch.Tensor) -> torch.Tensor:
        """(K, 1, S, S) views -> (K * P, D) patch descriptors, row-major per view.

        Patches that see only background share one descriptor, computed once.
        """
        dtype = next(self.detector.parameters()).dtype
        images = images.to(dtype)
        index = torch.nonzero(nonempty_patches(images, self.config)).squeeze(1)
        size = self.config.patch_size
        blank = torch.full(
            (1, 1, size, size), self.config.background, dtype=dtype, device=images.device
        )
        empty = self.descriptor(self.detector(blank))
        descriptors = empty.expand(len(images) * self.config.patches_per_view, -1)
        if len(index) == 0:
            return descriptors
        seen = select_patches(self.detector(images), index, self.config)
        return descriptors.index_put(
            (index,), self.descriptor(seen.contiguous(memory_format=torch.channels_last))
        )

    def features(self, verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
        """Descriptors of a mesh already in the metric's frame: (V, 3), (F, 3) -> (K * P, D)."""
        return self.describe(self.render(verts, faces))

    def score_meshes(self, a: Mesh, b: Mesh) -> float:
        """Evaluation-only score of checked meshes (float32, no autograd), as ``forward``."""
        # placed in float64 first: float32 coordinates far from the origin lose the detail
        verts_a, verts_b = normalize_pair(a.vertices, b.vertices, self.normalization)
        with torch.no_grad():
            return float(
                self(
                    torch.as_tensor(verts_a, dtype=torch.float32),
                    torch.as_tensor(a.faces),
                    torch.as_tensor(verts_b, dtype=torch.float32),
                    torch.as_tensor(b.faces),
                )
            )

    def target(self, verts: torch.Tensor, faces: torch.Tensor) -> Target:
        """The reference mesh B, (V, 3), (F, 3), placed and described. Differentiable like
        ``forward``; call it under ``torch.no_grad()`` for a fixed ground truth."""
        frame = reference_frame(verts, self.normalization)
        return Target(frame, self.features(place_by(verts, self.normalization, frame), faces))

    def score_to(self, verts: torch.Tensor, faces: torch.Tensor, target: Target) -> torch.Tensor:
        """The score of mesh A, (V, 3), (F, 3), against a prepared reference -> ()."""
        return match_score(self.features_to(verts, faces, target), target.features, self.config)

    def patch_distances(
        self, verts: torch.Tensor, faces: torch.Tensor, target: Target
    ) -> dict[str, torch.Tensor]:
        """Where mesh A, (V, 3), (F, 3), differs from a prepared reference: {side: (K, n, n)}
        best-match squared distance of each patch of A ('a', searching the reference) and of
        the reference ('b', searching A), for the sides the config's direction searches
        (``match_rules.query_sides``); n patches per image side. Differentiable like
        ``score_to``; log them (or ``drkfs-score explain``'s picture) to see where a
        prediction is wrong."""
        config = self.config
        grid = (config.num_views, config.patches_per_side, config.patches_per_side)
        pairs = match_rules.directions(
            self.features_to(verts, faces, target), target.features, config
        )
        return {
            side: best_match_distances(queries, targets, config).reshape(grid)
            for side, (queries, targets) in zip(match_rules.query_sides(config), pairs, strict=True)
        }

    def features_to(self, verts: torch.Tensor, faces: torch.Tensor, target: Target):
        """(K * P, D) descriptors of mesh A, (V, 3), (F, 3), placed as the reference ``target``
        asks (its frame under 'joint')."""
        return self.features(place_by(verts, self.normalization, target.frame), faces)

    def forward(
        self,
        verts_a: torch.Tensor,
        faces_a: torch.Tensor,
        verts_b: torch.Tensor,
        faces_b: torch.Tensor,
    ) -> torch.Tensor:
        return self.score_to(verts_a, faces_a, self.target(verts_b, faces_b))


def with_nets(config: PipelineConfig, detector: nn.Module, descriptor: nn.Module) -> DRKFS:
    """A DRKFS at ``config`` carrying copies of the given detector and HardNet."""
    metric = DRKFS(config)
    metric.detector.load_state_dict(detector.state_dict())
    metric.descriptor.load_state_dict(descriptor.state_dict())
    return metric
