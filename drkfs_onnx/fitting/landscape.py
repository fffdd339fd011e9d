"""How far a loss's gradient can be trusted: autograd's directional derivative against central
differences at growing step sizes. Where the two part, the loss is rough at that scale, and a
first-order optimiser stepping that far is guessing."""

from __future__ import annotations

import numpy as np
import torch

STEPS = (1e-6, 1e-4, 1e-2)  # in units of the target's normalised frame (radius 1)


def directional_derivatives(loss, verts: torch.Tensor, directions: int = 4, seed: int = 0) -> dict:
    """``loss(verts (V, 3) float64) -> ()`` at ``verts``, along random unit directions.

    -> {"autograd": [...], "central_difference": {step: [...]}, "median_relative_error":
    {step: median |difference - autograd| / |autograd|}}.
    """
    verts = verts.detach().double().requires_grad_(True)
    (grad,) = torch.autograd.grad(loss(verts), verts)
    generator = torch.Generator().manual_seed(seed)
    exact, differences = [], {f"{h:g}": [] for h in STEPS}
    for _ in range(directions):
        d = torch.randn(verts.shape, generator=generator, dtype=torch.float64)
        d /= d.norm()
        exact.append(float((grad * d).sum()))
        with torch.no_grad():
            for h in STEPS:
                change = loss(verts + h * d) - loss(verts - h * d)
                differences[f"{h:g}"].append(float(change) / (2 * h))
    reference = np.abs(exact)
    errors = {
        step: float(np.median(np.abs(np.array(values) - exact) / reference))
        for step, values in differences.items()
    }
    return {"autograd": exact, "central_difference": differences, "median_relative_error": errors}
