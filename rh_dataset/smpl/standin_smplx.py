"""The arrays a SMPL-X model file carries beyond SMPL's, for the SMPL-X stand-in (`standin.build_standin(...,
kind="smplx")`).

In: the stand-in's T-pose template (V,3), its faces (F,3) and its anatomical vertex ids (`skeletons.SMPLX_VERTEX_IDS`).
Out: `smplx_extras()`, a dict of the keys smplx's loader reads from a SMPL-X file besides the body model's own:
`lmk_faces_idx` (51,) and `lmk_bary_coords` (51,3), the facial landmarks; `dynamic_lmk_faces_idx` (79,17) and
`dynamic_lmk_bary_coords` (79,17,3), the face contour for each head turn of -39..39 degrees (read with
use_face_contour); `hands_componentsl/r` (45,45) and `hands_meanl/r` (45,), the hand pose PCA and mean pose.

What they are in the stand-in (NOT SMPL-X's): the 51 landmarks are spread points (farthest-point samples of
triangle centroids, barycentre of each triangle) over the front of the face, seeded at the nose, with no SMPL-X
landmark semantics; the contour is 17 triangles spread along the lower face, the same for every head turn; the hand
components are the identity (PCA coefficients = axis-angle values) and the hand means zero, so the stand-in's zero
hand pose is anny's reference hand with or without smplx's `flat_hand_mean`.
"""
from __future__ import annotations

import numpy as np

__all__ = ["smplx_extras", "N_LANDMARKS", "N_CONTOUR", "N_TURNS"]

N_LANDMARKS, N_CONTOUR, N_TURNS = 51, 17, 79  # as in SMPL-X's files


def _spread(points: np.ndarray, candidates: np.ndarray, n: int, seed: int) -> np.ndarray:
    """n of `candidates` (indices into points), farthest-point order from `seed` (ties: lowest index)."""
    from .standin_mesh import farthest_point_samples

    return candidates[farthest_point_samples(points[candidates], n, [int(np.flatnonzero(candidates == seed)[0])])]


def smplx_extras(template: np.ndarray, faces: np.ndarray, vertex_ids: dict) -> dict:
    """The SMPL-X-only arrays of the stand-in (see the module docstring)."""
    centroids = template[faces].mean(1)
    nose = template[vertex_ids["nose"]]
    eyes = 0.5 * (template[vertex_ids["leye"]] + template[vertex_ids["reye"]])
    d = np.linalg.norm(centroids - nose, axis=1)
    seed = int(np.argmin(d))
    # The front of the face: within 9 cm of the nose tip and no more than 5 cm behind it (Z is forward).
    front = np.flatnonzero((d < 0.09) & (centroids[:, 2] > nose[2] - 0.05))
    lmk = _spread(centroids, front, N_LANDMARKS, seed)
    # The lower face, below the eyes and a few centimetres behind the nose tip: where a contour runs.
    lower = np.flatnonzero((d < 0.12) & (centroids[:, 1] < eyes[1] - 0.03) & (centroids[:, 2] > nose[2] - 0.09)
                           & (centroids[:, 2] < nose[2] - 0.03))
    contour = _spread(centroids, lower, N_CONTOUR, int(lower[np.argmin(centroids[lower, 1])]))
    third = np.full(3, 1.0 / 3.0)
    return {
        "lmk_faces_idx": lmk.astype(np.int64),
        "lmk_bary_coords": np.tile(third, (N_LANDMARKS, 1)),
        "dynamic_lmk_faces_idx": np.tile(contour.astype(np.int64), (N_TURNS, 1)),
        "dynamic_lmk_bary_coords": np.tile(third, (N_TURNS, N_CONTOUR, 1)),
        "hands_componentsl": np.eye(45), "hands_componentsr": np.eye(45),
        "hands_meanl": np.zeros(45), "hands_meanr": np.zeros(45),
    }
