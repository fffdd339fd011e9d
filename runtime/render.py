"""The torch renderer's evaluation images, in numpy.

The same soft equations as ``drkfs_onnx.rasterize`` and ``drkfs_onnx.shade`` (coverage
D' = (sigmoid(+-d^2 / sigma) - eps) / (1 - eps), depth from the face plane clamped to the face's
range, SoftRas' softmax blend with the background, the same depth cull), evaluated once without
autograd, so runtime images equal the torch path's to float rounding. A float32 pass
(``candidates``) keeps the pixel-face pairs that may be covered and unhidden, and a float64 pass
computes those exactly, in cache-sized chunks.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from drkfs_onnx.cameras import Cameras, make_cameras
from drkfs_onnx.config import PipelineConfig
from drkfs_onnx.coverage import NUMPY_OPS, pair_terms

from .candidates import DEPTH_CULL, candidate_pairs, select

# Pairs per exact-pass chunk: its float64 temporaries stay in cache, and the chunk is long enough
# that threads rendering other views seldom wait for the GIL between numpy calls (2 threads:
# 5-12% faster than 1 << 13; one thread: 2-5% slower).
EXACT_CHUNK = 1 << 14
# View-faces rendered in one call. Small meshes share a call's fixed cost across views (cow,
# 6 views: 1.5x faster than a view per call); larger ones render fewer views per call, down to
# one, so memory follows one view's pixel-face pairs, not all views' (a 500k-face mesh under the
# paper preset peaked at 6.6 GB with every view in one call, 0.5 GB a view at a time).
VIEW_FACES_PER_CALL = 1 << 16


def _face_shading(verts_cam: np.ndarray, faces: np.ndarray, config: PipelineConfig) -> np.ndarray:
    """(K, V, 3), (F, 3) -> (K*F,) flat two-sided Lambertian grey."""
    # one (K, F) array per coordinate of each corner: contiguous loops, not length-3 rows
    (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = (
        [verts_cam[:, faces[:, i], axis] for axis in range(3)] for i in range(3)
    )
    ax, ay, az, bx, by, bz = x1 - x0, y1 - y0, z1 - z0, x2 - x0, y2 - y0, z2 - z0
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    length = np.sqrt(nx * nx + ny * ny + nz * nz + 1e-20)
    nx, ny, nz = nx / length, ny / length, nz / length
    outward = nx * (x0 + x1 + x2) / 3.0 + ny * (y0 + y1 + y2) / 3.0 + nz * (z0 + z1 + z2) / 3.0
    towards = np.where(outward > 0, -1.0, 1.0)
    lx, ly, lz = np.asarray(config.light_direction, dtype=np.float64) / np.linalg.norm(
        config.light_direction
    )
    lambert = np.maximum((nx * lx + ny * ly + nz * lz) * towards, 0.0)
    return (config.ambient + config.diffuse * lambert).reshape(-1)


def screen_faces(
    verts_cam: np.ndarray, faces: np.ndarray, focal: float, config: PipelineConfig
) -> tuple[np.ndarray, np.ndarray]:
    """(K, V, 3) camera-space vertices, (F, 3) faces -> (9, K*F) screen params (rows x0, y0, x1,
    y1, x2, y2 in NDC, w0, w1, w2 normalised inverse depth; view k's faces at k*F .. (k+1)*F),
    and (K*F,) whether all three vertices lie beyond the near plane."""
    k, f = len(verts_cam), len(faces)
    z = verts_cam[..., 2]
    near_ok = z > config.near
    z_safe = np.where(near_ok, z, config.near)
    x, y = focal * verts_cam[..., 0] / z_safe, focal * verts_cam[..., 1] / z_safe
    inv_near, inv_far = 1.0 / config.near, 1.0 / config.far
    inv_depth = (1.0 / z_safe - inv_far) / (inv_near - inv_far)
    params = np.empty((9, k * f))
    for i in range(3):
        corner = faces[:, i]
        params[2 * i] = x[:, corner].reshape(-1)
        params[2 * i + 1] = y[:, corner].reshape(-1)
        params[6 + i] = inv_depth[:, corner].reshape(-1)
    return params, near_ok[:, faces].all(axis=2).reshape(k * f)


class NumpyRenderer:
    """``render(verts (V, 3), faces (F, 3)) -> (K, S, S)`` float32 grey views.

    threads: groups of views render in parallel (numpy releases the GIL in its array loops).
    """

    def __init__(self, config: PipelineConfig, cameras: Cameras | None = None, threads: int = 1):
        self.config = config
        self.cameras = cameras if cameras is not None else make_cameras(config)
        self.threads = max(1, threads)

    def render(self, verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
        verts = np.asarray(verts, dtype=np.float64)
        views = len(self.cameras)
        views_per_call = max(1, VIEW_FACES_PER_CALL // max(len(faces), 1))
        calls = max(min(self.threads, views), -(-views // views_per_call))
        groups = [self.cameras.select(g) for g in np.array_split(np.arange(views), calls)]
        if self.threads == 1:
            return np.concatenate([self._render(verts, faces, group) for group in groups])
        with ThreadPoolExecutor(min(self.threads, calls)) as pool:
            return np.concatenate(list(pool.map(lambda c: self._render(verts, faces, c), groups)))

    def _render(self, verts: np.ndarray, faces: np.ndarray, cameras: Cameras) -> np.ndarray:
        cfg, size = self.config, self.config.image_size
        k = len(cameras)
        verts_cam = cameras.world_to_camera(verts)
        params, visible = screen_faces(verts_cam, faces, cameras.focal, cfg)
        candidates = candidate_pairs(params, visible, k, cfg)
        pixel, face, logit = self._exact_logits(params, *candidates)
        logit_max = np.full(k * size * size, cfg.background_eps / cfg.gamma)
        np.maximum.at(logit_max, pixel, logit)
        pixel, face, logit = select(logit >= logit_max[pixel] - DEPTH_CULL, pixel, face, logit)
        weight = np.exp(logit - logit_max[pixel])
        colors = _face_shading(verts_cam, faces, cfg)
        numerator = np.bincount(pixel, weight * colors[face], minlength=k * size * size)
        denominator = np.bincount(pixel, weight, minlength=k * size * size)
        background = np.exp(cfg.background_eps / cfg.gamma - logit_max)
        image = (numerator + background * cfg.background) / (denominator + background)
        return image.reshape(k, size, size).astype(np.float32)

    def _exact_logits(self, params: np.ndarray, pixel: np.ndarray, face: np.ndarray):
        """The covered pairs among candidates and their logits, log D' + depth / gamma, in
        float64 as the torch rasteriser computes them; in chunks small enough that the
        temporaries stay in cache."""
        cfg, size = self.config, self.config.image_size
        kept_pixel, kept_face, kept_logit = [], [], []
        for start in range(0, len(pixel), EXACT_CHUNK):
            p, fc = pixel[start : start + EXACT_CHUNK], face[start : start + EXACT_CHUNK]
            px = (2 * (p % size) + 1) / size - 1.0
            py = (2 * (p // size % size) + 1) / size - 1.0
            coverage, depth = pair_terms(params[:, fc], px, py, cfg, NUMPY_OPS)
            p, fc, coverage, depth = select(coverage > 0, p, fc, coverage, depth)
            kept_pixel.append(p)
            kept_face.append(fc)
            kept_logit.append(np.log(coverage) + depth / cfg.gamma)
        if not kept_pixel:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        return tuple(map(np.concatenate, (kept_pixel, kept_face, kept_logit)))
