"""Outside metrics the benchmark measures DR-KFS against, where they are installed. Never a
dependency: a peer that is missing is skipped, and the results say why.

LFD, the light-field distance (Chen et al. 2003; light-field-distance 0.0.9 on PyPI, the DR-KFS
paper's outside metric), as ``../shared/peers/lfd_setup.sh`` builds it: ``3DAlignment`` renders
100 silhouettes of a mesh under X and writes its descriptors; ``Distance`` matches two
descriptor sets over 60 rotations and 10 camera sets. LFD normalises position, scale and
orientation itself, so it sees shape, not pose.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import trimesh

from .methods import Method, Placed

# where lfd_setup.sh installs (its PEERS folder); DRKFS_LFD names another
LFD_HOME = Path(os.environ.get("DRKFS_LFD", "/tmp/peers"))
# the descriptor files 3DAlignment writes into its working folder, and what Distance reads
LFD_OUTPUTS = {
    f"all_{kind}_v1.8.{ext}": f"{{}}_{kind}_v1.8.{ext}"
    for kind, ext in (("q4", "art"), ("q8", "art"), ("q8", "cir"), ("q8", "ecc"), ("q8", "fd"))
}
SIMILARITY = re.compile(rb"SIMILARITY:\s*(\S+)")


def find_lfd(home: Path = LFD_HOME) -> tuple[Path, Path] | str:
    """(the folder holding 3DAlignment and its data, the Distance program) or why LFD cannot
    run. ``Distance_fixed`` (lfd_setup.sh step 4: it reads the second shape's eccentricity
    file, which 0.0.9 forgets, so LFD(A, A) = 0) is preferred to the package's ``Distance``."""
    found = sorted(home.glob("venv/lib/python*/site-packages/lfd/Executable/3DAlignment"))
    if not found:
        return f"LFD not installed under {home} (run ../shared/peers/lfd_setup.sh)"
    if shutil.which("Xvfb") is None:
        return "LFD needs Xvfb (its 3DAlignment opens an X window)"
    fixed = home / "lfd_fixed" / "Distance_fixed"
    return found[0].parent, fixed if fixed.is_file() else found[0].parent / "Distance"


class LightField(Method):
    """LFD between meshes: ``prepare`` describes one (3DAlignment under a private Xvfb, in a
    private copy of its folder, so runs never share files), ``compare`` matches two."""

    outputs = ("LFD",)

    def __init__(self, executables: Path, distance: Path):
        self.work = Path(tempfile.mkdtemp(prefix="drkfs-lfd-"))
        self.program = self.work / "Executable"
        shutil.copytree(executables, self.program)
        self.distance = distance
        # the fixed Distance reads both shapes' files alike: LFD(A, B) = LFD(B, A)
        self.symmetric = distance.name == "Distance_fixed"
        self.display, self.server = _start_xvfb()
        self.count = 0
        self.failed: list[str] = []  # the meshes 3DAlignment could not describe

    def prepare(self, placed: Placed):
        """The stem of the mesh's descriptor files, or None where 3DAlignment fails on it twice
        (it has failed once on a mesh it then described: its pairs are then unscored and the
        mesh is named in ``failed``)."""
        start = time.perf_counter()
        self.count += 1
        stem = self.work / f"mesh{self.count}"
        trimesh.Trimesh(placed.verts, placed.faces, process=False).export(f"{stem}.obj")
        env = {**os.environ, "DISPLAY": self.display}
        for _ in range(2):
            described = subprocess.run(
                ["./3DAlignment", str(stem)], cwd=self.program, env=env,
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            )  # fmt: skip
            if described.returncode == 0:
                break
        Path(f"{stem}.obj").unlink()
        if described.returncode != 0:
            self.failed.append(placed.key)
            return None, time.perf_counter() - start
        for made, kept in LFD_OUTPUTS.items():
            (self.program / made).replace(kept.format(stem))
        return stem, time.perf_counter() - start

    def compare(self, a, b):
        if a is None or b is None:
            return (None,)
        result = subprocess.run(
            [str(self.distance), str(a), str(b)], cwd=self.program, capture_output=True
        )
        found = SIMILARITY.search(result.stdout)
        return (float(found.group(1)) if found else None,)

    def close(self) -> None:
        self.server.terminate()
        self.server.wait()
        shutil.rmtree(self.work, ignore_errors=True)


def _start_xvfb() -> tuple[str, subprocess.Popen]:
    """A virtual X server on the first free display from :90, and its DISPLAY."""
    for number in range(90, 190):
        if Path(f"/tmp/.X{number}-lock").exists():
            continue
        server = subprocess.Popen(
            ["Xvfb", f":{number}", "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        for _ in range(50):
            if Path(f"/tmp/.X11-unix/X{number}").exists():
                return f":{number}", server
            if server.poll() is not None:
                break
            time.sleep(0.1)
        server.kill()
    raise RuntimeError("no free X display for LFD's Xvfb")
