"""Why a slight turn outscores a visible surface defect, and a match that searches small shifts.

    python bench/shift_tolerance.py --out bench/results/shift_tolerance.json [--nets FILE]

1. Sensitivity, per real mesh, with the metric nets (the default's until the tolerant nets;
   or ``--nets``, a state saved by ``bench/real_nets.py --save-nets``): the score of every
   view translated by 0.5, 1 and 2 pixels against the mesh's own views; of the mesh turned
   by 1, 2 and 3 degrees, with the light fixed (as the metric renders) and turned with the
   mesh (only the image motion left); and how far a 2-degree turn moves the projected
   vertices, in pixels.
2. A match that searches small shifts (the lever "tolerance to a patch's small displacement"):
   each patch's best-match distance is the least over the other mesh's views translated by
   every offset of a set, per patch (``patch``) or one offset per view (``view``); judged on
   the benchmark's synthetic tiers and both sides of the real tiers. With ``--nets`` only the
   sensitivity runs, at the config the nets were trained at (``NETS_TRAINED_AT``: softmax
   t = 0.1).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from drkfs_lab.benchmark import sets
from drkfs_lab.benchmark.methods import Method, timed_call
from drkfs_lab.benchmark.real_tiers import HELDOUT_MESHES, TRAINING_MESHES
from drkfs_lab.benchmark.run import lever_summary, score_everything
from drkfs_lab.benchmark.tiers import turned
from drkfs_lab.training.tolerance import warped
from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract import match_rules
from drkfs_onnx.contract.cameras import make_cameras, rotation_y
from drkfs_onnx.contract.config import NETS_TRAINED_AT
from drkfs_onnx.contract.mesh import frame_of, load_mesh, place
from drkfs_onnx.match import match_score
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.render.renderer import Renderer
from drkfs_onnx.render.torch_ops import TORCH_OPS

# the config the nets were trained at (the default's when this was measured), metric nets
DEFAULT = PipelineConfig(nets="metric", **NETS_TRAINED_AT)
SHIFTS = (0.5, 1.0, 2.0)  # pixels, along x
TURNS = (1.0, 2.0, 3.0)  # degrees about the vertical
SEARCHES = {  # name -> the (dx, dy) offsets searched, in pixels
    "no search": [(0, 0)],
    "+-1 px": [(x, y) for y in (-1, 0, 1) for x in (-1, 0, 1)],
    "+-2 px": [(x, y) for y in range(-2, 3) for x in range(-2, 3)],
    "+-2 px along x": [(x, 0) for x in range(-2, 3)],
    "+-4 px along x": [(x, 0) for x in range(-4, 5)],
}
OFFSETS = sorted({o for offsets in SEARCHES.values() for o in offsets})


def _features(metric: DRKFS, verts: np.ndarray, faces: np.ndarray) -> torch.Tensor:
    with torch.no_grad():
        return metric.features(torch.tensor(verts, dtype=torch.float32), torch.as_tensor(faces))


def _lit_with_the_turn(
    metric: DRKFS, verts: np.ndarray, faces: np.ndarray, degrees: float
) -> torch.Tensor:
    """Descriptors of a mesh turned by ``degrees``, each view lit by the camera-frame light
    turned with it (C R C^T l for camera rotation C and turn R): every surface point shaded as
    before the turn, so only the image motion differs."""
    config, cameras = metric.config, make_cameras(metric.config)
    views = []
    for k in range(len(cameras)):
        camera = cameras.select(np.array([k]))
        c = camera.rotations[0]
        light = c @ rotation_y(degrees) @ c.T @ np.asarray(config.light_direction)
        renderer = Renderer(config.replace(light_direction=tuple(map(float, light))), camera)
        with torch.no_grad():
            views.append(renderer.render(torch.tensor(verts, dtype=torch.float32),
                                         torch.as_tensor(faces)))  # fmt: skip
    with torch.no_grad():
        return metric.describe(torch.cat(views)[:, None])


def sensitivity(metric: DRKFS, name: str) -> dict:
    mesh = load_mesh(sets.real_mesh(name))
    verts, faces = mesh.vertices, mesh.faces
    frame = frame_of(verts)
    config = metric.config
    with torch.no_grad():
        views = metric.render(torch.tensor(place(verts, frame), dtype=torch.float32),
                              torch.as_tensor(faces))[:, 0]  # fmt: skip
        own = metric.describe(views[:, None])
        moved = {}
        for dx in SHIFTS:
            offsets = torch.tensor([[dx, 0.0]]).expand(len(views), 2)
            shifted = metric.describe(warped(views, offsets, config.background)[:, None])
            moved[f"{dx:g} px"] = float(match_score(shifted, own, config))
    cameras = make_cameras(config)
    turns, lit = {}, {}
    for degrees in TURNS:
        placed = place(turned(verts, degrees), frame)
        described = _features(metric, placed, faces)
        turns[f"{degrees:g} deg"] = float(match_score(described, own, config))
        lit[f"{degrees:g} deg"] = float(
            match_score(_lit_with_the_turn(metric, placed, faces, degrees), own, config)
        )
    pixels = cameras.focal * config.image_size / 2

    def projected(points: np.ndarray) -> np.ndarray:
        camera = cameras.world_to_camera(points)
        return camera[..., :2] / camera[..., 2:] * pixels

    motion = np.linalg.norm(
        projected(place(turned(verts, 2.0), frame)) - projected(place(verts, frame)), axis=-1
    )
    return {
        "shifted": moved,
        "turned": turns,
        "turned_with_the_light": lit,
        "two_degree_motion_px": {"mean": float(motion.mean()), "max": float(motion.max())},
    }


class ShiftSearch(Method):
    """The default's nets; each mesh described at every offset of OFFSETS, each search of
    SEARCHES a score, per patch and per view."""

    def __init__(self, metric: DRKFS):
        config = metric.config
        if (config.matching, config.window, config.direction) != ("window", 0, "both"):
            raise ValueError("the shift search replaces the default's match: window 0, both ways")
        self.metric = metric
        self.outputs = tuple(f"{n}, {mode}" for n in SEARCHES for mode in ("patch", "view"))
        self.index = {n: [OFFSETS.index(o) for o in offsets] for n, offsets in SEARCHES.items()}

    def _described(self, placed) -> torch.Tensor:
        metric = self.metric
        with torch.no_grad():
            views = metric.render(torch.tensor(placed.verts, dtype=torch.float32),
                                  torch.as_tensor(placed.faces))[:, 0]  # fmt: skip
            return torch.stack([
                metric.describe(warped(views, torch.tensor([o] * len(views), dtype=torch.float32),
                                       metric.config.background)[:, None])
                for o in OFFSETS
            ])  # fmt: skip

    def prepare(self, placed):
        return timed_call(self._described, placed)

    def compare(self, a, b):
        config = self.metric.config
        k, p, still = config.num_views, config.patches_per_view, OFFSETS.index((0, 0))
        # each side's unmoved patches against the other's at every offset: (O, K * P)
        directions = [((a[still][None] - b) ** 2).sum(-1), ((b[still][None] - a) ** 2).sum(-1)]
        scores = []
        for index in self.index.values():
            for mode in ("patch", "view"):
                reduced = []
                for distances in directions:
                    d = distances[index]
                    if mode == "patch":
                        best = d.min(0).values
                    else:
                        per_view = d.reshape(len(index), k, p)
                        pick = per_view.sum(-1).argmin(0)
                        best = per_view[pick, torch.arange(k)].reshape(-1)
                    reduced.append(match_rules.reduce(best, torch.ones_like(best), config,
                                                      TORCH_OPS))  # fmt: skip
                scores.append(float(torch.stack(reduced).mean()))
        return tuple(scores)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--nets", type=Path, help="a state of bench/real_nets.py --save-nets")
    args = parser.parse_args()
    torch.set_num_threads(2)
    start = time.perf_counter()
    metric = DRKFS.pretrained(DEFAULT).eval()
    if args.nets is not None:
        metric.load_state_dict(torch.load(args.nets, weights_only=True))
    meshes = [*TRAINING_MESHES, *HELDOUT_MESHES]
    results = {
        "command": f"python bench/shift_tolerance.py --out {args.out}"
        + (f" --nets {args.nets}" if args.nets else ""),
        "sensitivity": {name: sensitivity(metric, name) for name in meshes},
    }
    print(json.dumps(results["sensitivity"], indent=1), flush=True)
    if args.nets is None:
        bench = sets.tier_set(quick=False)
        sets.real_tiers(bench, meshes)
        scores, _ = score_everything(bench, [ShiftSearch(metric)], lambda *_: None)
        rows = {}
        for name, values in scores.comparisons.items():
            rows[name] = lever_summary(bench, values)
            print(name, json.dumps(rows[name]), flush=True)
        results["shift_search"] = rows
    results["seconds"] = time.perf_counter() - start
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
