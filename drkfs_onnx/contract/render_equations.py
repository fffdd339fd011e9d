"""The soft renderer's equations, written once for torch and numpy (``ops``: ``array_ops``).

The torch renderer (``render/``) passes ``TORCH_OPS``, the runtime's ``NUMPY_OPS``. Only what
is not an equation stays apart: autograd's two passes (``render/pixel_sums.py``) and the numpy
renderer's culling (``runtime/candidates.py``).

The stages: ``to_camera`` -> ``project_faces`` -> per face ``pixel_span`` (its box of pixels)
-> per pixel-face pair ``pair_terms`` (coverage and depth) and ``pair_logit`` -> per pixel
``soft_blend`` of the faces' greys (``face_light``: lit less shadow) with the background; where
the shadow is pushed back (``pushes_back``), the lit blend less the shadow's blend over the
screen ``pushed_back``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from .array_ops import NUMPY_OPS
from .config import PipelineConfig

TINY = 1e-12
TINY_LENGTH = 1e-9
# Pairs are listed slightly beyond the cut-off radius, so float32 rounding never drops one.
LOOSE_RADIUS = 1.01
# A pair whose blend logit lies this far under its pixel's largest is dropped: its weight is
# below exp(-DEPTH_CULL) of the front face's.
DEPTH_CULL = 30.0
# A mesh reads inside out (``mesh_orientation``) where its signed volume lies under minus this
# share of its tetrahedra's unsigned volumes (beyond FLAT_VOLUME): the real meshes read
# 0.47-0.95 (the horse of bench/records/real_levers.md -0.67), a flat relief roughened by noise
# under 0.01 either way, its sign noise's.
ORIENTED_SHARE = 0.05
# Meshes render inside the unit sphere, where a flat mesh's volume rounds to about 1e-17.
FLAT_VOLUME = 1e-9


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
    offsets = verts[..., None, :, :] - eyes[:, None]  # (..., K, V, 3)
    x, y, z = offsets[..., 0], offsets[..., 1], offsets[..., 2]
    r = rotations[:, None]  # (K, 1, 3, 3)
    # three products summed in order per coordinate, not a matrix product: BLAS picks its
    # kernel by the vertex count, so a mesh padded in a batch landed an ulp off the same mesh
    # alone, and its views 2e-6 off the loop's
    return ops.stack([x * r[..., i, 0] + y * r[..., i, 1] + z * r[..., i, 2] for i in range(3)], -1)


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


def edge_lines(params, ops):
    """(9, N) screen params -> per edge (corner i to i + 1) its line's (a, b, c), (N,) each:
    a x + b y + c is the signed distance from (x, y) to the line, positive on the triangle's
    side (0 everywhere for a degenerate face). A pixel further than the cut-off radius outside
    one of a face's lines is not covered by it: the distance to a triangle is at least the
    distance to each of its lines' inner half-planes."""
    x0, y0, x1, y1, x2, y2 = params[:6]
    orient = ops.sign((x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0))
    lines = []
    for ax, ay, bx, by in ((x0, y0, x1, y1), (x1, y1, x2, y2), (x2, y2, x0, y0)):
        ex, ey = bx - ax, by - ay
        scale = orient / ops.clip(ops.sqrt(ex * ex + ey * ey), TINY_LENGTH, None)
        lines.append((-ey * scale, ex * scale, (ey * ax - ex * ay) * scale))
    return lines


def line_columns(a, b, c, py, reach, size: int):
    """Along pixel rows at height ``py``: the line a x + b y + c's (``edge_lines``) distance
    at column 0, and the columns where it is 0 and where it is -``reach``, as fractional
    indices; at a > 0 the columns past the last are within ``reach`` of the line's inner side,
    at a < 0 those before it."""
    level = a * (1.0 / size - 1.0) + b * py + c
    per_column = (-size / 2.0) / a  # columns per unit of distance, negated
    root = level * per_column
    return level, root, root + reach * per_column


