"""The soft rasteriser's per pixel-face terms, written once for torch and numpy.

Torch-free: ``drkfs_onnx.rasterize`` passes the ``torch`` module as ``ops``, the runtime passes
``NUMPY_OPS``; both need ``where``, ``minimum``, ``maximum``, ``clip`` and ``sigmoid``.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from .config import PipelineConfig

TINY = 1e-12


def _sigmoid(x: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        return 1.0 / (1.0 + np.exp(-x))


NUMPY_OPS = SimpleNamespace(
    where=np.where, minimum=np.minimum, maximum=np.maximum, clip=np.clip, sigmoid=_sigmoid
)


def pair_terms(tri, px, py, config: PipelineConfig, ops):
    """Coverage D' and normalised inverse depth of P pixel-face pairs.

    tri: (9, P) face params (see ``rasterize.ScreenFaces``); px, py: (P,) pixel centres in NDC.
    Depth is the face's plane at the pixel (inverse depth is affine in screen space), clamped to
    the face's own depth range. Coplanar pieces of a surface then agree on depth however it is
    tessellated; SoftRas' clipped barycentrics instead jump to far vertices outside a face and
    let a barely-covering face win the depth softmax.
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
