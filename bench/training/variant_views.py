"""Training data in the metric's own terms: a base shape and its mild and structural variants,
rendered from the metric's cameras, with where each variant's surface differs from the base's.

The metric compares two meshes from the same cameras, so what its nets must learn is not
"the same point seen from another view" but "the same camera, a mild edit: the same
descriptors; a structural edit: other descriptors where it shows, the same elsewhere".
Geometry gives the labels: two hard depth maps of one camera differ where a part was removed or
added (foreground on one side only, or a surface much nearer or further).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.render.renderer import Renderer
from drkfs_onnx.synthetic.shapes import Part, assemble, random_shape
from drkfs_onnx.synthetic.variants import (
    MILD,
    STRUCTURAL,
    Variant,
    diagonal,
    make_variants,
    shifted,
    surface_variants,
)

from .data import camera_depth, hard_depth

# camera-depth change (normalised units; the shape's half-diagonal is 1) that counts as another
# surface: twice the largest mild shift (2.5% of the diagonal), so only silhouettes that move
# mark a mild edit
CHANGED_DEPTH = 0.1
# a patch shows a structural edit when its changed share exceeds every mild variant's there by
# this much: silhouettes that a mild edit moves are not counted as structure
STRUCTURAL_SHARE = 0.05
# a part moved this far (share of the diagonal): more than a mild shift (2.5%), less than a
# removal; the paper's feature-level test moves a chair's bars by about this much
MOVED_SHIFT = 0.08
# the variants of each base, in this order: part-based edits, then the same edits applied to
# the base's surface as to a scanned mesh (what the benchmark's shared meshes get), then one
# part moved by MOVED_SHIFT
VARIANT_NAMES = (
    *(f"{source}:{name}" for source in ("part", "surface") for name in STRUCTURAL + MILD),
    "part:moved",
)


@dataclass
class VariantViews:
    """B base shapes, each with the len(VARIANT_NAMES) variants, from the config's K cameras.

    images: (B, 1 + V, K, S, S) float32, the base first; changed: (B, 1 + V, K, P) float32,
    the share of each patch's pixels where that mesh's surface differs from the base's (0 for
    the base); family: (B,) index into the families rendered.
    """

    images: torch.Tensor
    changed: torch.Tensor
    family: torch.Tensor

    def __len__(self) -> int:
        return len(self.images)

    def to_dict(self) -> dict[str, torch.Tensor]:
        return dict(vars(self))

    @staticmethod
    def columns(kind: str) -> list[int]:
        """Columns (1-based: 0 is the base) of the variants of ``kind`` ('mild', 'structural'
        or 'moved')."""
        names = {"structural": STRUCTURAL, "mild": MILD, "moved": ("moved",)}[kind]
        return [1 + i for i, v in enumerate(VARIANT_NAMES) if v.split(":")[1] in names]

    def shows_edit(self) -> torch.Tensor:
        """(B, 1 + V, K * P) bool: the patches where each mesh differs from its base by more
        than any mild variant does there (STRUCTURAL_SHARE more). A structural variant with no
        such patch made its edit where no camera sees it: DR-KFS's blind spot."""
        mild = self.changed[:, self.columns("mild")].amax(1, keepdim=True)
        return (self.changed > mild + STRUCTURAL_SHARE).flatten(2)

    @staticmethod
    def sources() -> list[tuple[list[int], list[int]]]:
        """(mild columns, structural columns) of each variant source: part-based edits, then
        surface edits."""

        def columns(source: str, names: tuple[str, ...]) -> list[int]:
            return [1 + VARIANT_NAMES.index(f"{source}:{name}") for name in names]

        return [(columns(s, MILD), columns(s, STRUCTURAL)) for s in ("part", "surface")]


def _camera_z(depth: torch.Tensor, config: PipelineConfig) -> torch.Tensor:
    """Normalised inverse depth (0 on background) -> camera z, +inf on background."""
    z = camera_depth(depth.clamp_min(1e-12), config)
    return torch.where(depth > 0, z, torch.full_like(z, float("inf")))


def changed_share(base: torch.Tensor, other: torch.Tensor, config: PipelineConfig) -> torch.Tensor:
    """(K, S, S) hard depth maps of the base and another mesh from the same cameras -> (K, P)
    share of each patch's pixels where the surfaces differ (foreground on one side only, or
    camera depths further apart than CHANGED_DEPTH)."""
    za, zb = _camera_z(base, config), _camera_z(other, config)
    one_side = (base > 0) != (other > 0)
    both = (base > 0) & (other > 0)
    differs = (one_side | (both & ((za - zb).abs() > CHANGED_DEPTH))).float()
    size, stride = config.patch_size, config.patch_stride
    return F.avg_pool2d(differs[:, None], size, stride).flatten(1)


def _variants(parts: list[Part], rng: np.random.Generator) -> tuple[tuple, list[Variant]]:
    base = assemble(parts, 1)  # the variants' own tessellation
    size = diagonal(parts)
    direction = rng.normal(size=3)
    offset = MOVED_SHIFT * size * direction / np.linalg.norm(direction)
    name = parts[int(rng.integers(len(parts)))].name
    moved = Variant("moved", "moved", *assemble(shifted(parts, name, tuple(offset)), 1))
    return base, [*make_variants(parts, rng), *surface_variants(*base, rng), moved]


@torch.no_grad()
def render_variant_views(
    config: PipelineConfig, families: list[str], shapes_per_family: int, seed: int
) -> VariantViews:
    """Render ``shapes_per_family`` bases of each family (drawn from ``seed``) and their
    variants, every mesh placed in its base's frame as the metric places a pair."""
    rng = np.random.default_rng(seed)
    renderer = Renderer(config)
    images, changed, family_ids = [], [], []
    for f_index, family in enumerate(families):
        for _ in range(shapes_per_family):
            (base_verts, base_faces), variants = _variants(random_shape(family, rng), rng)
            frame = frame_of(base_verts)
            meshes = [(base_verts, base_faces)] + [(v.verts, v.faces) for v in variants]
            views, depths = [], []
            for verts, faces in meshes:
                placed = torch.tensor(place(verts, frame), dtype=torch.float32)
                faces_t = torch.as_tensor(faces)
                views.append(renderer.render(placed, faces_t))
                depths.append(hard_depth(renderer, placed, faces_t))
            images.append(torch.stack(views))
            changed.append(torch.stack([changed_share(depths[0], d, config) for d in depths]))
            family_ids.append(f_index)
    return VariantViews(torch.stack(images), torch.stack(changed), torch.tensor(family_ids))