def pixel_centre(index, size: int):
    """NDC of pixel centres: pixel i of a row or column sits at (2i + 1) / size - 1 (``index``
    as floats of the coordinates' dtype)."""
    return (2 * index + 1) / size - 1.0


class _Edge(NamedTuple):
    """One edge's terms for each pair (``_edges``); a NamedTuple, which ``torch.compile``
    traces as one graph (docs/design_notes.md)."""

    qx: Any
    qy: Any
    ex: Any
    ey: Any
    c: Any
    t: Any
    rx: Any
    ry: Any
    d2: Any


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
        parts.append(_Edge(qx, qy, ex, ey, ex * qy - ey * qx, t, rx, ry, rx * rx + ry * ry))
    return parts


def _step(x, ops):
    """1.0 where x > 0, else 0.0, in x's dtype: a mask to multiply by. On a CPU a comparison
    costs torch 3x an arithmetic pass and ``where`` 12x; sign and clip cost one each."""
    return ops.clip(ops.sign(x), 0.0, None)


def _pick(mask, a, b):
    """a where ``mask`` (a ``_step``) is 1, else b: exact for finite a and b (a * 1 + b * 0)."""
    return a * mask + b * (1.0 - mask)


def _first(masks):
    """The first of three 0/1 masks of which one at least is 1, one-hot."""
    a, b, _ = masks
    b = b * (1.0 - a)
    return a, b, 1.0 - a - b


def _coverage(edges, config: PipelineConfig, ops):
    """(+1 inside the triangle and -1 outside, the squared distance to the triangle,
    sigmoid(+-d^2 / sigma), coverage D')."""
    c0, c1, c2 = (e.c for e in edges)
    dist2 = ops.minimum(ops.minimum(edges[0].d2, edges[1].d2), edges[2].d2)
    # inside: the three edge functions are all positive or all negative, |sum of signs| = 3
    turns = abs(ops.sign(c0) + ops.sign(c1) + ops.sign(c2))
    side = 2.0 * _step(turns - 2.0, ops) - 1.0
    signed = dist2 * side / config.sigma
    eps = config.coverage_eps
    probability = ops.sigmoid(signed)
    return side, dist2, probability, ops.clip((probability - eps) / (1.0 - eps), 0.0, None)


def _plane(edges, w, ops):
    """(the guarded doubled area, the face's plane of inverse depth at the pixel)."""
    c0, c1, c2 = (e.c for e in edges)
    area2 = c0 + c1 + c2
    area_safe = _pick(_step(abs(area2) - TINY, ops), area2, TINY)
    return area_safe, (c1 * w[0] + c2 * w[1] + c0 * w[2]) / area_safe


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
    plane = _plane(edges, (w0, w1, w2), ops)[1]
    lowest = ops.minimum(ops.minimum(w0, w1), w2)
    highest = ops.maximum(ops.maximum(w0, w1), w2)
    return coverage, ops.maximum(ops.minimum(plane, highest), lowest)


