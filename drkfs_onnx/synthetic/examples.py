"""The bundled example meshes: a chair and its invisible and structural variants, made by code,
and the pairs file that scores each against the chair (``drkfs-score batch``)."""

from __future__ import annotations

from pathlib import Path

import trimesh

from .shapes import assemble, chair
from .variants import shifted, without

REFERENCE = "chair.obj"
PAIRS = "pairs.csv"


def example_meshes() -> dict[str, tuple[str, trimesh.Trimesh]]:
    """file name -> (what changed, mesh). The first entry is the reference."""
    base = chair()

    def mesh(parts, subdivisions: int = 1) -> trimesh.Trimesh:
        return trimesh.Trimesh(*assemble(parts, subdivisions), process=False)

    return {
        REFERENCE: ("reference", mesh(base)),
        "chair_retessellated.obj": ("invisible: the same surface, 4x the triangles", mesh(base, 2)),
        "chair_leg_shifted.obj": (
            "invisible: one leg shifted by 2% of the chair's size",
            mesh(shifted(base, "leg_3", (0.02, 0.0, 0.0))),
        ),
        "chair_no_leg.obj": ("structural: one leg removed", mesh(without(base, "leg_3"))),
        "chair_no_back.obj": ("structural: backrest removed", mesh(without(base, "back"))),
    }


def write_examples(folder: str | Path) -> list[Path]:
    """The example meshes and PAIRS written to ``folder`` -> their paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, (_, mesh) in example_meshes().items():
        path = folder / name
        mesh.export(path)
        paths.append(path)
    rows = "".join(f"{name},{REFERENCE}\n" for name in example_meshes())
    (folder / PAIRS).write_text("mesh_a,mesh_b\n" + rows)
    return [*paths, folder / PAIRS]
