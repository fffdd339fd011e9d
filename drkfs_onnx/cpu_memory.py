"""Freed memory kept for reuse by the C allocator, for the training loss's steps on a CPU.

A training step allocates and frees a few gigabytes of temporaries (the pairs' equations,
HardNet's activations). By default glibc hands much of it back to the system as soon as it is
freed: every block over its mmap threshold (at most 32 MB) and any heap top over its trim
threshold. The next step then takes it again one zeroed page at a time: the fine stage at B =
32 on 2 cores took 450-640k page faults and 2.5-3.7 s of system time a step, about 0.7-1 s of
its 10-11 s. With blocks up to ``MMAP_THRESHOLD`` taken from the heap and up to
``TRIM_THRESHOLD`` of it kept, the steps after the first reuse their memory (faults about 0).

This is process-wide: ``DrkfsLoss`` applies it on a CPU step with gradients, once; where the C
library has no ``mallopt`` (macOS, Windows, musl's does nothing) nothing changes.
``DRKFS_KEEP_FREED_MEMORY=0`` leaves the allocator as it is.
"""

from __future__ import annotations

import ctypes
import functools
import os

MMAP_THRESHOLD = 256 << 20
TRIM_THRESHOLD = 1 << 30
# mallopt's parameter numbers (glibc's malloc.h)
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3


@functools.cache
def keep_freed_memory() -> bool:
    """Raise the C allocator's mmap and trim thresholds, once per process -> whether it took
    them (False where ``DRKFS_KEEP_FREED_MEMORY=0`` or the C library has no glibc mallopt)."""
    if os.environ.get("DRKFS_KEEP_FREED_MEMORY", "1") == "0":
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the C library the process runs on
    except (OSError, AttributeError, TypeError):
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(
        mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD)
    )