def pair_terms_grad(tri, px, py, coverage, grad_coverage, grad_depth, config: PipelineConfig, ops):
    """The gradient of ``pair_terms`` with respect to ``tri`` in parts: (PAIR_GRAD_PARTS, P),
    given the pairs' coverage (``pair_terms``' own) and the gradients of their coverage and
    depth (P,); ``face_params_grad`` turns the parts, summed over each face's pairs, into the
    faces' (9, N) gradient. Written out so that a backward pass costs one recomputation of the
    pairs' edges, not autograd's graph of them; its masks are ``_step``s multiplied in. What is
    the same for every pair of a face (the plane's screen gradient, the corners at the depth
    clamps) multiplies the face's sums once, not each pair.

    The coverage's slope in the squared distance comes from the coverage itself: D = D' (1 -
    eps) + eps where covered, dD/d(d^2) = -+D (1 - D) / sigma, + inside (where D > 1/2). The
    distance to the triangle is its nearest edge's, |p - (a + t (b - a))|^2, whose slope in a
    and b is -2 r (1 - t) and -2 r t (r from the nearest point to the pixel; t's own slope
    meets r . e = 0). The plane is f(p) = sum_k lambda_k w_k, lambda the pixel's barycentric
    coordinates (lambda_k = c_(k+1) / area, c_i = e_i x q_i the edge functions): its slope in
    w_k is lambda_k, and moving corner k by delta moves it as moving the pixel by
    -lambda_k delta, a slope of -lambda_k grad f (grad f, the plane's screen gradient, is the
    face's own). A clamped depth sends its gradient to the corner whose depth it took.

    Parts: per corner k the distance's slope in x_k and y_k (rows 2k, 2k + 1), then per corner
    the depth's gradient times lambda_k (6 + k), then the depth's gradient where clamped to the
    lowest (9) and to the highest (10) corner depth.
    """
    edges = _edges(tri, px, py, ops)
    eps = config.coverage_eps
    probability = coverage * (1.0 - eps) + eps
    inside = ops.sign(probability - 0.5)  # 0 only where the distance, and so r, is 0
    # d coverage / d dist2 where the coverage is not cut, times grad_coverage, times -2
    grad_dist2 = grad_coverage * (-2.0 / ((1.0 - eps) * config.sigma)) * _step(coverage, ops)
    grad_dist2 = grad_dist2 * (probability * (1.0 - probability) * inside)
    # the nearest edge, the first at the smallest distance, one-hot; edge i runs from corner i
    # to corner i + 1, so the nearest point's weight on corner k is (1 - t) of edge k's and t
    # of edge k - 1's
    d2 = [e.d2 for e in edges]
    second = _step(d2[0] - d2[1], ops)
    third = _step(ops.minimum(d2[0], d2[1]) - d2[2], ops)
    second = second * (1.0 - third)
    nearest = [grad_dist2 * (1.0 - second - third), grad_dist2 * second, grad_dist2 * third]
    # the slope in each edge's nearest point, per axis (index 2 i + axis), shared between the
    # edge's start (1 - t) and end (t); corner k is edge k's start and edge k - 1's end
    at_start, at_end = [], []
    for edge, weight in zip(edges, nearest, strict=True):
        for r in (edge.rx, edge.ry):
            slope = weight * r
            at_end.append(slope * edge.t)
            at_start.append(slope - at_end[-1])
    parts = [at_start[i] + at_end[i - 2] for i in range(6)]

    w = tri[6:9]
    area_safe, plane = _plane(edges, w, ops)
    lowest = ops.minimum(ops.minimum(w[0], w[1]), w[2])
    highest = ops.maximum(ops.maximum(w[0], w[1]), w[2])
    above_lowest = _step(plane - lowest, ops)
    inner = above_lowest * _step(highest - plane, ops)
    grad_plane = grad_depth * inner / area_safe
    # lambda_k = c_(k + 1) / area
    parts += [grad_plane * edges[1].c, grad_plane * edges[2].c, grad_plane * edges[0].c]
    parts += [grad_depth * (1.0 - above_lowest), grad_depth * (above_lowest - inner)]
    return ops.stack(parts)


PAIR_GRAD_PARTS = 11


