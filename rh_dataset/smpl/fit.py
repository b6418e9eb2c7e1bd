"""Fit a SMPL-family model to posed, unclothed anny bodies: one shape per subject, one pose per frame.

In (`FitInput`): the model (`model.BodyModel`), and per frame a `FrameTarget`: the posed anny body's vertices and
faces in the camera frame (metres, OpenCV axes) and anny's joints mapped to the model's joints (`anny_joints`).
Out (`SubjectFit`): one `betas` shared bit-for-bit by every frame, `scale` (1.0: the betas carry the size, so the
ZJU-MoCap params, which have no scale, describe the same body), and per frame a `FrameFit`: `pose` (3·(J−1),
parent-relative axis-angle), `global_orient`, `global_trans`, the posed `vertices` and `joints` in the camera frame,
and `FitQuality` (vertex-to-surface distances both ways, from exact closest points, `geometry.closest_point`, and
joint error).

The camera-frame body is the one the Relighting Humans clients build (docs/research/clients_relighting_humans.md
§1.2): `x_cam = scale · (V − J0) + global_trans`, with V, J the model posed by (betas, pose, global_orient)
without translation and J0 its root joint (`camera_frame`).

Method (docs/INTEROP.md "SMPL fitted to every frame"): (1) initialise every frame from anny's joints: a rigid
Kabsch fit of the torso joints gives the root, then each joint turns its bone(s) onto anny's (the shortest
rotation, or a Kabsch fit over several children); (2) Levenberg-Marquardt on the joints alone (shape and pose);
(3) rounds of Levenberg-Marquardt on the surface: strided model vertices to the tangent plane of their nearest
anny vertex, strided anny vertices to the tangent plane of their nearest model vertex, plus a weak joint term and
small pose and shape priors, correspondences refreshed between rounds. Each frame's Jacobian block comes from
forward-mode autodiff (one tangent per parameter, shared by the frames); the shared betas are solved through the
Schur complement. Every count is fixed and torch runs on a fixed number of threads (`rh_common.threads`), so the
result is bitwise deterministic.
SMPL-X (55 joints) is fitted the same way: its body and finger joints from anny's bones (`skeletons.SMPLX`), the
jaw and eyes held at zero rotation (`Skeleton.held`; anny has no jaw and no eyeballs).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from rh_common.threads import torch_threads

from rh_dataset.mesh import vertex_normals
from rh_dataset.poses.joints import axis_angle, axis_angle_matrix

from .model import BodyModel, forward, model_tensors, rodrigues
from .skeletons import SKELETONS

__all__ = ["FrameTarget", "FitInput", "FitSettings", "FitQuality", "FrameFit", "SubjectFit", "FitRefused",
           "fit_subject", "camera_frame", "measure_quality", "check_quality", "ANNY_JOINT_BONES",
           "anny_joints"]

# The anny bones whose mean head stands for each SMPL joint: the stand-in's own map (skeletons.JOINT_BONES). It
# starts the fit and is a weak prior; a real SMPL's joints sit a little elsewhere inside the body, so a real-SMPL
# fit's joint error measures that difference as well as the fit. SMPL-X: skeletons.SMPLX.joint_bones, the same
# way (its fingers from anny's finger bones).
ANNY_JOINT_BONES: tuple[tuple[str, ...], ...] = tuple(SKELETONS["smpl"].joint_bones[j]
                                                      for j in SKELETONS["smpl"].joint_names)

# Joints whose rigid fit gives the root's first orientation: they move little with the pose.
_TORSO = (0, 1, 2, 3, 6, 9)


def anny_joints(bone_heads: np.ndarray, bone_labels, kind: str = "smpl") -> np.ndarray:
    """(J, 3) joints in the model's order (SMPL's 24 or SMPL-X's 55) from anny's posed bone heads (B, 3)."""
    index = {b: i for i, b in enumerate(bone_labels)}
    heads = np.asarray(bone_heads, np.float64)
    skel = SKELETONS[kind]
    return np.stack([heads[[index[b] for b in skel.joint_bones[j]]].mean(0) for j in skel.joint_names])


class FitRefused(ValueError):
    """A frame whose fit is worse than the thresholds; the message names the frame and its errors."""


@dataclass(frozen=True)
class FrameTarget:
    """One frame's posed unclothed anny body in the camera frame (metres)."""

    name: str               # for messages, e.g. 'subject_000/train/frame 3'
    vertices: np.ndarray    # (N, 3)
    faces: np.ndarray       # (F, 3)
    joints: np.ndarray      # (J, 3) anny's joints in the model's joint order (`anny_joints`)


