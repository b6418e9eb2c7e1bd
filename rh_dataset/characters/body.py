"""The generator's numpy views of the anny body: topology, one posed run, normals, phenotype sampling.

In: a phenotype (and optional bone deltas) and the topology name. Out: float64 numpy arrays, so the character code
treats anny as "phenotype + pose -> arrays" without touching torch. Everything here is a pure function of its
arguments (the model is cached). The model itself is loaded by `rh_common.body_model` (RANA poses the same body).
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from rh_common.body_model import ANNY_TOPOLOGY, load_anny
from rh_common.threads import torch_threads

__all__ = ["BodyTopology", "body_topology", "run_anny", "sample_phenotype", "PHENOTYPE_LABELS"]

PHENOTYPE_LABELS = ("gender", "age", "muscle", "weight", "height", "proportions")


@dataclasses.dataclass(frozen=True)
class BodyTopology:
    """Phenotype-independent mesh data of the anny body (read-only numpy arrays).

    `texcoords` use anny's own convention, v pointing up (OpenGL): image row = (1 - v) * H.
    """

    faces: np.ndarray  # (F, 3) int64 triangles into the body vertices
    texcoords: np.ndarray  # (T, 2) float64 UVs, one per face corner class
    face_texcoords: np.ndarray  # (F, 3) int64 into texcoords
    bone_labels: tuple[str, ...]
    bone_indices: np.ndarray  # (V, K) int64
    bone_weights: np.ndarray  # (V, K) float64, rows sum to 1
    n_vertices: int


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


@functools.lru_cache(maxsize=4)
def body_topology(topology: str = ANNY_TOPOLOGY) -> BodyTopology:
    """The body's faces, UVs and skinning weights as numpy arrays (cached per topology)."""
    model = load_anny(topology)
    faces = model.get_triangular_faces().cpu().numpy().astype(np.int64)
    return BodyTopology(
        faces=_readonly(faces),
        texcoords=_readonly(model.texture_coordinates.cpu().numpy().astype(np.float64)),
        face_texcoords=_readonly(model.face_texture_coordinate_indices.cpu().numpy().astype(np.int64)),
        bone_labels=tuple(model.bone_labels),
        bone_indices=_readonly(model.vertex_bone_indices.cpu().numpy().astype(np.int64)),
        bone_weights=_readonly(model.vertex_bone_weights.cpu().numpy().astype(np.float64)),
        n_vertices=int(model.template_vertices.shape[-2]),
    )


def run_anny(
    phenotype: dict[str, float],
    bone_deltas: dict[str, np.ndarray] | None = None,
    topology: str = ANNY_TOPOLOGY,
) -> dict[str, np.ndarray]:
    """Run anny once (batch 1, local-ref parameterisation) and return float64 numpy arrays without the batch axis:
    `vertices` (V,3) posed, `rest_vertices` (V,3), `bone_poses` (J,4,4), `rest_bone_poses` (J,4,4),
    `rest_bone_heads` (J,3). `bone_deltas` maps bone label -> 4x4 delta; missing bones are identity."""
    import torch

    model = load_anny(topology)
    missing = set(PHENOTYPE_LABELS) - set(phenotype)
    if missing:
        raise ValueError(f"run_anny: phenotype lacks {sorted(missing)}")
    labels = set(model.bone_labels)
    pose = None
    if bone_deltas:
        unknown = sorted(set(bone_deltas) - labels)
        if unknown:
            raise ValueError(f"run_anny: unknown bone labels {unknown}")
        pose = {}
        for label, delta in bone_deltas.items():
            d = np.asarray(delta, dtype=np.float64)
            if d.shape != (4, 4) or not np.all(np.isfinite(d)):
                raise ValueError(f"run_anny: bone_deltas[{label!r}] must be a finite 4x4 matrix, got shape {d.shape}")
            pose[label] = torch.tensor(np.array(d), dtype=model.dtype)[None]  # copy: inputs may be read-only
    pheno = {k: torch.tensor([float(phenotype[k])], dtype=model.dtype) for k in PHENOTYPE_LABELS}
    # One thread: anny's reductions sum in a thread-count-dependent order (last digit of vertices and bone
    # poses); one thread makes generated data identical whatever the core count, --workers or Ray worker.
    with torch.no_grad(), torch_threads(1):
        out = model(pose_parameters=pose, phenotype_kwargs=pheno, pose_parameterization="local-ref")
    keys = ("vertices", "rest_vertices", "bone_poses", "rest_bone_poses", "rest_bone_heads")
    return {k: out[k][0].cpu().numpy().astype(np.float64) for k in keys}


