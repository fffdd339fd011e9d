"""How the nets' convolutions run on a GPU: their precision and their memory layout."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch

# 'ieee': float32 throughout; 'tf32': cuDNN rounds a convolution's inputs to TF32's 10-bit
# mantissa (torch's own default). On an H100 TF32 turned a batch's gradient away from the
# per-mesh loop's (B = 4: cosine 0.99996-0.99998, against at least 0.999994 in float32), and
# saved the B = 32 step 57.5 -> 51.6 ms (coarse) and 69.5 -> 54.9 ms (fine)
CONV_PRECISIONS = ("ieee", "tf32")


def check_conv_precision(precision: str) -> str:
    if precision not in CONV_PRECISIONS:
        raise ValueError(
            f"unknown conv_precision {precision!r}; use one of {', '.join(CONV_PRECISIONS)}"
        )
    return precision


def current() -> str:
    """The precision cuDNN's float32 convolutions run at now."""
    return torch.backends.cudnn.conv.fp32_precision


@contextlib.contextmanager
def conv_precision(precision: str) -> Iterator[None]:
    """cuDNN's float32 convolutions at ``precision`` inside (no effect on a CPU); the setting
    is process-wide while it lasts. ``precision`` is any of torch's values ('none' too, as a
    backward restores what its forward ran at); a user's choice is checked where it is made
    (``check_conv_precision``)."""
    before = current()
    torch.backends.cudnn.conv.fp32_precision = precision
    try:
        yield
    finally:
        torch.backends.cudnn.conv.fp32_precision = before


# The activations' layout on a GPU: cuDNN's float32 convs ran faster in NCHW than channels-last
# (H100, the training step at B = 32: coarse 62.1 -> 57.5 ms and 3.06 -> 2.92 GB, fine 82.8 ->
# 69.5 ms and 2.82 -> 2.66 GB). On a CPU always channels-last: mkldnn ran HardNet's many small
# patches ~1.4x faster in it
GPU_LAYOUT = torch.contiguous_format


def conv_layout(device: torch.device) -> torch.memory_format:
    """The memory layout the nets' convolutions run in on ``device``."""
    return GPU_LAYOUT if device.type == "cuda" else torch.channels_last
