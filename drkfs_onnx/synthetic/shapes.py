"""Procedural part-based shapes: the project's example meshes and training data, built from code.

A shape is a list of named parts (boxes and cylinders), so variants can drop, add, move or
reshape one part (see ``variants.py``). Every family draws its parameters from a numpy Generator,
so a seed fixes the shape.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

# Unit cube corners and outward-facing triangles (counter-clockwise seen from outside).
_CUBE_CORNERS = np.array(
    [[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)], dtype=np.float64
)
_CUBE_FACES = np.array(
    [
        [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5],  # x = -0.5, x = +0.5
        [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],  # y = -0.5, y = +0.5
        [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],  # z = -0.5, z = +0.5
    ],
    dtype=np.int64,
)  # fmt: skip
CYLINDER_SEGMENTS = 16


def _unit_cylinder(segments: int = CYLINDER_SEGMENTS) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder of diameter 1 and height 1 along y, centred on the origin."""
    angle = 2 * np.pi * np.arange(segments) / segments
    ring = np.stack([0.5 * np.cos(angle), np.zeros(segments), 0.5 * np.sin(angle)], axis=1)
    verts = np.concatenate([ring - [0, 0.5, 0], ring + [0, 0.5, 0], [[0, -0.5, 0], [0, 0.5, 0]]])
    i = np.arange(segments)
    j = (i + 1) % segments
    bottom, top = 2 * segments, 2 * segments + 1
    faces = np.concatenate(
        [
            np.stack([i, segments + i, segments + j], axis=1),
            np.stack([i, segments + j, j], axis=1),
            np.stack([np.full(segments, bottom), i, j], axis=1),
            np.stack([np.full(segments, top), segments + j, segments + i], axis=1),
        ]
    )
    return verts, faces


_CYLINDER = _unit_cylinder()
_AXIS_ORDER = {0: [1, 0, 2], 1: [0, 1, 2], 2: [0, 2, 1]}  # put the cylinder's y onto the axis


@dataclass(frozen=True)
class Part:
    """An axis-aligned box or cylinder: centre and full size (x, y, z), y up.

    A cylinder's axis is ``axis`` (0, 1, 2 for x, y, z); its cross-section is the ellipse
    inscribed in the box's other two sides.
    """

    name: str
    center: tuple[float, float, float]
    size: tuple[float, float, float]
    kind: str = "box"
    axis: int = 1

    def mesh(self, subdivisions: int = 0) -> tuple[np.ndarray, np.ndarray]:
        if self.kind == "box":
            verts, faces = _CUBE_CORNERS, _CUBE_FACES
        else:
            verts, faces = _CYLINDER[0][:, _AXIS_ORDER[self.axis]], _CYLINDER[1]
            if self.axis != 1:  # swapping two coordinates mirrors the mesh: keep faces outward
                faces = faces[:, ::-1]
        for _ in range(subdivisions):
            verts, faces = subdivide(verts, faces)
        return verts * np.array(self.size) + np.array(self.center), faces


def subdivide(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split every triangle into four at its edge midpoints (the surface does not move)."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    mids = len(verts) + inverse.reshape(-1, 3)
    verts = np.concatenate([verts, verts[unique].mean(axis=1)])
    a, b, c = faces.T
    ab, bc, ca = mids.T
    children = np.array([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]])  # (4, 3, F)
    return verts, children.transpose(2, 0, 1).reshape(-1, 3)


