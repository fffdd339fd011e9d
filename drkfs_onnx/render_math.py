"""The soft renderer's equations, written once for torch and numpy.

Torch-free: ``drkfs_onnx.rasterize`` passes ``TORCH_OPS``, the runtime ``NUMPY_OPS``. Each
function takes the array module's few operations as ``ops``: ``where``, ``minimum``,
``maximum``, ``clip``, ``ceil``, ``floor``, ``sqrt``, ``exp``, ``log``, ``sigmoid``, ``stack``,
``einsum``, ``take(values, index)`` (gather along the last axis, broadcasting the others), and
``scatter_sum(index, values, length)`` / ``scatter_max(out, index, values)``.
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


def _take(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    return np.take_along_axis(values, index, axis=-1)


NUMPY_OPS = SimpleNamespace(
    where=np.where, minimum=np.minimum, maximum=np.maximum, clip=np.clip, ceil=np.ceil,
    floor=np.floor, sqrt=np.sqrt, exp=np.exp, log=np.log, sigmoid=_sigmoid, stack=np.stack,
    einsum=np.einsum, take=_take, scatter_sum=_scatter_sum, scatter_max=_scatter_max,
)  # fmt: skip


@dataclass
class ScreenFaces:
    """Faces projected into K views (numpy arrays or torch tensors).

    params: (9, K*F) per face: x0, y0, x1, y1, x2, y2 in NDC, then the three vertices' normalised
        inverse depths (1 at the near plane, 0 at the far plane). Coordinate-major, so that
        gathering pairs gives nine contiguous rows for fast elementwise work.
    visible: (K*F,) bool, False for faces with a vertex in front of the near plane.
    Faces of view k sit at k*F .. (k+1)*F. A batch of B meshes is B*K views, mesh b's at
    b*K .. (b+1)*K.
    """

    params: Any
    visible: Any
    num_views: int
    num_faces: int


def to_camera(verts, rotations, eyes, ops):
    """(V, 3) world vertices, or a batch (B, V, 3), (K, 3, 3) rotations, (K, 3) eyes -> (K, V, 3)
    camera frame, or (B, K, V, 3)."""
    return ops.einsum("kij,...knj->...kni", rotations, verts[..., None, :, :] - eyes[:, None])


def _corner_values(verts_cam, faces):
    """(K, V, 3) and (F, 3), or a batch (B, K, V, 3) and (B, F, 3) -> per corner i and axis a,
    ``values[i][a]``: (B, K, F) the corner's coordinate (B = 1 for one mesh)."""
    if faces.ndim == 2:
        verts_cam, faces = verts_cam[None], faces[None]
    return verts_cam, faces, [faces[:, None, :, i] for i in range(3)]


def project_faces(verts_cam, faces, focal: float, config: PipelineConfig, ops) -> ScreenFaces:
    """(K, V, 3) camera-frame vertices and (F, 3) faces, or a batch of B meshes' (B, K, V, 3)
    and (B, F, 3) -> ScreenFaces of the B*K views (pinhole, NDC)."""
    verts_cam, faces, corners = _corner_values(verts_cam, faces)
    b, k, f = verts_cam.shape[0], verts_cam.shape[1], faces.shape[1]
    z = verts_cam[..., 2]
    near_ok = z > config.near
    z_safe = ops.where(near_ok, z, config.near)
    x, y = focal * verts_cam[..., 0] / z_safe, focal * verts_cam[..., 1] / z_safe
    inv_near, inv_far = 1.0 / config.near, 1.0 / config.far
    inv_depth = (1.0 / z_safe - inv_far) / (inv_near - inv_far)
    rows = [ops.take(c, corner).reshape(-1) for corner in corners for c in (x, y)]
    params = ops.stack(rows + [ops.take(inv_depth, corner).reshape(-1) for corner in corners])
    visible = ops.take(near_ok, corners[0]) & ops.take(near_ok, corners[1])
    visible = visible & ops.take(near_ok, corners[2])
    return ScreenFaces(params, visible.reshape(b * k * f), b * k, f)


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


