"""A stand-in for SMPL's model files, built from anny, so that the SMPL path can be tested and tried without them.

In: a gender ('neutral', 'male', 'female'). Out: a `BodyModel` in SMPL's exact layout and conventions (6890
vertices, 24 joints in SMPL's order and kintree, metres, Y up, facing +Z, the character's left +X, the zero pose a
T-pose), and `write_test_models(folder)`, which writes SMPL_{NEUTRAL,MALE,FEMALE}.pkl (what `rh-export
--write-test-smpl DIR` does). It is NOT SMPL: numbers measured with it are not SMPL results.

How it is made (every step deterministic, so the same code writes the same bytes):
- Body: anny (topology `ANNY_TOPOLOGY`) at the gender's phenotype (anny's gender 0 = male, 1 = female, 0.5 for
  neutral; the other five values at anny's default 0.5), posed into a T-pose with anny's own rig (`tpose_rotations`:
  upper arms, forearms and hands turned onto the ±X line, palms down; each thigh turned about the forward axis so
  the ankle is under the hip; feet back to their rest orientation), then turned into SMPL's axes.
- Vertices: 6890 of anny's vertices (farthest-point samples on the neutral T-pose, the same ids for all genders),
  seeded with the anatomical points that smplx's `VertexJointSelector` reads and permuted onto SMPL's ids for them
  (`SMPL_VERTEX_IDS`). Faces: anny's triangles clustered onto the samples (graph-Voronoi regions along anny's
  edges; a triangle whose corners fall in three regions becomes a triangle of the three samples).
- Joints: SMPL joint k sits at the head of an anny bone (`JOINT_BONES`; the mean of the toe / finger base heads for
  the foot and hand joints). Each anny bone belongs to the joint of its nearest listed ancestor (`bone_joint_map`):
  skinning weights are summed per joint, and a SMPL pose moves each bone group rigidly. J_regressor: non-negative
  weights over the vertices around each joint, rows summing to 1, fitted by NNLS over the template and the shape
  samples; `standin_report()` states the residual.
- Shape: 64 phenotypes drawn from anny's calibrated distribution (`sample_phenotype`, gender drawn for neutral,
  fixed for male and female), T-posed the same way; shapedirs are the 10 principal directions of their offsets
  from the template, scaled by their standard deviation (betas ~ unit variance), so betas = 0 is the template, an
  exact anny body. posedirs are zero: anny has no pose correctives.
The pickle carries an extra key `rh_standin` (source, note, joint residuals, and `anny_vertex_ids`: which anny
vertex each stand-in vertex is), which SMPL readers ignore. `anny_tpose_bodies` gives any anny body as the stand-in
sees it (a shape fit's target); `standin_pose.py` poses anny as the stand-in is posed (the comparison's other side).
SMPL-X (`kind="smplx"`): the same construction in SMPL-X's layout (`skeletons.SMPLX`): 10,475 anny vertices
seeded with SMPL-X's anatomical ids, 55 joints (fingers from anny's finger bones; eyes at anny's eye bones; the jaw
at the mean of the head and eye bone heads, skinning nothing), shapedirs of 10 shape + 10 expression directions
(the expression ones zero), posedirs zero (486), and the landmark and hand-PCA arrays smplx reads
(`standin_smplx.py`); written as SMPLX_{NEUTRAL,MALE,FEMALE}.npz. It is NOT SMPL-X.
The built models are cached per process and shared: treat their arrays as read-only.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rh_common.body_model import ANNY_TOPOLOGY, load_anny
from rh_dataset.characters.body import PHENOTYPE_LABELS, body_topology, sample_phenotype
from rh_dataset.poses.rig import Rig
from rh_dataset.smpl.model import GENDERS, MODEL_FILE_NAMES, BodyModel, write_smplx_npz, write_smpl_pickle
from rh_dataset.smpl.skeletons import (JOINT_BONES, SKELETONS, SMPL, SMPL_JOINT_NAMES, SMPL_PARENTS,
                                       SMPL_VERTEX_IDS, Skeleton)

__all__ = ["build_standin", "write_test_models", "standin_report", "anny_tpose_bodies", "tpose_deltas",
           "tpose_rotations", "local_ref_deltas", "default_phenotype", "shape_phenotypes", "bone_joint_map",
           "to_smpl_axes", "SMPL_JOINT_NAMES", "SMPL_PARENTS", "JOINT_BONES", "SMPL_VERTEX_IDS", "ANNY_TO_SMPL",
           "N_VERTICES", "StandinReport"]

N_VERTICES = 6890  # SMPL's; SMPL-X's is skeletons.SMPLX.n_vertices
N_BETAS = 10
N_SHAPE_SAMPLES = 64
SHAPE_SEED = 15  # issue #15
GENDER_VALUE = {"neutral": 0.5, "male": 0.0, "female": 1.0}  # anny: gender 0 = male, 1 = female

# anny (Z up, facing -Y, left +X) -> SMPL (Y up, facing +Z, left +X): a proper rotation, x' = x, y' = z, z' = -y.
ANNY_TO_SMPL = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class StandinReport:
    """How closely the stand-in reproduces anny: J_regressor residuals (mm; max on the template, max and mean
    over the shape samples), the share of the samples' shape variance its 10 directions keep, its face count."""

    gender: str
    joint_residual_template_mm: float
    joint_residual_samples_mm: float
    joint_residual_samples_mean_mm: float
    shape_variance_kept: float
    n_faces: int


