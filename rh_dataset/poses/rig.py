"""A numpy copy of anny's rig for one body shape: forward kinematics and linear blend skinning.

The pose prior calls its self-intersection check on every candidate pose; anny's own forward pass recomputes the
rest model from the blend shapes every time (~100 ms), while the kinematic chain and skinning alone cost a few
milliseconds in numpy. `tests/test_poses.py` checks this copy against anny's output.

anny's 'local-ref' parameterisation (see `anny/utils/kinematics.py`), for a bone c of parent p:
    P_c = [R_c | h_c] rest pose, U_c reference orientation (a fixed buffer, the same for every body shape),
    D_c the delta, W_c the posed pose, A_p = U_p R_p^T (A_0 = I), q_c - q_p = A_p (h_c - h_p),
    W_0 = [U_0^T D_0 U_0 | U_0^T d_0],   W_c = W_p [U_p^T D_c U_c | U_p^T (d_c + q_c - q_p)],
    skinning transform T_c = W_c P_c^-1.
Consequence used throughout this package: the posed world rotation relative to the reference pose is
G_c = W_c U_c^T = G_p D_c, i.e. each delta rotates its bone (about its head) in its parent's carried copy of the
world axes. Joint axes derived from the reference pose's bone directions therefore stay valid whatever the parent
does.
"""
from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping

import numpy as np

__all__ = ["Rig", "rig_for"]


@dataclasses.dataclass(frozen=True, eq=False)
class Rig:
    """Everything of one anny body (one phenotype) that the pose code needs, as float64 numpy arrays."""

    bone_labels: tuple[str, ...]
    parents: np.ndarray  # (J,) int, -1 for the root; parents precede children
    rest_poses: np.ndarray  # (J, 4, 4) P_c
    reference_orientations: np.ndarray  # (J, 3, 3) U_c
    rest_vertices: np.ndarray  # (V, 3)
    faces: np.ndarray  # (F, 3) int
    weights: np.ndarray  # (V, K) linear-blend weights
    weight_bones: np.ndarray  # (V, K) bone index of each weight

    def __post_init__(self) -> None:
        if np.any(self.parents[1:] >= np.arange(1, len(self.parents))):
            raise ValueError("anny's bones are expected in topological order (parent index < child index)")
        for value in dataclasses.astuple(self):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)

    @functools.cached_property
    def index(self) -> dict[str, int]:
        return {label: i for i, label in enumerate(self.bone_labels)}

    def world_poses(self, deltas: np.ndarray) -> np.ndarray:
        """Posed bone poses W (J, 4, 4) for 'local-ref' deltas (J, 4, 4); joints are W[:, :3, 3]."""
        R, h = self.rest_poses[:, :3, :3], self.rest_poses[:, :3, 3]
        U = self.reference_orientations
        W = np.empty_like(deltas)
        W[:, 3] = (0.0, 0.0, 0.0, 1.0)
        W[0, :3, :3] = U[0].T @ deltas[0, :3, :3] @ U[0]
        W[0, :3, 3] = U[0].T @ deltas[0, :3, 3]
        for c in range(1, len(self.parents)):
            p = self.parents[c]
            a_p = np.eye(3) if p == 0 else U[p] @ R[p].T
            offset = a_p @ (h[c] - h[p]) + deltas[c, :3, 3]
            Wp = W[p, :3, :3] @ U[p].T
            W[c, :3, :3] = Wp @ deltas[c, :3, :3] @ U[c]
            W[c, :3, 3] = W[p, :3, 3] + Wp @ offset
        return W

    def skinning_transforms(self, W: np.ndarray) -> np.ndarray:
        """T_c = W_c P_c^-1 as (J, 3, 4)."""
        rot = W[:, :3, :3] @ np.transpose(self.rest_poses[:, :3, :3], (0, 2, 1))
        trans = W[:, :3, 3] - np.einsum("jab,jb->ja", rot, self.rest_poses[:, :3, 3])
        return np.concatenate([rot, trans[:, :, None]], axis=2)

    def skin(self, W: np.ndarray, vertex_ids: np.ndarray | slice = slice(None),
             normals: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """Linear-blend-skinned positions of the chosen rest vertices (and rest normals, rotated by the same
        blended matrices then renormalised: the usual LBS normal approximation)."""
        T = self.skinning_transforms(W)
        blended = np.einsum("vk,vkab->vab", self.weights[vertex_ids], T[self.weight_bones[vertex_ids]])
        rest = self.rest_vertices[vertex_ids]
        points = np.einsum("vab,vb->va", blended[:, :, :3], rest) + blended[:, :, 3]
        if normals is None:
            return points, None
        n = np.einsum("vab,vb->va", blended[:, :, :3], normals)
        return points, n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def _phenotype_key(phenotype: Mapping[str, float] | None) -> tuple[tuple[str, float], ...]:
    return tuple(sorted((str(k), float(v)) for k, v in (phenotype or {}).items()))


def rig_for(model, phenotype: Mapping[str, float] | None = None) -> Rig:
    """The numpy rig of `model` for a phenotype (None = anny's default body). Cached per (model, phenotype)."""
    return _rig_cached(model, _phenotype_key(phenotype))


@functools.lru_cache(maxsize=8)
def _rig_cached(model, phenotype_key: tuple[tuple[str, float], ...]) -> Rig:
    import torch

    from rh_common.threads import torch_threads

    with torch.no_grad(), torch_threads(1):  # thread count changes the last digits (rh_common.threads)
        out = model(pose_parameters=None, phenotype_kwargs=dict(phenotype_key) or None)
    as_np = lambda t: t.detach().cpu().numpy().astype(np.float64)  # noqa: E731
    return Rig(
        bone_labels=tuple(model.bone_labels),
        parents=np.asarray(model.bone_parents, dtype=np.int64),
        rest_poses=as_np(out["rest_bone_poses"][0]),
        reference_orientations=as_np(model.reference_bone_orientations),
        rest_vertices=as_np(out["rest_vertices"][0]),
        faces=model.faces.detach().cpu().numpy().astype(np.int64),
        weights=as_np(model.vertex_bone_weights),
        weight_bones=model.vertex_bone_indices.detach().cpu().numpy().astype(np.int64),
    )