def _edges(tri, px, py, ops):
    """Per edge i of each pair's triangle (corner i to corner i + 1): the edge (ex, ey), the
    pixel from its start (qx, qy), the edge function c_i = e x q, the clipped projection t of q
    on the edge and the squared distance d2 from the pixel to the edge."""
    x0, y0, x1, y1, x2, y2 = tri[:6]
    parts = []
    for ax, ay, bx, by in ((x0, y0, x1, y1), (x1, y1, x2, y2), (x2, y2, x0, y0)):
        ex, ey = bx - ax, by - ay
        qx, qy = px - ax, py - ay
        t = ops.clip((qx * ex + qy * ey) / (ex * ex + ey * ey + TINY), 0.0, 1.0)
        rx, ry = qx - t * ex, qy - t * ey
        parts.append(SimpleNamespace(qx=qx, qy=qy, ex=ex, ey=ey, c=ex * qy - ey * qx, t=t,
                                     rx=rx, ry=ry, d2=rx * rx + ry * ry))  # fmt: skip
    return parts


def _coverage(edges, config: PipelineConfig, ops):
    """(inside, the squared distance to the triangle, sigmoid(+-d^2 / sigma), coverage D')."""
    c0, c1, c2 = (e.c for e in edges)
    dist2 = ops.minimum(ops.minimum(edges[0].d2, edges[1].d2), edges[2].d2)
    inside = ((c0 > 0) & (c1 > 0) & (c2 > 0)) | ((c0 < 0) & (c1 < 0) & (c2 < 0))
    signed = ops.where(inside, dist2, -dist2) / config.sigma
    eps = config.coverage_eps
    probability = ops.sigmoid(signed)
    return inside, dist2, probability, ops.clip((probability - eps) / (1.0 - eps), 0.0, None)


def _plane(edges, w, ops):
    """(the doubled area, its guarded value, the face's plane of inverse depth at the pixel)."""
    c0, c1, c2 = (e.c for e in edges)
    area2 = c0 + c1 + c2
    area_safe = ops.where(abs(area2) > TINY, area2, TINY)
    return area2, area_safe, (c1 * w[0] + c2 * w[1] + c0 * w[2]) / area_safe


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
    edges = _edges(tri, px, py, ops)
    coverage = _coverage(edges, config, ops)[3]
    w0, w1, w2 = tri[6:9]
    plane = _plane(edges, (w0, w1, w2), ops)[2]
    lowest = ops.minimum(ops.minimum(w0, w1), w2)
    highest = ops.maximum(ops.maximum(w0, w1), w2)
    return coverage, ops.maximum(ops.minimum(plane, highest), lowest)


