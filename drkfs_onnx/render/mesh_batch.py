"""A batch of triangle meshes as the torch path takes it: padded tensors, checked up front.

Accepted forms (``MeshBatch.of``):

- one mesh: (V, 3) vertices, (F, 3) faces (the result keeps no batch axis);
- a template deformed B ways: (B, V, 3) vertices and one (F, 3) face tensor (or (B, F, 3));
- meshes of different sizes: lists of (V_i, 3) and (F_i, 3), or one (F, 3) shared by all;
- any object with ``verts_list()`` and ``faces_list()`` (PyTorch3D's ``Meshes``), faces None;
- packed tensors with per-mesh counts: ``MeshBatch.packed``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

from ..contract.mesh import has_area

Tensors = torch.Tensor | Sequence[torch.Tensor]


@dataclass(frozen=True)
class MeshBatch:
    """B meshes padded to the largest: verts (B, V, 3), faces (B, F, 3) int64.

    A shorter mesh's padding vertices repeat its first vertex, so its bounding box (the frame
    it is placed in) is its own; its padding faces are (0, 0, 0) and ``face_valid`` (B, F) is
    False there (None when no face is padding). ``single``: the input was one (V, 3) mesh.
    """

    verts: torch.Tensor
    faces: torch.Tensor
    face_valid: torch.Tensor | None = None
    single: bool = False

    def __len__(self) -> int:
        return self.verts.shape[0]

    @classmethod
    def of(cls, verts, faces=None, device: torch.device | None = None) -> MeshBatch:
        """Any of the module's forms as a checked ``MeshBatch``.

        Args:
            verts: (V, 3) one mesh; (B, V, 3) a template deformed B ways; a list of (V_i, 3);
                an object with ``verts_list()`` and ``faces_list()``; or a ``MeshBatch``.
            faces: (F, 3) int, shared; (B, F, 3) one each; a list of (F_i, 3); None for the
                forms that carry their faces.
            device: where the tensors must already be (checked, not moved); None for any.

        Returns:
            verts (B, V, 3) and faces (B, F, 3) int64, padded to the largest; B = 1 and
            ``single`` for one (V, 3) mesh.

        Raises:
            ValueError: naming the argument and the shape, dtype or index range expected.
        """
        if isinstance(verts, MeshBatch):
            _check_verts(verts.verts, "verts", (3,), device)
            return verts
        if hasattr(verts, "verts_list") and hasattr(verts, "faces_list"):
            return cls.of(list(verts.verts_list()), list(verts.faces_list()), device)
        if isinstance(verts, (list, tuple)):
            return cls._ragged(list(verts), faces, device)
        _check_verts(verts, "verts", (2, 3), device)
        _check_faces(faces, "faces", (2, 3) if verts.ndim == 3 else (2,), verts.device)
        if verts.ndim == 2:
            _check_values(
                verts[None], faces[None], torch.full((1,), len(verts), device=verts.device)
            )
            return cls(verts[None], faces[None].long(), None, single=True)
        if faces.ndim == 3 and len(faces) != len(verts):
            raise ValueError(
                f"faces: expected one (F, 3) tensor or (B, F, 3) with B = {len(verts)} as the "
                f"vertices; got {tuple(faces.shape)}"
            )
        faces = (faces.expand(len(verts), -1, -1) if faces.ndim == 2 else faces).long()
        _check_values(verts, faces, torch.full((len(verts),), verts.shape[1], device=verts.device))
        return cls(verts, faces)

    @classmethod
    def packed(
        cls,
        verts: torch.Tensor,
        faces: torch.Tensor,
        verts_per_mesh: Sequence[int],
        faces_per_mesh: Sequence[int],
    ) -> MeshBatch:
        """Packed (sum V_i, 3) vertices and (sum F_i, 3) faces indexing them (PyTorch3D's
        ``verts_packed`` / ``faces_packed``), with each mesh's counts."""
        _check_verts(verts, "packed verts", (2,))
        _check_faces(faces, "packed faces", (2,), verts.device)
        if sum(verts_per_mesh) != len(verts) or sum(faces_per_mesh) != len(faces):
            raise ValueError(
                f"packed meshes: the counts sum to {sum(verts_per_mesh)} vertices and "
                f"{sum(faces_per_mesh)} faces; the tensors hold {len(verts)} and {len(faces)}"
            )
        offsets = torch.cumsum(torch.tensor([0, *verts_per_mesh[:-1]]), 0).tolist()
        face_parts = faces.split(list(faces_per_mesh))
        return cls._ragged(
            list(verts.split(list(verts_per_mesh))),
            [f - o for f, o in zip(face_parts, offsets, strict=True)],
        )

    @classmethod
    def _ragged(cls, verts: list[torch.Tensor], faces, device=None) -> MeshBatch:
        if not verts:
            raise ValueError("verts: expected at least one mesh; got an empty list")
        device = device or getattr(verts[0], "device", None)
        for i, v in enumerate(verts):
            _check_verts(v, f"verts[{i}]", (2,), device)
        if isinstance(faces, torch.Tensor):
            faces = [faces] * len(verts)
        if not isinstance(faces, (list, tuple)) or len(faces) != len(verts):
            raise ValueError(
                f"faces: expected a list of {len(verts)} (F_i, 3) tensors or one (F, 3) tensor "
                f"shared by every mesh; got {type(faces).__name__}"
            )
        for i, f in enumerate(faces):
            _check_faces(f, f"faces[{i}]", (2,), device)
        counts = torch.tensor([len(v) for v in verts], device=device)
        width = max(len(v) for v in verts)
        steps = torch.arange(width, device=device)
        local = torch.where(steps[None] < counts[:, None], steps[None], 0)
        index = local + (torch.cumsum(counts, 0) - counts)[:, None]
        padded_verts = torch.cat(list(verts)).index_select(0, index.reshape(-1))
        padded_faces = torch.nn.utils.rnn.pad_sequence([f.long() for f in faces], batch_first=True)
        face_counts = torch.tensor([len(f) for f in faces], device=device)
        valid = torch.arange(padded_faces.shape[1], device=device)[None] < face_counts[:, None]
        padded_verts = padded_verts.reshape(len(verts), width, 3)
        _check_values(padded_verts, padded_faces, counts)
        return cls(padded_verts, padded_faces, valid)

    @torch.no_grad()
    def faces_with_area(self) -> torch.Tensor:
        """(B, F) bool: the real faces that have area (``mesh.has_area``, the rule by which
        ``check_mesh`` drops faces on the runtime path), padding False."""
        corners = torch.take_along_dim(self.verts[:, :, None], self.faces[..., None], dim=1)
        extent = (self.verts.amax(1) - self.verts.amin(1)).amax(-1)
        found = has_area(corners, extent)
        return found if self.face_valid is None else found & self.face_valid

    def split(self, size: int) -> list[MeshBatch]:
        """Runs of at most ``size`` meshes, in order."""
        valid = self.face_valid
        return [
            MeshBatch(
                self.verts[i : i + size],
                self.faces[i : i + size],
                None if valid is None else valid[i : i + size],
                self.single,
            )  # fmt: skip
            for i in range(0, len(self), size)
        ]

    def moved(self, verts: torch.Tensor) -> MeshBatch:
        """The same meshes with new (B, V, 3) vertex positions."""
        return MeshBatch(verts, self.faces, self.face_valid, self.single)

    def unbatch(self, values: torch.Tensor) -> torch.Tensor:
        """(B, ...) per-mesh values -> (...) for a single mesh's input, else unchanged."""
        return values[0] if self.single else values