def face_params_grad(params, parts, ops):
    """(9, N) faces' screen params, (PAIR_GRAD_PARTS, N) each face's ``pair_terms_grad`` parts
    summed over its pairs -> (9, N) the gradient with respect to ``params``: corner k's x and y
    take the distance's slope less the plane's screen gradient times the depth's barycentric
    sum, its depth that sum and the clamped depths' gradients where it is the (first) lowest
    or highest corner."""
    x0, y0, x1, y1, x2, y2 = params[:6]
    w = params[6:9]
    ex0, ey0, ex1, ey1, ex2, ey2 = x1 - x0, y1 - y0, x2 - x1, y2 - y1, x0 - x2, y0 - y2
    # the doubled area as the pairs' edge functions sum to it, guarded as they guard it
    area2 = ex0 * ey1 - ey0 * ex1
    area_safe = _pick(_step(abs(area2) - TINY, ops), area2, TINY)
    # grad f, the plane's screen gradient: c_i's slope in px is -ey_i, in py ex_i
    slope_x = -(ey1 * w[0] + ey2 * w[1] + ey0 * w[2]) / area_safe
    slope_y = (ex1 * w[0] + ex2 * w[1] + ex0 * w[2]) / area_safe
    lowest = ops.minimum(ops.minimum(w[0], w[1]), w[2])
    highest = ops.maximum(ops.maximum(w[0], w[1]), w[2])
    at_lowest = _first([1.0 - _step(wk - lowest, ops) for wk in w])
    at_highest = _first([1.0 - _step(highest - wk, ops) for wk in w])
    grads = []
    for k in range(3):
        grads += [parts[2 * k] - slope_x * parts[6 + k], parts[2 * k + 1] - slope_y * parts[6 + k]]
    for k in range(3):
        grads.append(parts[6 + k] + parts[9] * at_lowest[k] + parts[10] * at_highest[k])
    return ops.stack(grads)


def pair_logit(coverage, depth, config: PipelineConfig, ops):
    """A covered pair's softmax logit in SoftRas' blend: log D' + depth / gamma."""
    return ops.log(coverage) + depth / config.gamma


def pair_logits(coverage, depth, config: PipelineConfig, ops):
    """The logits each pixel's largest is taken over, one an enumerated pair: ``pair_logit``
    where the pair is covered, the background's (every pixel's floor) where it is not; not
    log 0 = -inf, whose log costs torch 6x a finite one's on a CPU."""
    covered = _step(coverage, ops)
    logit = pair_logit(coverage + (1.0 - covered), depth, config, ops)
    return _pick(covered, logit, background_logit(config))


def background_logit(config: PipelineConfig) -> float:
    """The background's logit, every pixel's floor: background_eps / gamma."""
    return config.background_eps / config.gamma