# ------------------------------------------------------------------------------------------------- the anny rig

def bone_joint_map(bone_labels: tuple[str, ...], bone_parents, skel: Skeleton = SMPL) -> np.ndarray:
    """(B,) model joint of every anny bone: the joint that lists it in `skel.group_bones`, else its parent's."""
    starts = {b: k for k, j in enumerate(skel.joint_names) for b in skel.group_bones[j]}
    out = np.empty(len(bone_labels), np.int64)
    for i, label in enumerate(bone_labels):
        out[i] = starts[label] if label in starts else out[bone_parents[i]]
    return out


def _rot_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking direction a onto direction b."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    v, c = np.cross(a, b), float(a @ b)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K / (1.0 + c)


def _frame(along: np.ndarray, across: np.ndarray) -> np.ndarray:
    x = along / np.linalg.norm(along)
    y = across - (across @ x) * x
    y /= np.linalg.norm(y)
    return np.stack([x, y, np.cross(x, y)], 1)


def tpose_deltas(rig: Rig) -> np.ndarray:
    """anny 'local-ref' deltas (J,4,4) that put `rig`'s body (reference A-pose) into SMPL's T-pose."""
    return local_ref_deltas(rig.parents, tpose_rotations(rig))


def local_ref_deltas(parents: np.ndarray, G: np.ndarray) -> np.ndarray:
    """'local-ref' deltas from world rotations relative to the reference pose: D_c = G_parent^T G_c."""
    D = np.tile(np.eye(4), (len(parents), 1, 1))
    for c in range(len(parents)):
        D[c, :3, :3] = G[c] if parents[c] < 0 else G[parents[c]].T @ G[c]
    return D


def tpose_rotations(rig: Rig) -> np.ndarray:
    """(J,3,3) world rotations, relative to anny's reference A-pose, of every bone in SMPL's T-pose.

    Built as G_c = G_parent D_c (see rig.py), walking the chain root-first and turning the listed bones so their
    children land where the T-pose wants them."""
    idx, parents = rig.index, rig.parents
    ref = rig.world_poses(np.tile(np.eye(4), (len(parents), 1, 1)))[:, :3, 3]  # reference heads
    G = np.tile(np.eye(3), (len(parents), 1, 1))
    heads = ref.copy()
    targets = {}
    for s, sx in (("L", 1.0), ("R", -1.0)):
        out = np.array([sx, 0.0, 0.0])
        targets[f"upperarm01.{s}"] = ("swing", f"lowerarm01.{s}", out)
        targets[f"lowerarm01.{s}"] = ("swing", f"wrist.{s}", out)
        targets[f"wrist.{s}"] = ("hand", s, out)
        targets[f"upperleg01.{s}"] = ("leg", f"foot.{s}", None)
        targets[f"foot.{s}"] = ("rest", None, None)
    for c in range(len(parents)):
        p = parents[c]
        if p >= 0:
            G[c] = G[p]
            heads[c] = heads[p] + G[p] @ (ref[c] - ref[p])
        label = rig.bone_labels[c]
        if label not in targets:
            continue
        kind, arg, out = targets[label]
        if kind == "swing":  # the child's head onto the line from this head along `out`
            G[c] = _rot_between(G[c] @ (ref[idx[arg]] - ref[c]), out) @ G[c]
        elif kind == "leg":  # the ankle under the hip: remove the thigh's sideways lean (a turn about anny's Y)
            d = G[c] @ (ref[idx[arg]] - ref[c])
            phi = np.pi - np.arctan2(d[0], d[2])  # a turn about Y adds phi to atan2(x, z); the target is -Z
            cs, sn = np.cos(phi), np.sin(phi)
            G[c] = np.array([[cs, 0.0, sn], [0.0, 1.0, 0.0], [-sn, 0.0, cs]]) @ G[c]
        elif kind == "rest":
            G[c] = np.eye(3)
        else:  # hand: fingers along `out`, index-to-little knuckle line pointing backwards (+Y): palm down
            along = G[c] @ (ref[idx[f"finger3-1.{arg}"]] - ref[c])
            across = G[c] @ (ref[idx[f"finger5-1.{arg}"]] - ref[idx[f"finger2-1.{arg}"]])
            G[c] = _frame(out, np.array([0.0, 1.0, 0.0])) @ _frame(along, across).T @ G[c]
    return G


