"""DR-KFS as a differentiable torch module: mesh -> views -> PoI maps -> patches -> descriptors
-> best matches -> score."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import torch
from torch import nn

from .contract import match_rules
from .contract.alignment import SurfaceSamples, aligning_turn, reference_surface, turns_nothing
from .contract.config import PipelineConfig
from .contract.mesh import Mesh, check_normalization, normalize_pair, place_by, reference_frame
from .match import best_match_distances, match_score, pairing_scores, window_index
from .nets.detector import PoIDetector
from .nets.hardnet import HardNet
from .nets.patches import nonempty_patches_on_device, select_patches
from .nets.precision import check_conv_precision, conv_dtype, conv_precision
from .nets.weights import RANDOM_SEED, load_shipped_state
from .render.mesh_batch import MeshBatch, over_batch
from .render.renderer import Renderer, RenderMode
from .render.torch_ops import TORCH_OPS

# HardNet's patches per call on a CPU: a group's activations stay in cache, where the whole
# batch's do not (docs/design_notes.md)
CPU_PATCH_GROUP = 128
# On a GPU: groups bound the peak memory, where one group of a batch's every patch holds each
# conv's output for all of them at once, at about the same speed (docs/design_notes.md)
GPU_PATCH_GROUP = 2048


def _without_autocast(method: Callable) -> Callable:
    """A ``DRKFS`` method run with autocast off on the metric's device, so that it computes in
    float32 inside a caller's mixed precision (``torch.autocast``, a network's usual training
    step): there the renderer's camera transform, the nets and the match would run in float16
    or bfloat16, and the rasteriser's float32 sums failed on the mixed dtypes (bfloat16 on a
    CPU)."""

    @functools.wraps(method)
    def run(self: DRKFS, *args, **kwargs):
        with torch.autocast(self.window_table.device.type, enabled=False):
            return method(self, *args, **kwargs)

    return run


def _as_numpy(meshes: MeshBatch, index: int) -> tuple[np.ndarray, np.ndarray]:
    """Mesh ``index`` of a batch as float64 verts (V, 3) and faces (F, 3), detached (its
    padding faces have no area: no sample falls on them)."""
    verts = meshes.verts[index].detach().to("cpu", torch.float64).numpy()
    return verts, meshes.faces[index].cpu().numpy()


def _unbatched(meshes: MeshBatch, views: torch.Tensor | None) -> torch.Tensor | None:
    """A batch's (B, ...) views as ``meshes.unbatch`` gives its descriptors, or None."""
    return None if views is None else meshes.unbatch(views)


class MissingWeights(ValueError):
    """No shipped weights serve the asked config."""


class Target(NamedTuple):
    """A reference mesh prepared once: the frame predictions are placed in ((3,) centre, ()
    scale), its (N, D) descriptors and, for a config with a solid change, its (K * T, S, S)
    views (else None); or a batch of B references, one per prediction: (B, 3) and (B,) frames,
    (B, N, D) descriptors, (B, K * T, S, S) views. surface: for a config that turns a
    prediction onto its reference first, the samples of each reference's surface (one, or B)
    the turn is fitted to (``contract.alignment``; numpy, found without gradients), else None."""

    frame: tuple[torch.Tensor, torch.Tensor] | None
    features: torch.Tensor
    views: torch.Tensor | None = None
    surface: tuple[SurfaceSamples, ...] | None = None

    @property
    def batch(self) -> int | None:
        """How many references a batch holds; None for one reference, shared by a batch."""
        return len(self.features) if self.features.ndim == 3 else None

    def to(self, device: torch.device | str) -> Target:
        frame = None if self.frame is None else tuple(t.to(device) for t in self.frame)
        views = None if self.views is None else self.views.to(device)
        return Target(frame, self.features.to(device), views, self.surface)

    def of_views(self, views: list[int], config: PipelineConfig) -> Target:
        """The reference as the cameras at ``views`` (of a one-ring ``config``'s K) see it:
        those views' rows of its descriptors, and those views."""
        per_view = config.patches_per_view
        rows = torch.cat([torch.arange(k * per_view, (k + 1) * per_view) for k in views])
        features = self.features.index_select(-2, rows.to(self.features.device))
        seen = None if self.views is None else self.views[..., list(views), :, :]
        return Target(self.frame, features, seen, self.surface)

    @staticmethod
    def stack(targets: list[Target]) -> Target:
        """One reference each -> a batch of them, in order."""
        frames = [t.frame for t in targets]
        frame = None if frames[0] is None else tuple(map(torch.stack, zip(*frames, strict=True)))
        views = None if targets[0].views is None else torch.stack([t.views for t in targets])
        surface = None if targets[0].surface is None else sum((t.surface for t in targets), ())
        return Target(frame, torch.stack([t.features for t in targets]), views, surface)