def mesh_orientation(verts, faces, ops):
    """(V, 3) world vertices and (F, 3) faces, or a batch (B, V, 3) and (B, F, 3) -> (B,) +1.0
    where the faces wind outward, -1.0 where the mesh is wound inside out: the sign of its signed
    volume about the world origin, where the cameras look (an open mesh's is the side most of
    its surface winds towards; a padding face of no area adds nothing). A mesh whose volume is
    no clear share of its tetrahedra's (``ORIENTED_SHARE``), a flat relief even roughened,
    keeps its winding: the sign would be rounding's or noise's."""
    if faces.ndim == 2:
        verts, faces = verts[None], faces[None]
    (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = (
        [ops.take(verts[..., axis], faces[..., corner]) for axis in range(3)] for corner in range(3)
    )
    # six times each face's tetrahedron with the origin, v0 . (v1 x v2)
    tetra = x0 * (y1 * z2 - z1 * y2) + y0 * (z1 * x2 - x1 * z2) + z0 * (x1 * y2 - y1 * x2)
    clear = ORIENTED_SHARE * abs(tetra).sum(-1) + 6.0 * FLAT_VOLUME
    return ops.where(tetra.sum(-1) < -clear, -1.0, 1.0)


def outward_signs(
    verts: np.ndarray, faces: np.ndarray, eyes: np.ndarray, config: PipelineConfig
) -> np.ndarray:
    """(V, 3) world vertices and (F, 3) faces, or a batch (B, V, 3) and (B, F, 3), and the
    cameras' (K, 3) world positions -> (B, F), or (B, 1) for every face alike: +1.0 where a
    face's winding points outward, -1.0 where it is turned, by ``config.winding``: 'file' turns
    the mesh's winding as a whole by the sign of its volume (``mesh_orientation``), 'geometry'
    orients each face by the surface it belongs to (``face_orientation``). Moot under
    two-sided light, where no face is in the shadow."""
    verts, faces = np.asarray(verts, dtype=np.float64), np.asarray(faces)
    if faces.ndim == 2:
        verts, faces = verts[None], faces[None]
    if config.back_light >= 1.0:
        return np.ones((len(faces), 1))
    if config.winding == "file":
        return mesh_orientation(verts, faces, NUMPY_OPS)[:, None]
    return np.stack([face_orientation(v, f, eyes) for v, f in zip(verts, faces, strict=True)])


def face_orientation(verts: np.ndarray, faces: np.ndarray, eyes: np.ndarray) -> np.ndarray:
    """(V, 3) world vertices, (F, 3) faces and the cameras' (K, 3) positions -> (F,) +1.0 where
    a face's winding points outward, -1.0 where it points inward, read from the geometry and
    not from how the file happens to wind it. Faces that share an edge with no third face
    (vertices joined by position, so an unwelded soup is joined too; a face's copies,
    double-sided or repeated, count once) lie on one piece of surface and are wound alike
    (where a neighbour runs the shared edge the same way, one of the two is turned); each piece
    is then turned as a whole by the sign of its volume: a closed piece's own, an open one's
    about the origin where it is a clear share (the rule of ``mesh_orientation``); an open piece
    whose volume is no clear share (a relief, a sheet) shows its outside to the cameras, the side
    more of its area faces. A face that shares no edge takes the whole mesh's
    ``mesh_orientation``; a piece that cannot be wound alike (a Moebius band) keeps the file's
    winding, turned as a whole. So faces flipped at random, a part wound against the rest, a
    mesh wound inside out or double-sided render as one surface wound outward."""
    count = len(faces)
    if count == 0:
        return np.ones(0)
    corners = _same_rows(verts)[faces]
    # a face's copies (the same three vertices, either way round) stand on its first's side
    copy_of = _same_rows(np.sort(corners, axis=1))
    parity = _cyclic_parity(corners)
    unique = np.flatnonzero(copy_of == np.arange(count))
    signs = np.ones(count)
    signs[unique] = _piece_signs(verts, faces[unique], corners[unique], eyes)
    alone = signs == 0.0
    if alone.any():
        signs[alone] = mesh_orientation(verts, faces, NUMPY_OPS)[0]
    return signs[copy_of] * np.where(parity == parity[copy_of], 1.0, -1.0)


def opposed_edges(verts: np.ndarray, faces: np.ndarray) -> int:
    """How many edges two faces share and run the same way (vertices joined by position;
    edges of three faces or more, where parts meet, left out): 0 for a consistently wound
    surface; more where a face is wound against its neighbours, a part against the rest, or a
    face doubled to be seen from both sides, which a config's ``winding`` 'file' shades as the
    inside of a shell."""
    return int(np.count_nonzero(_edge_uses(_same_rows(verts)[faces]).alike))


class _EdgeUses(NamedTuple):
    """Faces' edges grouped by edge (either direction). face: (U,) the face of each use, an
    edge's uses together; uses: (E,) how many faces use each edge; first: (P,) the first use
    of each edge exactly two faces share; alike: (P,) whether those two run it the same way
    (are wound against each other)."""

    face: np.ndarray
    uses: np.ndarray
    first: np.ndarray
    alike: np.ndarray


def _edge_uses(corners: np.ndarray) -> _EdgeUses:
    """The edges of faces given as (F, 3) welded vertex indices; edges of no length left out."""
    corners = corners.astype(np.int64)
    start, end = corners.reshape(-1), corners[:, [1, 2, 0]].reshape(-1)
    face = np.repeat(np.arange(len(corners)), 3)
    real = start != end
    start, end, face = start[real], end[real], face[real]
    key = np.minimum(start, end) * (int(corners.max(initial=0)) + 1) + np.maximum(start, end)
    order = np.argsort(key, kind="stable")
    key, forward, face = key[order], (start < end)[order], face[order]
    edge_start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    uses = np.diff(np.r_[edge_start, len(key)])
    first = edge_start[uses == 2]
    return _EdgeUses(face, uses, first, forward[first] == forward[first + 1])


def _same_rows(rows: np.ndarray) -> np.ndarray:
    """(N,) for each row of (N, 3) the index of the first row equal to it."""
    order = np.lexsort(rows.T[::-1])
    ordered = rows[order]
    new = np.r_[True, (ordered[1:] != ordered[:-1]).any(axis=1)]
    group = np.cumsum(new) - 1
    first = np.minimum.reduceat(order, np.flatnonzero(new))  # the group's earliest row
    found = np.empty(len(rows), dtype=np.int64)
    found[order] = first[group]
    return found


def _cyclic_parity(corners: np.ndarray) -> np.ndarray:
    """(F,) whether each face's corners run as their sorted order does (True) or against it."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    return ((a < b) & (b < c)) | ((b < c) & (c < a)) | ((c < a) & (a < b))


def _piece_signs(
    verts: np.ndarray, faces: np.ndarray, corners: np.ndarray, eyes: np.ndarray
) -> np.ndarray:
    """(F,) of distinct faces: +1.0 or -1.0 per ``face_orientation``'s pieces, 0.0 for a face
    that shares no edge."""
    count = len(faces)
    face, uses, first, alike = _edge_uses(corners)
    f, g = face[first], face[first + 1]  # the two faces of each edge exactly two share
    # node f is face f as wound, node f + count the face turned: joining f to g (or to g turned
    # where the two are wound against each other) and their turned selves, each component of
    # the nodes is one piece of surface wound one way
    turned_g = g + count * alike
    label = _components(2 * count, np.r_[f, f + count], np.r_[turned_g, g + count * ~alike])
    as_wound, turned = label[:count], label[count:]
    relative = np.where(as_wound > turned, -1.0, 1.0)  # the class of the lesser label: as wound
    piece = np.minimum(as_wound, turned)
    x0, x1, x2 = (verts[faces[:, k]] for k in range(3))
    tetra = np.einsum("ij,ij->i", x0, np.cross(x1, x2)) * relative
    volume = np.bincount(piece, tetra, minlength=2 * count)
    clear = ORIENTED_SHARE * np.bincount(piece, abs(tetra), minlength=2 * count) + 6 * FLAT_VOLUME
    # a closed piece (no edge of it borders nothing or a third face) has its true volume
    loose = np.bincount(piece[face[np.repeat(uses != 2, uses)]], minlength=2 * count) > 0
    clear = np.where(loose, clear, 6 * FLAT_VOLUME)
    sign = np.where(volume < 0, -1.0, 1.0)
    unclear = abs(volume) <= clear
    vague = np.flatnonzero(unclear[piece])
    if len(vague):  # no clear volume: the side the cameras see more of, area by area
        a, b, c = x0[vague], x1[vague], x2[vague]
        normal = np.cross(b - a, c - a) * relative[vague, None]
        seen = np.sign(normal @ eyes.T - np.einsum("ij,ij->i", normal, a)[:, None]).sum(1)
        area = seen * np.linalg.norm(normal, axis=1)
        facing = np.bincount(piece[vague], area, minlength=2 * count)
        sign[unclear] = np.where(facing < 0, -1.0, 1.0)[unclear]
    joined = np.bincount(np.r_[f, g], minlength=count) > 0
    return np.where(joined, relative * sign[piece], 0.0)


def _components(count: int, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(count,) a label per node, the same across each connected component of the edges
    (u, v): each root hooked under the least root it meets, then every node pointed at its
    root, until no edge joins two roots."""
    parent = np.arange(count)
    while True:
        pu, pv = parent[u], parent[v]
        apart = pu != pv
        if not apart.any():
            return parent
        np.minimum.at(parent, np.maximum(pu, pv)[apart], np.minimum(pu, pv)[apart])
        while True:
            up = parent[parent]
            if np.array_equal(up, parent):
                break
            parent = up


def face_light(verts_cam, faces, orientation, config: PipelineConfig, ops):
    """(K, V, 3) camera-frame vertices, (F, 3) faces, or a batch (B, K, V, 3), (B, F, 3), and
    the faces' (B, F) or (B, 1) ``outward_signs`` -> (lit, shadow, behind), (B*K*F,) each.

    lit: flat Lambertian grey, a face seen from behind lit as if its normal faced the camera
    (two-sided); shadow: the diffuse light the shell's shadow takes from a face seen from behind,
    (1 - ``config.back_light``) of it, 0 on a face seen from the front; behind: 1.0 where the
    face's outward side (its winding, turned by the orientation) looks away from the camera.
    A face's grey is lit - shadow: at ``back_light`` 1 (two-sided) open and non-watertight
    meshes show their inner side lit as surface, at 0 in the shell's shadow (ambient alone).
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
    # the normal as wound, turned towards the camera: two-sided light reads no winding
    towards = ops.where(outward > 0, -1.0, 1.0)
    light = np.asarray(config.light_direction, dtype=np.float64)
    lx, ly, lz = (float(v) for v in light / np.linalg.norm(light))
    lambert = ops.clip((nx * lx + ny * ly + nz * lz) * towards, 0.0, None)
    behind = ops.where(outward * orientation[:, None, :] > 0, 1.0, 0.0)
    lit = config.ambient + config.diffuse * lambert
    # the light times (1 - share) itself, not a precomputed factor: a share float32 cannot hold
    # takes the same rounding on both paths
    shadow = behind * (config.diffuse * lambert - config.diffuse * lambert * config.back_light)
    return lit.reshape(-1), shadow.reshape(-1), behind.reshape(-1)


def pushes_back(config: PipelineConfig) -> bool:
    """Whether the shell's shadow falls only where faces seen from behind still show when pushed
    back (``pushed_back``): a second blend, of the shadow alone."""
    return config.back_push > 0 and config.back_light < 1


def pushed_back(screen: ScreenFaces, behind, config: PipelineConfig, ops) -> ScreenFaces:
    """The screen with each face seen from behind (``behind``, (N,) 1.0 or 0.0) pushed back by
    ``config.back_push`` of normalised inverse depth behind the faces seen from the front, so
    the soft blend leaves it only pixels that no face seen from the front reaches within the
    push: an opening's inside, not an outline. The faces seen from the front are drawn forward
    by the push, not those from behind sent back: the background stays behind both."""
    shift = (1.0 - behind) * config.back_push
    params = screen.params
    params = ops.stack([*(params[i] for i in range(6)), *(params[i] + shift for i in range(6, 9))])
    return ScreenFaces(params, screen.visible, screen.num_views, screen.num_faces)


def blend_weight(logit, logit_max, ops):
    """A pair's weight in SoftRas' blend, its logit shifted by its pixel's largest so none
    overflows: w = exp(logit - logit_max)."""
    return ops.exp(logit - logit_max)


def blend_image(numerator, denominator, logit_max, config: PipelineConfig, ops, background=None):
    """Per pixel: I = (sum_j w_j C_j + w_b C_b) / (sum_j w_j + w_b), from the sums of the
    pairs' weighted colours (``numerator``) and weights (``denominator``), w_b = exp(background
    logit - logit_max); C_b the config's background unless ``background`` is given (0 for the
    shadow's blend, which only takes light away)."""
    colour = config.background if background is None else background
    weight = ops.exp(background_logit(config) - logit_max)
    return (numerator + weight * colour) / (denominator + weight)


def soft_blend(pixel, face, logit, logit_max, colors, config: PipelineConfig, ops, background=None):
    """SoftRas aggregation of pixel-face pairs -> (K*S*S,) flat grey images; ``logit_max``
    (K*S*S,) is each pixel's largest logit, background included (``blend_image``)."""
    weight = blend_weight(logit, logit_max[pixel], ops)
    numerator = ops.scatter_sum(pixel, weight * colors[face], len(logit_max))
    denominator = ops.scatter_sum(pixel, weight, len(logit_max))
    return blend_image(numerator, denominator, logit_max, config, ops, background)
