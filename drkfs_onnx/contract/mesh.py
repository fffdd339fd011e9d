"""Mesh input through trimesh, with checks that name the file and the reason, and normalisation.

numpy only: the server runtime loads meshes through here without torch.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import trimesh

from .array_ops import NUMPY_OPS, ArrayOps
from .config import NORMALIZATIONS

AREA_EPS = 1e-14
# Text formats trimesh decodes itself: a byte that is not UTF-8 (a Latin-1 comment) sends it to
# charset_normalizer, which the base install lacks, so they are decoded here (see ``_read``).
TEXT_FORMATS = (".obj", ".off")


class MeshError(ValueError):
    """A mesh that cannot be scored; the message names the source and the reason."""

    def __init__(self, source: str, reason: str):
        super().__init__(f"{source}: {reason}")
        self.source = source
        self.reason = reason


@dataclass(frozen=True)
class Mesh:
    """A checked triangle mesh: vertices (V, 3) float64, faces (F, 3) int64, all finite and
    non-degenerate."""

    vertices: np.ndarray
    faces: np.ndarray
    source: str = "<array>"

    def in_unit_sphere(self) -> Mesh:
        """This mesh placed in the metric's frame (its bounding box centred, fitting the unit
        sphere): where a training loop's template sits, so a target loaded from a file in
        other units or off the origin is one the template can reach."""
        return replace(self, vertices=place(self.vertices, frame_of(self.vertices)))


def load_mesh(path: str | Path) -> Mesh:
    """Read any format trimesh reads (scenes are merged) and check it with ``check_mesh``."""
    source, path = str(path), Path(path)
    if path.is_dir():
        raise MeshError(source, "a folder, not a mesh file")
    if not path.is_file():
        raise MeshError(source, "no such file")
    if path.suffix.lower() == ".npz":
        raise MeshError(
            source,
            "a features file (drkfs-score features), not a mesh: it can only be the reference "
            "(mesh B) of drkfs-score pair or batch and of Scorer.score; give the mesh itself here",
        )
    try:
        loaded = _read(path)
        vertices, faces = _geometry(loaded)
    except NotImplementedError as exc:  # trimesh's "file_type 'x' not supported"
        raise MeshError(
            source, f"not a mesh format trimesh reads ({path.suffix or 'no extension'}): {exc}"
        ) from exc
    except Exception as exc:  # trimesh raises many types for unreadable input
        reason = _range_reason(exc) or f"unreadable ({type(exc).__name__}: {exc})"
        raise MeshError(source, reason) from exc
    if len(faces) == 0:
        raise MeshError(source, _why_no_faces(path, _point_count(loaded)))
    return check_mesh(vertices, faces, source)


def _why_no_faces(path: Path, vertices: int) -> str:
    """What a file that gave no faces holds, as far as its bytes say."""
    if path.stat().st_size == 0:
        return "an empty file"
    if path.suffix.lower() == ".ply" and any(
        line.split()[:2] == ["element", "tristrips"] for line in _header_lines(path)
    ):
        return (
            "its faces are triangle strips (element tristrips), which trimesh does not read; "
            "save it with a face list"
        )
    if vertices == 0:
        return f"no vertices and no faces: not a {path.suffix or 'mesh'} file trimesh can read"
    return f"{vertices} vertices and no faces (a point cloud?)"


def _point_count(loaded) -> int:
    """The vertices trimesh read, whether or not any face uses them."""
    geometries = loaded.geometry.values() if isinstance(loaded, trimesh.Scene) else [loaded]
    return sum(len(getattr(g, "vertices", [])) for g in geometries)


def _header_lines(path: Path) -> list[str]:
    """The first 4 KiB of a file as text lines: a PLY's or OFF's header."""
    with open(path, "rb") as handle:
        return handle.read(4096).decode("latin-1").splitlines()


def declared_faces(path: str | Path) -> int | None:
    """The face count a PLY or OFF file declares in its header, read without the geometry (a
    server can refuse a huge file before reading it); None for other formats or a header that
    does not say."""
    suffix = Path(path).suffix.lower()
    if suffix not in (".ply", ".off") or not Path(path).is_file():
        return None
    head = _header_lines(Path(path))
    if suffix == ".ply":
        for line in head:
            words = line.split()
            if words[:2] == ["element", "face"] and len(words) == 3 and words[2].isdigit():
                return int(words[2])
            if words[:1] == ["end_header"]:
                break
        return None
    # OFF: "OFF", then (comments aside) "vertices faces edges", possibly on the OFF line itself
    counts = " ".join(line.split("#")[0] for line in head).split()
    if counts[:1] == ["OFF"] and len(counts) >= 3 and counts[2].isdigit():
        return int(counts[2])
    return None


def _read(path: Path):
    """trimesh's reading of ``path``, geometry only: materials and textures would need Pillow,
    which servers may lack. A text format is decoded here, as UTF-8 or else Latin-1 (every byte
    a character; keywords and numbers are ASCII, so the geometry is the same either way), so
    every install reads the same files."""
    options = dict(process=False, skip_materials=True)
    suffix = path.suffix.lower()
    if suffix not in TEXT_FORMATS:
        return trimesh.load(path, **options)
    data = path.read_bytes()
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        data = data.decode("latin-1").encode("utf-8")
    resolver = trimesh.resolvers.FilePathResolver(path)
    return trimesh.load(io.BytesIO(data), file_type=suffix[1:], resolver=resolver, **options)


def _range_reason(exc: Exception) -> str | None:
    """numpy's IndexError for a face naming a vertex the file does not have, in a reader's
    words (None for any other error)."""
    pattern = r"index (-?\d+) is out of bounds for axis 0 with size (\d+)"
    found = re.search(pattern, str(exc)) if isinstance(exc, IndexError) else None
    if found is None:
        return None
    index, count = found.groups()
    return f"a face uses vertex {index} (counting from 0), but the file has {count} vertices"


def _geometry(loaded) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a mesh, or of a scene's meshes placed by its graph, merged."""
    if isinstance(loaded, trimesh.Scene):
        parts = []
        for node in loaded.graph.nodes_geometry:
            transform, name = loaded.graph[node]
            geometry = loaded.geometry[name]
            if len(getattr(geometry, "faces", [])):
                points = trimesh.transform_points(np.asarray(geometry.vertices), transform)
                parts.append((points, np.asarray(geometry.faces)))
    else:
        parts = [(np.asarray(loaded.vertices), np.asarray(getattr(loaded, "faces", [])))]
    parts = [(v, f.reshape(-1, 3)) for v, f in parts if len(f)]
    if not parts:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    vertices = np.concatenate([v for v, _ in parts])
    faces = np.concatenate([f + offset for (_, f), offset in zip(parts, offsets, strict=True)])
    return vertices, faces


