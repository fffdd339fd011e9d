"""The real tiers' third and fourth sides: meshes from outside the repository, never chosen on,
written as welded OBJs into a folder for ``bench/real_tiers.py --other`` and
``bench/real_levers.py --other`` (bench/records/real_tiers.md, "A third side";
bench/records/real_levers.md, "Openings seen dark").

    git clone https://github.com/alecjacobson/common-3d-test-models CLONE   # commit 8a4f864
    python bench/other_meshes.py --clone CLONE --out DIR
    git clone https://github.com/libigl/libigl-tutorial-data CLONE   # commit c1f9ede
    python bench/other_meshes.py --side fourth --clone CLONE --out DIR

The third side is read from common-3d-test-models (the repository the ten shipped meshes come
from, meshes/README.md), the fourth, chosen by kind before any was scored, from libigl's
tutorial data; neither is shipped: their sources' terms are theirs. Each is welded (vertices
at one position merged, whatever their texture coordinates or normals): the files split their
surfaces along texture seams, where the recipe's noise would open cracks and the second piece
would be a texture island.
"""

from __future__ import annotations

import argparse
import zipfile
from pathlib import Path

import trimesh

# side -> name -> its file in the clone (an archive's member after a colon)
SIDES = {
    "third": {
        "horse": "data/horse.zip:horse.ply",
        "nefertiti": "data/nefertiti.obj",
        "ogre": "data/ogre.obj",
        "spot": "data/spot.obj",
        "suzanne": "data/suzanne.obj",
        "teapot": "data/teapot.obj",
    },
    # a scan, a bust, an animal, a statue of holes, a sculpted head, a CAD part
    "fourth": {
        "armadillo": "armadillo.obj",
        "max": "decimated-max.obj",
        "elephant": "elephant.obj",
        "fertility": "fertility.off",
        "lion": "lion.off",
        "screwdriver": "screwdriver.off",
    },
}


def read(clone: Path, entry: str) -> trimesh.Trimesh:
    """The mesh ``entry`` names in ``clone``, welded."""
    archive, _, member = entry.partition(":")
    if member:
        with zipfile.ZipFile(clone / archive) as opened, opened.open(member) as file:
            mesh = trimesh.load(file, file_type=Path(member).suffix[1:], force="mesh")
    else:
        mesh = trimesh.load(clone / archive, force="mesh")
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    return mesh


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", choices=list(SIDES), default="third")
    parser.add_argument("--clone", type=Path, required=True, help="the side's repository")
    parser.add_argument("--out", type=Path, required=True, help="the folder to write")
    args = parser.parse_args()
    meshes = SIDES[args.side]
    if missing := [e for e in meshes.values() if not (args.clone / e.split(":")[0]).is_file()]:
        raise SystemExit(f"{args.clone}: not in this clone: {', '.join(missing)}")
    args.out.mkdir(parents=True, exist_ok=True)
    for name, entry in meshes.items():
        mesh = read(args.clone, entry)
        mesh.export(args.out / f"{name}.obj")
        print(f"{name}: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces")


if __name__ == "__main__":
    main()
