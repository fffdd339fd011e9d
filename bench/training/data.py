"""Synthetic training views with ground-truth geometry.

Each sample is a pair of nearby views of one procedural shape, rendered with the metric's
renderer (same focal length, distance, shading) under two different lights, plus a hard depth map
per view. Depth gives every foreground pixel its surface point, so a pixel of view 0 maps to
view 1 wherever that point is not hidden (a depth test): the ground-truth correspondences both
nets learn from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from drkfs_onnx.contract.cameras import Cameras, look_at, make_cameras
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.render.renderer import Renderer
from drkfs_onnx.synthetic.shapes import assemble, random_shape

DEPTH_TOLERANCE = 0.01  # relative camera-depth difference still counted as the same surface


@dataclass
class ViewPairs:
    """N view pairs: images and depth (N, 2, S, S); rotations (N, 2, 3, 3); eyes (N, 2, 3);
    family (N,) index into FAMILIES; shape (N,) shape id. Depth is normalised inverse depth
    (the rasteriser's), 0 on background."""

    images: torch.Tensor
    depth: torch.Tensor
    rotations: torch.Tensor
    eyes: torch.Tensor
    family: torch.Tensor
    shape: torch.Tensor

    def __len__(self) -> int:
        return len(self.images)

    def to_dict(self) -> dict[str, torch.Tensor]:
        return dict(vars(self))

    def swapped(self) -> ViewPairs:
        """The same pairs with view 1 first."""
        order = [1, 0]
        return ViewPairs(
            self.images[:, order],
            self.depth[:, order],
            self.rotations[:, order],
            self.eyes[:, order],
            self.family,
            self.shape,
        )


def _random_direction(rng: np.random.Generator) -> np.ndarray:
    """A unit direction on the upper hemisphere, elevation 5 to 80 degrees."""
    elevation = rng.uniform(math.radians(5), math.radians(80))
    azimuth = rng.uniform(0, 2 * math.pi)
    ring = math.cos(elevation)
    return np.array([ring * math.cos(azimuth), math.sin(elevation), ring * math.sin(azimuth)])


def _nearby(direction: np.ndarray, degrees: float, rng: np.random.Generator) -> np.ndarray:
    """``direction`` turned by ``degrees`` about a random perpendicular axis, kept above y=0.05."""
    axis = np.cross(direction, rng.normal(size=3))
    axis /= np.linalg.norm(axis)
    t = math.radians(degrees)
    out = direction * math.cos(t) + np.cross(axis, direction) * math.sin(t)
    out[1] = max(out[1], 0.05)
    return out / np.linalg.norm(out)


def random_light(config: PipelineConfig, rng: np.random.Generator) -> tuple[float, float, float]:
    """The metric's light direction perturbed by up to ~35 degrees."""
    light = np.array(config.light_direction) / np.linalg.norm(config.light_direction)
    light = light + rng.normal(scale=0.35, size=3)
    return tuple((light / np.linalg.norm(light)).tolist())


def views_in_frame(renderer: Renderer, meshes, frame) -> torch.Tensor:
    """(verts, faces) meshes, each placed in one ``frame`` (a base's, as the metric places a
    pair) -> (M, K, S, S) their views."""
    return torch.stack([
        renderer.render(torch.tensor(place(v, frame), dtype=torch.float32), torch.as_tensor(f))
        for v, f in meshes
    ])  # fmt: skip


def hard_depth(renderer: Renderer, verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """(K, S, S) normalised inverse depth of the nearest face covering each pixel centre, else 0."""
    cfg = renderer.config
    frags = renderer.rasterize(verts, faces, depth_cull=True)
    # D' >= (0.5 - eps) / (1 - eps) exactly where the pixel centre lies inside the face
    inside = frags.coverage >= (0.5 - cfg.coverage_eps) / (1 - cfg.coverage_eps)
    depth = torch.zeros(len(renderer.cameras) * cfg.image_size**2, dtype=verts.dtype)
    depth.scatter_reduce_(0, frags.pixel[inside].long(), frags.depth[inside], reduce="amax")
    return depth.view(len(renderer.cameras), cfg.image_size, cfg.image_size)


def render_pairs(
    config: PipelineConfig,
    families: list[str],
    shapes_per_family: int,
    pairs_per_shape: int,
    seed: int,
    max_degrees: float = 30.0,
) -> ViewPairs:
    """Render view pairs 5 to ``max_degrees`` apart, each view under its own random light."""
    rng = np.random.default_rng(seed)
    focal = make_cameras(config).focal
    out: dict[str, list] = {k: [] for k in ("images", "depth", "rotations", "eyes")}
    family_ids, shape_ids = [], []
    for f_index, family in enumerate(families):
        for s in range(shapes_per_family):
            verts, faces = assemble(random_shape(family, rng))
            verts_t = torch.tensor(place(verts, frame_of(verts)), dtype=torch.float32)
            faces_t = torch.tensor(faces)
            for _ in range(pairs_per_shape):
                first = _random_direction(rng)
                second = _nearby(first, rng.uniform(5.0, max_degrees), rng)
                eyes = np.stack([first, second]) * config.camera_distance
                cameras = Cameras(look_at(eyes), eyes, focal)
                images = []
                for view in range(2):
                    lit = config.replace(light_direction=random_light(config, rng))
                    one = Cameras(cameras.rotations[view : view + 1], eyes[view : view + 1], focal)
                    images.append(Renderer(lit, one).render(verts_t, faces_t)[0])
                with torch.no_grad():
                    out["depth"].append(hard_depth(Renderer(config, cameras), verts_t, faces_t))
                out["images"].append(torch.stack(images).detach())
                out["rotations"].append(torch.tensor(cameras.rotations, dtype=torch.float32))
                out["eyes"].append(torch.tensor(eyes, dtype=torch.float32))
                family_ids.append(f_index)
                shape_ids.append(f_index * shapes_per_family + s)
    return ViewPairs(
        **{k: torch.stack(v) for k, v in out.items()},
        family=torch.tensor(family_ids),
        shape=torch.tensor(shape_ids),
    )


def camera_depth(w: torch.Tensor, config: PipelineConfig) -> torch.Tensor:
    """Normalised inverse depth -> camera-frame z."""
    inv_near, inv_far = 1.0 / config.near, 1.0 / config.far
    return 1.0 / (w * (inv_near - inv_far) + inv_far)


def correspond(
    pairs: ViewPairs, index: torch.Tensor, pixels: torch.Tensor, config: PipelineConfig
) -> tuple[torch.Tensor, torch.Tensor]:
    """Map pixels of view 0 into view 1.

    index: (C,) pair ids; pixels: (C, 2) row, col in view 0.
    Returns (C, 2) row, col in view 1 (rounded) and (C,) bool: the surface point is on screen
    and not hidden in view 1.
    """
    size = config.image_size
    focal = make_cameras(config).focal
    rows, cols = pixels[:, 0], pixels[:, 1]
    w0 = pairs.depth[index, 0, rows, cols]
    z = camera_depth(w0, config)
    ndc = torch.stack([(2 * cols + 1) / size - 1, (2 * rows + 1) / size - 1], dim=1)
    cam0 = torch.cat([ndc * z[:, None] / focal, z[:, None]], dim=1)
    rot, eyes = pairs.rotations[index], pairs.eyes[index]
    world = torch.einsum("cji,cj->ci", rot[:, 0], cam0) + eyes[:, 0]
    cam1 = torch.einsum("cij,cj->ci", rot[:, 1], world - eyes[:, 1])
    xy = focal * cam1[:, :2] / cam1[:, 2:3]
    target = torch.round(((xy + 1) * size - 1) / 2).long()  # col, row
    on_screen = (w0 > 0) & (target >= 0).all(1) & (target < size).all(1)
    target = target.clamp(0, size - 1).flip(1)  # row, col
    w1 = pairs.depth[index, 1, target[:, 0], target[:, 1]]
    z1 = camera_depth(w1, config)
    seen = on_screen & (w1 > 0) & ((z1 - cam1[:, 2]).abs() < DEPTH_TOLERANCE * cam1[:, 2])
    return target, seen


def sample_matches(
    pairs: ViewPairs,
    config: PipelineConfig,
    per_pair: int,
    border: int,
    seed: int,
) -> torch.Tensor:
    """(C, 5) int64 rows: pair id, row0, col0, row1, col1 of visible correspondences.

    Pixels of view 0 are drawn with probability growing with the local image gradient (plus a
    floor), so matches favour structure over flat faces; both ends lie ``border`` pixels inside
    the image so that patches around them need no padding.
    """
    gen = torch.Generator().manual_seed(seed)
    size = config.image_size
    images = pairs.images[:, 0:1]
    grad = (images[..., 1:, :-1] - images[..., :-1, :-1]).abs() + (
        images[..., :-1, 1:] - images[..., :-1, :-1]
    ).abs()
    grad = torch.nn.functional.pad(grad, (0, 1, 0, 1))
    weight = torch.nn.functional.max_pool2d(grad, 9, 1, 4)[:, 0] + 0.05
    weight = weight * (pairs.depth[:, 0] > 0)
    inner = torch.zeros(size, size)
    inner[border : size - border, border : size - border] = 1
    weight = (weight * inner).flatten(1)
    rows = []
    for i in range(len(pairs)):
        if weight[i].sum() == 0:
            continue
        flat = torch.multinomial(weight[i], per_pair, replacement=True, generator=gen)
        pixels = torch.stack([flat // size, flat % size], dim=1)
        index = torch.full((per_pair,), i)
        target, seen = correspond(pairs, index, pixels, config)
        inside = ((target >= border) & (target < size - border)).all(1)
        keep = seen & inside
        rows.append(torch.cat([index[keep, None], pixels[keep], target[keep]], dim=1))
    return torch.cat(rows).unique(dim=0)


def crops(maps: torch.Tensor, centers: torch.Tensor, size: int) -> torch.Tensor:
    """maps (N, S, S); centers (C, 3) map id, row, col -> (C, size, size) windows whose pixel
    (size // 2, size // 2) is the centre. Centres must lie size // 2 inside the map."""
    offsets = torch.arange(size) - size // 2
    n, r, c = centers[:, 0], centers[:, 1], centers[:, 2]
    return maps[
        n[:, None, None], (r[:, None] + offsets)[:, :, None], (c[:, None] + offsets)[:, None, :]
    ]
