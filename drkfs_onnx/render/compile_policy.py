"""Where the rasteriser's per-pair equations are compiled (``torch.compile``), and how they
fall back to eager torch."""

from __future__ import annotations

import functools
import os
import warnings
from collections.abc import Callable

import torch

from ..contract.config import PipelineConfig
from .torch_ops import TORCH_OPS

# DRKFS_COMPILE's values: where the rasteriser's per-pair equations are compiled
COMPILE_SETTINGS = ("auto", "0", "1")


def compiles(device_type: str, differentiable: bool) -> bool:
    """Whether ``DRKFS_COMPILE`` asks for compiled equations: 'auto' (default) on a GPU, and on
    a CPU where the render is differentiable (a training step, whose many steps repay the
    compile; docs/design_notes.md); '1' everywhere; '0' nowhere.
    A CPU's evaluation-only renders stay eager: one score would wait for the compiler."""
    wanted = os.environ.get("DRKFS_COMPILE", "auto")
    if wanted not in COMPILE_SETTINGS:
        raise ValueError(f"DRKFS_COMPILE={wanted!r}: use one of {', '.join(COMPILE_SETTINGS)}")
    return wanted == "1" or (wanted == "auto" and (device_type == "cuda" or differentiable))


class CompiledOrEager:
    """An equation compiled by ``torch.compile``, or eager from the first call whose compile
    fails (a CPU without a working C++ compiler, say), with one warning that says why. An error
    of the equation itself is the eager call's, raised as it is; running out of memory is the
    caller's to handle (a smaller batch), and the equation stays compiled."""

    def __init__(self, eager: Callable):
        self.eager = eager
        self.compiled = torch.compile(eager, dynamic=True, options=compile_options())

    def __call__(self, *tensors):
        if self.compiled is None:
            return self.eager(*tensors)
        try:
            return self.compiled(*tensors)
        except torch.OutOfMemoryError:
            raise
        except Exception as error:  # compilers fail in many ways; the eager call tells them apart
            result = self.eager(*tensors)
            self.compiled = None
            reason = (str(error).strip().splitlines() or [type(error).__name__])[0]
            warnings.warn(
                f"the rasteriser's equations run eagerly, slower: torch.compile failed "
                f"({reason[:300]}); DRKFS_COMPILE=0 skips the attempt",
                RuntimeWarning,
                stacklevel=2,
            )
            return result


@functools.cache
def fused(
    equation: Callable, config: PipelineConfig, device_type: str, differentiable: bool
) -> Callable:
    """``equation(*tensors, config, TORCH_OPS)`` as a function of its tensors, compiled where
    ``compiles`` says: its hundred-odd elementwise steps fused into a few kernels, where
    eagerly each is a pass over memory (and on a GPU a launch) of its own."""

    def eager(*tensors):
        return equation(*tensors, config, TORCH_OPS)

    return CompiledOrEager(eager) if compiles(device_type, differentiable) else eager


# Inductor's GPU kernels contract a * b + c into one rounding (FMA) and divide approximately,
# where eager torch, and so the CPU, rounds each step and divides exactly. A pair's depth comes
# from edge functions that cancel, and at the paper's gamma = 1e-4 its blend logit (depth /
# gamma) carries the difference into the gradient; these settings keep eager's rounding at
# eager's speed (docs/design_notes.md)
EAGER_NUMERICS = {
    "emulate_precision_casts": True,  # no FMA contraction
    "eager_numerics.division_rounding": True,
    "emulate_divison_rounding": True,  # the division's setting in older torch, so spelt
}


def compile_options() -> dict:
    """``EAGER_NUMERICS``' settings that this torch's inductor has (by either name)."""
    known = torch._inductor.config.get_config_copy()
    return {name: value for name, value in EAGER_NUMERICS.items() if name in known}
