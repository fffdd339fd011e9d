"""The torch renderer's evaluation images, in numpy.

The equations are ``drkfs_onnx.contract.render_equations``', the ones the torch renderer runs
(projection, coverage and depth, shading, the soft blend, the depth cull), evaluated once
without autograd, so runtime images equal the torch path's to float rounding. Only the culling
is numpy's own: a float32 pass (``candidates``) keeps the pixel-face pairs that may be covered
and unhidden, and a float64 pass computes those exactly, in cache-sized chunks.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from drkfs_onnx.contract.array_ops import NUMPY_OPS
from drkfs_onnx.contract.cameras import Cameras, make_cameras
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.mesh import has_area
from drkfs_onnx.contract.render_equations import (
    DEPTH_CULL,
    ScreenFaces,
    background_logit,
    face_light,
    outward_signs,
    pair_logit,
    pair_terms,
    pixel_centre,
    project_faces,
    pushed_back,
    pushes_back,
    soft_blend,
)

from .candidates import candidate_pairs, faces_over, select

# Pairs per exact-pass chunk: its float64 temporaries stay in cache, and the chunk is long enough
# that threads rendering other views seldom wait for the GIL between numpy calls
# (docs/design_notes.md).
EXACT_CHUNK = 1 << 14
# View-faces rendered in one call. Small meshes share a call's fixed cost across views; larger
# ones render fewer views per call, down to one, so memory follows one view's pixel-face pairs,
# not all views' (docs/design_notes.md).
VIEW_FACES_PER_CALL = 1 << 16


class NumpyRenderer:
    """``render(verts (V, 3), faces (F, 3)) -> (K, S, S)`` float32 grey views.

    threads: groups of views render in parallel (numpy releases the GIL in its array loops).
    """

    def __init__(self, config: PipelineConfig, cameras: Cameras | None = None, *, threads: int = 1):
        self.config = config
        self.cameras = cameras if cameras is not None else make_cameras(config)
        self.threads = max(1, threads)

    def render(self, verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
        verts = np.asarray(verts, dtype=np.float64)
        # faces of no area cover no pixel, as on the torch path (check_mesh drops them too)
        faces = np.asarray(faces)[has_area(verts[faces], np.asarray(np.ptp(verts, 0).max()))]
        views = len(self.cameras)
        views_per_call = max(1, VIEW_FACES_PER_CALL // max(len(faces), 1))
        calls = max(min(self.threads, views), -(-views // views_per_call))
        groups = [self.cameras.select(g) for g in np.array_split(np.arange(views), calls)]
        # one per mesh, in the world frame: every group of views shares it
        orientation = outward_signs(verts, faces, self.cameras.eyes, self.config)

        def render_group(cameras: Cameras) -> np.ndarray:
            return self._render(verts, faces, orientation, cameras)

        if self.threads == 1:
            return np.concatenate([render_group(group) for group in groups])
        with ThreadPoolExecutor(min(self.threads, calls)) as pool:
            return np.concatenate(list(pool.map(render_group, groups)))

    def _render(
        self, verts: np.ndarray, faces: np.ndarray, orientation: np.ndarray, cameras: Cameras
    ) -> np.ndarray:
        cfg, size = self.config, self.config.image_size
        k = len(cameras)
        verts_cam = cameras.world_to_camera(verts)
        screen = project_faces(verts_cam, faces, cameras.focal, cfg, NUMPY_OPS)
        lit, shadow, behind = face_light(verts_cam, faces, orientation, cfg, NUMPY_OPS)
        pairs = self._kept_pairs(screen, k)
        if not pushes_back(cfg):
            image = soft_blend(*pairs, lit - shadow, cfg, NUMPY_OPS)
            return image.reshape(k, size, size).astype(np.float32)
        # lit from both sides, less the shadow where faces seen from behind still show pushed
        # back: an opening's inside, not an outline
        image = soft_blend(*pairs, lit, cfg, NUMPY_OPS)
        image -= self._shadow(screen, behind, shadow, pairs)
        return image.reshape(k, size, size).astype(np.float32)

    def _kept_pairs(
        self, screen: ScreenFaces, k: int, pixels: np.ndarray | None = None
    ) -> tuple[np.ndarray, ...]:
        """The pairs the soft blend of ``screen``'s k views keeps (pixel, face, logit) and each
        pixel's largest logit, the background's included; only over ``pixels`` (a (k*S*S,)
        mask) where given: a pixel's pairs and largest logit are its own."""
        cfg, size = self.config, self.config.image_size
        candidates = candidate_pairs(screen.params, screen.visible, k, cfg)
        if pixels is not None:
            candidates = select(pixels[candidates[0]], *candidates)
        pixel, face, logit = self._exact_logits(screen.params, *candidates)
        logit_max = np.full(k * size * size, background_logit(cfg))
        NUMPY_OPS.scatter_max(logit_max, pixel, logit)
        pixel, face, logit = select(logit >= logit_max[pixel] - DEPTH_CULL, pixel, face, logit)
        return pixel, face, logit, logit_max

    def _shadow(self, screen: ScreenFaces, behind, shadow, pairs) -> np.ndarray:
        """(k*S*S,) the blend of the shadow over the screen pushed back (``pushed_back``), given
        the unpushed blend's kept ``pairs``.

        Pushed back, a face seen from behind keeps no pair it did not keep unpushed. Nor does
        it keep one where a face seen from the front kept a pair, once the push exceeds twice
        the depth cull: drawn forward, that face rises above it by more than the cull. There
        the shadow is 0, at every outline of a closed mesh. The faces over the other pixels it
        fell on (an opening's inside) are listed again, pushed back, each view's first."""
        cfg, k = self.config, screen.num_views
        pixel, face, _, logit_max = pairs
        from_behind = behind[face] > 0
        relisted = np.bincount(pixel[from_behind], minlength=len(logit_max)) > 0
        # a logit's margin for the rounding of the pushed planes' depths
        if cfg.back_push / cfg.gamma > 2 * DEPTH_CULL + 1.0:
            relisted &= np.bincount(pixel[~from_behind], minlength=len(logit_max)) == 0
        shade = np.zeros(len(logit_max))
        at = np.nonzero(relisted)[0]
        if not len(at):
            return shade
        over = faces_over(at, screen.params, screen.visible, k, cfg).reshape(k, -1)
        first = np.argsort(~over, axis=1, kind="stable")[:, : over.sum(1).max()]
        index = (first + screen.num_faces * np.arange(k)[:, None]).reshape(-1)
        listed = np.take_along_axis(over, first, 1).reshape(-1)
        relisted_faces = ScreenFaces(screen.params[:, index], listed, k, first.shape[1])
        pushed = pushed_back(relisted_faces, behind[index], cfg, NUMPY_OPS)
        # blended over the relisted pixels alone, numbered 0 .. len(at) - 1
        pixel, face, logit, logit_max = self._kept_pairs(pushed, k, relisted)
        local = np.cumsum(relisted) - 1
        again = soft_blend(
            local[pixel], face, logit, logit_max[at], shadow[index], cfg, NUMPY_OPS, 0.0
        )
        shade[at] = again
        return shade

    def _exact_logits(self, params: np.ndarray, pixel: np.ndarray, face: np.ndarray):
        """The covered pairs among candidates and their logits, log D' + depth / gamma, in
        float64 as the torch rasteriser computes them; in chunks small enough that the
        temporaries stay in cache."""
        cfg, size = self.config, self.config.image_size
        kept_pixel, kept_face, kept_logit = [], [], []
        for start in range(0, len(pixel), EXACT_CHUNK):
            p, fc = pixel[start : start + EXACT_CHUNK], face[start : start + EXACT_CHUNK]
            px = pixel_centre((p % size).astype(np.float64), size)
            py = pixel_centre((p // size % size).astype(np.float64), size)
            coverage, depth = pair_terms(params[:, fc], px, py, cfg, NUMPY_OPS)
            p, fc, coverage, depth = select(coverage > 0, p, fc, coverage, depth)
            kept_pixel.append(p)
            kept_face.append(fc)
            kept_logit.append(pair_logit(coverage, depth, cfg, NUMPY_OPS))
        if not kept_pixel:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        return tuple(map(np.concatenate, (kept_pixel, kept_face, kept_logit)))
