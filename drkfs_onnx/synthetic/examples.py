"""The bundled example meshes: a chair and its mild and structural variants, made by code."""

from __future__ import annotations

from pathlib import Path

import trimesh

from .shapes import assemble, chair
from .variants import shifted, without

REFERENCE = "chair.obj"


def example_meshes() -> dict[str, tuple[str, trimesh.Trimesh]]:
    """file name -> (what changed, mesh). The first entry is the reference."""
    base = chair()

    def mesh(parts, subdivisions: int = 1) -> trimesh.Trimesh:
        return trimesh.Trimesh(*assemble(parts, subdivisions), process=False)

    return {
        REFERENCE: ("reference", mesh(base)),
        "chair_retessellated.obj": ("mild: same surface, 4x the triangles", mesh(base, 2)),
        "chair_leg_shifted.obj": (
            "mild: one leg shifted by 2% of the chair's size",
            mesh(shifted(base, "leg_3", (0.02, 0.0, 0.0))),
        ),
        "chair_no_leg.obj": ("structural: one leg removed", mesh(without(base, "leg_3"))),
        "chair_no_back.obj": ("structural: backrest removed", mesh(without(base, "back"))),
    }


def write_examples(folder: str | Path) -> list[Path]:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, (_, mesh) in example_meshes().items():
        path = folder / name
        mesh.export(path)
        paths.append(path)
    return paths