@dataclass(frozen=True)
class FitSettings:
    """Fixed iteration counts (determinism) and the refusal thresholds, documented in docs/INTEROP.md."""

    joint_iterations: int = 12        # Levenberg-Marquardt steps on the joints alone
    surface_rounds: int = 6           # correspondence refreshes
    surface_iterations: int = 2       # Levenberg-Marquardt steps per round
    model_points: int = 1500          # model vertices (evenly strided) pulled to anny's surface
    anny_points: int = 1500           # anny vertices (evenly strided) pulled to the model's surface
    joint_weight: float = 0.01        # of the joint term in the surface rounds (1 in the joint steps)
    pose_prior: float = 1e-7          # per squared radian of body pose
    shape_prior: float = 1e-7         # per squared beta
    threads: int = 1
    max_mean_mm: float = 15.0         # refuse a frame whose mean vertex-to-surface distance (either way) is above
    max_max_mm: float = 100.0         # ... or whose largest distance (either way) is above


@dataclass(frozen=True)
class FitInput:
    model: BodyModel
    frames: tuple[FrameTarget, ...]
    settings: FitSettings = field(default_factory=FitSettings)
    betas: np.ndarray | None = None   # a subject's betas from an earlier run: held fixed, only poses are fitted


@dataclass(frozen=True)
class FitQuality:
    """Millimetres. model_to_anny: each model vertex to anny's surface; anny_to_model: each anny vertex to the
    model's surface; joint: the model's joints to anny's mapped joints."""

    model_to_anny_mean_mm: float
    model_to_anny_max_mm: float
    anny_to_model_mean_mm: float
    anny_to_model_max_mm: float
    joint_mean_mm: float
    joint_max_mm: float

    def to_json(self) -> dict:
        return {k: round(float(v), 4) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class FrameFit:
    name: str
    pose: np.ndarray            # (3·(J−1),)
    global_orient: np.ndarray   # (3,)
    global_trans: np.ndarray    # (3,) metres, camera frame
    vertices: np.ndarray        # (V, 3) metres, camera frame
    joints: np.ndarray          # (J, 3) metres, camera frame
    quality: FitQuality


@dataclass(frozen=True)
class SubjectFit:
    betas: np.ndarray           # (10,) (or the model's shape count if fewer)
    scale: float
    frames: tuple[FrameFit, ...]
    seconds: float              # wall time of the whole fit (quality measurement included)
    model_sha256: str


# ---------------------------------------------------------------------------------------------------------- pieces

def camera_frame(model: BodyModel, betas, pose, global_orient, global_trans, scale: float = 1.0,
                 tensors: dict | None = None):
    """The clients' body: `scale · (V − J0) + global_trans` (torch, batched (B, ...)); returns (vertices, joints)."""
    V, J = forward(model, betas, pose, global_orient, None, tensors=tensors)
    J0 = J[:, :1]
    return scale * (V - J0) + global_trans[:, None], scale * (J - J0) + global_trans[:, None]


def _kabsch(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation R minimising Σ|R a_i − b_i|² (rows are vectors, both already centred as wanted)."""
    U, _, Vt = np.linalg.svd(b.T @ a)
    d = np.sign(np.linalg.det(U @ Vt))
    return U @ np.diag([1.0, 1.0, d]) @ Vt


def _shortest(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation turning direction a onto direction b."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    v, c = np.cross(a, b), float(a @ b)
    s = np.linalg.norm(v)
    if s < 1e-9:
        if c > 0:
            return np.eye(3)
        axis = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K * ((1 - c) / s ** 2)


def _initial_pose(rest_joints: np.ndarray, target: np.ndarray, parents: np.ndarray):
    """(global_orient, pose, trans) turning the rest skeleton's bones onto the target joints, root first."""
    n = len(parents)
    children = [[c for c in range(n) if parents[c] == j] for j in range(n)]
    torso = [j for j in _TORSO if j < n]
    G = [np.eye(3)] * n
    G[0] = _kabsch(rest_joints[torso] - rest_joints[0], target[torso] - target[0])
    local = [np.eye(3) for _ in range(n)]
    local[0] = G[0]
    for j in range(1, n):
        Gp = G[parents[j]]
        kids = children[j]
        if kids:
            cur = np.array([Gp @ (rest_joints[c] - rest_joints[j]) for c in kids])
            want = np.array([target[c] - target[j] for c in kids])
            Rm = _shortest(cur[0], want[0]) if len(kids) == 1 else _kabsch(cur, want)
            local[j] = Gp.T @ Rm @ Gp
        G[j] = Gp @ local[j]
    pose = np.concatenate([axis_angle(local[j]) for j in range(1, n)])
    return axis_angle(local[0]), pose, target[0].copy()


def measure_quality(model_vertices, model_faces, model_joints, target: FrameTarget) -> FitQuality:
    """Distances both ways from exact closest points on the triangles (`geometry.closest_point`), in millimetres."""
    from rh_dataset.characters.geometry import closest_point, query_mesh

    _, d_ma, _ = closest_point(query_mesh(target.vertices, target.faces), model_vertices)
    _, d_am, _ = closest_point(query_mesh(model_vertices, model_faces), target.vertices)
    dj = np.linalg.norm(np.asarray(model_joints) - target.joints, axis=1)
    return FitQuality(1e3 * float(d_ma.mean()), 1e3 * float(d_ma.max()), 1e3 * float(d_am.mean()),
                      1e3 * float(d_am.max()), 1e3 * float(dj.mean()), 1e3 * float(dj.max()))


def check_quality(qualities, settings: FitSettings, where: str = "", name: str = "SMPL") -> None:
    """Raise FitRefused naming the first frame above the thresholds; `qualities`: (frame name, FitQuality) pairs."""
    for frame, q in qualities:
        mean = max(q.model_to_anny_mean_mm, q.anny_to_model_mean_mm)
        peak = max(q.model_to_anny_max_mm, q.anny_to_model_max_mm)
        if mean > settings.max_mean_mm or peak > settings.max_max_mm:
            raise FitRefused(
                f"{where}{frame}: the {name} fit is too far from the anny body (mean {mean:.1f} mm, limit "
                f"{settings.max_mean_mm:g}; max {peak:.1f} mm, limit {settings.max_max_mm:g}); check that the model "
                f"file is a {name} body model, or raise --smpl-max-mean-mm / --smpl-max-peak-mm if this pose is known "
                f"to be hard")


# ---------------------------------------------------------------------------------------------------------- fitting

def fit_subject(inp: FitInput, log=print) -> SubjectFit:
    """Fit one subject's frames jointly (shared betas) and measure each frame; see the module docstring."""
    if not inp.frames:
        raise ValueError("fit_subject: no frames to fit")
    skel = SKELETONS.get(inp.model.kind)
    if skel is None or inp.model.n_joints != skel.n_joints:
        raise ValueError(f"fit_subject: {inp.model.path or 'the model'} has {inp.model.n_joints} joints; the fit "
                         f"maps anny onto SMPL's 24 or SMPL-X's 55 joints")
    import torch

    t0 = time.perf_counter()
    model, s = inp.model, inp.settings
    # One thread count for the fit and the posed result: torch's reductions sum in a thread-dependent order.
    with torch_threads(s.threads):
        betas, poses = _optimise(inp)
        with torch.no_grad():
            V, J = camera_frame(model, torch.as_tensor(np.repeat(betas[None], len(poses), 0)),
                                torch.as_tensor(np.stack([p[1] for p in poses])),
                                torch.as_tensor(np.stack([p[0] for p in poses])),
                                torch.as_tensor(np.stack([p[2] for p in poses])), 1.0,
                                tensors=model_tensors(model))
    frames = []
    for i, target in enumerate(inp.frames):
        q = measure_quality(V[i].numpy(), model.faces, J[i].numpy(), target)
        frames.append(FrameFit(target.name, poses[i][1], poses[i][0], poses[i][2], V[i].numpy().copy(),
                               J[i].numpy().copy(), q))
    seconds = time.perf_counter() - t0
    if log:
        log(f"{model.kind.upper()} fit: {len(frames)} frames in {seconds:.1f} s "
            f"({seconds / len(frames):.2f} s per frame, "
            f"{s.threads} torch thread(s)); worst mean distance "
            f"{max(max(f.quality.model_to_anny_mean_mm, f.quality.anny_to_model_mean_mm) for f in frames):.2f} mm")
    return SubjectFit(betas, 1.0, tuple(frames), seconds, model.sha256)


def _optimise(inp: FitInput):
    """Levenberg-Marquardt on stacked residuals (joints, then surface rounds); returns (betas, per-frame
    (global_orient, pose, global_trans))."""
    import torch
    from scipy.spatial import cKDTree

    model, s = inp.model, inp.settings
    dt = torch.float64
    n_b = min(10, model.n_betas)
    B, nj = len(inp.frames), model.n_joints
    P = 3 + 3 * (nj - 1) + 3  # per frame: root turn δ, body pose, translation
    # Joints held at their initial zero (SMPL-X's jaw and eyes: anny has no jaw and no eyeballs to fit them to):
    # their rows and columns of the normal equations become the identity's, their gradient zero, so their step is
    # exactly zero and the other parameters' step is the one without them.
    free = torch.ones(P, dtype=dt)
    for j in SKELETONS[model.kind].held:
        free[3 * j:3 * j + 3] = 0.0
    fixed = torch.diag(1.0 - free)
    beta0 = np.zeros(n_b) if inp.betas is None else np.asarray(inp.betas, np.float64)[:n_b]
    rest = model.J_regressor @ (model.v_template + model.shapedirs[..., :n_b] @ beta0)
    init = [_initial_pose(rest, f.joints, model.parents) for f in inp.frames]
    # The root turns as R(δ)·R0 about the pelvis with δ starting at zero, away from axis-angle's singular shell
    # at π (a body facing the camera is about π from SMPL's facing +Z).
    R0 = torch.tensor(np.stack([axis_angle_matrix(x[0]) for x in init]), dtype=dt)
    theta = torch.tensor(np.stack([np.concatenate([np.zeros(3), x[1], x[2]]) for x in init]), dtype=dt)
    beta = torch.tensor(beta0, dtype=dt)
    target_joints = torch.tensor(np.stack([f.joints for f in inp.frames]), dtype=dt)
    w_joint_fit, w_pose, w_shape = 1.0 / nj, s.pose_prior, s.shape_prior

    def posed(th, be, frames, tensors):
        """Camera-frame (vertices of `tensors`, joints) of `frames` (a slice) for parameters th (b,P), be."""
        b = th.shape[0]
        V, J = forward(model, be[None].expand(b, n_b), th[:, 3:P - 3], th.new_zeros(b, 3), None, tensors=tensors)
        R = rodrigues(th[:, :3]) @ R0[frames]
        J0 = J[:, :1]
        tr = th[:, None, P - 3:]
        return (V - J0) @ R.transpose(1, 2) + tr, (J - J0) @ R.transpose(1, 2) + tr

    def lm(residual, iterations, fit_beta):
        """`residual(th, be, frames)` -> (b, m). Damped Gauss-Newton steps; frames are independent but for β,
        whose block is solved through the Schur complement."""
        nonlocal theta, beta
        from torch.func import jacfwd

        lam = 1e-3
        nx = P + (n_b if fit_beta else 0)

        def cost_of(th, be):
            c = sum(float((residual(th[sl], be, sl) ** 2).sum()) for sl in chunks)
            return c + (w_shape * float((be ** 2).sum()) if fit_beta else 0.0)

        chunks = [slice(i, min(B, i + 8)) for i in range(0, B, 8)]
        cost = cost_of(theta, beta)
        for _ in range(iterations):
            Htt, Htb, gt = [], [], []
            Hbb = torch.zeros(n_b, n_b, dtype=dt)
            gb = torch.zeros(n_b, dtype=dt)
            for sl in chunks:
                th, r = theta[sl], residual(theta[sl], beta, sl)
                # One tangent per parameter, shared by the chunk's frames: frame i's residuals depend on its own
                # parameters only, so each frame's rows of the result are its own Jacobian block.
                Jc = jacfwd(lambda x: residual(th + x[:P], beta + x[P:] if fit_beta else beta, sl))(
                    torch.zeros(nx, dtype=dt))
                Jt = Jc[..., :P]
                Htt.append(Jt.transpose(1, 2) @ Jt)
                gt.append(torch.einsum("bmp,bm->bp", Jt, r))
                if fit_beta:
                    Jb = Jc[..., P:]
                    Htb.append(Jt.transpose(1, 2) @ Jb)
                    Hbb += torch.einsum("bmi,bmj->ij", Jb, Jb)
                    gb += torch.einsum("bmi,bm->i", Jb, r)
            Htt = torch.cat(Htt) * (free[:, None] * free[None]) + fixed
            gt = torch.cat(gt) * free
            if fit_beta:
                Htb = torch.cat(Htb) * free[:, None]
                Hbb += w_shape * torch.eye(n_b, dtype=dt)
                gb += w_shape * beta
            for _try in range(4):
                A = Htt + lam * (torch.diag_embed(torch.diagonal(Htt, dim1=1, dim2=2)) + 1e-9 * torch.eye(P, dtype=dt))
                if fit_beta:
                    X = torch.linalg.solve(A, torch.cat([gt[..., None], Htb], -1))
                    S = Hbb + lam * (torch.diag(torch.diagonal(Hbb)) + 1e-9 * torch.eye(n_b, dtype=dt))
                    S = S - torch.einsum("bpi,bpj->ij", Htb, X[..., 1:])
                    db = -torch.linalg.solve(S, gb - torch.einsum("bpi,bp->i", Htb, X[..., 0]))
                    dth = -(X[..., 0] + (X[..., 1:] @ db))
                else:
                    db = torch.zeros(n_b, dtype=dt)
                    dth = -torch.linalg.solve(A, gt)
                new = cost_of(theta + dth, beta + db)
                if new < cost:
                    theta, beta, cost, lam = theta + dth, beta + db, new, max(lam / 3.0, 1e-7)
                    break
                lam *= 4.0

    fit_beta = inp.betas is None
    t_joints = model_tensors(model, dt, vertex_ids=np.zeros(0, np.int64))

    def joint_residual(th, be, sl):
        _, J = posed(th, be, sl, t_joints)
        return torch.cat([((J - target_joints[sl]) * w_joint_fit ** 0.5).reshape(th.shape[0], -1),
                          w_pose ** 0.5 * th[:, 3:P - 3]], 1)

    lm(joint_residual, s.joint_iterations, fit_beta)

    # Surface rounds: correspondences fixed within a round (nearest vertices, scipy's KD-tree), refreshed between.
    t_full = model_tensors(model, dt)
    trees = [cKDTree(f.vertices) for f in inp.frames]
    normals = [vertex_normals(f.vertices, f.faces) for f in inp.frames]
    fwd_ids = np.arange(0, model.n_vertices, max(1, model.n_vertices // s.model_points))
    rev_ids = [np.arange(0, len(f.vertices), max(1, len(f.vertices) // s.anny_points)) for f in inp.frames]
    n_rev = min(len(r) for r in rev_ids)
    rev_ids = [r[:n_rev] for r in rev_ids]
    rev_pts = torch.tensor(np.stack([f.vertices[r] for f, r in zip(inp.frames, rev_ids)]), dtype=dt)
    all_frames = slice(0, B)
    for _ in range(s.surface_rounds):
        with torch.no_grad():
            Vn = posed(theta, beta, all_frames, t_full)[0].numpy()
        near = [tree.query(Vn[i, fwd_ids])[1] for i, tree in enumerate(trees)]
        p = torch.tensor(np.stack([f.vertices[k] for f, k in zip(inp.frames, near)]), dtype=dt)
        n = torch.tensor(np.stack([nm[k] for nm, k in zip(normals, near)]), dtype=dt)
        back = np.stack([cKDTree(Vn[i]).query(rev_pts[i].numpy())[1] for i in range(B)])
        back_n = torch.tensor(np.stack([vertex_normals(Vn[i], model.faces)[back[i]] for i in range(B)]), dtype=dt)
        ids, inverse = np.unique(np.concatenate([fwd_ids, back.ravel()]), return_inverse=True)
        t_round = model_tensors(model, dt, vertex_ids=ids)
        fwd_pos = torch.as_tensor(inverse[:len(fwd_ids)])
        back_pos = torch.as_tensor(inverse[len(fwd_ids):].reshape(B, n_rev))
        wf, wr, wj = (1.0 / len(fwd_ids)) ** 0.5, (1.0 / n_rev) ** 0.5, (s.joint_weight / nj) ** 0.5

        def surface_residual(th, be, sl):
            V, J = posed(th, be, sl, t_round)
            b = th.shape[0]
            d = V[:, fwd_pos] - p[sl]
            e = torch.gather(V, 1, back_pos[sl][..., None].expand(-1, -1, 3)) - rev_pts[sl]
            return torch.cat([wf * (d * n[sl]).sum(-1), 0.1 * wf * d.reshape(b, -1),
                              wr * (e * back_n[sl]).sum(-1), 0.1 * wr * e.reshape(b, -1),
                              wj * (J - target_joints[sl]).reshape(b, -1), w_pose ** 0.5 * th[:, 3:P - 3]], 1)

        lm(surface_residual, s.surface_iterations, fit_beta)
    with torch.no_grad():
        R = (rodrigues(theta[:, :3]) @ R0).numpy()
    th = theta.numpy()
    return beta.numpy().copy(), [(axis_angle(R[i]), th[i, 3:P - 3].copy(), th[i, P - 3:].copy()) for i in range(B)]