class DRKFS(nn.Module):
    """The DR-KFS visual distance between two triangle meshes: render -> describe -> match ->
    reduce, differentiable with respect to both meshes' vertices.

    Args:
        config: every number of the score (cameras, renderer, nets, match, reduction);
            ``PipelineConfig()`` by default, ``PipelineConfig.paper()`` the paper's recipe.
        normalization: 'joint' places both meshes by the reference B's bounding box, 'each'
            each by its own, 'none' leaves them.
        conv_precision: the nets' convolutions: 'ieee' (float32; a batch's gradient that of
            the per-mesh loop), 'tf32' (on a GPU: faster, less exact) or 'bfloat16' (HardNet's
            convolutions in bfloat16: a cheaper training step on a CPU with AVX-512 BF16 or
            AMX, the loss near float32's, not equal to it; untested on a GPU).

    Shape:
        - verts_a, verts_b: (V, 3) one mesh, or a batch in any form ``MeshBatch.of`` takes
          ((B, V, 3) with shared (F, 3) faces, lists of meshes, PyTorch3D-like ``Meshes``).
          One reference B is shared by a batch of A.
        - faces_a, faces_b: (F, 3) int64, or None where the batch form carries its faces.
        - output: () for one mesh A; for a batch, () under ``batch_reduction`` 'mean' (the
          default) or 'sum', (B,) under 'none'.

    The detector and HardNet are frozen and always in evaluation mode: use
    ``DRKFS.pretrained()`` for the shipped weights. As a training loss against a fixed ground
    truth, prepare it once (``target``) and call ``score_to`` each step. ``render_mode`` is what
    the nets see: 'shaded' grey views (the metric), or 'silhouette' in a subclass.

    Example:
        >>> metric = DRKFS.pretrained()
        >>> score = metric(verts_a, faces_a, verts_b, faces_b)  # () tensor
    """

    render_mode: RenderMode = "shaded"

    def __init__(
        self,
        config: PipelineConfig | None = None,
        normalization: str = "joint",
        conv_precision: str = "ieee",
    ):
        super().__init__()
        self.config = config or PipelineConfig()
        self.normalization = check_normalization(normalization)
        self.conv_precision = check_conv_precision(conv_precision)
        self.renderer = Renderer(self.config)
        self.detector = PoIDetector(self.config)
        # its convs' layout is HardNet._folded's (precision.conv_layout), set on every call
        self.descriptor = HardNet(self.config)
        table = window_index(self.config, torch.device("cpu"))
        self.register_buffer("window_table", table, persistent=False)
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
                nets = config.shaping("features")
                raise MissingWeights(
                    f"no trained weights in models/ for {nets.nets} nets at width "
                    f"{nets.descriptor_width:g}, detector {nets.detector_n}x{nets.detector_m} "
                    f"{nets.detector_kernel}x{nets.detector_kernel}, descriptor dim "
                    f"{nets.descriptor_dim} (the tolerant nets come at width 0.5, the metric and "
                    "correspondence nets at 1, 0.5 and 0.25): train them (drkfs train --out "
                    "models, then drkfs tune-tolerant --out models), or pass random_weights=True "
                    "for seeded random nets"
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

    @_without_autocast
    def render(self, verts, faces=None) -> torch.Tensor:
        """(V, 3), (F, 3) -> (K, 1, S, S) grey views; a batch -> (B * K, 1, S, S)."""
        meshes = self._meshes(verts, faces)
        return self.renderer.render(meshes, mode=self.render_mode).unsqueeze(1)

    @_without_autocast
    def describe(self, images: torch.Tensor) -> torch.Tensor:
        """(N, 1, S, S) views -> (N * P, D) patch descriptors, row-major per view.

        Patches that see only background share one descriptor, computed once. On a GPU every
        patch goes through HardNet and the empty ones take the shared descriptor: listing the
        others would wait for the host, which costs it more than their convolutions.
        """
        with conv_precision(self.conv_precision):
            return self._describe(images)

    def _describe(self, images: torch.Tensor) -> torch.Tensor:
        dtype = next(self.detector.parameters()).dtype
        images = images.to(dtype)
        seen = nonempty_patches_on_device(images, self.config)
        size = self.config.patch_size
        blank = torch.full(
            (1, 1, size, size), self.config.background, dtype=dtype, device=images.device
        )
        convs = conv_dtype(self.conv_precision)
        empty = self.descriptor(self.detector(blank), None, convs)
        if images.is_cuda:
            every = torch.arange(len(seen), device=images.device)
            patches = select_patches(self.detector(images), every, self.config)
            described = self.descriptor(patches, GPU_PATCH_GROUP, convs)
            return torch.where(seen[:, None], described, empty)
        index = torch.nonzero(seen).squeeze(1)
        descriptors = empty.expand(len(seen), -1)
        if len(index) == 0:
            return descriptors
        patches = select_patches(self.detector(images), index, self.config)
        # on a CPU in groups whose activations stay in cache, forward and backward
        described = self.descriptor(patches, CPU_PATCH_GROUP, convs)
        return descriptors.index_put((index,), described)

    @_without_autocast
    def features(self, verts, faces=None) -> torch.Tensor:
        """Descriptors of a mesh already in the metric's frame: (V, 3), (F, 3) -> (K * T * P, D)
        (T rings of K views); a batch -> (B, K * T * P, D)."""
        return self.described(verts, faces)[0]

    @_without_autocast
    def described(self, verts, faces=None) -> tuple[torch.Tensor, torch.Tensor | None]:
        """``features`` and, for a config with a solid change, the (K * T, S, S) views they
        describe, (B, K * T, S, S) for a batch (else None): both sides of ``match_score``."""
        meshes = self._meshes(verts, faces)
        descriptors, views = self._described(meshes)
        return meshes.unbatch(descriptors), _unbatched(meshes, views)

    def _described(
        self, meshes: MeshBatch, renderer: Renderer | None = None
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """(B, K * T * P, D) descriptors and, for a config with a solid change, the
        (B, K * T, S, S) views they describe (else None); from ``renderer``'s cameras where
        given, else the config's."""
        renderer = self.renderer if renderer is None else renderer
        images = renderer.render(meshes, mode=self.render_mode).unsqueeze(1)
        descriptors = self.describe(images)
        views = images.reshape(len(meshes), -1, *images.shape[-2:])
        return (
            descriptors.reshape(len(meshes), -1, descriptors.shape[-1]),
            views if self.config.solid_weight else None,
        )

    def _meshes(self, verts, faces) -> MeshBatch:
        """Any form ``MeshBatch.of`` takes, checked, on the metric's device."""
        return MeshBatch.of(verts, faces, self.window_table.device)

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

    @_without_autocast
    def target(self, verts, faces=None) -> Target:
        """The reference mesh B, (V, 3), (F, 3), placed and described; a batch of references
        (one per prediction) -> a batched ``Target``. Differentiable like ``forward``; call it
        under ``torch.no_grad()`` for a fixed ground truth."""
        meshes = self._meshes(verts, faces)
        mode = self.normalization
        frame = reference_frame(meshes.verts, mode, TORCH_OPS)
        placed = meshes.moved(place_by(meshes.verts, mode, frame, TORCH_OPS))
        features, views = self._described(placed)
        if frame is not None:
            frame = tuple(meshes.unbatch(t) for t in frame)
        surface = None
        if self.config.align_degrees:
            surface = tuple(
                reference_surface(*_as_numpy(placed, i), self.config) for i in range(len(placed))
            )
        return Target(frame, meshes.unbatch(features), _unbatched(meshes, views), surface)

    @_without_autocast
    def score_to(
        self,
        verts,
        faces,
        target: Target,
        batch_reduction: str = "mean",
        temperature: float | None = None,
        cameras: list[int] | None = None,
    ) -> torch.Tensor:
        """The score of mesh A against a prepared reference.

        Args:
            verts, faces: mesh A, (V, 3) and (F, 3), or a batch (any form ``MeshBatch.of``
                takes).
            target: the reference, from this metric's ``target``.
            batch_reduction: a batch's scores' 'mean', 'sum', or 'none'.
            temperature: soft best matches (``match.soft_match_distances``), a loss form;
                None for the metric's hard ones.
            cameras: the indices of some of a one-ring, window-matched config's K cameras:
                the score from those views of both meshes alone (the rest are not rendered).
                Under a mean reduction, the mean of such scores over a partition of the
                cameras into equal groups is the score (``DrkfsLoss``'s ``view_groups``).

        Returns:
            () for one mesh; a batch's () mean or sum, or its (B,) scores.
        """
        meshes = self._meshes(verts, faces)
        if cameras is None:
            features, views = self._described_to(meshes, target)
            config, table = self.config, self._table
        else:
            config = self._subset_config(cameras)
            renderer = Renderer(config, self.renderer.cameras.select(list(cameras)))
            renderer = renderer.to(self.window_table.device)
            features, views = self._described_to(meshes, target, renderer)
            target = target.of_views(cameras, self.config)
            table = window_index(config, self.window_table.device)
        scores = match_score(
            features, target.features, config, temperature, table, views, target.views
        )
        return over_batch(scores, meshes.single, batch_reduction)

    def _subset_config(self, cameras: list[int]) -> PipelineConfig:
        """The config of a score from some of the cameras: one ring and a window match (within a
        view), so that the score of every camera is the mean of a partition's, and each camera
        once."""
        config, count = self.config, self.config.num_views
        if len(config.rings) > 1 or config.matching != "window":
            raise ValueError(
                "cameras: a score from some cameras needs one ring of them and a window match "
                f"(the loss preset's); this config has {len(config.rings)} rings and "
                f"{config.matching!r} matching"
            )
        if (
            not cameras
            or len(set(cameras)) != len(cameras)
            or not set(cameras) <= set(range(count))
        ):
            raise ValueError(f"cameras: distinct indices of the config's {count}; got {cameras}")
        return config.replace(num_views=len(cameras))

    @property
    def _table(self) -> torch.Tensor | None:
        return self.window_table if self.config.matching == "window" else None

    @_without_autocast
    def patch_distances(self, verts, faces, target: Target) -> dict[str, torch.Tensor]:
        """Where mesh A, (V, 3), (F, 3), differs from a prepared reference: {side: (K, n, n)}
        best-match squared distance of each patch of A ('a', searching the reference) and of
        the reference ('b', searching A), for the sides the config's direction searches
        (``match_rules.query_sides``); n patches per image side; a batch -> (B, K, n, n). With
        a turned ring of cameras, the patches of the rings whose comparison counts (the least
        score of ``match_rules.ring_pairings``; where that is own ring against own ring, the
        turned ring's own comparison has a part in it too, ``match_rules.pairing_part``, which
        these patches stand for). Differentiable like ``score_to``; log them (or
        ``drkfs-score explain``'s picture) to see where a prediction is wrong."""
        config, one, rows = self.config, self.config.one_ring(), match_rules.ring_rows
        grid = (config.num_views, config.patches_per_side, config.patches_per_side)
        meshes = self._meshes(verts, faces)
        features, views = self._described_to(meshes, target)
        features, views = meshes.unbatch(features), _unbatched(meshes, views)
        pairs = [
            (features[..., rows(i, config), :], target.features[..., rows(j, config), :])
            for i, j in match_rules.ring_pairings(config)
        ]
        with torch.no_grad():  # (*lead,) the pairing whose score counts
            least = pairing_scores(
                features, target.features, config, None, self._table, views, target.views
            ).argmin(0)
        found = {}
        for k, side in enumerate(match_rules.query_sides(one)):
            per_pairing = torch.stack(
                [best_match_distances(*match_rules.directions(a, b, one)[k], one, self._table)
                 for a, b in pairs]
            )  # fmt: skip
            distances = torch.take_along_dim(per_pairing, least[None, ..., None], dim=0)[0]
            found[side] = distances.reshape(*distances.shape[:-1], *grid)
        return found

    def _described_to(
        self, meshes: MeshBatch, target: Target, renderer: Renderer | None = None
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        self._check_target(target)
        if target.batch is not None and target.batch != len(meshes):
            raise ValueError(
                f"target: a batch of {target.batch} references needs as many predictions; got "
                f"{len(meshes)} (prepare one reference to share it with a whole batch)"
            )
        placed = meshes.moved(place_by(meshes.verts, self.normalization, target.frame, TORCH_OPS))
        return self._described(self._turned(placed, target), renderer)

    def _turned(self, placed: MeshBatch, target: Target) -> MeshBatch:
        """Each placed mesh turned onto its reference's surface (``contract.alignment``): the
        turn is found without gradients, its rotation applied to the vertices."""
        if not self.config.align_degrees:
            return placed
        surfaces = target.surface * len(placed) if target.batch is None else target.surface
        turns = [
            aligning_turn(*_as_numpy(placed, i), surface, self.config)
            for i, surface in enumerate(surfaces)
        ]
        unturned = [turns_nothing(turn) for turn in turns]
        if all(unturned):
            return placed
        verts = placed.verts
        rotations = torch.as_tensor(np.stack(turns), dtype=verts.dtype, device=verts.device)
        kept = torch.tensor(unturned, device=verts.device)[:, None, None]  # exactly as placed
        return placed.moved(torch.where(kept, verts, verts @ rotations.transpose(1, 2)))

    def _check_target(self, target: Target) -> None:
        """A reference prepared by a metric of this config, on this metric's device."""
        config, features = self.config, target.features
        shape = (config.views_per_mesh * config.patches_per_view, config.descriptor_dim)
        if tuple(features.shape[-2:]) != shape:
            raise ValueError(
                f"target: {tuple(features.shape[-2:])} descriptors, where this metric's config "
                f"makes {shape}: prepare it with this metric's target()"
            )
        if config.solid_weight and target.views is None:
            raise ValueError(
                f"target: no views, which this metric's solid change (solid_weight "
                f"{config.solid_weight:g}) compares: prepare it with this metric's target()"
            )
        if config.align_degrees and len(target.surface or ()) != (target.batch or 1):
            raise ValueError(
                "target: no surface samples of each reference to turn a prediction onto, which "
                f"this metric's turn (align_degrees {config.align_degrees:g}) needs: prepare it "
                "with this metric's target()"
            )
        if features.device != self.window_table.device:
            raise ValueError(
                f"target: on {features.device}, the metric on {self.window_table.device}: move "
                "it with target.to(), or prepare it after moving the metric"
            )

    def forward(
        self, verts_a, faces_a, verts_b, faces_b, batch_reduction: str = "mean"
    ) -> torch.Tensor:
        """The score of A against the reference B (the class's Shape)."""
        return self.score_to(verts_a, faces_a, self.target(verts_b, faces_b), batch_reduction)


def with_nets(
    config: PipelineConfig, detector: nn.Module, descriptor: nn.Module, **options
) -> DRKFS:
    """A DRKFS at ``config`` carrying copies of the given detector and HardNet; ``options`` as
    ``DRKFS``'s (normalization, conv_precision)."""
    metric = DRKFS(config, **options)
    metric.detector.load_state_dict(detector.state_dict())
    metric.descriptor.load_state_dict(descriptor.state_dict())
    return metric
