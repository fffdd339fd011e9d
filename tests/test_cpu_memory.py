"""A CPU training step keeps freed memory for the next step's temporaries (glibc)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
import torch

# In a fresh process: a 64 MB tensor allocated, filled and freed four times (after
# keep_freed_memory(), as a CPU training step calls it) -> the page faults of the last time
# (glibc's heap takes the first two from the system whatever its thresholds).
REUSE = """
import resource, torch
from drkfs_onnx.cpu_memory import keep_freed_memory
print(keep_freed_memory())
for turn in range(4):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    torch.empty(16 << 20).fill_(1.0)
    print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def last_turn_faults(keep: str) -> tuple[bool, int]:
    env = {**os.environ, "DRKFS_KEEP_FREED_MEMORY": keep}
    run = subprocess.run(
        [sys.executable, "-c", REUSE], capture_output=True, text=True, check=True, env=env
    )
    took, *faults = run.stdout.split()
    return took == "True", int(faults[-1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
def test_kept_memory_is_reused_and_the_system_allocator_is_the_opt_out():
    took, faults = last_turn_faults("1")
    if not took:
        pytest.skip("this C library has no glibc mallopt")
    # 64 MB is 16k pages: taken anew from the system each time unless kept
    assert faults < 1000
    took, faults = last_turn_faults("0")
    assert not took and faults > 10_000


def test_a_cpu_step_with_gradients_keeps_freed_memory_and_scoring_does_not(monkeypatch):
    import drkfs_onnx.loss as loss_module
    from drkfs_onnx.loss import DrkfsLoss, Stage
    from drkfs_onnx.metric import DRKFS

    calls = []
    monkeypatch.setattr(loss_module, "keep_freed_memory", lambda: calls.append(1))
    config = DRKFS.pretrained().config.replace(num_views=1, image_size=32)
    loss = DrkfsLoss([DRKFS.pretrained(config)], (Stage(config, 1.0),), None)
    verts = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    faces = torch.tensor([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])
    target = loss.target(verts, faces)
    with torch.no_grad():
        loss(verts, faces, target)
    assert calls == []
    loss(verts.requires_grad_(True), faces, target)
    assert calls == [1]
