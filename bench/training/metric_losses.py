"""Objectives in the metric's own terms, on ``VariantViews``: fine-tuning the detector and
HardNet so that a mild edit keeps the descriptors and a structural edit moves them.

Both objectives run the nets exactly as the metric does (``DRKFS.describe``: evaluation-mode
BatchNorm, no dropout, background patches sharing one descriptor), so what they optimise is what
the benchmark scores.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from drkfs_onnx.contract.patch_grid import nonempty_patches
from drkfs_onnx.match import descriptor_score
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.nets.patches import select_patches

from .net_losses import descriptor_distances, hardest_triplet_loss
from .variant_views import VariantViews

RANK_MARGIN = 0.5  # log-ratio: a structural variant should score >= e^0.5 = 1.65x a mild one
BARS_MARGIN = float(np.log(2.0))  # a removed part should score twice a moved one (bars ratio 2)
RETRIEVAL_MARGIN = 0.1  # a shape of the same family only needs to come first
PATCH_MARGIN = 1.0  # HardNet's margin, in descriptor distance

LossFn = Callable[[DRKFS, int], torch.Tensor]


def _source_columns(rng: np.random.Generator) -> tuple[list[int], list[int]]:
    """Mild and structural columns of one variant source (part-based or surface edits)."""
    return VariantViews.sources()[0 if rng.random() < 0.5 else 1]


def ranking_loss(lower: torch.Tensor, higher: torch.Tensor, margin: float) -> torch.Tensor:
    """(Nl,), (Nh,) scores that should rank lower and higher -> () mean over every pair of
    max(0, margin - log(higher / lower)): a hinge on the score ratio, scale-free, so the nets
    cannot win by scaling the descriptors."""
    gap = higher.clamp_min(1e-12).log()[:, None] - lower.clamp_min(1e-12).log()[None, :]
    return (margin - gap).clamp_min(0).mean()


def _family_split(data: VariantViews, base: int) -> tuple[np.ndarray, np.ndarray]:
    """The other bases of ``base``'s family, and the bases of other families."""
    family = data.family
    same = np.flatnonzero((family == family[base]).numpy() & (np.arange(len(data)) != base))
    return same, np.flatnonzero((family != family[base]).numpy())


def _other_bases(data: VariantViews, base: int, rng: np.random.Generator) -> tuple[int, int]:
    """Another base of the same family and one of another family."""
    same, other = _family_split(data, base)
    return int(rng.choice(same)), int(rng.choice(other))


def metric_ranking(data: VariantViews, seed: int, tiers: bool, retrieval: int = 0) -> LossFn:
    """End to end through the metric: each step scores one base's variants (part-based or
    surface edits) against the base with ``descriptor_score`` at the metric's config and ranks mild
    below structural. With ``tiers`` it also ranks a mild edit below a part moved by
    MOVED_SHIFT, the moved part below half a structural edit (the paper's bars test), a
    structural edit below a shape of another family, and another shape of the same family below
    one of another family (retrieval). With ``retrieval`` > 0 it instead ranks that many other
    bases of the same family below that many of other families, every pair, by
    RETRIEVAL_MARGIN: the order the benchmark's retrieval needs, without asking a family to be
    tight."""

    # an edit no camera sees cannot be ranked: it would only push the nets towards noise
    visible = data.shows_edit().any(-1)
    bases = torch.nonzero(visible[:, VariantViews.columns("structural")].any(1))[:, 0]

    def loss_fn(metric: DRKFS, step: int) -> torch.Tensor:
        rng = np.random.default_rng([seed, 3, step])
        base = int(rng.choice(bases))
        mild, structural = _source_columns(rng)
        structural = [j for j in structural if visible[base, j]] or [
            j for j in VariantViews.columns("structural") if visible[base, j]
        ]
        part_source = mild == VariantViews.sources()[0][0]
        views = data.images[base][:, :, None]  # (1 + V, K, 1, S, S)
        reference = metric.describe(views[0])

        def scores(meshes) -> torch.Tensor:
            return torch.stack(
                [descriptor_score(metric.describe(m), reference, metric.config) for m in meshes]
            )

        d_mild, d_structural = scores(views[mild]), scores(views[structural])
        loss = ranking_loss(d_mild, d_structural, RANK_MARGIN)
        if retrieval:
            same, other = _family_split(data, base)
            near = rng.choice(same, min(retrieval, len(same)), replace=False)
            far = rng.choice(other, retrieval, replace=False)
            d_near, d_far = (
                scores(data.images[near, 0, :, None]),
                scores(data.images[far, 0, :, None]),
            )
            return loss + ranking_loss(d_near, d_far, RETRIEVAL_MARGIN)
        if not tiers:
            return loss
        same, other = _other_bases(data, base, rng)
        d_same, d_other = scores(data.images[[same, other], 0, :, None])
        loss = loss + ranking_loss(d_structural, d_other[None], RANK_MARGIN)
        loss = loss + ranking_loss(d_same[None], d_other[None], RANK_MARGIN)
        if part_source:
            d_moved = scores(views[VariantViews.columns("moved")])
            loss = loss + ranking_loss(d_mild, d_moved, RANK_MARGIN)
            loss = loss + ranking_loss(d_moved, d_structural, BARS_MARGIN)
        return loss

    return loss_fn