def pair_terms_grad(tri, px, py, grad_coverage, grad_depth, config: PipelineConfig, ops):
    """The gradient of ``pair_terms`` with respect to ``tri``: (9, P), given the gradients of
    its coverage and depth (P,). Written out so that a backward pass costs one recomputation
    of the pairs' terms, not autograd's graph of them.

    The distance to the triangle is its nearest edge's, |p - (a + t (b - a))|^2, whose slope in
    a and b is -2 r (1 - t) and -2 r t (r from the nearest point to the pixel; t's own slope
    meets r . e = 0). The plane is (c1 w0 + c2 w1 + c0 w2) / (c0 + c1 + c2), each edge function
    c = e x q bilinear in the corners. A clamped depth sends its gradient to the corner whose
    depth it took.
    """
    edges = _edges(tri, px, py, ops)
    inside, dist2, probability, coverage = _coverage(edges, config, ops)
    eps = config.coverage_eps
    slope = probability * (1.0 - probability) / (1.0 - eps) / config.sigma
    signed_grad = ops.where(coverage > 0, grad_coverage * slope, 0.0)
    grad_dist2 = ops.where(inside, signed_grad, -signed_grad)
    w = tri[6:9]
    area2, area_safe, plane = _plane(edges, w, ops)
    lowest = ops.minimum(ops.minimum(w[0], w[1]), w[2])
    highest = ops.maximum(ops.maximum(w[0], w[1]), w[2])
    inner = (plane < highest) & (plane > lowest)
    grad_plane = ops.where(inner, grad_depth, 0.0)
    # the plane's slope in each edge function, through its numerator and (unguarded) area
    area_slope = ops.where(abs(area2) > TINY, -plane / area_safe, 0.0)
    grads = [0.0 * px for _ in range(9)]
    nearest_taken = dist2 < 0  # all False: the first edge at the minimum takes its gradient
    for i, (edge, weight) in enumerate(zip(edges, (w[2], w[0], w[1]), strict=True)):
        a, b = i, (i + 1) % 3
        # the edge function's slope in its corners: c = ex qy - ey qx
        grad_c = grad_plane * (weight / area_safe + area_slope)
        grads[2 * a] = grads[2 * a] + grad_c * (edge.ey - edge.qy)
        grads[2 * a + 1] = grads[2 * a + 1] + grad_c * (edge.qx - edge.ex)
        grads[2 * b] = grads[2 * b] + grad_c * edge.qy
        grads[2 * b + 1] = grads[2 * b + 1] - grad_c * edge.qx
        nearest = (edge.d2 == dist2) & ~nearest_taken
        nearest_taken = nearest_taken | nearest
        grad_d2 = ops.where(nearest, -2.0 * grad_dist2, 0.0)
        grads[2 * a] = grads[2 * a] + grad_d2 * edge.rx * (1.0 - edge.t)
        grads[2 * a + 1] = grads[2 * a + 1] + grad_d2 * edge.ry * (1.0 - edge.t)
        grads[2 * b] = grads[2 * b] + grad_d2 * edge.rx * edge.t
        grads[2 * b + 1] = grads[2 * b + 1] + grad_d2 * edge.ry * edge.t
    area_weight = grad_plane / area_safe
    edge_c = [e.c for e in edges]
    for i, c in enumerate((edge_c[1], edge_c[2], edge_c[0])):  # w0 * c1, w1 * c2, w2 * c0
        # a clamped depth is the nearest or farthest corner's own (the first one at it)
        takes_low = (plane <= lowest) & (w[i] == lowest)
        takes_high = (plane >= highest) & (w[i] == highest)
        for j in range(i):
            takes_low = takes_low & (w[j] != lowest)
            takes_high = takes_high & (w[j] != highest)
        clamped = ops.where(takes_low | takes_high, grad_depth, 0.0)
        grads[6 + i] = c * area_weight + clamped
    return ops.stack(grads)


def pair_logit(coverage, depth, config: PipelineConfig, ops):
    """A covered pair's softmax logit in SoftRas' blend: log D' + depth / gamma."""
    return ops.log(coverage) + depth / config.gamma


def background_logit(config: PipelineConfig) -> float:
    """The background's logit, every pixel's floor: background_eps / gamma."""
    return config.background_eps / config.gamma


def face_shading(verts_cam, faces, config: PipelineConfig, ops):
    """(K, V, 3) camera-frame vertices, (F, 3) faces, or a batch (B, K, V, 3), (B, F, 3) ->
    (B*K*F,) grey value per face.

    Flat two-sided Lambertian shading: a face seen from behind is lit as if its normal faced the
    camera, so open and non-watertight meshes show their inner side instead of a black hole.
    """
    # one (B, K, F) array per coordinate of each corner: contiguous loops, not length-3 rows
    verts_cam, _, corners = _corner_values(verts_cam, faces)
    (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = (
        [ops.take(verts_cam[..., axis], corner) for axis in range(3)] for corner in corners
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


def blend_weight(logit, logit_max, ops):
    """A pair's weight in SoftRas' blend, its logit shifted by its pixel's largest so none
    overflows: w = exp(logit - logit_max)."""
    return ops.exp(logit - logit_max)


def blend_image(numerator, denominator, logit_max, config: PipelineConfig, ops):
    """Per pixel: I = (sum_j w_j C_j + w_b C_b) / (sum_j w_j + w_b), from the sums of the
    pairs' weighted colours (``numerator``) and weights (``denominator``), w_b = exp(background
    logit - logit_max)."""
    background = ops.exp(background_logit(config) - logit_max)
    return (numerator + background * config.background) / (denominator + background)


def soft_blend(pixel, face, logit, logit_max, colors, config: PipelineConfig, ops):
    """SoftRas aggregation of pixel-face pairs -> (K*S*S,) flat grey images; ``logit_max``
    (K*S*S,) is each pixel's largest logit, background included (``blend_image``)."""
    weight = blend_weight(logit, logit_max[pixel], ops)
    numerator = ops.scatter_sum(pixel, weight * colors[face], len(logit_max))
    denominator = ops.scatter_sum(pixel, weight, len(logit_max))
    return blend_image(numerator, denominator, logit_max, config, ops)
