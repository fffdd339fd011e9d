"""How far a loss's gradient can be trusted at the step lengths its optimiser takes.

The probe follows a fit (its optimiser, step size and smoothness) and every EVERY steps asks two
questions of the objective alone:

- agreement: does autograd's prediction of the change, g . delta, match the change central
  differences measure along the optimiser's actual step delta, (f(x + delta) - f(x - delta)) / 2?
- descent: along the negative gradient, scaled so that no vertex moves further than the
  optimiser moved any vertex in that step, does f fall at each of DESCENT_POINTS points?

Where either fails, the loss is rough at the scale the optimiser works at, and a first-order
optimiser is guessing.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from .mesh_fit import FitSettings, Objective, fit_mesh

EVERY = 5  # optimiser steps between checks
CHECKS = 4  # checks per probe: at steps 0, 5, 10, 15
DESCENT_POINTS = 4  # points along the negative gradient, one vertex step apart
AGREEMENT = 0.2  # the median relative error a usable gradient stays within
TINY = 1e-30


def probe(
    objective: Objective,
    template: torch.Tensor,
    faces: torch.Tensor,
    settings: FitSettings,
    checks: int = CHECKS,
) -> dict:
    """-> {"checks": [...], "median_relative_error", "monotone_share", "monotone_at_start"}.

    The probe runs the fit's first ``checks`` x EVERY steps, each at the progress it has in the
    whole fit (``settings.steps``), so a staged loss is probed at the stage the fit is in."""
    found = []

    def check(step: int, verts: torch.Tensor, delta: torch.Tensor) -> None:
        if step % EVERY:
            return
        verts = verts.detach().requires_grad_(True)
        value = objective(verts)
        (grad,) = torch.autograd.grad(value, verts)
        with torch.no_grad():
            predicted = float((grad * delta).sum())
            measured = float(objective(verts + delta) - objective(verts - delta)) / 2
            vertex_step = float(delta.norm(dim=1).max())
            downhill = -grad / grad.norm(dim=1).max().clamp_min(TINY)
            line = [float(value)] + [
                float(objective(verts + k * vertex_step * downhill))
                for k in range(1, DESCENT_POINTS + 1)
            ]
        found.append(
            {
                "step": step,
                "vertex_step": vertex_step,
                "predicted_change": predicted,
                "measured_change": measured,
                "relative_error": abs(measured - predicted) / max(abs(predicted), TINY),
                "line": line,
                "monotone": all(b < a for a, b in zip(line, line[1:], strict=False)),
            }
        )

    short = replace(settings, steps=checks * EVERY)
    fit_mesh(objective, template, faces, short, check, total_steps=settings.steps)
    return {
        "checks": found,
        "median_relative_error": float(np.median([c["relative_error"] for c in found])),
        "monotone_share": float(np.mean([c["monotone"] for c in found])),
        "monotone_at_start": found[0]["monotone"],
    }