@functools.lru_cache(maxsize=4)
def _ring_mean(topology: str = ANNY_TOPOLOGY):
    """Sparse (V, V) operator: each body vertex's mean with its edge neighbours, uniform weights."""
    from scipy import sparse

    f = body_topology(topology).faces
    n = body_topology(topology).n_vertices
    i = np.concatenate([f[:, 0], f[:, 1], f[:, 2], np.arange(n)])
    j = np.concatenate([f[:, 1], f[:, 2], f[:, 0], np.arange(n)])
    adj = sparse.coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)).tocsr()
    adj = ((adj + adj.T) > 0).astype(np.float64)
    return sparse.diags(1.0 / np.asarray(adj.sum(axis=1)).ravel()) @ adj


def smoothed_normals(normals: np.ndarray, rounds: int, topology: str = ANNY_TOPOLOGY) -> np.ndarray:
    """The body's vertex normals averaged `rounds` times over each vertex and its edge neighbours, unit length: a
    linear map of the normals, so a rigid motion of the body moves them with it."""
    out = np.asarray(normals, np.float64)
    op = _ring_mean(topology)
    for _ in range(rounds):
        out = op @ out
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)


def blended_normals(normals: np.ndarray, bv: np.ndarray, bw: np.ndarray) -> np.ndarray:
    """Unit normals (P, 3) float64 of blended anchors: the `bw`-weighted sums (P, K) of body vertex normals `bv`."""
    return _unit_rows(_weighted_rows(normals, bv, bw))


def _unit_rows(x: np.ndarray) -> np.ndarray:
    return x / np.maximum(np.linalg.norm(x, axis=1, keepdims=True), 1e-12)


def _weighted_rows(rows: np.ndarray, idx: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """sum_k weights[:, k] * rows[idx[:, k]] (P, C) float64, as a sparse (P, V) x (V, C) product (scipy's CSR kernel
    adds each row's K products in order, from zero): numpy's `(rows[idx] * w[..., None]).sum(1)` adds them in the
    same order, so the same bits (but for the sign of a sum whose every term is -0.0), ~7x faster for the hair's
    45,000 points x 16 weights (no (P, K, 3) array, no strided reduce; tests/test_geometry.py)."""
    from scipy import sparse

    p, k = idx.shape
    op = sparse.csr_matrix((weights.astype(np.float64).ravel(), idx.ravel(), np.arange(p + 1) * k),
                           shape=(p, len(rows)))
    return np.asarray(op @ np.asarray(rows, np.float64))


def anchor_points(verts: np.ndarray, normals: np.ndarray, bv: np.ndarray, bw: np.ndarray, off: np.ndarray
                  ) -> np.ndarray:
    """Blended anchors of body vertices plus offsets along the blended normals (P, 3) float64: where a shell's,
    hair's or headwear's vertices sit on a posed body (`verts`, `normals`)."""
    both = _weighted_rows(np.concatenate([verts, normals], axis=1), bv, bw)  # one sparse operator for the two
    return both[:, :3] + off[:, None].astype(np.float64) * _unit_rows(both[:, 3:])


@functools.lru_cache(maxsize=1)
def _shape_distribution():
    from anny.shape_distribution import SimpleShapeDistribution

    return SimpleShapeDistribution(load_anny())


def sample_phenotype(rng: np.random.Generator, age_years: tuple[float, float] = (18.0, 70.0),
                     gender: float | None = None) -> dict[str, float]:
    """Draw a realistic adult phenotype from anny's calibrated (WHO-fitted) conditional Beta distributions.

    anny's own `SimpleShapeDistribution.sample` draws from torch's global generator; here the same calibrated
    distributions are evaluated for their Beta parameters and sampled with the caller's numpy generator, so the
    draw is reproducible from one explicit seed. Ages are restricted to adults (the benchmark films adults).
    `gender` fixes anny's gender value (0 male, 1 female) instead of drawing it (the SMPL stand-in's male and
    female shape spaces); None draws it, as the generator does.
    """
    import torch

    dist = _shape_distribution()
    morph_age = rng.uniform(*age_years)
    age = dist.morphological_age_mapping.morphological_to_anny_age(torch.tensor([morph_age], dtype=torch.float64))
    gender = float(rng.uniform(0.0, 1.0)) if gender is None else float(gender)
    sex = "boys" if gender <= 0.5 else "girls"  # anny's convention: gender 0 = male, 1 = female
    out = {"gender": gender, "age": float(age[0])}
    for key in ("height", "weight", "muscle", "proportions"):
        cond = getattr(dist, f"{sex}_conditional_{key}_distribution")
        alpha, beta = cond.get_distribution_params(age)
        out[key] = float(np.clip(rng.beta(float(alpha[0]), float(beta[0])), 0.0, 1.0))
    return {k: out[k] for k in PHENOTYPE_LABELS}