def _rigs(phenotypes: list[dict[str, float]]) -> list[Rig]:
    """One numpy rig per phenotype, anny run once as a batch (one thread: bitwise reproducible)."""
    import torch

    from rh_common.threads import torch_threads

    model = load_anny(ANNY_TOPOLOGY)
    pheno = {k: torch.tensor([float(p[k]) for p in phenotypes], dtype=torch.float64) for k in PHENOTYPE_LABELS}
    with torch.no_grad(), torch_threads(1):
        out = model(pose_parameters=None, phenotype_kwargs=pheno)
    as_np = lambda t: t.detach().cpu().numpy().astype(np.float64)  # noqa: E731
    rest_v, rest_p = as_np(out["rest_vertices"]), as_np(out["rest_bone_poses"])
    common = dict(bone_labels=tuple(model.bone_labels), parents=np.asarray(model.bone_parents, np.int64),
                  reference_orientations=as_np(model.reference_bone_orientations),
                  faces=body_topology(ANNY_TOPOLOGY).faces,
                  weights=as_np(model.vertex_bone_weights),
                  weight_bones=model.vertex_bone_indices.detach().cpu().numpy().astype(np.int64))
    return [Rig(rest_poses=rest_p[i], rest_vertices=rest_v[i], **common) for i in range(len(phenotypes))]


