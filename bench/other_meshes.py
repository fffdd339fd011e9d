"""The real tiers' third side: six meshes from outside the repository, never chosen on, written
as welded OBJs into a folder for ``bench/real_tiers.py --other`` and ``bench/real_levers.py
--other`` (docs/benchmark.md, "A third side").

    git clone https://github.com/alecjacobson/common-3d-test-models CLONE   # commit 8a4f864
    python bench/other_meshes.py --clone CLONE --out DIR

They are read from a clone of common-3d-test-models (the repository the ten shipped meshes come
from, meshes/README.md), not shipped: their sources' terms are theirs. Each is welded (vertices
at one position merged, whatever their texture coordinates or normals): the files split their
surfaces along texture seams, where the recipe's noise would open cracks and the second piece
would be a texture island.
"""

from __future__ import annotations

import argparse
import zipfile
from pathlib import Path

import trimesh

# name -> its file under data/ of the clone (an archive's member after a colon)
OTHER_MESHES = {
    "horse": "horse.zip:horse.ply",
    "nefertiti": "nefertiti.obj",
    "ogre": "ogre.obj",
    "spot": "spot.obj",
    "suzanne": "suzanne.obj",
    "teapot": "teapot.obj",
}


def read(data: Path, entry: str) -> trimesh.Trimesh:
    """The mesh ``entry`` names under ``data``, welded."""
    archive, _, member = entry.partition(":")
    if member:
        with zipfile.ZipFile(data / archive) as opened, opened.open(member) as file:
            mesh = trimesh.load(file, file_type=Path(member).suffix[1:], force="mesh")
    else:
        mesh = trimesh.load(data / archive, force="mesh")
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    return mesh


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clone", type=Path, required=True, help="common-3d-test-models")
    parser.add_argument("--out", type=Path, required=True, help="the folder to write")
    args = parser.parse_args()
    data = args.clone / "data"
    if missing := [e for e in OTHER_MESHES.values() if not (data / e.split(":")[0]).is_file()]:
        raise SystemExit(f"{data}: not in this clone: {', '.join(missing)}")
    args.out.mkdir(parents=True, exist_ok=True)
    for name, entry in OTHER_MESHES.items():
        mesh = read(data, entry)
        mesh.export(args.out / f"{name}.obj")
        print(f"{name}: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces")


if __name__ == "__main__":
    main()
