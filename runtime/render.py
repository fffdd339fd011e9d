"""The torch renderer's evaluation images, in numpy.

The same soft equations as ``drkfs_onnx.rasterize`` and ``drkfs_onnx.shade`` (coverage
D' = (sigmoid(+-d^2 / sigma) - eps) / (1 - eps), depth from the face plane clamped to the face's
range, SoftRas' softmax blend with the background, the same depth cull), evaluated once without
autograd, so runtime images equal the torch path's to float rounding. Pixel-face pairs are listed
per face over its bounding box grown by the cut-off radius, in chunks, as in the torch rasteriser;
a float32 pass finds the covered, unhidden pairs and a float64 pass computes them exactly.
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
LOOSE_EPS = 0.9
PAIR_CHUNK = 1 << 18


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
        # The float32 candidate pass keeps a superset of the covered pairs: a slightly lower
        # coverage cut-off than the exact pass, which then drops the extras.
        self._loose = config.replace(coverage_eps=config.coverage_eps * LOOSE_EPS)

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

        Lists each face's bounding box grown by the cut-off radius, scores the pairs in float32
        (about 4x faster than float64) with the loose cut-off, and drops pairs hidden by more
        than DEPTH_CULL + CULL_MARGIN logits.
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
        params32 = params.astype(np.float32)
        ids = np.nonzero(counts)[0]
        # A loose coverage above twice the cut-offs' gap is positive at the exact cut-off too.
        sure_coverage = 2.0 * (cfg.coverage_eps - self._loose.coverage_eps)
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
            coverage, depth = pair_terms(params32[:, pair_face], px, py, self._loose, NUMPY_OPS)
            keep = coverage > 0
            out_pixel.append((row.astype(np.int64) * size + col)[keep])
            out_face.append(pair_face[keep])
            out_logit.append(np.log(coverage[keep]) + depth[keep] / np.float32(cfg.gamma))
            out_sure.append(coverage[keep] > sure_coverage)
        if not out_pixel:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        pixel, face, logit = map(np.concatenate, (out_pixel, out_face, out_logit))
        # Only pairs surely covered at the exact cut-off may cull others.
        sure = np.concatenate(out_sure)
        logit_max = np.full(k * size * size, cfg.background_eps / cfg.gamma, dtype=np.float32)
        np.maximum.at(logit_max, pixel[sure], logit[sure])
        kept = logit >= logit_max[pixel] - (DEPTH_CULL + CULL_MARGIN)
        return pixel[kept], face[kept]
