"""The losses the studies fit with, as data: a recipe is weighted terms, a term is Chamfer, pixel
MSE, or one of DR-KFS's loss forms (``FORMS``: its stages and match, ``loss.DrkfsLoss``).

The forms are the loss study's ideas, alone and combined: the scoring match at the training
renderer (the first studies' DR-KFS), the position-aligned match with dense reductions (window
r0 or r1; mean or power 2), a soft best match with an annealed temperature, and a coarse-to-fine
schedule (``loss.COARSE_TO_FINE``'s first stage before each).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from drkfs_lab.judging.rule import CHAMFER
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.loss import COARSE_TO_FINE, DrkfsLoss, SoftMatch, Stage
from drkfs_onnx.metric import DRKFS

from .mesh_fit import ChamferLoss, DrkfsTerm, Fade, Objective, PixelLoss

PIXEL = "pixel MSE"
FADED_CONTROL = "the control, pixel MSE last"  # fit_ideas.py's control, pixel MSE alone at its end
SCORING = "DR-KFS (scoring match)"  # the first studies' "DR-KFS": the default's match, softer
COARSE = COARSE_TO_FINE[0]


def _fine(**changes) -> tuple[Stage, ...]:
    return (Stage(PipelineConfig.loss(**changes), 1.0),)


def _coarse_to_fine(**changes) -> tuple[Stage, ...]:
    coarse = Stage(COARSE.config.replace(**changes), COARSE.until)
    return (coarse, *_fine(**changes))


# name -> (stages, soft match or None); each form names its window, so the forms stay what the
# study measured whatever the preset (``PipelineConfig.loss()``, the study's choice) becomes
FORMS: dict[str, tuple[tuple[Stage, ...], SoftMatch | None]] = {
    SCORING: ((Stage(PipelineConfig.training(), 1.0),), None),
    "window r0 mean": (_fine(window=0), None),
    "window r0 power 2": (_fine(window=0, reduction="power", power=2.0), None),
    "window r1 mean": (_fine(window=1), None),
    "soft match, window r1": (_fine(window=1), SoftMatch()),
    "window r0 mean, coarse to fine": (_coarse_to_fine(window=0), None),
    "soft match, window r1, coarse to fine": (_coarse_to_fine(window=1), SoftMatch()),
}
# the form ``DrkfsLoss.pretrained()`` fits with: the network study's choice between the loss
# study's two best forms (tests tie it to both)
SHIPPED = "window r0 mean, coarse to fine"


@dataclass(frozen=True)
class Recipe:
    """A loss: (weight, term) pairs, a term being CHAMFER, PIXEL or a name of FORMS; each term
    is divided by its value at the start (``Objective``). With a ``fade`` every term but pixel
    MSE fades out over the fit (``pixel_mse_last``)."""

    name: str
    terms: tuple[tuple[float, str], ...]
    fade: Fade | None = None

    @property
    def forms(self) -> list[str]:
        return [term for _, term in self.terms if term in FORMS]

    @property
    def rendered(self) -> bool:
        """Whether every term renders (Chamfer resamples the surface at every call)."""
        return all(term != CHAMFER for _, term in self.terms)


def alone(term: str) -> Recipe:
    return Recipe(term, ((1.0, term),))


def with_pixel(form: str, weight: float) -> Recipe:
    return Recipe(f"pixel MSE + {weight:g} x {form}", ((1.0, PIXEL), (weight, form)))


def with_chamfer(form: str, weight: float) -> Recipe:
    return Recipe(f"{form} + {weight:g} x Chamfer", ((1.0, form), (weight, CHAMFER)))


def with_both(form: str, pixel_weight: float, chamfer_weight: float) -> Recipe:
    """Pixel MSE with ``form`` and Chamfer beside it at their own weights."""
    name = f"pixel MSE + {pixel_weight:g} x {form} + {chamfer_weight:g} x Chamfer"
    return Recipe(name, ((1.0, PIXEL), (pixel_weight, form), (chamfer_weight, CHAMFER)))


def pixel_with_chamfer(weight: float) -> Recipe:
    """The same without DR-KFS: what its term adds to the other two."""
    return Recipe(f"pixel MSE + {weight:g} x Chamfer", ((1.0, PIXEL), (weight, CHAMFER)))


def pixel_mse_last(recipe: Recipe, fade: Fade) -> Recipe:
    """``recipe`` whose terms other than pixel MSE fade out over ``fade``, so the fit is shaped
    by all of them first and ends on pixel MSE alone."""
    if PIXEL not in (t for _, t in recipe.terms):  # else nothing is left to fit at the end
        raise ValueError(f"{recipe.name}: no pixel MSE term to end on")
    name = f"{recipe.name}, pixel MSE alone from {fade.end:g}"
    return Recipe(name, recipe.terms, fade)


class Terms:
    """Builds the terms of recipes for targets; every DR-KFS form's nets are loaded once: the
    shipped ones, or copies of ``nets``' detector and HardNet."""

    def __init__(self, nets: DRKFS | None = None):
        # pixel MSE of the training renderer's views: the renders DR-KFS's loss forms end with
        self.pixel_metric = DRKFS.pretrained(PipelineConfig.training())
        self.nets = nets
        self.losses: dict[tuple, DrkfsLoss] = {}  # by (stages, soft match)

    def loss_of(self, stages: tuple[Stage, ...], soft: SoftMatch | None) -> DrkfsLoss:
        key = (stages, soft)
        if key not in self.losses:
            self.losses[key] = (
                DrkfsLoss.pretrained(stages, soft)
                if self.nets is None
                else DrkfsLoss.from_nets(self.nets, stages, soft)
            )
        return self.losses[key]

    def term(self, term: str, target_verts: np.ndarray, target_faces: np.ndarray, faces):
        if term == CHAMFER:
            return ChamferLoss(target_verts, target_faces, faces)
        if term == PIXEL:
            return PixelLoss(self.pixel_metric, target_verts, target_faces, faces)
        return DrkfsTerm(self.loss_of(*FORMS[term]), target_verts, target_faces, faces)

    def objective(
        self, recipe: Recipe, target_verts: np.ndarray, target_faces: np.ndarray,
        template: torch.Tensor, faces: torch.Tensor,
    ) -> Objective:  # fmt: skip
        built = [(w, self.term(t, target_verts, target_faces, faces)) for w, t in recipe.terms]
        fades = [None if t == PIXEL else recipe.fade for _, t in recipe.terms]
        return Objective(built, template, fades)
