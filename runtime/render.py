"""The torch renderer's evaluation images, in numpy.

The same soft equations as ``drkfs_onnx.rasterize`` and ``drkfs_onnx.shade`` (coverage
D' = (sigmoid(+-d^2 / sigma) - eps) / (1 - eps), depth from the face plane clamped to the face's
range, SoftRas' softmax blend with the background, the same depth cull), evaluated once without
autograd, so runtime images equal the torch path's to float rounding. Pixel-face pairs are listed
per face over its bounding box grown by the cut-off radius, in chunks, as in the torch rasteriser;
a float32 pass of per-face affine tests (edge lines, plane depth) keeps the pairs that may be
covered and unhidden, and a float64 pass computes those exactly.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from drkfs_onnx.cameras import Cameras, make_cameras
from drkfs_onnx.config import PipelineConfig
from drkfs_onnx.coverage import NUMPY_OPS, pair_terms

DEPTH_CULL = 30.0
# float32 logits near 1 / gamma = 1e4 are good to ~1e-3; a wide margin costs a few pairs
CULL_MARGIN = 2.0
# Candidates reach slightly beyond the cut-off radius, so float32 rounding never drops a pair.
LOOSE_RADIUS = 1.01
PAIR_CHUNK = 1 << 18
TINY_LENGTH = 1e-9
# Inverse-depth slope (per NDC unit) above which float32 plane evaluation is not trusted.
MAX_SLOPE = 100.0


def _face_shading(verts_cam: np.ndarray, faces: np.ndarray, config: PipelineConfig) -> np.ndarray:
    """(K, V, 3), (F, 3) -> (K*F,) flat two-sided Lambertian grey."""
    v0, v1, v2 = (verts_cam[:, faces[:, i]] for i in range(3))
    normal = np.cross(v1 - v0, v2 - v0)
    normal /= np.sqrt((normal * normal).sum(-1, keepdims=True) + 1e-20)
    centroid = (v0 + v1 + v2) / 3.0
    towards = np.where((normal * centroid).sum(-1, keepdims=True) > 0, -1.0, 1.0)
    light = np.asarray(config.light_direction, dtype=np.float64)
    lambert = np.maximum((normal * towards) @ (light / np.linalg.norm(light)), 0.0)
    return (config.ambient + config.diffuse * lambert).reshape(-1)


class NumpyRenderer:
    """``render(verts (V, 3), faces (F, 3)) -> (K, S, S)`` float32 grey views.

    threads: views are independent, so groups of cameras render in parallel (numpy releases the
    GIL in its array loops).
    """

    def __init__(self, config: PipelineConfig, cameras: Cameras | None = None, threads: int = 1):
        self.config = config
        self.cameras = cameras if cameras is not None else make_cameras(config)
        self.threads = max(1, threads)

    def render(self, verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
        verts = np.asarray(verts, dtype=np.float64)
        groups = np.array_split(np.arange(len(self.cameras)), min(self.threads, len(self.cameras)))
        cams = self.cameras
        parts = [
            Cameras(rotations=cams.rotations[g], eyes=cams.eyes[g], focal=cams.focal)
            for g in groups
        ]
        if len(parts) == 1:
            return self._render(verts, faces, parts[0])
        with ThreadPoolExecutor(len(parts)) as pool:
            images = list(pool.map(lambda c: self._render(verts, faces, c), parts))
        return np.concatenate(images)

    def _render(self, verts: np.ndarray, faces: np.ndarray, cameras: Cameras) -> np.ndarray:
        cfg, size = self.config, self.config.image_size
        k = len(cameras)
        verts_cam = cameras.world_to_camera(verts)
        z = verts_cam[..., 2]
        near_ok = z > cfg.near
        z_safe = np.where(near_ok, z, cfg.near)
        xy = cameras.focal * verts_cam[..., :2] / z_safe[..., None]
        inv_near, inv_far = 1.0 / cfg.near, 1.0 / cfg.far
        inv_depth = (1.0 / z_safe - inv_far) / (inv_near - inv_far)
        f = len(faces)
        params = np.concatenate(
            [xy[:, faces].reshape(k * f, 6), inv_depth[:, faces].reshape(k * f, 3)], axis=1
        ).T
        visible = near_ok[:, faces].all(axis=2).reshape(k * f)
        pixel, face = self._candidates(params, visible, k, f)
        # Exact pass in float64 on the surviving pairs, as the torch rasteriser computes them.
        px = (2 * (pixel % size) + 1) / size - 1.0
        py = (2 * (pixel // size % size) + 1) / size - 1.0
        coverage, depth = pair_terms(params[:, face], px, py, cfg, NUMPY_OPS)
        covered = coverage > 0
        pixel, face = pixel[covered], face[covered]
        logit = np.log(coverage[covered]) + depth[covered] / cfg.gamma
        logit_max = np.full(k * size * size, cfg.background_eps / cfg.gamma)
        np.maximum.at(logit_max, pixel, logit)
        kept = logit >= logit_max[pixel] - DEPTH_CULL
        pixel, face, logit = pixel[kept], face[kept], logit[kept]
        weight = np.exp(logit - logit_max[pixel])
        colors = _face_shading(verts_cam, faces, cfg)
        numerator = np.bincount(pixel, weight * colors[face], minlength=k * size * size)
        denominator = np.bincount(pixel, weight, minlength=k * size * size)
        background = np.exp(cfg.background_eps / cfg.gamma - logit_max)
        image = (numerator + background * cfg.background) / (denominator + background)
        return image.reshape(k, size, size).astype(np.float32)

    def _candidates(self, params: np.ndarray, visible: np.ndarray, k: int, f: int):
        """Pixel-face pairs that may be covered and not hidden: flat pixel and face indices.

        Lists each face's bounding box grown by the cut-off radius and tests the pairs with
        per-face affine functions in float32 (``_face_planes``): a pixel further than the radius
        outside any edge's line is uncovered; a pixel inside a face is covered at least as much
        as on its edge, so its plane depth bounds the pixel's winning logit from below; a pair
        whose plane depth is more than DEPTH_CULL + CULL_MARGIN logits below that is hidden.
        """
        cfg, size = self.config, self.config.image_size
        radius = cfg.coverage_radius
        xs, ys = params[0:6:2], params[1:6:2]

        def to_index(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            first = np.clip(np.ceil((lo - radius + 1.0) * size / 2.0 - 0.5), 0, size)
            last = np.clip(np.floor((hi + radius + 1.0) * size / 2.0 - 0.5), -1, size - 1)
            first, last = first.astype(np.int64), last.astype(np.int64)
            return first, np.maximum(last - first + 1, 0)

        i0, width = to_index(xs.min(0), xs.max(0))
        j0, height = to_index(ys.min(0), ys.max(0))
        counts = width * height * visible
        # int32 index arithmetic halves the memory traffic of listing pairs
        i0, width, counts = i0.astype(np.int32), width.astype(np.int32), counts.astype(np.int32)
        first_row = (np.repeat(np.arange(k), f) * size + j0).astype(np.int32)
        lines, plane, (lowest, highest), trusted = _face_planes(params)
        inv_gamma = np.float32(1.0 / cfg.gamma)
        # Coverage on a face's edge: (sigmoid(0) - eps) / (1 - eps); inside it is higher.
        edge_log_coverage = np.log((0.5 - cfg.coverage_eps) / (1.0 - cfg.coverage_eps))
        ids = np.nonzero(counts)[0]
        out_pixel, out_face, out_logit, out_sure = [], [], [], []
        bucket = (np.cumsum(counts[ids]) - 1) // PAIR_CHUNK
        for chunk in np.split(ids, np.nonzero(np.diff(bucket))[0] + 1) if len(ids) else []:
            n = counts[chunk]
            pair_face = np.repeat(chunk, n)
            starts = (np.cumsum(n) - n).astype(np.int32)
            local = np.arange(n.sum(), dtype=np.int32) - np.repeat(starts, n)
            down, across = np.divmod(local, width[pair_face])
            row = first_row[pair_face] + down
            col = i0[pair_face] + across
            px = col.astype(np.float32) * np.float32(2 / size) + np.float32(1 / size - 1)
            py = (row % size).astype(np.float32) * np.float32(2 / size) + np.float32(1 / size - 1)
            inside = None
            for a, b, c in lines:
                distance = a[pair_face] * px + b[pair_face] * py + c[pair_face]
                inside = distance if inside is None else np.minimum(inside, distance)
            near = inside > -LOOSE_RADIUS * radius
            pair_face, px, py, inside = pair_face[near], px[near], py[near], inside[near]
            a, b, c = plane
            depth = a[pair_face] * px + b[pair_face] * py + c[pair_face]
            depth = np.minimum(np.maximum(depth, lowest[pair_face]), highest[pair_face])
            out_pixel.append(row[near].astype(np.int64) * size + col[near])
            out_face.append(pair_face)
            out_logit.append(depth * inv_gamma)
            out_sure.append((inside > 0) & trusted[pair_face])
        if not out_pixel:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        pixel, face, logit = map(np.concatenate, (out_pixel, out_face, out_logit))
        sure = np.concatenate(out_sure)
        # logit bounds every pair's logit from above, and a sure pair's from below once the
        # edge's log coverage is added: only sure pairs may cull others.
        logit_max = np.full(k * size * size, cfg.background_eps / cfg.gamma, dtype=np.float32)
        np.maximum.at(logit_max, pixel[sure], logit[sure] + np.float32(edge_log_coverage))
        kept = logit >= logit_max[pixel] - (DEPTH_CULL + CULL_MARGIN)
        return pixel[kept], face[kept]


def _face_planes(params: np.ndarray):
    """Affine functions of the pixel (px, py) per face, float32: ``lines`` (3 edges x (a, b, c))
    give the signed distance to each edge's line, positive inside; ``plane`` (a, b, c) the
    face plane's inverse depth, to be clamped to the face's ``(lowest, highest)`` vertex depth,
    which is exact where ``trusted``. Edge-on faces (steep planes,
    where float32 cancellation would mislead) get their highest vertex depth and are not
    trusted, so they never cull."""
    x0, y0, x1, y1, x2, y2, w0, w1, w2 = params
    area2 = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
    orient = np.sign(area2)
    lines = []
    for ax, ay, bx, by in ((x0, y0, x1, y1), (x1, y1, x2, y2), (x2, y2, x0, y0)):
        ex, ey = bx - ax, by - ay
        scale = orient / np.maximum(np.sqrt(ex * ex + ey * ey), TINY_LENGTH)
        lines.append(
            tuple(
                v.astype(np.float32) for v in (-ey * scale, ex * scale, (ey * ax - ex * ay) * scale)
            )
        )
    safe = np.where(np.abs(area2) > TINY_LENGTH**2, area2, 1.0)
    # w(p) = w0 + (w1 - w0) * beta + (w2 - w0) * gamma, barycentrics affine in p
    slope_x = ((w1 - w0) * (y2 - y0) - (w2 - w0) * (y1 - y0)) / safe
    slope_y = ((w2 - w0) * (x1 - x0) - (w1 - w0) * (x2 - x0)) / safe
    trusted = (np.abs(area2) > TINY_LENGTH**2) & (np.abs(slope_x) + np.abs(slope_y) < MAX_SLOPE)
    lowest, highest = params[6:].min(0), params[6:].max(0)
    slope_x, slope_y = np.where(trusted, slope_x, 0.0), np.where(trusted, slope_y, 0.0)
    offset = np.where(trusted, w0 - slope_x * x0 - slope_y * y0, highest)
    plane = tuple(v.astype(np.float32) for v in (slope_x, slope_y, offset))
    return lines, plane, (lowest.astype(np.float32), highest.astype(np.float32)), trusted
