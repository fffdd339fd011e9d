"""How the nets' convolutions run: their precision and their memory layout."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch

# 'ieee': float32 throughout; 'tf32': cuDNN rounds a convolution's inputs to TF32's 10-bit
# mantissa (torch's own default): faster, and a batch's gradient no longer the per-mesh loop's
# to float32 rounding (docs/design_notes.md); 'bfloat16': HardNet's convolutions, forward and
# backward, in bfloat16 (a CPU with AVX-512 BF16 or AMX runs them natively; untested on a GPU),
# its descriptors back in float32 before their normalisation, the detector in float32: a
# cheaper training step whose values are no longer float32's (docs/usage.md)
CONV_PRECISIONS = ("ieee", "tf32", "bfloat16")


def check_conv_precision(precision: str) -> str:
    if precision not in CONV_PRECISIONS:
        raise ValueError(
            f"unknown conv_precision {precision!r}; use one of {', '.join(CONV_PRECISIONS)}"
        )
    return precision


def conv_dtype(precision: str) -> torch.dtype | None:
    """The dtype HardNet's convolutions run in at ``precision``; None: the patches'."""
    return torch.bfloat16 if precision == "bfloat16" else None


def current() -> str:
    """The precision cuDNN's float32 convolutions run at now."""
    return torch.backends.cudnn.conv.fp32_precision


@contextlib.contextmanager
def conv_precision(precision: str) -> Iterator[None]:
    """cuDNN's float32 convolutions at ``precision`` inside (no effect on a CPU); the setting
    is process-wide while it lasts. ``precision`` is any of torch's values ('none' too, as a
    backward restores what its forward ran at) or 'bfloat16', under which the float32
    convolutions left run in IEEE float32; a user's choice is checked where it is made
    (``check_conv_precision``)."""
    before = current()
    torch.backends.cudnn.conv.fp32_precision = "ieee" if precision == "bfloat16" else precision
    try:
        yield
    finally:
        torch.backends.cudnn.conv.fp32_precision = before


# The activations' layout on a GPU: cuDNN's float32 convs run faster in NCHW than channels-last;
# on a CPU always channels-last, where mkldnn runs HardNet's many small patches faster
# (docs/design_notes.md)
GPU_LAYOUT = torch.contiguous_format


def conv_layout(device: torch.device) -> torch.memory_format:
    """The memory layout the nets' convolutions run in on ``device``."""
    return GPU_LAYOUT if device.type == "cuda" else torch.channels_last
