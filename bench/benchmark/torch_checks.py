"""Checks only the differentiable torch path can answer: finite gradients on every stability
case, a score that changes smoothly as a part slides, zero for a shape against itself, and how
far a device's value and gradient are from the CPU's."""

from __future__ import annotations

import numpy as np
import torch

from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.match import match_score
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.synthetic.shapes import assemble, chair
from drkfs_onnx.synthetic.variants import diagonal, shifted

SLIDE_STEPS = 11
SLIDE_RANGE = 0.05  # of the chair's bounding-box diagonal
JUMP_LIMIT = 3.0  # the largest step may be at most this many times the mean step


def gradient_check(metric: DRKFS, a: tuple, b: tuple) -> dict:
    """Score A against B with autograd; the gradient on A's vertices must be finite."""
    verts = torch.as_tensor(a[0], dtype=torch.float32).requires_grad_(True)
    score = metric(verts, torch.as_tensor(a[1]), torch.as_tensor(b[0], dtype=torch.float32),
                   torch.as_tensor(b[1]))  # fmt: skip
    score.backward()
    finite = bool(torch.isfinite(verts.grad).all()) and bool(torch.isfinite(score))
    return {"score": score.item(), "gradient_finite": finite,
            "gradient_norm": float(verts.grad.norm())}  # fmt: skip


def value_and_gradient(score, verts: torch.Tensor, device: str):
    """-> one step to call (or time): ``score`` of a copy of ``verts`` moved to ``device``,
    returning (the value, its gradient with respect to that copy, back on the CPU)."""

    def step() -> tuple[float, torch.Tensor]:
        moved = verts.detach().to(device, copy=True).requires_grad_(True)
        value = score(moved)
        value.backward()
        return float(value.detach()), moved.grad.cpu()

    return step


def agreement(cpu: tuple[float, torch.Tensor], other: tuple[float, torch.Tensor]) -> dict:
    """How far another device's (value, gradient) is from the CPU's: the value's relative
    difference and the cosine between the gradients (a GPU may convolve in TF32, so the
    gradient's direction is what can be asked of it, not every digit)."""
    (a, grad_a), (b, grad_b) = cpu, other
    cosine = torch.nn.functional.cosine_similarity(grad_a.flatten(), grad_b.flatten(), dim=0)
    return {"value_relative_difference": abs(b - a) / abs(a), "gradient_cosine": float(cosine)}


def self_score(metric: DRKFS, mesh: tuple) -> float:
    verts = torch.as_tensor(mesh[0], dtype=torch.float32)
    with torch.no_grad():
        return float(metric(verts, torch.as_tensor(mesh[1]), verts, torch.as_tensor(mesh[1])))


def slide(metric: DRKFS, steps: int = SLIDE_STEPS) -> dict:
    """Score of a chair with one leg slid sideways by 0 .. SLIDE_RANGE of its diagonal against
    the chair (``slide_of`` with the torch metric)."""

    def described(verts: np.ndarray, faces: np.ndarray) -> tuple:
        with torch.no_grad():
            return metric.described(
                torch.as_tensor(verts, dtype=torch.float32), torch.as_tensor(faces)
            )

    def against(reference: tuple[np.ndarray, np.ndarray]):
        ref_features, ref_views = described(*reference)

        def score(verts: np.ndarray, faces: np.ndarray) -> float:
            own, views = described(verts, faces)
            with torch.no_grad():
                return float(
                    match_score(own, ref_features, metric.config, None, None, views, ref_views)
                )

        return score

    return slide_of(against, steps)


def slide_of(against, steps: int = SLIDE_STEPS) -> dict:
    """The slide check of any score: ``against((verts, faces))`` of the placed chair returns a
    score of a placed mesh ``(verts, faces) -> float`` against it. Passes when no step of the
    slid leg jumps more than JUMP_LIMIT times the mean step."""
    parts = chair()
    size = diagonal(parts)
    ref_v, ref_f = assemble(parts, 1)
    frame = frame_of(ref_v)
    score = against((place(ref_v, frame), ref_f))
    offsets = np.linspace(0.0, SLIDE_RANGE, steps)
    scores = []
    for t in offsets:
        v, f = assemble(shifted(parts, "leg_3", (t * size, 0.0, 0.0)), 1)
        scores.append(score(place(v, frame), f))
    ratio = jump_ratio(scores)
    return {"offsets": offsets.tolist(), "scores": scores, "max_over_mean_step": ratio,
            "limit": JUMP_LIMIT, "passed": ratio <= JUMP_LIMIT}  # fmt: skip


def jump_ratio(scores) -> float:
    """A slide's largest step over its mean step (inf when it never moves): at most
    JUMP_LIMIT passes."""
    steps = np.abs(np.diff(np.asarray(scores, dtype=float)))
    return float(steps.max() / steps.mean()) if steps.mean() > 0 else float("inf")