BATCH_REDUCTIONS = ("mean", "sum", "none")


def over_batch(scores: torch.Tensor, single: bool, batch_reduction: str) -> torch.Tensor:
    """(B,) per-mesh scores -> their mean, sum or themselves ('none'); a single mesh's input
    -> its () score."""
    if batch_reduction not in BATCH_REDUCTIONS:
        raise ValueError(
            f"unknown batch_reduction {batch_reduction!r}; use one of {', '.join(BATCH_REDUCTIONS)}"
        )
    if single:
        return scores[0]
    return {"mean": scores.mean, "sum": scores.sum, "none": lambda: scores}[batch_reduction]()


def _check_verts(verts, name: str, ndims: tuple[int, ...], device=None) -> None:
    shapes = " or ".join({2: "(V, 3)", 3: "(B, V, 3)"}[n] for n in ndims)
    if not isinstance(verts, torch.Tensor):
        raise ValueError(f"{name}: expected a float tensor {shapes}; got {type(verts).__name__}")
    if verts.ndim not in ndims or verts.shape[-1] != 3 or not verts.is_floating_point():
        raise ValueError(
            f"{name}: expected a float tensor {shapes}; got {verts.dtype} {tuple(verts.shape)}"
        )
    if device is not None and verts.device != device:
        raise ValueError(
            f"{name}: expected a tensor on {device} (move the mesh, or the metric with .to()); "
            f"got one on {verts.device}"
        )


def _check_faces(faces, name: str, ndims: tuple[int, ...], device: torch.device) -> None:
    shapes = " or ".join({2: "(F, 3)", 3: "(B, F, 3)"}[n] for n in ndims)
    if not isinstance(faces, torch.Tensor):
        raise ValueError(f"{name}: expected an integer tensor {shapes}; got {type(faces).__name__}")
    if (
        faces.ndim not in ndims
        or faces.shape[-1] != 3
        or faces.is_floating_point()
        or faces.is_complex()
        or faces.dtype == torch.bool
    ):
        raise ValueError(
            f"{name}: expected an integer tensor {shapes}; got {faces.dtype} {tuple(faces.shape)}"
        )
    if faces.device != device:
        raise ValueError(
            f"{name}: expected a tensor on the vertices' device {device}; got one on {faces.device}"
        )


def _check_values(verts: torch.Tensor, faces: torch.Tensor, vertex_counts: torch.Tensor) -> None:
    """(B, V, 3) vertices all finite, and (B, F, 3) face indices within each mesh's
    ``vertex_counts``: one host wait for the whole batch. A NaN or infinite vertex would
    otherwise drop its faces from every view and leave a finite, wrong score."""
    if faces.numel() == 0:
        raise ValueError("faces: expected at least one face; got none")
    low, high = faces.amin(dim=(1, 2)), faces.amax(dim=(1, 2))
    outside = (low < 0) | (high >= vertex_counts)
    nonfinite = ~torch.isfinite(verts.detach()).flatten(1).all(dim=1)
    bad = outside | nonfinite
    if bad.any():  # the one wait; the message is built only for a bad batch
        first = int(torch.nonzero(bad)[0])
        if outside[first]:
            raise ValueError(
                f"faces: mesh {first} has face indices outside its "
                f"{int(vertex_counts[first])} vertices"
            )
        raise ValueError(f"verts: mesh {first} has NaN or infinite coordinates")