def _tposed(rig: Rig, skel: Skeleton = SMPL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The body in SMPL's T-pose and axes: vertices (V,3), bone heads (B,3), the model's joints (J,3)."""
    W = rig.world_poses(tpose_deltas(rig))
    verts, _ = rig.skin(W)
    heads = W[:, :3, 3]
    idx = rig.index
    joints = np.stack([heads[[idx[b] for b in skel.joint_bones[j]]].mean(0) for j in skel.joint_names])
    return to_smpl_axes(verts), to_smpl_axes(heads), to_smpl_axes(joints)


def to_smpl_axes(points: np.ndarray) -> np.ndarray:
    """anny's axes to SMPL's (`ANNY_TO_SMPL`) by moving coordinates, exactly: (x, y, z) -> (x, z, -y)."""
    p = np.asarray(points)
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], -1)


def default_phenotype(gender: str) -> dict[str, float]:
    """The template's anny phenotype: the gender's value, every other value at anny's default 0.5."""
    if gender not in GENDER_VALUE:
        raise ValueError(f"unknown gender {gender!r}; one of {', '.join(GENDERS)}")
    return {k: (GENDER_VALUE[gender] if k == "gender" else 0.5) for k in PHENOTYPE_LABELS}


def shape_phenotypes(gender: str) -> list[dict[str, float]]:
    """The phenotypes whose T-posed bodies span the shape directions (seeded, one stream per gender)."""
    rng = np.random.default_rng([SHAPE_SEED, GENDERS.index(gender)])
    fixed = None if gender == "neutral" else GENDER_VALUE[gender]
    return [sample_phenotype(rng, gender=fixed) for _ in range(N_SHAPE_SAMPLES)]


# ------------------------------------------------------------------------------------------------- the model

# The joint whose direction from joint k sets the axis of k's ring (the bone onwards); leaves use their parent's,
# and so does the head (SMPL-X's jaw and eyes hang from it, but its ring circles the neck's line).
_AXIS_CHILD = {0: 3, 9: 12, 13: 16, 14: 17, 15: None}
_FINGER_SLAB = 0.01  # a phalanx is 2-5 cm long: the trunk's 3 cm slab would hold its neighbours too


def _rings(template: np.ndarray, joints: np.ndarray, owner: np.ndarray, skel: Skeleton = SMPL, slab: float = 0.03,
           least: int = 24) -> list[np.ndarray]:
    """Per joint, the template vertices around it: those skinned mostly to the joint, its parent or a child, in a
    slab across the bone through the joint (half-width `slab`, widened until it holds `least` vertices), so the
    ring circles the limb or trunk and the joint lies inside its hull."""
    parents = skel.parents
    n = len(parents)
    children = {k: [c for c in range(n) if parents[c] == k] for k in range(n)}
    out = []
    for k in range(n):
        c = _AXIS_CHILD[k] if k in _AXIS_CHILD else (children[k][0] if children[k] else None)
        axis = joints[c] - joints[k] if c is not None else joints[k] - joints[parents[k]]
        axis = axis / np.linalg.norm(axis)
        family = [k, *children[k]] + ([parents[k]] if k else [])
        mine = np.flatnonzero(np.isin(owner, family))
        along = np.abs((template[mine] - joints[k]) @ axis)
        half = _FINGER_SLAB if k >= 25 else slab
        while (along < half).sum() < least:
            half *= 1.25
        out.append(mine[along < half])
    return out


def _fit_regressor(bodies: np.ndarray, joints: np.ndarray, rings: list[np.ndarray]) -> np.ndarray:
    """(24,N) J_regressor: per joint, non-negative weights over its ring, summing to 1, least squares over all
    bodies (bodies (P,N,3), joints (P,24,3); body 0 the template, weighted 100x: its joints come out exact to a
    fraction of a millimetre, the shape samples' as close as a linear regressor allows)."""
    from scipy.optimize import nnls

    P, N, _ = bodies.shape
    w_body = np.ones(P)
    w_body[0] = 100.0
    out = np.zeros((joints.shape[1], N))
    for k, near in enumerate(rings):
        A = (bodies[:, near, :] * w_body[:, None, None]).transpose(0, 2, 1).reshape(3 * P, len(near))
        b = (joints[:, k, :] * w_body[:, None]).reshape(3 * P)
        A = np.vstack([A, np.full((1, len(near)), 1e3)])  # the rows-sum-to-1 constraint, weighted in
        b = np.append(b, 1e3)
        x, _ = nnls(A, b, maxiter=50 * len(near))
        out[k, near] = x / x.sum()
    return out


def _shape_space(template: np.ndarray, bodies: np.ndarray) -> tuple[np.ndarray, float]:
    """shapedirs (N,3,10) from bodies (P,N,3): principal directions of their offsets from the template, each scaled
    by its standard deviation, the sign fixed so the largest entry is positive; and the variance share kept."""
    X = (bodies - template[None]).reshape(len(bodies), -1)
    # Through the small (P,P) Gram matrix: the same directions as an SVD of X, at a fraction of its cost.
    # einsum, not BLAS: OpenBLAS's threaded products change the last bits with the core count, the file's bytes
    # must not.
    ev, U = np.linalg.eigh(np.einsum("ik,jk->ij", X, X))
    ev, U = np.maximum(ev[::-1], 0.0), U[:, ::-1]
    s = np.sqrt(ev)
    Vt = np.einsum("pb,pk->bk", U[:, :N_BETAS], X) / s[:N_BETAS, None]
    dirs = Vt * (s[:N_BETAS, None] / np.sqrt(len(bodies)))
    sign = np.sign(dirs[np.arange(N_BETAS), np.argmax(np.abs(dirs), axis=1)])
    dirs = dirs * sign[:, None]
    kept = float((s[:N_BETAS] ** 2).sum() / (s ** 2).sum())
    return np.ascontiguousarray(dirs.T.reshape(template.shape[0], 3, N_BETAS)), kept


@functools.lru_cache(maxsize=2)
def _resampled(kind: str = "smpl"):
    """The stand-in's vertex subset and faces, chosen once on the neutral template (same for every gender)."""
    from .standin_mesh import resample

    skel = SKELETONS[kind]
    rig = _rigs([default_phenotype("neutral")])[0]
    verts, heads, _ = _tposed(rig, skel)
    dominant = rig.weight_bones[np.arange(len(verts)), np.argmax(rig.weights, axis=1)]
    return resample(verts, rig.faces, dominant, heads, rig.index, skel.n_vertices, skel.vertex_ids)


def _build(gender: str, kind: str = "smpl") -> tuple[BodyModel, StandinReport]:
    import anny

    skel = SKELETONS[kind]
    phenos = [default_phenotype(gender)] + shape_phenotypes(gender)
    rigs = _rigs(phenos)
    mesh = _resampled(kind)
    ids = mesh.anny_ids
    bodies, joints = _tposed_bodies(rigs, ids, skel)
    template = bodies[0]
    shapedirs, kept = _shape_space(template, bodies[1:])
    rig = rigs[0]
    owner = bone_joint_map(rig.bone_labels, rig.parents, skel)
    dominant = owner[rig.weight_bones[ids, np.argmax(rig.weights[ids], axis=1)]]
    J_regressor = _fit_regressor(bodies, joints, _rings(template, joints[0], dominant, skel))
    res = np.linalg.norm(np.einsum("jn,pnc->pjc", J_regressor, bodies) - joints, axis=2) * 1e3
    weights = np.zeros((len(ids), skel.n_joints))
    np.add.at(weights, (np.repeat(np.arange(len(ids)), rig.weights.shape[1]), owner[rig.weight_bones[ids]].ravel()),
              rig.weights[ids].ravel())
    weights /= weights.sum(1, keepdims=True)
    report = StandinReport(gender, float(res[0].max()), float(res[1:].max()), float(res[1:].mean()), kept,
                           int(len(mesh.faces)))
    extra = {"rh_standin": {
        "source": f"anny {getattr(anny, '__version__', '?')}, topology {ANNY_TOPOLOGY}",
        "note": "not SMPL: a stand-in built from anny for tests and trials; results with it are not SMPL results",
        "gender": gender, "phenotype": phenos[0], "anny_vertex_ids": ids.astype(np.int64),
        "joint_bones": {j: list(skel.joint_bones[j]) for j in skel.joint_names},
        "joint_residual_mm": {"template_max": report.joint_residual_template_mm,
                              "shape_samples_max": report.joint_residual_samples_mm,
                              "shape_samples_mean": report.joint_residual_samples_mean_mm},
    }}
    n_pose = 9 * (skel.n_joints - 1)
    if kind == "smplx":  # 10 expression directions after the 10 shape ones (zero: anny has no face rig)
        from .standin_smplx import smplx_extras

        shapedirs = np.concatenate([shapedirs, np.zeros_like(shapedirs)], axis=2)
        extra.update(smplx_extras(template, mesh.faces, skel.vertex_ids))
        extra["rh_standin"]["note"] = ("not SMPL-X: a stand-in built from anny for tests and trials; results with "
                                       "it are not SMPL-X results")
    model = BodyModel(kind=kind, gender=gender, v_template=template, shapedirs=shapedirs,
                      posedirs=np.zeros((len(ids), 3, n_pose)), J_regressor=J_regressor,
                      weights=weights, parents=skel.parents.copy(), faces=mesh.faces.astype(np.int64), extra=extra)
    return model, report


def _tposed_bodies(rigs: list[Rig], ids: np.ndarray, skel: Skeleton = SMPL) -> tuple[np.ndarray, np.ndarray]:
    posed = [_tposed(r, skel) for r in rigs]
    return np.stack([p[0][ids] for p in posed]), np.stack([p[2] for p in posed])


def anny_tpose_bodies(phenotypes: list[dict[str, float]], kind: str = "smpl") -> tuple[np.ndarray, np.ndarray]:
    """anny bodies of `phenotypes` as the stand-in sees them: T-posed, in SMPL's axes, at the stand-in's vertices
    (P,V,3), with their mapped joints (P,J,3). What a shape fit of the stand-in to anny aims at."""
    return _tposed_bodies(_rigs(list(phenotypes)), _resampled(kind).anny_ids, SKELETONS[kind])


@functools.lru_cache(maxsize=6)
def _build_cached(gender: str, kind: str) -> tuple[BodyModel, StandinReport]:
    return _build(gender, kind)


def build_standin(gender: str = "neutral", kind: str = "smpl") -> BodyModel:
    """The stand-in model of `gender` in SMPL's (kind 'smpl') or SMPL-X's ('smplx') layout (cached per process;
    seconds the first time)."""
    if gender not in GENDERS:
        raise ValueError(f"unknown gender {gender!r}; one of {', '.join(GENDERS)}")
    if kind not in SKELETONS:
        raise ValueError(f"unknown stand-in kind {kind!r}; one of {', '.join(SKELETONS)}")
    return _build_cached(gender, kind)[0]


def standin_report(gender: str = "neutral", kind: str = "smpl") -> StandinReport:
    """How closely the stand-in of `gender` reproduces anny (joint residuals, shape variance kept)."""
    build_standin(gender, kind)
    return _build_cached(gender, kind)[1]


def write_test_models(folder: str | Path, kind: str = "smpl") -> list[Path]:
    """Write the stand-in (NOT SMPL) into `folder`: SMPL_{NEUTRAL,MALE,FEMALE}.pkl for kind 'smpl',
    SMPLX_{NEUTRAL,MALE,FEMALE}.npz for kind 'smplx'."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for gender in GENDERS:
        path = folder / MODEL_FILE_NAMES[kind][gender][0]
        (write_smpl_pickle if kind == "smpl" else write_smplx_npz)(path, build_standin(gender, kind))
        paths.append(path)
    return paths
