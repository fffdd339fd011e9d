"""Levers for a viewer's tolerance and attention, measured without retraining: a config's nets (the
default's unless ``--nets``) under other matches, reductions, camera counts, view sizes, turned
rings of cameras, solid changes of the views, the light on faces seen from behind and searches over
turns of the meshes, on the benchmark's synthetic tiers and on both sides of its real-mesh tiers (a
lever is chosen on the training side and judged on the held-out one), with the bench's targets a
default must keep (the bars test, retrieval, the slide check; people's judgments with --human). Each
lever moves the config the nets were trained at (``NETS_TRAINED_AT``: 6 views of 128 px, t = 0.1,
one ring, no solid change, the default's until the lever "5 cameras, 144 px, softmax t = 0.05"
became the default, then "rings 0 and 2.5, ...", then "solid change x0.5 shift 2 block 3, ...", then
"solid change x0.7 over reaches 2-3, ...", then ``NOW_LEVER``, then ``WINDOW_LEVER``), named
"default" in the results. The turn searches (``TURN_SEARCHES``, not run unless named) wrap a lever's
scorer, and so do the recombinations (``RECOMBINED``, not run unless named: the descriptors' part
bounded, the solid change from other cameras than the descriptors', the views' solid changes in a
power mean, a pixel's change taken over other reaches inside the mesh and at its outline than a
config's ramp allows, the descriptors' distances counted above a floor the whole shown surface sets,
the outline's change netted, mesh lost against mesh gained, so that a moved part counts less than a
removed one, the own-ring pairing's solid change taken over both rings' views, or the descriptors'
part made convex). A lever's solid change is at one reach unless it names a ramp (``ONE_REACH``), as
every lever before the ramp was, and its own-ring pairing from its own ring alone unless it names
both (``OWN_RING_ONLY``), as every lever before ``NOW_LEVER``. A turn search's slide check is its
lever's, as the torch path has none; a recombination's is its own, on the runtime path it is scored
on (``runtime_slide``).

    python bench/real_levers.py --out bench/results/real_levers_tolerant.json
    python bench/real_levers.py --nets metric --out bench/results/real_levers.json
    python bench/real_levers.py --out ... --levers default "192 px" --human DIR  # and people

A view size with no shipped feature graph for the nets is exported for the run into a
temporary folder (the nets are convolutions: any size is the same weights).
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from drkfs_lab.benchmark import human, sets, torch_checks
from drkfs_lab.benchmark.methods import DrkfsOnnx, Method, Placed
from drkfs_lab.benchmark.real_tiers import HELDOUT_MESHES, TRAINING_MESHES, parse_relabels
from drkfs_lab.benchmark.run import (
    bars_summary,
    lever_summary,
    ranked_retrieval,
    retrieval_summary,
    score_everything,
    tier_accuracy,
)
from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract import match_rules
from drkfs_onnx.contract.array_ops import NUMPY_OPS
from drkfs_onnx.contract.cameras import rotation_y
from drkfs_onnx.contract.config import NETS_TRAINED_AT, ONE_REACH, OWN_RING_ONLY
from drkfs_onnx.contract.model_files import features_file, models_dir, shipped_entry
from drkfs_onnx.contract.solid_change import (
    held_change,
    reach_change,
    solid_reaches,
    view_range,
    window_extreme,
)
from drkfs_onnx.export.onnx_files import export_features
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.runtime.match import best_matches, descriptor_part
from drkfs_onnx.runtime.render import NumpyRenderer

NOW_LEVER = (
    "own ring from both rings (max, ring 1's part x0.2), solid change x1.2 over reaches 2-3, 1-2 "
    "at power 1.5 inside the mesh, block 3, rings 0 and 2.5, 5 cameras, 144 px, softmax t = 0.05"
)
NOW_SETTINGS = {  # NOW_LEVER's: what it moves from NETS_TRAINED_AT
    "num_views": 5,
    "image_size": 144,
    "temperature": 0.05,
    "turn_degrees": 2.5,
    "solid_weight": 1.2,
    "solid_shift": 3,
    "solid_block": 3,
    "solid_ramp": 1,
    "solid_inner_drop": 1,
    "solid_inner_power": 1.5,
    "turned_part_share": 0.2,
    "solid_both_rings": True,
}
WINDOW_LEVER = f"descriptors' part at slope 0.6 between 0.04 and 0.18, {NOW_LEVER}"
WINDOW_SETTINGS = {
    **NOW_SETTINGS, "moderate_slope": 0.6, "moderate_from": 0.04, "moderate_to": 0.18,
}  # fmt: skip
RAMP_LEVER = (  # the default since the ramp and its neighbours
    "solid change x{w:g} over reaches 2-3, 1-2 at power 1.5 inside the mesh, block 3, rings 0 "
    "and 2.5, {k} cameras, {px} px, softmax t = {t:g}"
)
# name -> the settings the lever moves (from NETS_TRAINED_AT's config, its solid change at
# ONE_REACH unless the lever names a ramp, as before the ramp)
LEVERS = {
    "default": {},
    "window r1": {"window": 1},
    "softmax t = 0.05": {"temperature": 0.05},
    "softmax t = 0.03": {"temperature": 0.03},
    "tail 10%": {"reduction": "tail", "tail_fraction": 0.1},
    "12 cameras": {"num_views": 12},
    "12 cameras, window r1": {"num_views": 12, "window": 1},
    "160 px": {"image_size": 160},
    "192 px": {"image_size": 192},
    "256 px": {"image_size": 256},
    "256 px, softmax t = 0.05": {"image_size": 256, "temperature": 0.05},
    # finer views at about the default's cost a mesh (from 144 px, with fewer cameras)
    "144 px, softmax t = 0.05": {"image_size": 144, "temperature": 0.05},
    "5 cameras, 144 px, softmax t = 0.05": {"num_views": 5, "image_size": 144, "temperature": 0.05},
    "4 cameras, 144 px, softmax t = 0.05": {"num_views": 4, "image_size": 144, "temperature": 0.05},
    # the neighbours of the default's 5 cameras of 144 px at t = 0.05
    "5 cameras, 144 px": {"num_views": 5, "image_size": 144},
    "5 cameras, 144 px, softmax t = 0.07": {"num_views": 5, "image_size": 144, "temperature": 0.07},
    "5 cameras, 144 px, softmax t = 0.04": {"num_views": 5, "image_size": 144, "temperature": 0.04},
    "5 cameras, 144 px, softmax t = 0.03": {"num_views": 5, "image_size": 144, "temperature": 0.03},
    # the cameras and a second ring turned by an angle (PipelineConfig.turn_degrees): the least
    # of own ring against own ring and each one's own against the other's turned ring; at 2
    # degrees with sharper softmaxes, and at other angles than the tiers' own 2-degree turn,
    # which a ring at 2 matches exactly
    **{
        f"rings 0 and {a:g}, 5 cameras, 144 px, softmax t = {t:g}": {
            "num_views": 5,
            "image_size": 144,
            "temperature": t,
            "turn_degrees": a,
        }
        for a, t in ((2.0, 0.05), (2.0, 0.04), (2.0, 0.03), (1.5, 0.05), (2.5, 0.05), (3.0, 0.05))
    },
    # a solid change of the views added to the score (``contract.solid_change``): weight, reach
    # of the shift it forgives (pixels) and block (a square of pixels that changes as a whole)
    **{
        f"solid change x{w:g} shift {shift} block {block}, rings 0 and 2.5, 5 cameras, 144 px, "
        "softmax t = 0.05": {
            "num_views": 5,
            "image_size": 144,
            "temperature": 0.05,
            "turn_degrees": 2.5,
            "solid_weight": w,
            "solid_shift": shift,
            "solid_block": block,
        }
        for w, shift, block in (
            (0.2, 1, 3),
            (0.25, 1, 3),
            (0.3, 1, 3),
            (0.5, 1, 3),
            (1.0, 1, 3),
            (0.3, 2, 3),
            (0.5, 2, 3),
            (0.7, 2, 3),
            (1.0, 2, 3),
            (0.5, 3, 3),
            (1.0, 3, 3),
            (0.6, 3, 3),
            (0.7, 3, 3),
            (0.7, 4, 3),
            (0.5, 1, 5),
            (1.0, 1, 5),
            (1.0, 2, 5),
        )
    },  # fmt: skip
    # the default's match with 6 or 7 cameras of 128 px, about the same pixels a mesh, and with 6
    # of 144 px (a fifth more): more cameras see more of a small hole (the real tiers' misses are
    # holes the 5 cameras hardly see)
    **{
        f"solid change x{w:g} shift {shift} block 3, rings 0 and 2.5, {k} cameras, {px} px, "
        f"softmax t = {t:g}": {
            "num_views": k,
            "image_size": px,
            "temperature": t,
            "turn_degrees": 2.5,
            "solid_weight": w,
            "solid_shift": shift,
            "solid_block": 3,
        }
        for k, px, w, shift, t in (
            (6, 128, 0.5, 2, 0.05),
            (6, 128, 0.7, 2, 0.05),
            (6, 128, 0.5, 1, 0.05),
            (6, 128, 0.7, 1, 0.05),
            (6, 128, 0.5, 1, 0.07),
            (7, 128, 0.5, 2, 0.05),
            (6, 144, 0.5, 2, 0.05),
            (6, 144, 0.5, 1, 0.07),
        )
    },  # fmt: skip
    # the default: the solid change ramped over reaches 2 and 3, 1 and 2 at power 1.5 inside;
    # the same ramp with 6 cameras of 128 px, which see the holes the default's hardly do;
    # heavier (the held-out side's small holes and tips are the solid change's, not the
    # descriptors'); and the default's neighbours in temperature
    **{
        RAMP_LEVER.format(w=w, k=k, px=px, t=t): {
            "num_views": k,
            "image_size": px,
            "temperature": t,
            "turn_degrees": 2.5,
            "solid_weight": w,
            "solid_shift": 3,
            "solid_block": 3,
            "solid_ramp": 1,
            "solid_inner_drop": 1,
            "solid_inner_power": 1.5,
        }
        for k, px, w, t in (
            (5, 144, 0.7, 0.05),
            (6, 128, 0.5, 0.05),
            (6, 128, 0.7, 0.05),
            (5, 144, 0.85, 0.05),
            (5, 144, 0.87, 0.05),
            (5, 144, 1.0, 0.05),
            (5, 144, 1.2, 0.05),
            (5, 144, 1.5, 0.05),
            (5, 144, 3.0, 0.05),
            (5, 144, 4.0, 0.05),
            (6, 128, 4.0, 0.05),
            (5, 144, 0.7, 0.04),
            (5, 144, 0.7, 0.06),
        )
    },  # fmt: skip
    # the default since the own-ring pairing took the turned ring's views too
    # (``match_rules.pairing_part``, ``pairing_solid``): what the recombination "descriptors'
    # and solid change from both rings (max, ring 1's part x0.2), ... x1.2 ..." measured
    NOW_LEVER: NOW_SETTINGS,
    # the default since its descriptors' part counts at slope 0.6 between 0.04 and 0.18
    # (``match_rules.moderated_part``), chosen by bench/part_transforms.py from NOW_LEVER's parts
    WINDOW_LEVER: WINDOW_SETTINGS,
    # the default with faces seen from behind lit by a share of the diffuse light
    # (``PipelineConfig.back_light``): at 0 the inside of a cut hole or a removed part's opening
    # lies in the shell's shadow, as a viewer sees it, where two-sided light shows more surface
    **{
        f"faces seen from behind at {share:g} of the light, {WINDOW_LEVER}": {
            **WINDOW_SETTINGS,
            "back_light": share,
        }
        for share in (0.0, 0.25, 0.5, 0.75)
    },  # fmt: skip
    # the shadow only where faces seen from behind still show when pushed back in the depth
    # order by that much normalised inverse depth (``PipelineConfig.back_push``): an opening's
    # inside, not the outlines, where the soft depth order blends the faces that meet there
    **{
        f"openings seen dark (faces seen from behind at {share:g} of the light, pushed back "
        f"{push:g}), {WINDOW_LEVER}": {**WINDOW_SETTINGS, "back_light": share, "back_push": push}
        for share, push in ((0.0, 0.02), (0.0, 0.05), (0.0, 0.1), (0.5, 0.05))
    },  # fmt: skip
    # the default (openings seen dark, pushed 0.05) with each face's outside read from the
    # surface rather than from the file's winding (``PipelineConfig.winding``)
    f"faces oriented by the surface, openings seen dark (faces seen from behind at 0 of the "
    f"light, pushed back 0.05), {WINDOW_LEVER}": {
        **WINDOW_SETTINGS,
        "back_light": 0.0,
        "back_push": 0.05,
        "winding": "geometry",
    },  # fmt: skip
    # the default's match from 6 cameras of 128 px, which saw the bunny's hole (0.023) before
    # the own-ring pairing read both rings
    **{
        NOW_LEVER.replace("5 cameras, 144 px", f"{k} cameras, {px} px").replace(
            "x1.2", f"x{w:g}"
        ): {**NOW_SETTINGS, "num_views": k, "image_size": px, "solid_weight": w}
        for k, px, w in ((6, 128, 1.2), (6, 128, 0.7))
    },
    "5 cameras, 128 px, softmax t = 0.05": {"num_views": 5, "temperature": 0.05},
    "5 cameras, 160 px, softmax t = 0.05": {"num_views": 5, "image_size": 160, "temperature": 0.05},
    "4 cameras, 192 px": {"num_views": 4, "image_size": 192},
    "4 cameras, 192 px, softmax t = 0.05": {"num_views": 4, "image_size": 192, "temperature": 0.05},
    "3 cameras, 256 px, softmax t = 0.05": {"num_views": 3, "image_size": 256, "temperature": 0.05},
    "4 cameras, 256 px, softmax t = 0.05": {"num_views": 4, "image_size": 256, "temperature": 0.05},
}
DEFAULT_LEVER = "5 cameras, 144 px, softmax t = 0.05"  # the default before its turned ring
# name -> (a lever above, pairings): A and B each described turned about the vertical by the
# angles (degrees) of the pairings (A's, B's) it takes part in, the score the least over the
# pairings; a viewer does not see a slight turn. Per mesh, one render of the views per angle.
TURN_SEARCHES = {
    f"turn search +-{a:g}, {lever}": (lever, ((0.0, -a), (0.0, 0.0), (0.0, a)))
    for a in (1.0, 1.5, 2.0)
    for lever in (DEFAULT_LEVER, "5 cameras, 144 px, softmax t = 0.04")
} | {
    f"turn search +-1, +-2, {DEFAULT_LEVER}": (
        DEFAULT_LEVER, tuple((0.0, b) for b in (-2.0, -1.0, 0.0, 1.0, 2.0))
    ),
} | {  # every mesh seen from two rings of cameras 2 degrees apart: turns of 0 and +-2 between them
    f"two rings +-1, {lever}": (lever, ((-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)))
    for lever in (DEFAULT_LEVER, "5 cameras, 144 px, softmax t = 0.04",
                  "5 cameras, 144 px, softmax t = 0.03")
} | {  # what the two rings' search does without its turns: the cameras moved, no search
    f"cameras turned 1, {DEFAULT_LEVER}": (DEFAULT_LEVER, ((1.0, 1.0),)),
    f"two rings +-1, each ring alone, {DEFAULT_LEVER}": (DEFAULT_LEVER, ((-1.0, -1.0), (1.0, 1.0))),
}  # fmt: skip
SOLID_LEVER = (  # the default before the ramp (weight 0.5, shift 2) and its neighbours
    "solid change x{w:g} shift {s} block 3, rings 0 and 2.5, 5 cameras, 144 px, softmax t = 0.05"
)
DEFAULT_NOW = RAMP_LEVER.format(w=0.7, k=5, px=144, t=0.05)  # the default from the ramp on
# name -> (a lever above, ``Recombined``'s settings): what a config cannot say
RECOMBINED = {
    # the default itself on the runtime path: its slide check there against the torch path's
    f"recombined with nothing, {SOLID_LEVER.format(w=0.5, s=2)}": (
        SOLID_LEVER.format(w=0.5, s=2), {}
    ),
} | {
    f"solid change from 6 cameras of 128 px, {SOLID_LEVER.format(w=w, s=2)}": (
        SOLID_LEVER.format(w=w, s=2), {"solid_cameras": (6, 128)}
    )
    for w in (0.5, 0.7)
} | {
    f"descriptors' part at most {c:g}, {SOLID_LEVER.format(w=0.5, s=2)}": (
        SOLID_LEVER.format(w=0.5, s=2), {"ceiling": c}
    )
    for c in (0.1, 0.05)
} | {  # a change one camera sees counts more than the mean over the views gives it
    f"views' solid changes in a power mean p = {power:g}, {SOLID_LEVER.format(w=w, s=2)}": (
        SOLID_LEVER.format(w=w, s=2), {"view_power": power}
    )
    for power, w in ((4.0, 0.5), (math.inf, 0.3))
} | {  # a hole shows the mesh's inside, where a moved part's outline shows the background
    f"solid change at reach 1 where both views show the mesh, {SOLID_LEVER.format(w=w, s=2)}": (
        SOLID_LEVER.format(w=w, s=2), {"inside": (1,)}
    )
    for w in (0.5, 0.7)
} | {  # and a strong change of grey there counts more than a faint one (a facet's)
    f"solid change at reach 1 and power {power:g} where both views show the mesh, "
    f"{SOLID_LEVER.format(w=w, s=2)}": (
        SOLID_LEVER.format(w=w, s=2), {"inside": (1,), "inner_power": power}
    )
    for power in (1.5, 2.0)
    for w in (0.5, 0.7)
} | {  # a pixel's change ramped up over several reaches: a shift crosses no single threshold
    f"solid change the mean over reaches {'-'.join(map(str, r))}, "
    f"{SOLID_LEVER.format(w=w, s=max(r))}": (
        SOLID_LEVER.format(w=w, s=max(r)), {"inside": r, "outline": r}
    )
    for r, w in (((1, 2, 3), 0.5), ((1, 2, 3), 0.7), ((1, 2), 0.5), ((1, 2), 0.7), ((2, 3), 0.5),
                 ((1, 2, 3, 4), 0.7))
} | {  # the outline ramped over reaches 2 and 3, the mesh's inside from a reach of 1
    f"solid change the mean over reaches {'-'.join(map(str, i))}"
    + (f" and power {p:g}" if p != 1 else "")
    + f" where both views show the mesh, over 2-3 elsewhere, "
    f"{SOLID_LEVER.format(w=w, s=3)}": (
        SOLID_LEVER.format(w=w, s=3),
        {"inside": i, "inner_power": p, "outline": (2, 3)},
    )
    for i, p, w in (((1, 2, 3), 1, 0.5), ((1, 2, 3), 1, 0.7), ((1, 2), 1, 0.5), ((1, 2), 1, 0.7),
                    ((1,), 1.5, 0.7), ((1, 2, 3), 1.5, 0.7), ((1, 2), 1.5, 0.7),
                    ((1, 2), 1.5, 0.5), ((1, 2), 1.5, 0.6), ((1, 2), 2, 0.7), ((1, 2, 3), 2, 0.7))
} | {  # the descriptors' distances above a floor the whole shown surface sets
    f"descriptors' distances above {c:g} x their {q:g} quantile, {DEFAULT_NOW}": (
        DEFAULT_NOW, {"floor": (q, c)}
    )
    for q, c in ((0.5, 0.5), (0.5, 1.0), (0.25, 1.0), (0.75, 0.5))
} | {  # a moved part's outline change netted, lost against gained, at the default's ramp
    f"moves netted, {RAMP_LEVER.format(w=w, k=5, px=144, t=0.05)}": (
        RAMP_LEVER.format(w=w, k=5, px=144, t=0.05), {"netted": True}
    )
    for w in (0.7, 1.0, 1.5, 3.0, 4.0)
} | {  # and from the six cameras of 128 px that see the held-out side's holes
    f"moves netted, {RAMP_LEVER.format(w=4.0, k=6, px=128, t=0.05)}": (
        RAMP_LEVER.format(w=4.0, k=6, px=128, t=0.05), {"netted": True}
    ),
} | {  # the same, the solid term bounded: between different shapes it is then one offset
    f"moves netted, solid term at most {c:g}, {RAMP_LEVER.format(w=4.0, k=k, px=px, t=0.05)}": (
        RAMP_LEVER.format(w=4.0, k=k, px=px, t=0.05), {"netted": True, "solid_ceiling": c}
    )
    for k, px, c in ((6, 128, 0.3), (6, 128, 0.5), (5, 144, 0.5))
} | {  # the default's solid term bounded, alone and with the netted outline change added
    f"solid term at most {c:g}, {DEFAULT_NOW}": (DEFAULT_NOW, {"solid_ceiling": c})
    for c in (0.5,)
} | {
    f"moves netted x{b:g} added, solid term at most {c:g}, {DEFAULT_NOW}": (
        DEFAULT_NOW, {"moved": b, "solid_ceiling": c}
    )
    for b, c in ((0.7, 0.5), (0.7, 0.7), (0.7, 0.75), (0.7, 1.0))
} | {  # and with the outline's reaches shortened, which a netted move no longer needs
    f"moves netted, outline over reaches {'-'.join(map(str, o))}, "
    f"{RAMP_LEVER.format(w=w, k=5, px=144, t=0.05)}": (
        RAMP_LEVER.format(w=w, k=5, px=144, t=0.05),
        {"netted": True, "inside": (1, 2), "inner_power": 1.5, "outline": o},
    )
    for o, w in (((1, 2), 0.7), ((1, 2), 1.0))
} | {  # the netted outline change added to the default's: a removal gains, a move hardly
    f"moves netted x{b:g} added, {DEFAULT_NOW}": (DEFAULT_NOW, {"moved": b})
    for b in (0.3, 0.7, 1.5)
} | {  # netted by area: two different shapes' lost and gained areas net out as a move's do
    f"moves netted by area x{b:g} added, {DEFAULT_NOW}": (
        DEFAULT_NOW, {"moved": b, "by_area": True}
    )
    for b in (0.7, 1.5)
} | {  # and counted only where the outline's change is local: different shapes' is not
    f"moves netted x{b:g} added below {c:g} of the shape, {DEFAULT_NOW}": (
        DEFAULT_NOW, {"moved": b, "local": c}
    )
    for b, c in ((0.7, 0.1), (0.7, 0.2), (1.5, 0.1))
} | {  # and counted only between near shapes, as the descriptors' part says
    f"moves netted x{b:g} added, near {n:g}, {DEFAULT_NOW}": (DEFAULT_NOW, {"moved": b, "near": n})
    for b, n in ((0.7, 1.0), (0.7, 2.0), (1.0, 1.0))
} | {  # the own-ring pairing's solid change over both rings' views: the turned ring's cameras,
    # 2.5 degrees off, see a sliver the own ring's miss (the mean of the ten views, or each
    # camera's larger of its two rings)
    f"solid change from both rings ({how}), {RAMP_LEVER.format(w=w, k=5, px=144, t=0.05)}": (
        RAMP_LEVER.format(w=w, k=5, px=144, t=0.05), {"both_rings": how}
    )
    for how, w in (("mean", 0.7), ("max", 0.7), ("mean", 1.0), ("max", 1.0), ("mean", 1.5),
                   ("max", 1.5), ("max", 1.2))
} | {  # and with the outline's change netted, heavier, as the held-out side's holes ask
    "solid change from both rings (max), moves netted"
    + (f", solid term at most {c:g}" if c else "")
    + f", {RAMP_LEVER.format(w=w, k=5, px=144, t=0.05)}": (
        RAMP_LEVER.format(w=w, k=5, px=144, t=0.05),
        {"both_rings": "max", "netted": True, "solid_ceiling": c},
    )
    for w, c in ((4.0, 0.5), (4.0, 1.0), (4.0, None), (3.0, None))
} | {  # and the netted change added to the default's, alone and bounded
    f"solid change from both rings (max), moves netted x{b:g} added"
    + (f", solid term at most {c:g}" if c else "")
    + f", {DEFAULT_NOW}": (DEFAULT_NOW, {"both_rings": "max", "moved": b, "solid_ceiling": c})
    for b, c in ((0.7, 0.75), (0.7, None))
} | {  # and the own-ring pairing's descriptor part the mean of both rings' own
    f"descriptors' and solid change from both rings ({how}"
    + (f", ring 1's part x{s:g}" if s != 0.5 else "")
    + f"), {RAMP_LEVER.format(w=w, k=5, px=144, t=0.05)}": (
        RAMP_LEVER.format(w=w, k=5, px=144, t=0.05), {"both_rings": how, "both_parts": s}
    )
    for how, w, s in (("max", 0.7, 0.5), ("max", 1.0, 0.5), ("max", 1.2, 0.5), ("mean", 1.0, 0.5),
                      ("max", 1.0, 0.25), ("max", 1.2, 0.25), ("max", 1.2, 0.35),
                      ("max", 1.5, 0.25), ("max", 1.2, 0.1), ("max", 1.2, 0.15), ("max", 1.2, 0.2),
                      ("max", 1.0, 0.15))
} | {
    f"descriptors from both rings, {DEFAULT_NOW}": (DEFAULT_NOW, {"both_parts": 0.5}),
} | {  # the default with its descriptors' part convex: a moderate part (a crumpled or faceted
    # surface) counts less against the solid change, a large one (another shape) as before
    f"descriptors' part to the power {q:g} about {c:g}, {NOW_LEVER}": (
        NOW_LEVER, {"both_rings": "max", "both_parts": 0.2, "part_power": (q, c)}
    )
    for q, c in ((2.0, 1.0), (1.5, 1.0), (2.0, 0.5))
} | {  # the same, linear up to a knee: a small defect's part as the default counts it
    f"descriptors' part to the power {q:g} about 1 above {k:g}, {NOW_LEVER}": (
        NOW_LEVER, {"both_rings": "max", "both_parts": 0.2, "part_power": (q, 1.0, k)}
    )
    for q, k in ((2.0, 0.005), (2.0, 0.01), (2.0, 0.02),
                 (1.25, 0.01), (1.5, 0.01), (1.5, 0.02), (1.75, 0.01))
}  # fmt: skip
WRAPPED = {name: lever for name, (lever, *_) in (TURN_SEARCHES | RECOMBINED).items()}


def _turned(placed: Placed, angle: float) -> Placed:
    """``placed`` turned about its frame's vertical, kept with it so that searches over the same
    angles share renders."""
    if angle == 0.0:
        return placed
    return placed.shared(
        ("turned", angle),
        lambda: Placed(f"{placed.key}@{angle:g}", placed.verts @ rotation_y(angle).T, placed.faces),
    )[0]


class TurnSearch(Method):
    """A lever's scorer over turns: ``prepare`` describes a mesh turned about the frame's
    vertical by each angle of the pairings, ``compare(a, b)`` is the least score over the
    pairings (A turned by the first angle, B by the second)."""

    def __init__(self, method: DrkfsOnnx, name: str, pairings: tuple[tuple[float, float], ...]):
        self.method, self.outputs, self.pairings = method, (name,), pairings
        self.symmetric = set(pairings) == {(b, a) for a, b in pairings} and method.symmetric

    def prepare(self, placed):
        turned, seconds = {}, 0.0
        for angle in dict.fromkeys(angle for pairing in self.pairings for angle in pairing):
            turned[angle], cost = self.method.prepare(_turned(placed, angle))
            seconds += cost
        return turned, seconds

    def compare(self, a, b):
        return (min(self.method.compare(a[i], b[j])[0] for i, j in self.pairings),)


class Recombined(Method):
    """A lever's scorer with what its config cannot say: each ring pairing's descriptor part
    (``runtime.match.descriptor_part``), at most about ``ceiling`` where set (ceiling *
    tanh(part / ceiling): however strong a surface change, the descriptors' part of it stays
    below a large solid change), plus the config's solid weight times the solid change of the
    views of ``solid_cameras`` (count, px) where set, else of the lever's own views, its views'
    changes reduced by their power mean of ``view_power`` (1: their mean; inf: the largest),
    and, where ``inside`` is set, each pixel's change the mean of its changes at the reaches
    ``inside``, raised to ``inner_power``, where both views show the mesh, and at the reaches
    ``outline`` (the config's shift unless set) elsewhere (``pixel_changes``); the
    least over the ring pairings. With ``floor`` = (q, c) each patch's best-match distance
    counts only above c times the q-quantile of the distances of the patches either mesh shows
    (``floored_part``): a change that raises every patch (noise, faceting) counts less against
    one that raises a few (a hole, a missing tip). With ``netted`` a view's change at the
    outline is netted, mesh lost against mesh gained (``moves_change``): a part moved, lost at
    its old place and gained at its new one, counts less than one removed; with ``moved`` > 0
    that netted outline change is added, at that weight, to the config's solid change instead
    of replacing it; ``by_area`` nets by the areas changed (the larger side's peak times the
    areas' difference over the larger area) instead of the peaks' difference; with ``local``
    the netted change counts less as the changed outline grows, none past ``local`` of the
    shape's grey-weighted area (two different shapes change much of it, a removed part
    little); with ``near`` it is weighed by exp(-part / near), the pairing's descriptor part:
    full between near shapes, where a change's kind orders the tiers, little between different
    shapes, whose order the descriptors decide (retrieval). With ``solid_ceiling`` the whole
    solid term is at most about it (c tanh(term / c)): once a region changes as a whole a viewer
    has seen it, and how different two shapes are beyond that the descriptors say. With
    ``both_rings`` the own-ring pairing's solid change is over both rings' views, each ring's
    against the same ring's: the turned ring's cameras, a few degrees off, see a sliver the own
    ring's miss ('mean': the mean over all their views; 'max': each camera's larger change of
    its two rings, then the views' mean); with ``both_parts`` = s its descriptor part is
    (1 - s) times ring 0's own part plus s times ring 1's (0.5: their mean). With
    ``part_power`` = (q, c) each pairing's descriptor part is c (part / c)^q: convex, so that
    a moderate part counts less against the solid change while a part near c keeps its value;
    given as (q, c, k), a part up to k keeps its value and one above it is k + c ((part - k) /
    c)^q: a small defect's part, which a turn's solid change would outweigh once squared, stays
    as it is (``powered_part``). Each of these reads the pairing's part as the config gives it:
    moderated by its window where it has one (``match_rules.moderated_part``)."""

    def __init__(self, method: DrkfsOnnx, name: str, threads: int, ceiling: float | None = None,
                 solid_cameras: tuple[int, int] | None = None, view_power: float = 1.0,
                 inside: tuple[int, ...] | None = None, inner_power: float = 1.0,
                 outline: tuple[int, ...] | None = None,
                 floor: tuple[float, float] | None = None, netted: bool = False,
                 moved: float = 0.0, by_area: bool = False,
                 local: float | None = None, near: float | None = None,
                 solid_ceiling: float | None = None,
                 both_rings: str | None = None, both_parts: float = 0.0,
                 part_power: tuple[float, ...] | None = None):  # fmt: skip
        if method.scorer.config.align_degrees:
            raise ValueError("a recombined lever describes each mesh as placed: no turn onto B")
        self.method, self.outputs, self.symmetric = method, (name,), method.symmetric
        self.floor, self.netted, self.moved, self.by_area = floor, netted, moved, by_area
        self.local, self.near, self.solid_ceiling = local, near, solid_ceiling
        self.both_rings, self.both_parts, self.part_power = both_rings, both_parts, part_power
        self.config, self.ceiling, self.view_power = method.scorer.config, ceiling, view_power
        self.solid = None
        solid_config = self.config
        if solid_cameras is not None:
            count, size = solid_cameras
            solid_config = self.config.replace(num_views=count, image_size=size)
            self.solid = NumpyRenderer(solid_config, threads=threads)
        # the reaches a pixel's change is taken at where both views show the mesh, and
        # elsewhere, and the power of the first: the solid config's own unless ``inside`` is set
        self.reaches = (
            (*solid_reaches(solid_config), solid_config.solid_inner_power) if inside is None
            else (inside, outline or (self.config.solid_shift,), inner_power)
        )  # fmt: skip

    def prepare(self, placed):
        (_, features, _), seconds = self.method.prepare(placed)
        if self.solid is None:
            return (features, features.views), seconds
        views, render_s = placed.views(self.solid)
        return (features, views), seconds + render_s

    def compare(self, a, b):
        return (min(part + term for part, term in self.pairings(a, b)),)

    def pairings(self, a, b) -> list[tuple[float, float]]:
        """Each ring pairing's (descriptor part, solid term) of A against B: the score is the
        least of their sums."""
        one, pairs = self.config.one_ring(), []
        solid_config = self.config if self.solid is None else self.solid.config
        for i, j in match_rules.ring_pairings(self.config):
            if self.floor is None:
                part = match_rules.pairing_part(
                    i, j, lambda k, m: descriptor_part(a[0].ring(k), b[0].ring(m), one),
                    self.config.replace(turned_part_share=self.both_parts),
                )  # fmt: skip
            else:
                part = floored_part(a[0].ring(i), b[0].ring(j), one, *self.floor)
                window = (self.config.moderate_slope, self.config.moderate_from,
                          self.config.moderate_to)  # fmt: skip
                part = float(match_rules.moderated_part(part, *window))
            if self.ceiling is not None:
                part = self.ceiling * math.tanh(part / self.ceiling)
            if self.part_power is not None:
                part = float(powered_part(part, *self.part_power))
            # the views compared for the solid change: the pairing's rings, and with
            # ``both_rings`` in the own-ring pairing the turned ring's against each other too
            rings = [(i, j)] + ([(1, 1)] if self.both_rings and (i, j) == (0, 0) else [])
            changes = [self._view_changes(a[1], b[1], k, m, solid_config, part)
                       for k, m in rings]  # fmt: skip
            per_view = np.stack([c[0] for c in changes])
            per_view = per_view.max(0) if self.both_rings == "max" else per_view.reshape(-1)
            moved = float(np.mean([c[1] for c in changes]))
            if math.isinf(self.view_power):
                solid = float(per_view.max())
            else:
                solid = float(np.mean(per_view**self.view_power) ** (1.0 / self.view_power))
            term = self.config.solid_weight * solid + moved
            if self.solid_ceiling is not None:  # a whole region changed: noticed, then no more
                term = self.solid_ceiling * math.tanh(term / self.solid_ceiling)
            pairs.append((part, term))
        return pairs

    def _view_changes(
        self, views_a: np.ndarray, views_b: np.ndarray, i: int, j: int,
        solid_config: PipelineConfig, part: float,
    ) -> tuple[np.ndarray, float]:  # fmt: skip
        """A's ring ``i`` against B's ring ``j`` (``part`` their descriptor part): each view's
        solid change (K,), and the netted outline change added at ``moved`` (0 unless set)."""
        # each view's solid change over the whole views: at the config's reaches, the
        # runtime's windowed mean of them to the bit
        views_a = views_a[match_rules.ring_views(i, solid_config)]
        views_b = views_b[match_rules.ring_views(j, solid_config)]
        change = pixel_changes(views_a, views_b, solid_config, *self.reaches)
        per_view = held_change(change, solid_config.solid_block, NUMPY_OPS)
        moved = 0.0
        if self.netted or self.moved:
            inner, lost, gained = moves_change(views_a, views_b, change, solid_config)
            peaks = [held.max(axis=(-2, -1)) for held in (inner, lost, gained)]
            if self.by_area:  # each side's peak less the share the other side's area nets
                area_lost, area_gained = lost.sum(axis=(-2, -1)), gained.sum(axis=(-2, -1))
                larger = np.maximum(np.maximum(area_lost, area_gained), 1e-12)
                net = np.maximum(peaks[1], peaks[2]) * np.abs(area_lost - area_gained) / larger
            else:
                net = np.abs(peaks[1] - peaks[2])
            if self.local is not None:  # only a change local to the shape counts
                m = (views_a.shape[-1] - lost.shape[-1]) // 2  # the held maps' margin
                both = np.maximum(views_a, views_b)[..., m:-m, m:-m]
                shape = both.sum(axis=(-2, -1))
                changed = (lost + gained).sum(axis=(-2, -1)) / np.maximum(shape, 1e-12)
                net = net * np.clip(1.0 - changed / self.local, 0.0, 1.0)
            moved = self.moved * float(net.mean())
            if self.near is not None:  # between far shapes the descriptors decide
                moved *= math.exp(-part / self.near)
            if self.netted:
                per_view = np.maximum(peaks[0], net)
        return per_view, moved


def powered_part(part, power: float, kept: float, knee: float = 0.0):
    """A descriptors' part (a float or an array) kept up to ``knee`` and ``knee + kept ((part -
    knee) / kept)^power`` above it: convex, so that a moderate part counts less."""
    above = np.maximum(np.asarray(part) - knee, 0.0)
    return np.where(np.asarray(part) > knee, knee + kept * (above / kept) ** power, part)


def floored_part(a, b, config: PipelineConfig, quantile: float, scale: float) -> float:
    """``descriptor_part`` with each direction's best-match distances taken above ``scale``
    times their ``quantile`` over the patches either mesh shows (window matching)."""
    shown = np.zeros(a.patches, bool)
    shown[a.patch_index] = shown[b.patch_index] = True
    scores = []
    for queries, targets in match_rules.directions(a, b, config):
        distances, weights = best_matches(queries, targets, config)
        floor = scale * np.quantile(distances[shown], quantile) if shown.any() else 0.0
        scores.append(
            float(match_rules.reduce(np.maximum(distances - floor, 0.0), weights, config))
        )
    return float(np.mean(scores))


def runtime_slide(method: Method) -> dict:
    """The slide check (``torch_checks.slide_of``) of a method scored on the runtime path."""

    def against(reference: tuple[np.ndarray, np.ndarray]):
        prepared = method.prepare(Placed("chair", *reference))[0]
        return lambda verts, faces: method.compare(
            method.prepare(Placed("slid", verts, faces))[0], prepared
        )[0]

    return torch_checks.slide_of(against)


def pixel_changes(
    views_a: np.ndarray, views_b: np.ndarray, config: PipelineConfig,
    inside: tuple[int, ...], outline: tuple[int, ...], power: float = 1.0,
) -> np.ndarray:  # fmt: skip
    """(K, H, W) two meshes' views -> (K, h, w) each pixel's change (``contract.solid_change``)
    as the mean over the reaches ``inside``, raised to ``power``, where both views show the
    mesh, and over the reaches ``outline`` elsewhere: any two sets of reaches, where the
    config's are a ramp and the same ramp less a drop. ``held_change`` of it is each view's
    solid change."""
    ranges = [{r: view_range(v, r, NUMPY_OPS) for r in {*inside, *outline}}
              for v in (views_a, views_b)]  # fmt: skip
    return reach_change(
        views_a, views_b, *ranges, inside, outline, power, config.background, NUMPY_OPS
    )


def moves_change(
    views_a: np.ndarray, views_b: np.ndarray, change: np.ndarray, config: PipelineConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, H, W) two meshes' views and their ``pixel_changes`` (K, h, w) -> three (K, h', w'):
    the changes held over the block (eroded) apart where both views show the mesh, where only A
    does (mesh lost) and where only B does (mesh gained). A moved part is lost at one place and
    gained at another, so lost and gained nearly cancel; a removed one's do not."""
    outer = (views_a.shape[-1] - change.shape[-1]) // 2  # the changes' margin: the largest reach
    window = (..., slice(outer, views_a.shape[-2] - outer), slice(outer, views_a.shape[-1] - outer))
    shown_a, shown_b = views_a[window] != config.background, views_b[window] != config.background
    return tuple(
        window_extreme(change * where, (config.solid_block - 1) // 2, NUMPY_OPS.minimum)
        for where in (shown_a & shown_b, shown_a & ~shown_b, ~shown_a & shown_b)
    )


def retrieval_misses(bench: sets.BenchSet, values: dict[tuple[str, str], float | None]) -> dict:
    """Each retrieval query whose nearest shape is of another family -> that shape and its
    score, and the nearest of its own family and its score."""
    misses = {}
    for query, found in ranked_retrieval(bench, values).items():
        family = bench.retrieval[query]
        if bench.retrieval[found[0][0]] != family:
            own = next((list(f) for f in found if bench.retrieval[f[0]] == family), None)
            misses[query] = {"nearest": list(found[0]), "own_family": own}
    return misses


def feature_graph(config: PipelineConfig, folder: Path) -> Path | None:
    """The shipped feature graph for ``config`` (None: the scorer finds it), else one exported
    into ``folder`` from the shipped weights."""
    if (models_dir() / features_file(config)).is_file():
        return None
    path = folder / features_file(config)
    if not path.exists():
        export_features(DRKFS.pretrained(config), path, shipped_entry(config, True)["sha256"])
    return path


def trained_at(nets: str) -> PipelineConfig:
    """The config every lever moves: the nets' at the config they were trained at, its solid
    change at one reach and its own-ring pairing from its own ring alone, no mesh turned onto
    another (the levers move what a mesh's views are; bench/turn_alignment.py studies the turn)."""
    return PipelineConfig(
        nets=nets, align_degrees=0.0, **NETS_TRAINED_AT, **ONE_REACH, **OWN_RING_ONLY
    )


def add_bench_options(parser: argparse.ArgumentParser) -> None:
    """--human, --other and --relabel: what ``lever_bench`` reads besides the repository."""
    parser.add_argument("--human", type=Path, help="a Geo-metric clone (see drkfs bench --human)")
    parser.add_argument(
        "--other", type=Path, help="a folder of meshes from outside the repository: a third side"
    )
    parser.add_argument(
        "--relabel", default="", help="with --other: mesh/variant=tier,... as the renders show"
    )


def lever_bench(parser: argparse.ArgumentParser, args) -> tuple[sets.BenchSet, dict | None]:
    """The bench a lever is judged on: the synthetic tiers, both sides of the real tiers (and
    the third with --other), the bars, retrieval and people's pairs with --human; with the
    people's judgments. A bad folder or relabel ends the run through ``parser.error``."""
    if args.relabel and args.other is None:
        parser.error("--relabel names meshes of --other DIR")
    bench = sets.tier_set(quick=False)
    sets.real_tiers(bench, [*TRAINING_MESHES, *HELDOUT_MESHES])
    if args.other is not None:
        try:
            sets.other_tiers(bench, args.other, parse_relabels(args.relabel))
        except ValueError as exc:  # a bad folder or relabel: say which, no traceback
            parser.error(str(exc))
    sets.bars(bench)  # the benchmark's own targets a default must keep
    sets.retrieval(bench, list(sets.ALL_FAMILIES), sets.RETRIEVAL_PER_FAMILY)
    return bench, human.add_human(bench, args.human) if args.human else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--nets", default=PipelineConfig().nets, help="the default's unless set")
    parser.add_argument(
        "--levers",
        nargs="+",
        choices=[*LEVERS, *WRAPPED],
        default=list(LEVERS),
        metavar="LEVER",
        help="every lever but the turn searches and recombinations unless set",
    )
    add_bench_options(parser)
    args = parser.parse_args()
    start = time.perf_counter()
    default = trained_at(args.nets)
    configs = {name: default.replace(**LEVERS[WRAPPED.get(name, name)]) for name in args.levers}
    bench, jod = lever_bench(parser, args)
    with tempfile.TemporaryDirectory() as folder:
        methods = [
            DrkfsOnnx(name, config, feature_graph(config, Path(folder)), args.threads)
            for name, config in configs.items()
        ]
        methods = [
            TurnSearch(m, m.outputs[0], TURN_SEARCHES[m.outputs[0]][1])
            if m.outputs[0] in TURN_SEARCHES
            else Recombined(m, m.outputs[0], args.threads, **RECOMBINED[m.outputs[0]][1])
            if m.outputs[0] in RECOMBINED else m
            for m in methods
        ]  # fmt: skip
        scores, costs = score_everything(bench, methods, print)
        # a recombination's own slide check, on the runtime path it is scored on
        slides = {m.outputs[0]: runtime_slide(m) for m in methods if isinstance(m, Recombined)}
    rows = {}
    for name, values in scores.comparisons.items():
        rows[name] = {
            "config": configs[name].to_dict(),
            "seconds_per_mesh": costs[name]["seconds_per_mesh"],
            **lever_summary(bench, values),
            "real_misses": tier_accuracy(bench, values, "real")["misses"],
            "bars": bars_summary(bench, values),
            "retrieval": retrieval_summary(bench, scores.retrieval[name]),
            "retrieval_misses": retrieval_misses(bench, scores.retrieval[name]),
            # the torch path has no turn search: the slide check of one is its lever's
            "slide": slides.get(name) or torch_checks.slide(DRKFS.pretrained(configs[name])),
            "human": None if jod is None else human.human_agreement(bench, values, jod),
        }
        shown = ("tiers", "real", "checks", "bars", "human")
        print(name, json.dumps({k: rows[name][k] for k in shown}))
    results = {
        "command": f"python bench/real_levers.py --nets {args.nets} --out {args.out}"
        + ("" if args.levers == list(LEVERS) else " --levers " + " ".join(map(repr, args.levers)))
        + (" --human DIR" if args.human else "")
        + (f" --other DIR --relabel '{args.relabel}'" if args.other is not None else ""),
        "threads": args.threads,
        "levers": rows,
        "values": {
            name: {
                f"{c.base}/{c.label}": values.get(i)
                for i, c in enumerate(bench.comparisons)
                if c.group in ("tiers", "real")
            }
            for name, values in scores.comparisons.items()
        },  # fmt: skip
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