def _positions(
    shows: np.ndarray, seen: np.ndarray, mild: int, count: int, rng
) -> tuple[np.ndarray, np.ndarray]:
    """Patch rows for one base: half where the structural variant shows its edit (``shows``,
    (K * P,) bool; when it does), the rest anywhere the base or the mild variant sees something.
    -> (rows, shows)."""
    edited = np.flatnonzero(shows)
    anywhere = np.flatnonzero(seen[0] | seen[mild])
    picked = rng.choice(edited, min(len(edited), count // 2), replace=False)
    rest = rng.choice(anywhere, count - len(picked), replace=len(anywhere) < count - len(picked))
    rows = np.concatenate([picked, rest])
    return rows, shows[rows]


def patch_contrast(data: VariantViews, seed: int, bases_per_step: int, per_base: int) -> LossFn:
    """Patch level: anchors are the base's patches, positives the same grid position in a mild
    variant, negatives the hardest other patch in the batch (HardNet) and, where a structural
    variant shows its edit, that variant's patch at the same position:
    max(0, margin + d(a, p) - d(a, s))."""
    k = data.images.shape[2]
    edit_shows = data.shows_edit().numpy()
    cache: dict[int, np.ndarray] = {}

    def nonempty(b: int, config) -> np.ndarray:
        if b not in cache:
            cache[b] = np.stack([nonempty_patches(mesh.numpy(), config) for mesh in data.images[b]])
        return cache[b]

    def loss_fn(metric: DRKFS, step: int) -> torch.Tensor:
        rng = np.random.default_rng([seed, 4, step])
        config = metric.config
        anchors, positives, negatives, shows, places = [], [], [], [], []
        for i, b in enumerate(rng.choice(len(data), min(bases_per_step, len(data)), False)):
            mild_cols, structural_cols = _source_columns(rng)
            mild, structural = int(rng.choice(mild_cols)), int(rng.choice(structural_cols))
            rows, show = _positions(
                edit_shows[b, structural], nonempty(b, config), mild, per_base, rng
            )
            index = torch.as_tensor(rows)
            maps = metric.detector(data.images[b][[0, mild, structural]].flatten(0, 1)[:, None])
            for store, m in zip((anchors, positives, negatives), range(3), strict=True):
                store.append(select_patches(maps[m * k : (m + 1) * k], index, config))
            shows.append(torch.as_tensor(show))
            places.append(torch.stack([torch.full_like(index, i), index], 1))
        count = len(torch.cat(shows))
        out = metric.descriptor(torch.cat(anchors + positives + negatives))
        a, p, s = out[:count], out[count : 2 * count], out[2 * count :]
        place = torch.cat(places)
        same = (place[:, None, :] == place[None, :, :]).all(-1)
        loss = hardest_triplet_loss(a, p, same)
        show = torch.cat(shows)
        if show.any():
            d = descriptor_distances(a[show], torch.cat([p[show], s[show]]))
            n = int(show.sum())
            positive, negative = d[:, :n].diagonal(), d[:, n:].diagonal()
            loss = loss + (PATCH_MARGIN + positive - negative).clamp_min(0).mean()
        return loss

    return loss_fn