def assemble(parts: list[Part], subdivisions: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate part meshes into one (V, 3) float64, (F, 3) int64 mesh."""
    verts, faces, offset = [], [], 0
    for part in parts:
        v, f = part.mesh(subdivisions)
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
    return np.concatenate(verts), np.concatenate(faces)


def _legs(prefix: str, half_x: float, half_z: float, height: float, thick: float) -> list[Part]:
    corners = [(-1, -1), (1, -1), (-1, 1), (1, 1)]
    return [
        Part(f"{prefix}_{i}", (sx * half_x, height / 2, sz * half_z), (thick, height, thick))
        for i, (sx, sz) in enumerate(corners)
    ]


def chair(
    seat_height: float = 0.45, seat_width: float = 0.5, back_height: float = 0.5, leg: float = 0.05
) -> list[Part]:
    """A four-legged chair with a backrest."""
    half = seat_width / 2 - leg / 2
    seat = Part("seat", (0.0, seat_height + 0.025, 0.0), (seat_width, 0.05, seat_width))
    back = Part(
        "back", (0.0, seat_height + 0.05 + back_height / 2, -half), (seat_width, back_height, leg)
    )
    return [*_legs("leg", half, half, seat_height, leg), seat, back]


def random_chair(rng: np.random.Generator) -> list[Part]:
    parts = chair(
        seat_height=rng.uniform(0.35, 0.55),
        seat_width=rng.uniform(0.4, 0.6),
        back_height=rng.uniform(0.3, 0.6),
        leg=rng.uniform(0.03, 0.07),
    )
    if rng.random() < 0.5:  # bars between the front and back legs
        seat_width = parts[4].size[0]
        height = rng.uniform(0.1, 0.25)
        for side, x in (("left", parts[0].center[0]), ("right", parts[1].center[0])):
            parts.append(Part(f"bar_{side}", (x, height, 0.0), (0.03, 0.03, seat_width)))
    return parts


def table(rng: np.random.Generator) -> list[Part]:
    width, depth = rng.uniform(0.8, 1.4), rng.uniform(0.5, 0.9)
    height, leg, top = rng.uniform(0.5, 0.8), rng.uniform(0.04, 0.1), rng.uniform(0.03, 0.08)
    top_part = Part("top", (0.0, height + top / 2, 0.0), (width, top, depth))
    if rng.random() < 0.3:  # pedestal table
        radius = rng.uniform(0.3, 0.5) * depth
        return [
            Part("base", (0.0, 0.02, 0.0), (2 * radius, 0.04, 2 * radius), "cylinder"),
            Part("pedestal", (0.0, height / 2, 0.0), (leg * 1.5, height, leg * 1.5), "cylinder"),
            top_part,
        ]
    return [*_legs("leg", width / 2 - leg, depth / 2 - leg, height, leg), top_part]


def lamp(rng: np.random.Generator) -> list[Part]:
    base, pole = rng.uniform(0.25, 0.45), rng.uniform(0.6, 1.2)
    shade_w, shade_h = rng.uniform(0.25, 0.5), rng.uniform(0.15, 0.3)
    arm = rng.uniform(0.0, 0.3)
    parts = [
        Part("base", (0.0, 0.025, 0.0), (base, 0.05, base), "cylinder"),
        Part("pole", (0.0, 0.05 + pole / 2, 0.0), (0.03, pole, 0.03), "cylinder"),
    ]
    top = 0.05 + pole
    if arm > 0.1:
        parts.append(Part("arm", (arm / 2, top, 0.0), (arm, 0.03, 0.03), "cylinder", axis=0))
    shade_x = arm if arm > 0.1 else 0.0
    parts.append(
        Part("shade", (shade_x, top - shade_h / 3, 0.0), (shade_w, shade_h, shade_w), "cylinder")
    )
    return parts


def airplane(rng: np.random.Generator) -> list[Part]:
    length, body = rng.uniform(1.2, 1.8), rng.uniform(0.12, 0.2)
    span, chord = rng.uniform(1.0, 1.8), rng.uniform(0.2, 0.35)
    wing_x = rng.uniform(-0.1, 0.15) * length
    tail_x = -0.42 * length
    parts = [
        Part("fuselage", (0.0, 0.0, 0.0), (length, body, body), "cylinder", axis=0),
        Part("wings", (wing_x, 0.0, 0.0), (chord, 0.03, span)),
        Part("stabilizer", (tail_x, 0.0, 0.0), (chord * 0.6, 0.02, span * 0.35)),
        Part("fin", (tail_x, body * 1.2, 0.0), (chord * 0.6, body * 1.6, 0.02)),
    ]
    if rng.random() < 0.6:
        for side in (-1, 1):
            parts.append(
                Part(
                    f"engine_{'lr'[side > 0]}",
                    (wing_x + 0.05, -body * 0.7, side * span * 0.25),
                    (0.25, 0.09, 0.09),
                    "cylinder",
                    axis=0,
                )
            )
    return parts


def car(rng: np.random.Generator) -> list[Part]:
    length, width = rng.uniform(1.2, 1.8), rng.uniform(0.6, 0.8)
    body_h, cabin_h = rng.uniform(0.2, 0.35), rng.uniform(0.18, 0.3)
    wheel = rng.uniform(0.22, 0.32)
    clearance = wheel * 0.5
    cabin_len = rng.uniform(0.4, 0.6) * length
    parts = [
        Part("body", (0.0, clearance + body_h / 2, 0.0), (length, body_h, width)),
        Part(
            "cabin",
            (rng.uniform(-0.1, 0.05) * length, clearance + body_h + cabin_h / 2, 0.0),
            (cabin_len, cabin_h, width * 0.9),
        ),
    ]
    for i, (sx, sz) in enumerate([(-1, -1), (1, -1), (-1, 1), (1, 1)]):
        parts.append(
            Part(
                f"wheel_{i}",
                (sx * length * 0.32, wheel / 2, sz * (width / 2)),
                (wheel, wheel, 0.1),
                "cylinder",
                axis=2,
            )
        )
    return parts


def mug(rng: np.random.Generator) -> list[Part]:
    radius, height = rng.uniform(0.3, 0.45), rng.uniform(0.5, 0.9)
    reach, thick = rng.uniform(0.12, 0.2), 0.04
    low, high = height * rng.uniform(0.2, 0.3), height * rng.uniform(0.7, 0.8)
    outer = radius + reach
    return [
        Part("body", (0.0, height / 2, 0.0), (2 * radius, height, 2 * radius), "cylinder"),
        Part("handle_low", (radius + reach / 2, low, 0.0), (reach, thick, thick)),
        Part("handle_high", (radius + reach / 2, high, 0.0), (reach, thick, thick)),
        Part("handle_grip", (outer, (low + high) / 2, 0.0), (thick, high - low + thick, thick)),
    ]


def shelf(rng: np.random.Generator) -> list[Part]:
    width, height, depth = rng.uniform(0.6, 1.0), rng.uniform(0.8, 1.6), rng.uniform(0.25, 0.4)
    board = 0.03
    count = int(rng.integers(2, 6))
    parts = [
        Part("side_left", (-width / 2, height / 2, 0.0), (board, height, depth)),
        Part("side_right", (width / 2, height / 2, 0.0), (board, height, depth)),
    ]
    if rng.random() < 0.5:
        parts.append(Part("back", (0.0, height / 2, -depth / 2), (width, height, board)))
    for i in range(count):
        y = board / 2 + i * (height - board) / (count - 1)
        parts.append(Part(f"board_{i}", (0.0, y, 0.0), (width, board, depth)))
    return parts


def sofa(rng: np.random.Generator) -> list[Part]:
    width, depth = rng.uniform(1.2, 2.0), rng.uniform(0.6, 0.9)
    seat_h, back_h, arm_w = rng.uniform(0.3, 0.45), rng.uniform(0.3, 0.5), rng.uniform(0.1, 0.2)
    seats = int(rng.integers(1, 4))
    inner = width - 2 * arm_w
    parts = [
        Part("base", (0.0, seat_h / 2, 0.0), (width, seat_h, depth)),
        Part("back", (0.0, seat_h + back_h / 2, -depth / 2 + 0.08), (width, back_h, 0.16)),
        Part("arm_left", (-(width - arm_w) / 2, seat_h + 0.12, 0.0), (arm_w, 0.24, depth)),
        Part("arm_right", ((width - arm_w) / 2, seat_h + 0.12, 0.0), (arm_w, 0.24, depth)),
    ]
    for i in range(seats):
        x = -inner / 2 + (i + 0.5) * inner / seats
        size = (inner / seats * 0.95, 0.1, depth - 0.2)
        parts.append(Part(f"cushion_{i}", (x, seat_h + 0.05, 0.06), size))
    return parts


def primitives(rng: np.random.Generator) -> list[Part]:
    """3 to 6 random boxes and cylinders, each touching the previous one."""
    parts: list[Part] = []
    center = np.zeros(3)
    for i in range(int(rng.integers(3, 7))):
        size = rng.uniform(0.1, 0.6, size=3)
        if parts:
            step = rng.normal(size=3)
            center = center + 0.5 * (np.abs(step) / np.abs(step).max() * size) * np.sign(step)
        kind = "cylinder" if rng.random() < 0.4 else "box"
        axis = int(rng.integers(0, 3))
        parts.append(Part(f"part_{i}", tuple(center.tolist()), tuple(size.tolist()), kind, axis))
    return parts


FAMILIES: dict[str, Callable[[np.random.Generator], list[Part]]] = {
    "chair": random_chair,
    "table": table,
    "lamp": lamp,
    "airplane": airplane,
    "car": car,
    "mug": mug,
    "shelf": shelf,
    "sofa": sofa,
    "primitives": primitives,
}


def bed(rng: np.random.Generator) -> list[Part]:
    width, length = rng.uniform(0.9, 1.6), rng.uniform(1.8, 2.1)
    frame_h, mattress = rng.uniform(0.2, 0.35), rng.uniform(0.15, 0.25)
    head = rng.uniform(0.4, 0.8)
    parts = [
        Part("frame", (0.0, 0.05 + frame_h / 2, 0.0), (width, frame_h, length)),
        Part(
            "mattress",
            (0.0, 0.05 + frame_h + mattress / 2, 0.02),
            (width * 0.95, mattress, length * 0.95),
        ),
        Part(
            "headboard",
            (0.0, (0.05 + frame_h + head) / 2, -length / 2),
            (width, 0.05 + frame_h + head, 0.06),
        ),
    ]
    if rng.random() < 0.5:
        height = 0.05 + frame_h + mattress
        parts.append(Part("footboard", (0.0, height / 2, length / 2), (width, height, 0.05)))
    return parts + _legs("leg", width / 2 - 0.04, length / 2 - 0.04, 0.05, 0.06)


def bench(rng: np.random.Generator) -> list[Part]:
    length, depth = rng.uniform(1.0, 1.8), rng.uniform(0.3, 0.45)
    height, seat = rng.uniform(0.4, 0.5), 0.05
    parts = [Part("seat", (0.0, height + seat / 2, 0.0), (length, seat, depth))]
    if rng.random() < 0.5:  # two slab legs
        for side in (-1, 1):
            x = side * (length / 2 - 0.1)
            parts.append(Part(f"slab_{side}", (x, height / 2, 0.0), (0.05, height, depth * 0.9)))
    else:
        parts += _legs("leg", length / 2 - 0.06, depth / 2 - 0.04, height, 0.05)
    if rng.random() < 0.5:
        back = rng.uniform(0.25, 0.4)
        centre = (0.0, height + seat + back / 2 + 0.05, -depth / 2)
        parts.append(Part("back", centre, (length, back, 0.04)))
    return parts


def stool(rng: np.random.Generator) -> list[Part]:
    height, radius, leg = rng.uniform(0.45, 0.8), rng.uniform(0.15, 0.22), rng.uniform(0.025, 0.04)
    legs = int(rng.integers(3, 5))
    parts = [Part("seat", (0.0, height + 0.025, 0.0), (2 * radius, 0.05, 2 * radius), "cylinder")]
    for i in range(legs):
        angle = 2 * np.pi * i / legs
        x, z = 0.8 * radius * np.cos(angle), 0.8 * radius * np.sin(angle)
        parts.append(Part(f"leg_{i}", (x, height / 2, z), (leg, height, leg), "cylinder"))
    if rng.random() < 0.6:
        ring = 1.6 * radius
        parts.append(Part("footrest", (0.0, height * 0.35, 0.0), (ring, 0.03, ring), "cylinder"))
    return parts


def desk(rng: np.random.Generator) -> list[Part]:
    width, depth, height = rng.uniform(1.0, 1.6), rng.uniform(0.5, 0.75), rng.uniform(0.7, 0.78)
    drawers = rng.uniform(0.3, 0.45)
    top = Part("top", (0.0, height + 0.02, 0.0), (width, 0.04, depth))
    block = Part(
        "drawers", (width / 2 - drawers / 2, height / 2, 0.0), (drawers, height, depth * 0.95)
    )
    side = Part("side", (-width / 2 + 0.025, height / 2, 0.0), (0.05, height, depth * 0.95))
    parts = [top, block, side]
    if rng.random() < 0.5:
        parts.append(
            Part(
                "modesty", (0.0, height * 0.6, -depth / 2 + 0.02), (width * 0.9, height * 0.5, 0.02)
            )
        )
    return parts


def cabinet(rng: np.random.Generator) -> list[Part]:
    width, height, depth = rng.uniform(0.5, 1.0), rng.uniform(0.8, 1.8), rng.uniform(0.35, 0.6)
    feet = rng.uniform(0.05, 0.15)
    parts = [Part("body", (0.0, feet + height / 2, 0.0), (width, height, depth))]
    parts += _legs("foot", width / 2 - 0.04, depth / 2 - 0.04, feet, 0.05)
    doors = int(rng.integers(1, 3))
    for i in range(doors):
        x = (i - (doors - 1) / 2) * width / doors + 0.3 * width / doors
        size = (0.03, height * 0.2, 0.04)
        parts.append(Part(f"handle_{i}", (x, feet + height * 0.55, depth / 2 + 0.02), size))
    return parts


def bottle(rng: np.random.Generator) -> list[Part]:
    radius, body = rng.uniform(0.12, 0.25), rng.uniform(0.5, 0.9)
    neck_r, neck = radius * rng.uniform(0.3, 0.45), rng.uniform(0.15, 0.3)
    shoulder = rng.uniform(0.05, 0.12)
    return [
        Part("body", (0.0, body / 2, 0.0), (2 * radius, body, 2 * radius), "cylinder"),
        Part(
            "shoulder",
            (0.0, body + shoulder / 2, 0.0),
            (1.4 * radius, shoulder, 1.4 * radius),
            "cylinder",
        ),
        Part(
            "neck",
            (0.0, body + shoulder + neck / 2, 0.0),
            (2 * neck_r, neck, 2 * neck_r),
            "cylinder",
        ),
        Part(
            "cap",
            (0.0, body + shoulder + neck + 0.03, 0.0),
            (2.3 * neck_r, 0.06, 2.3 * neck_r),
            "cylinder",
        ),
    ]


def rocket(rng: np.random.Generator) -> list[Part]:
    radius, length = rng.uniform(0.1, 0.18), rng.uniform(1.0, 1.8)
    nose, fin = rng.uniform(0.15, 0.3), rng.uniform(0.2, 0.35)
    parts = [
        Part("body", (0.0, length / 2, 0.0), (2 * radius, length, 2 * radius), "cylinder"),
        Part("nose", (0.0, length + nose / 2, 0.0), (radius, nose, radius), "cylinder"),
    ]
    for i, (x, z) in enumerate([(1, 0), (-1, 0), (0, 1), (0, -1)][: int(rng.integers(3, 5))]):
        size = (fin if x else 0.02, fin * 1.2, fin if z else 0.02)
        centre = (x * (radius + fin / 2), fin * 0.6, z * (radius + fin / 2))
        parts.append(Part(f"fin_{i}", centre, size))
    return parts


def bicycle(rng: np.random.Generator) -> list[Part]:
    wheel, base = rng.uniform(0.55, 0.7), rng.uniform(0.9, 1.1)
    tube = 0.04
    height = wheel * rng.uniform(1.1, 1.3)
    parts = [
        Part(f"wheel_{i}", (x, wheel / 2, 0.0), (wheel, wheel, 0.04), "cylinder", axis=2)
        for i, x in enumerate((-base / 2, base / 2))
    ]
    parts += [
        Part("top_tube", (0.0, height, 0.0), (base * 0.6, tube, tube)),
        Part("down_tube", (0.0, wheel / 2 + 0.05, 0.0), (base, tube, tube)),
        Part(
            "seat_post",
            (-base * 0.25, (wheel / 2 + height) / 2 + 0.05, 0.0),
            (tube, height - wheel / 2 + 0.1, tube),
        ),
        Part("seat", (-base * 0.25, height + 0.12, 0.0), (0.22, 0.05, 0.1)),
        Part(
            "fork",
            (base * 0.3, (wheel / 2 + height) / 2 + 0.05, 0.0),
            (tube, height - wheel / 2 + 0.15, tube),
        ),
        Part(
            "handlebar",
            (base * 0.3, height + 0.15, 0.0),
            (tube, tube, rng.uniform(0.4, 0.6)),
            "cylinder",
            axis=2,
        ),
    ]
    return parts


def monitor(rng: np.random.Generator) -> list[Part]:
    width, height = rng.uniform(0.5, 0.9), rng.uniform(0.3, 0.55)
    neck, base = rng.uniform(0.1, 0.25), rng.uniform(0.2, 0.35)
    parts = [
        Part("base", (0.0, 0.015, 0.0), (base, 0.03, base * 0.7)),
        Part("neck", (0.0, 0.03 + neck / 2, -0.02), (0.05, neck, 0.03)),
        Part("screen", (0.0, 0.03 + neck + height / 2, 0.0), (width, height, 0.03)),
    ]
    if rng.random() < 0.4:  # a round base instead
        parts[0] = Part("base", (0.0, 0.015, 0.0), (base, 0.03, base), "cylinder")
    return parts


def ladder(rng: np.random.Generator) -> list[Part]:
    height, width = rng.uniform(1.2, 2.0), rng.uniform(0.35, 0.55)
    rungs = int(rng.integers(4, 9))
    rail = 0.05
    parts = [
        Part(f"rail_{side}", (side * width / 2, height / 2, 0.0), (rail, height, rail * 1.5))
        for side in (-1, 1)
    ]
    for i in range(rungs):
        y = (i + 1) * height / (rungs + 1)
        parts.append(Part(f"rung_{i}", (0.0, y, 0.0), (width, 0.03, 0.03), "cylinder", axis=0))
    return parts


def dumbbell(rng: np.random.Generator) -> list[Part]:
    bar, plate = rng.uniform(0.35, 0.6), rng.uniform(0.15, 0.3)
    plates = int(rng.integers(1, 3))
    parts = [Part("bar", (0.0, plate / 2, 0.0), (bar, 0.04, 0.04), "cylinder", axis=0)]
    for side in (-1, 1):
        for i in range(plates):
            x = side * (bar / 2 - 0.03 - i * 0.06)
            size = (0.05, plate * (1 - 0.2 * i), plate * (1 - 0.2 * i))
            parts.append(Part(f"plate_{side}_{i}", (x, plate / 2, 0.0), size, "cylinder", axis=0))
    return parts


def tree(rng: np.random.Generator) -> list[Part]:
    trunk, girth = rng.uniform(0.4, 0.8), rng.uniform(0.08, 0.15)
    levels = int(rng.integers(2, 4))
    width = rng.uniform(0.6, 1.0)
    parts = [Part("trunk", (0.0, trunk / 2, 0.0), (girth, trunk, girth), "cylinder")]
    y = trunk
    for i in range(levels):
        layer = width * (1 - 0.3 * i)
        height = rng.uniform(0.2, 0.35)
        parts.append(
            Part(f"crown_{i}", (0.0, y + height / 2, 0.0), (layer, height, layer), "cylinder")
        )
        y += height * 0.8
    return parts


FAMILIES_NOT_TRAINED = {
    "bed": bed,
    "bench": bench,
    "stool": stool,
    "desk": desk,
    "cabinet": cabinet,
    "bottle": bottle,
    "rocket": rocket,
    "bicycle": bicycle,
    "monitor": monitor,
    "ladder": ladder,
    "dumbbell": dumbbell,
    "tree": tree,
}
# every family: the nets' training data and the benchmark's tiers use FAMILIES; retrieval adds
# the ones no training ever saw
ALL_FAMILIES = {**FAMILIES, **FAMILIES_NOT_TRAINED}


def random_shape(family: str, seed: int | np.random.Generator) -> list[Part]:
    """A shape of ``family`` (any of ``ALL_FAMILIES``) with parameters drawn from ``seed``."""
    return ALL_FAMILIES[family](np.random.default_rng(seed))
