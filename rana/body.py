"""The body model side of SMPL+D on anny: posing from frame metadata, linear offsets, normals, UVs, head point.

anny skins with linear blend skinning, so the posed mesh is linear in a rest-space offset D:
``posed(D)_v = posed(0)_v + A_v D_v`` with ``A_v`` the 3x3 part of vertex v's blended bone transform (then the
frame's root transform, a rigid map). `PosedBody` stores ``posed(0)`` and ``A`` once per frame, so fitting D and
re-posing it cost an einsum instead of an anny forward pass.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import torch

from rh_common.layout import read_body_pose

__all__ = [
    "BodyTopology",
    "PosedBody",
    "body_topology",
    "pose_tensor_from_json",
    "pose_body",
    "vertex_normals",
    "uniform_laplacian",
]


@dataclass(frozen=True)
class BodyTopology:
    """What does not change with pose or shape: faces, per-corner UVs, the head vertices."""

    faces: torch.Tensor  # (F, 3) int64
    uv: torch.Tensor  # (T, 2) float32 texture coordinates, v up (OBJ convention)
    face_uv: torch.Tensor  # (F, 3) int64 indices into uv
    head_vertices: torch.Tensor  # (H,) int64: vertices skinned mostly to the head (face crop centre)
    n_vertices: int


@functools.lru_cache(maxsize=2)
def body_topology() -> BodyTopology:
    from rh_common.body_model import load_anny

    m = load_anny()
    faces = m.get_triangular_faces().to(torch.int64).cpu()
    uv = m.texture_coordinates.to(torch.float32).cpu()
    face_uv = m.face_texture_coordinate_indices.to(torch.int64).cpu()
    labels = list(m.bone_labels)
    head_ids = [i for i, lab in enumerate(labels) if lab == "head" or _descends_from(m, i, labels.index("head"))]
    dominant = m.vertex_bone_indices.gather(1, m.vertex_bone_weights.argmax(1, keepdim=True))[:, 0]
    head = torch.nonzero(torch.isin(dominant, torch.tensor(head_ids, dtype=dominant.dtype)))[:, 0].cpu()
    return BodyTopology(faces, uv, face_uv, head, int(m.template_vertices.shape[0]))


def _descends_from(m, i: int, ancestor: int) -> bool:
    parents = [int(p) for p in m.bone_parents]
    while i >= 0:
        if i == ancestor:
            return True
        i = parents[i] if parents[i] != i else -1
    return False


def pose_tensor_from_json(pose_json: dict, model) -> tuple[torch.Tensor, np.ndarray]:
    """(1, J, 4, 4) float64 local-ref bone deltas in the model's bone order and the 4x4 root transform of a frame's
    `body.pose`, read by `rh_common.layout.read_body_pose` (the one reader of that format)."""
    pose = read_body_pose(pose_json)
    return torch.as_tensor(pose.deltas(model.bone_labels))[None], np.array(pose.root_transform)


@dataclass
class PosedBody:
    """One frame's body: ``vertices(D) = rest_posed + A @ D`` in world coordinates (root transform included)."""

    posed0: torch.Tensor  # (V, 3) float32 world
    A: torch.Tensor  # (V, 3, 3) float32: d(world vertex)/d(rest offset)

    def vertices(self, offsets: torch.Tensor | None = None) -> torch.Tensor:
        if offsets is None:
            return self.posed0
        return self.posed0 + torch.einsum("vij,vj->vi", self.A, offsets)


@torch.no_grad()
def pose_body(phenotype: dict, pose_json: dict) -> PosedBody:
    """Pose anny for one frame from its metadata (`body.phenotype`, `body.pose`)."""
    from rh_common.body_model import load_anny

    m = load_anny()
    pose, root = pose_tensor_from_json(pose_json, m)
    dt = m.template_vertices.dtype
    ph = {k: float(v) for k, v in phenotype.items()}
    p, ph_t, lc, fa = m.get_tensor_inputs(pose.to(dt), ph, None, None)
    coeffs = m._get_phenotype_blendshape_coefficients(ph_t, lc, fa)
    rest = m.get_rest_model(coeffs)
    bt, _ = m.get_bone_transforms(p, rest["rest_bone_poses"])
    if not isinstance(bt, torch.Tensor):  # older anny returns roma rigids
        bt = torch.stack([t.to_homogeneous() for t in bt], dim=1)
    # Linear blend skinning written out: the per-vertex blended transform is what makes posing linear in D.
    Tv = (m.vertex_bone_weights[..., None, None] * bt[0][m.vertex_bone_indices]).sum(1)  # (V, 4, 4)
    rv = rest["rest_vertices"][0]
    posed = (Tv[:, :3, :3] @ rv[..., None])[..., 0] + Tv[:, :3, 3]
    R = torch.as_tensor(np.array(root[:3, :3]), dtype=posed.dtype)
    t = torch.as_tensor(np.array(root[:3, 3]), dtype=posed.dtype)
    posed = posed @ R.T + t
    A = R @ Tv[:, :3, :3]
    return PosedBody(posed.to(torch.float32).contiguous(), A.to(torch.float32).contiguous())


def vertex_normals(vertices: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Area-weighted vertex normals (V, 3), unit length; differentiable. Outward for anny's winding."""
    v0, v1, v2 = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    fn = torch.cross(v1 - v0, v2 - v0, dim=-1)  # length = 2 x area: area weighting for free
    n = torch.zeros_like(vertices).index_add_(0, faces.reshape(-1), fn.repeat_interleave(3, dim=0))
    return torch.nn.functional.normalize(n, dim=-1, eps=1e-12)


@functools.lru_cache(maxsize=2)
def _laplacian_cached(n: int, faces_bytes: bytes) -> torch.Tensor:
    faces = torch.frombuffer(bytearray(faces_bytes), dtype=torch.int64).reshape(-1, 3)
    e = torch.cat([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = torch.cat([e, e.flip(1)])
    e = torch.unique(e, dim=0)
    deg = torch.bincount(e[:, 0], minlength=n).to(torch.float32).clamp_min(1)
    vals = -1.0 / deg[e[:, 0]]
    idx = torch.cat([e.T, torch.arange(n).repeat(2, 1)], dim=1)
    vals = torch.cat([vals, torch.ones(n)])
    return torch.sparse_coo_tensor(idx, vals, (n, n), check_invariants=False).coalesce()


def uniform_laplacian(n_vertices: int, faces: torch.Tensor) -> torch.Tensor:
    """Sparse (V, V) uniform Laplacian: (L x)_i = x_i - mean of i's neighbours."""
    return _laplacian_cached(n_vertices, faces.to(torch.int64).contiguous().numpy().tobytes())