def has_area(corners, extent):
    """(..., F, 3, 3) face corners and their mesh's (...) largest box side -> (..., F) bool:
    whether a face has area, measured in units of its mesh's box (repeated corners have
    none). The one rule both paths drop faces by: ``check_mesh`` here, the torch renderer
    (``MeshBatch.faces_with_area``). numpy or torch."""
    # in units of the box: a mesh in other units (1e-100 or 1e100) is the same shape, and its
    # squared coordinates would under- or overflow
    unit = (extent + (extent == 0))[..., None, None]
    u = (corners[..., 1, :] - corners[..., 0, :]) / unit
    v = (corners[..., 2, :] - corners[..., 0, :]) / unit
    x = u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1]
    y = u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2]
    z = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    return x * x + y * y + z * z > AREA_EPS**2


def check_mesh(vertices: np.ndarray, faces: np.ndarray, source: str = "<array>") -> Mesh:
    """Validate arrays and drop degenerate triangles (repeated indices or zero area)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise MeshError(source, f"vertices must be (V, 3), got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise MeshError(source, f"no faces: triangle faces must be (F, 3), got {faces.shape}")
    if not np.issubdtype(faces.dtype, np.integer):
        raise MeshError(source, f"face indices must be integers, got {faces.dtype}")
    faces = faces.astype(np.int64)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshError(source, f"face indices out of range for {len(vertices)} vertices")
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        count = int(bad.sum())
        which = "1 vertex is" if count == 1 else f"{count} vertices are"
        raise MeshError(
            source,
            f"{which} NaN or infinite (first: vertex {int(np.flatnonzero(bad)[0])}); "
            "fix or drop it in the file",
        )
    # areas relative to the mesh's own size, in units of its box: a mesh in other units (1e-100
    # or 1e100) is the same shape, and its squared coordinates would under- or overflow
    area_ok = has_area(vertices[faces], np.asarray(np.ptp(vertices, axis=0).max()))
    if not area_ok.any():
        raise MeshError(source, "no non-degenerate triangle left (all faces have zero area)")
    return Mesh(vertices=vertices, faces=faces[area_ok], source=source)


def bounding_frame(lower, upper, ops: ArrayOps = NUMPY_OPS):
    """(centre, scale) that map the box [lower, upper] into the unit sphere: v' = (v - c) / s
    (scale 1 for a box of no extent).

    (3,) corners give (3,) and (); a batch's (B, 3) give (B, 3) and (B,). numpy arrays, or
    torch tensors (keeping gradients) with ``ops=TORCH_OPS``.
    """
    centre = lower / 2.0 + upper / 2.0  # halves first: the sum of two huge values overflows
    extent = upper / 2.0 - lower / 2.0
    # the half-diagonal as |extent|_max * |extent / |extent|_max|: squares of very small or very
    # large coordinates would under- or overflow
    largest = ops.amax(abs(extent), -1)
    # a mesh collapsed to a point has nothing to scale: its frame keeps scale 1, and the square
    # root stays off 0, where its slope is infinite (a NaN gradient for a collapsed prediction)
    point = largest == 0
    safe = largest + point
    return centre, safe * ((((extent / safe[..., None]) ** 2).sum(-1) + point) ** 0.5)


def check_normalization(mode: str) -> str:
    if mode not in NORMALIZATIONS:
        raise ValueError(f"unknown normalisation {mode!r}; use one of {', '.join(NORMALIZATIONS)}")
    return mode


def frame_of(vertices, ops: ArrayOps = NUMPY_OPS):
    """(centre, scale) of a vertex array's bounding box, (V, 3) or a batch's (B, V, 3): (3,)
    and (), or (B, 3) and (B,); torch tensors (values keep grads) with ``ops=TORCH_OPS``."""
    return bounding_frame(ops.amin(vertices, -2), ops.amax(vertices, -2), ops)


def reference_frame(vertices, mode: str, ops: ArrayOps = NUMPY_OPS):
    """The frame ``mode`` places meshes in relative to the reference ``vertices``: its
    (centre, scale), or None for 'none'."""
    return None if check_normalization(mode) == "none" else frame_of(vertices, ops)


def place(vertices, frame):
    """Vertices moved into ``frame`` = (centre, scale): v' = (v - c) / s; arithmetic only, so
    numpy or torch. A batch's frame, (B, 3) and (B,), places (B, V, 3) vertices mesh by mesh."""
    centre, scale = frame
    if centre.ndim == 2:
        centre, scale = centre[:, None], scale[:, None, None]
    return (vertices - centre) / scale


def place_by(vertices, mode: str, reference, ops: ArrayOps = NUMPY_OPS):
    """Move a mesh into the metric's frame: by the reference's frame (joint), its own (each),
    or not at all (none). ``reference`` comes from ``reference_frame``."""
    if mode == "none":
        return vertices
    return place(vertices, reference if mode == "joint" else frame_of(vertices, ops))


def normalize_pair(vertices_a, vertices_b, mode: str = "joint", ops: ArrayOps = NUMPY_OPS):
    """Put two meshes into the metric's frame; B is the reference (numpy arrays, or torch
    tensors with ``ops=TORCH_OPS``).

    joint: both moved and scaled by B's bounding box (reconstructions judged in the truth's frame);
    each: each by its own bounding box; none: unchanged.
    """
    reference = reference_frame(vertices_b, mode, ops)
    return place_by(vertices_a, mode, reference, ops), place_by(vertices_b, mode, reference, ops)
