"""The soft renderer's equations, written once for torch and numpy.

Torch-free: ``drkfs_onnx.rasterize`` passes ``TORCH_OPS``, the runtime ``NUMPY_OPS``. Each
function takes the array module's few operations as ``ops``: ``where``, ``minimum``,
``maximum``, ``clip``, ``ceil``, ``floor``, ``sqrt``, ``exp``, ``log``, ``sigmoid``, ``stack``,
``einsum``, and ``scatter_sum(index, values, length)`` / ``scatter_max(out, index, values)``.
Only what is not an equation stays apart: autograd's two passes (``rasterize.py``) and the
numpy renderer's culling (``runtime/candidates.py``).

The stages: ``to_camera`` -> ``project_faces`` -> per face ``pixel_span`` (its box of pixels)
-> per pixel-face pair ``pair_terms`` (coverage and depth) and ``pair_logit`` -> per pixel
``soft_blend`` of the faces' ``face_shading`` with the background.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from .config import PipelineConfig

TINY = 1e-12
# A pair whose blend logit lies this far under its pixel's largest is dropped: its weight is
# below exp(-DEPTH_CULL) of the front face's.
DEPTH_CULL = 30.0


def _sigmoid(x: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        return 1.0 / (1.0 + np.exp(-x))


def _scatter_sum(index: np.ndarray, values: np.ndarray, length: int) -> np.ndarray:
    return np.bincount(index, values, minlength=length)


def _scatter_max(out: np.ndarray, index: np.ndarray, values: np.ndarray) -> np.ndarray:
    np.maximum.at(out, index, values)
    return out


NUMPY_OPS = SimpleNamespace(
    where=np.where, minimum=np.minimum, maximum=np.maximum, clip=np.clip, ceil=np.ceil,
    floor=np.floor, sqrt=np.sqrt, exp=np.exp, log=np.log, sigmoid=_sigmoid, stack=np.stack,
    einsum=np.einsum, scatter_sum=_scatter_sum, scatter_max=_scatter_max,
)  # fmt: skip


@dataclass
class ScreenFaces:
    """Faces projected into K views (numpy arrays or torch tensors).

    params: (9, K*F) per face: x0, y0, x1, y1, x2, y2 in NDC, then the three vertices' normalised
        inverse depths (1 at the near plane, 0 at the far plane). Coordinate-major, so that
        gathering pairs gives nine contiguous rows for fast elementwise work.
    visible: (K*F,) bool, False for faces with a vertex in front of the near plane.
    Faces of view k sit at k*F .. (k+1)*F.
    """

    params: Any
    visible: Any
    num_views: int
    num_faces: int


def to_camera(verts, rotations, eyes, ops):
    """(V, 3) world vertices, (K, 3, 3) rotations, (K, 3) eyes -> (K, V, 3) camera frame."""
    return ops.einsum("kij,knj->kni", rotations, verts[None] - eyes[:, None])


def project_faces(verts_cam, faces, focal: float, config: PipelineConfig, ops) -> ScreenFaces:
    """(K, V, 3) camera-frame vertices and (F, 3) faces -> ScreenFaces (pinhole, NDC)."""
    k, f = verts_cam.shape[0], faces.shape[0]
    z = verts_cam[..., 2]
    near_ok = z > config.near
    z_safe = ops.where(near_ok, z, config.near)
    x, y = focal * verts_cam[..., 0] / z_safe, focal * verts_cam[..., 1] / z_safe
    inv_near, inv_far = 1.0 / config.near, 1.0 / config.far
    inv_depth = (1.0 / z_safe - inv_far) / (inv_near - inv_far)
    corners = [faces[:, i] for i in range(3)]
    rows = [c[:, corner].reshape(-1) for corner in corners for c in (x, y)]
    params = ops.stack(rows + [inv_depth[:, corner].reshape(-1) for corner in corners])
    visible = near_ok[:, corners[0]] & near_ok[:, corners[1]] & near_ok[:, corners[2]]
    return ScreenFaces(params, visible.reshape(k * f), k, f)


def pixel_span(lo, hi, config: PipelineConfig, ops):
    """First pixel and pixel count along one axis of boxes spanning NDC [lo, hi], grown by the
    coverage cut-off radius and clipped to the image (floats; the count is 0 for none)."""
    size, radius = config.image_size, config.coverage_radius
    first = ops.clip(ops.ceil((lo - radius + 1.0) * size / 2.0 - 0.5), 0, size)
    last = ops.clip(ops.floor((hi + radius + 1.0) * size / 2.0 - 0.5), -1, size - 1)
    return first, ops.clip(last - first + 1, 0, None)


def pixel_centre(index, size: int):
    """NDC of pixel centres: pixel i of a row or column sits at (2i + 1) / size - 1 (``index``
    as floats of the coordinates' dtype)."""
    return (2 * index + 1) / size - 1.0


def pair_terms(tri, px, py, config: PipelineConfig, ops):
    """Coverage D' and normalised inverse depth of P pixel-face pairs.

    tri: (9, P) face params (see ``ScreenFaces``); px, py: (P,) pixel centres in NDC.
    Coverage: D = sigmoid(+-d^2 / sigma), d the screen distance from the pixel to the triangle
    (+ inside), cut where it falls below ``coverage_eps`` by D' = max(D - eps, 0) / (1 - eps),
    so the cut is continuous. Depth is the face's plane at the pixel (inverse depth is affine in
    screen space), clamped to the face's own depth range. Coplanar pieces of a surface then agree
    on depth however it is tessellated; SoftRas' clipped barycentrics instead jump to far
    vertices outside a face and let a barely-covering face win the depth softmax.
    """
    x0, y0, x1, y1, x2, y2, w0, w1, w2 = tri
    edges = ((x0, y0, x1, y1), (x1, y1, x2, y2), (x2, y2, x0, y0))
    edge_fn = []
    dist2 = None
    for ax, ay, bx, by in edges:
        ex, ey = bx - ax, by - ay
        qx, qy = px - ax, py - ay
        edge_fn.append(ex * qy - ey * qx)
        t = ops.clip((qx * ex + qy * ey) / (ex * ex + ey * ey + TINY), 0.0, 1.0)
        rx, ry = qx - t * ex, qy - t * ey
        d2 = rx * rx + ry * ry
        dist2 = d2 if dist2 is None else ops.minimum(dist2, d2)
    c0, c1, c2 = edge_fn
    inside = ((c0 > 0) & (c1 > 0) & (c2 > 0)) | ((c0 < 0) & (c1 < 0) & (c2 < 0))
    signed = ops.where(inside, dist2, -dist2) / config.sigma
    eps = config.coverage_eps
    coverage = ops.clip((ops.sigmoid(signed) - eps) / (1.0 - eps), 0.0, None)

    area2 = c0 + c1 + c2
    area_safe = ops.where(abs(area2) > TINY, area2, TINY)
    plane = (c1 * w0 + c2 * w1 + c0 * w2) / area_safe
    lowest = ops.minimum(ops.minimum(w0, w1), w2)
    highest = ops.maximum(ops.maximum(w0, w1), w2)
    return coverage, ops.maximum(ops.minimum(plane, highest), lowest)


def pair_logit(coverage, depth, config: PipelineConfig, ops):
    """A covered pair's softmax logit in SoftRas' blend: log D' + depth / gamma."""
    return ops.log(coverage) + depth / config.gamma


def background_logit(config: PipelineConfig) -> float:
    """The background's logit, every pixel's floor: background_eps / gamma."""
    return config.background_eps / config.gamma


def face_shading(verts_cam, faces, config: PipelineConfig, ops):
    """(K, V, 3) camera-frame vertices, (F, 3) faces -> (K*F,) grey value per face.

    Flat two-sided Lambertian shading: a face seen from behind is lit as if its normal faced the
    camera, so open and non-watertight meshes show their inner side instead of a black hole.
    """
    # one (K, F) array per coordinate of each corner: contiguous loops, not length-3 rows
    (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = (
        [verts_cam[:, faces[:, i], axis] for axis in range(3)] for i in range(3)
    )
    ax, ay, az, bx, by, bz = x1 - x0, y1 - y0, z1 - z0, x2 - x0, y2 - y0, z2 - z0
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    length = ops.sqrt(nx * nx + ny * ny + nz * nz + 1e-20)
    nx, ny, nz = nx / length, ny / length, nz / length
    outward = nx * (x0 + x1 + x2) / 3.0 + ny * (y0 + y1 + y2) / 3.0 + nz * (z0 + z1 + z2) / 3.0
    towards = ops.where(outward > 0, -1.0, 1.0)
    light = np.asarray(config.light_direction, dtype=np.float64)
    lx, ly, lz = (float(v) for v in light / np.linalg.norm(light))
    lambert = ops.clip((nx * lx + ny * ly + nz * lz) * towards, 0.0, None)
    return (config.ambient + config.diffuse * lambert).reshape(-1)


def soft_blend(pixel, face, logit, logit_max, colors, config: PipelineConfig, ops):
    """SoftRas aggregation of pixel-face pairs -> (K*S*S,) flat grey images.

    I = (sum_j w_j C_j + w_b C_b) / (sum_j w_j + w_b), w_j = exp(logit_j), w_b = exp(background
    logit), all shifted by each pixel's largest logit ``logit_max`` (K*S*S,) so none overflows.
    """
    weight = ops.exp(logit - logit_max[pixel])
    numerator = ops.scatter_sum(pixel, weight * colors[face], len(logit_max))
    denominator = ops.scatter_sum(pixel, weight, len(logit_max))
    background = ops.exp(background_logit(config) - logit_max)
    return (numerator + background * config.background) / (denominator + background)
