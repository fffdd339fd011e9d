"""Which patches of a view see anything: the one mask both the torch path and the runtime use.

numpy only, so the torch-free runtime and the torch metric skip exactly the same patches.
"""

from __future__ import annotations

import numpy as np

from .config import PipelineConfig


def nonempty_patches(images: np.ndarray, config: PipelineConfig) -> np.ndarray:
    """(K, S, S) rendered images -> (K * P,) bool, row-major per view: does the patch's PoI map
    see anything?

    A patch whose window, grown by the detector's reach, holds only background pixels has the
    constant PoI map of an empty scene, hence one shared descriptor: computing it once is exact.
    Window sums come from an integral image of the non-background pixels.
    """
    reach, size, stride = config.detector_kernel // 2, config.patch_size, config.patch_stride
    window = size + 2 * reach
    seen = np.pad(images != config.background, ((0, 0), (reach, reach), (reach, reach)))
    integral = np.zeros((len(images), seen.shape[1] + 1, seen.shape[2] + 1), dtype=np.int64)
    integral[:, 1:, 1:] = seen.cumsum(1).cumsum(2)
    start = np.arange(config.patches_per_side) * stride
    end = start + window
    total = (
        integral[:, end[:, None], end[None, :]]
        - integral[:, start[:, None], end[None, :]]
        - integral[:, end[:, None], start[None, :]]
        + integral[:, start[:, None], start[None, :]]
    )
    return total.reshape(-1) > 0
