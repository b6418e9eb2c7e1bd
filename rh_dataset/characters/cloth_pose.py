"""Draped garments in a frame's pose: skinned to the body (cheap) or simulated from the rest pose into the pose.

In: the character's draped garments (`drape.DrapedGarment`, inner first, each settled on the rest-pose body), its
phenotype and the frame's anny bone deltas ('local-ref', as `pose_character` takes them). Out: the posed vertices
(V, 3) float64 of each garment, in anny's posed space (before a pose's `root_transform`), by one of `CLOTH_MODES`:

  "skinned"    each cloth vertex follows the body's linear-blend skinning (`drape.bind_loose`: the closest body
               point's weights, diffused over the cloth below the hips so a stride does not split it), then
               `drape.push_out` moves what a limb swung into back onto the skin. The fold pattern of the rest drape
               is carried into every pose: a thigh lifted into a skirt stretches the cloth with it.
  "simulated"  `simulate_into_pose`: newton's VBD cloth solver runs from the draped rest state while the body
               moves from the rest pose into the frame's pose (every bone's delta rotation slerped from identity,
               the root's translation lerped, eased in and out), the body a deforming triangle-mesh collider whose
               vertices (and velocities) are set every step, the pinned waistband kinematic on the skinned body;
               then the cloth settles with the body still, with the cloth self-contact it was draped with, each
               garment in its own fabric (`pose_fabric`). `pose_character` then applies `push_out` as for skinned
               cloth: newton's penalty contact can leave a vertex a few millimetres inside a limb that pressed the
               cloth.
  "auto"       skinned, and a frame whose skinned cloth leaves more than `SIMULATE_ABOVE` skin vertices out through it
               (`skin_out`, after the lift and the tuck), or whose skinned skirt or dress has more than
               `STRETCHED_ABOVE` of its edges stretched past `STRETCH_LIMIT` (`overstretched`), simulated instead:
               the few poses that carry a limb through the cloth (a raised leg through an open coat) or pull a
               skirt taut between the thighs (sitting) take the simulation's cost, the others skinning's.
Either way `pose_character` then pushes draped cloth out over the draped cloth under it (`push_over`,
`drape.DRAPED_OVER`): skinned, each layer follows its own binding and a swinging thigh can carry a skirt through it.

Skin that still lies out through a lifted garment (`LIFT_KINDS`) is then tucked back under it in the body's render
mesh (`tuck_skin`, by `pose_character`).

Measures of posed cloth: `self_crossings` (cloth through itself), `hem_split` (a hem wrapped round each leg),
`layer_depth` (an outer layer under an inner garment's surface), `covers` (skin the cloth lies over).

Which preset uses which is decided by bench/bench_cloth_pose.py (docs/TRADEOFFS.md, "Skinned or simulated cloth"),
and so is which kinds "simulated" simulates (`SIMULATED_KINDS`: today every draped kind) and with what fabric
(`pose_fabric`: each garment its own, the one it was draped with but for `POSE_FABRIC`'s wide-leg trousers).
Determinism: Warp's CPU kernels run in a fixed order, so the same inputs give the same bits on one machine
(tests/test_cloth_pose.py); other machines and Warp/newton versions are not promised the same bits.
"""
from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Mapping, Sequence

import numpy as np

from rh_dataset.mesh import vertex_normals

from .body import body_topology, run_anny
from .drape import (DrapedGarment, DrapeSettings, bind_loose, bind_to_skeleton, cloth_model, cloth_solver,
                    collider_faces, drape_garment, draped_over, push_clearance, push_out, skin_points)
from .geometry import edge_counts, query_mesh, smoothstep, unique_rows

__all__ = ["CLOTH_MODES", "SIMULATED_KINDS", "POSE_FABRIC", "pose_fabric", "ClothPoseSettings", "BodyMotion",
           "body_motion", "simulate_into_pose", "skin_into_pose", "simulated_parts", "self_crossings", "hem_split",
           "layer_depth", "push_over", "covers", "LIFT_KINDS", "skin_inside", "lift_over_skin", "edges_through",
           "crossing_points", "tuck_skin", "TUCK_DEPTH", "TUCK_REACH", "TUCK_TOLERANCE", "skin_out", "SKIN_OUT_REACH",
           "SIMULATE_ABOVE", "overstretched", "STRETCH_LIMIT", "STRETCH_KINDS", "STRETCHED_ABOVE"]

CLOTH_MODES = ("skinned", "simulated", "auto")
# The draped kinds the "simulated" mode simulates (the others would be skinned in every mode): today all of them.
# The wide-leg trousers are simulated with `POSE_FABRIC` since 3 December: with the fabric they are draped with, a
# sitting or bending thigh passed out through its leg tube (65 mm deep in the body before push_out), which then hung
# straight down beside the raised leg (bench/bench_cloth_pose.py --kind draped_trousers --drape-fabric).
# The hoodie's hood is simulated in its own fabric (a heavier, firmer fleece) since garments simulated together
# each keep theirs (3 December): when `simulate_into_pose` gave them all the first one's fabric, a hood over a skirt
# moved as the skirt's light cloth and crossed itself more than skinned (98 edges against 52, 3 posed frames); in its
# own fabric (bench_cloth_pose.py --kind draped_hoodie --simulate-all, 2 subjects, 6 posed frames) 60 against 61, no
# hood vertex in the body either way, the renders 38.3 dB apart (median) against standard's 42.9 dB noise: by the
# bench's rule simulated at reference (docs/TRADEOFFS.md, "Every draped kind").
# The open jacket is simulated as the coat is (the same cloth and layers, cut shorter): bench_cloth_pose.py --kind
# draped_jacket (3 December, 3 posed frames, no renders) found no panel vertex in the body and no self-crossing edge
# either way (docs/TRADEOFFS.md, "Every draped kind").
# The loose t-shirt is simulated too: bench_cloth_pose.py --kind draped_tshirt --simulate-all (3 December, load
# ~0.7-1.7; 2 subjects, 6 posed frames, no renders) found no cloth vertex in the body either way, fewer self-crossing
# edges simulated (32 against 37) and the simulation at 5.0 s a posed frame (median); rendered (1 subject, 2 frames)
# the two ways lie 26.4 and 31.1 dB apart against standard's 38-40 dB noise. The bench's rule: simulated at reference.
# The loose long sleeve's cloth is the loose t-shirt's (the same cut and fabric), measured on its own when its sleeves
# were shells (bench_cloth_pose.py --kind draped_longsleeve, 2 subjects, 6 posed frames): no cloth in the body either
# way, 71 self-crossing edges skinned against 128 simulated (the seated laps), renders 33.6 dB apart against
# standard's 42.3 dB noise: simulated at reference.
# The hoodie's body (6 December) is the loose t-shirt's cut in the hood's fleece: simulated as the loose tops are,
# in its own fabric. Not measured skinned against simulated (bench_cloth_pose.py picks wearers of a recipe kind and
# measures that part: `--kind draped_hoodie`, the hood); bench_cloth_layers.py's simulated frames keep the hood over it.
# The loose shorts are the wide trousers cut above the knee, the straight-leg trousers their legs without the flare:
# simulated, lifted and posed in their fabric likewise.
# The draped sleeves (`sleeves.SLEEVE_CUTS`: the loose tops', the hoodie's, the open coat's) are skinned in every
# mode: the per-frame simulation's body leaves the arms out (`body_motion`, `collider_faces`), so simulated they would
# fall through the arms they hang round.
SIMULATED_KINDS = ("draped_skirt", "draped_dress", "draped_trousers", "draped_coat", "draped_hoodie", "draped_jacket",
                   "draped_tshirt", "draped_longsleeve", "draped_shorts", "draped_straight_trousers",
                   "draped_hoodie_body")
# What a kind's per-frame simulation changes in the `DrapeSettings` it was draped with. The wide-leg trousers: the
# drape's membrane (1e5, stiff enough that the 80 cm legs, held at the waist only, do not stretch to the floor as they
# settle) would not stretch over the seat a sitting thigh swings forward, and at the drape's contact stiffness (5e4)
# the thigh pushed through the front of its leg tube instead. A softer membrane and a tenfold stiffer contact keep the
# thighs in their tubes. Tried by hand on subject 4 sitting (bench/bench_cloth_pose.py --kind draped_trousers's
# first subject, 3 December), as the share of the thighs' skin the cloth lies over (`covers`): the drape's fabric
# 27 %, a 1e4 membrane 66 %, a 2e5 contact 57 %, a 1e6 contact 73 %, 1e4 with 2e5 79 % (flapping
# more), 3e4 with 5e5 (kept) 77 %, skinned 83 %; holding the hems where skinning puts them did not help (27 % in the
# drape's fabric; in this one 22 mm of cloth in the body before push_out in a bend, against 6 mm without). The
# bench over its 6 posed frames, of the skin the trousers cover at rest (docs/TRADEOFFS.md, "Every draped kind"):
# worst pose 76.8 % still covered (33.8 % in the drape's fabric, 76.0 % skinned); 15 mm in the body before push_out
# at most (65.5 mm).
POSE_FABRIC = {"draped_trousers": dict(tri_ke=3.0e4, tri_ka=3.0e4, contact_ke=5.0e5)}
POSE_FABRIC["draped_shorts"] = POSE_FABRIC["draped_straight_trousers"] = POSE_FABRIC["draped_trousers"]


def pose_fabric(kind: str, drape: DrapeSettings | None) -> DrapeSettings:
    """The fabric a draped kind is simulated with per frame: the `DrapeSettings` it was draped with (its part's
    `drape`; None: the defaults), changed as `POSE_FABRIC` says for its kind."""
    return dataclasses.replace(drape or DrapeSettings(), **POSE_FABRIC.get(kind, {}))


@dataclasses.dataclass(frozen=True)
class ClothPoseSettings:
    """The per-frame simulation. The motion is sampled at `keyframes` poses (forward kinematics and skinning of the
    whole collider) and interpolated linearly between them; each `dt` step advances it as far as keeps the move of
    every collider vertex within `reach` metres of the cloth (and of the pinned waistband) at or below
    `max_body_step` metres (at 5 mm a thigh lifted into a skirt stays out of it, at 10 mm it passed through), in
    at most `max_move_steps` steps; then `settle_steps` with the body still, the cloth's velocities multiplied by
    `settle_damping` after each (a frame is a static pose: the skirt's swing is damped out rather than frozen
    mid-swing). `iterations`: VBD sweeps per step; `contact_gap`: newton's soft-contact detection distance
    (metres). The cloth's material, body contact and self-contact are the ones it was draped with
    (`DrapeSettings`)."""

    dt: float = 0.01
    iterations: int = 10
    max_body_step: float = 0.005
    reach: float = 0.1
    max_move_steps: int = 600
    settle_steps: int = 30
    settle_damping: float = 0.8
    keyframes: int = 17
    contact_gap: float = 0.015

    def __post_init__(self) -> None:
        for name in ("iterations", "max_move_steps", "settle_steps", "keyframes"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < (2 if name == "keyframes" else 0):
                raise ValueError(f"ClothPoseSettings.{name} must be an integer >= {2 if name == 'keyframes' else 0},"
                                 f" got {v!r}")
        if self.max_move_steps < self.keyframes - 1:
            raise ValueError(f"ClothPoseSettings.max_move_steps must be >= keyframes - 1 (a step per keyframe "
                             f"interval), got {self.max_move_steps}")
        if isinstance(self.settle_damping, bool) or not isinstance(self.settle_damping, (int, float)) \
                or not 0.0 <= self.settle_damping <= 1.0:
            raise ValueError(f"ClothPoseSettings.settle_damping must be in [0, 1], got {self.settle_damping!r}")
        for name in ("dt", "max_body_step", "reach", "contact_gap"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v <= 0:
                raise ValueError(f"ClothPoseSettings.{name} must be a positive number, got {v!r}")


@dataclasses.dataclass(frozen=True)
class BodyMotion:
    """The body moving from the rest pose (t = 0) into the frame's pose without its heading (t = 1), sampled at K
    keyframes: bone_poses (K, J, 4, 4) anny's posed bone poses, rest_bone_poses (J, 4, 4), and `collider`
    (K, C, 3) the posed collider vertices `collider_vertices` (C,) of the body (its faces `collider_faces` (F, 3)
    index them). `heading` (3, 3): the pose's turn about +Z through the origin (the root's rotation about the
    vertical), applied rigidly afterwards: the frame's pose = heading @ the motion's last keyframe."""

    heading: np.ndarray
    times: np.ndarray
    bone_poses: np.ndarray
    rest_bone_poses: np.ndarray
    collider_vertices: np.ndarray
    collider_faces: np.ndarray
    collider: np.ndarray


def body_motion(phenotype: Mapping[str, float], bone_deltas: Mapping[str, np.ndarray] | None,
                keyframes: int = ClothPoseSettings.keyframes) -> BodyMotion:
    """Rest pose -> the frame's pose: at eased time s each bone's delta is the rotation by s times its rotation
    vector (the slerp from identity) and s times its translation (the root's), through anny's forward kinematics
    and linear-blend skinning (`poses.rig`, anny's own maths in numpy). The root's turn about the vertical (the
    twist about +Z of its world rotation; sampled poses put their heading there, up to 60 degrees) is not part of
    the motion but `heading`: turning about the gravity axis changes nothing of a static drape, while a body that
    turned in the simulation would twirl the skirt, which then swings long after it stops."""
    from scipy.spatial.transform import Rotation

    from rh_common.body_model import load_anny
    from rh_dataset.poses.pose import BodyPose
    from rh_dataset.poses.rig import rig_for

    target = BodyPose(bones=dict(bone_deltas or {})).deltas()  # validated: rigid, translation on the root only
    rig = rig_for(load_anny(), phenotype)
    # The root's world pose is [U0^T R U0 | U0^T d] (poses.rig); split its world rotation A = G B, G the twist
    # about +Z (the quaternion's (w, z) part: the same angle in either order of the swing-twist split).
    U0 = rig.reference_orientations[0]
    x, y, z, w = Rotation.from_matrix(U0.T @ target[0, :3, :3] @ U0).as_quat()
    heading = Rotation.from_rotvec([0.0, 0.0, 2.0 * np.arctan2(z, w)]).as_matrix()
    target[0, :3, :3] = U0 @ heading.T @ U0.T @ target[0, :3, :3]
    target[0, :3, 3] = U0 @ heading.T @ U0.T @ target[0, :3, 3]
    rotvec = Rotation.from_matrix(target[:, :3, :3]).as_rotvec()
    faces = collider_faces(phenotype)
    used, compact = np.unique(faces, return_inverse=True)
    times = np.linspace(0.0, 1.0, int(keyframes))
    poses, collider = [], []
    for s in smoothstep(times):  # the body starts and stops at rest (zero velocity), so the cloth is not jerked
        D = np.tile(np.eye(4), (len(target), 1, 1))
        D[:, :3, :3] = Rotation.from_rotvec(rotvec * s).as_matrix()
        D[:, :3, 3] = target[:, :3, 3] * s
        W = rig.world_poses(D)
        poses.append(W)
        collider.append(rig.skin(W, used)[0])
    return BodyMotion(heading, times, np.stack(poses), rig.rest_poses, used,
                      compact.reshape(faces.shape).astype(np.int32), np.stack(collider))


def _is_rest(bone_deltas: Mapping[str, np.ndarray] | None) -> bool:
    return not bone_deltas or all(np.array_equal(np.asarray(m, np.float64), np.eye(4)) for m in bone_deltas.values())


def _check_garments(garments: Sequence[DrapedGarment], simulated: bool = False) -> None:
    if not garments or not all(isinstance(g, DrapedGarment) for g in garments):
        raise ValueError("cloth_pose: garments must be a non-empty sequence of DrapedGarment (drape.drape_garment)")
    for g in garments if simulated else ():
        if g.pattern is None or np.shape(g.pattern) != np.shape(g.vertices):
            raise ValueError(f"cloth_pose: DrapedGarment {g.kind!r} needs its pattern (the cloth's rest shape, "
                             "as drape.drape_garment returns it) to be simulated further")


def _next_time(x: float, collider: np.ndarray, cloth: np.ndarray, pin_keys: np.ndarray,
               st: ClothPoseSettings) -> float:
    """The motion time (in keyframe intervals, 0..K-1) of the next step after `x`: as far as keeps the move of every
    collider vertex now within `st.reach` of the cloth, and of every pinned vertex, at or below
    `st.max_body_step` (the rates of the current keyframe interval and of the next, whichever is faster); a foot far
    below a skirt does not slow its simulation down, a shin swinging into its hem does."""
    from scipy.spatial import cKDTree

    k = len(collider) - 1
    i = min(int(x), k - 1)
    f = x - i
    now = collider[i] * (1.0 - f) + collider[i + 1] * f
    near = cKDTree(cloth).query(now, distance_upper_bound=st.reach)[0] <= st.reach
    rate = 0.0
    for j in (i, min(i + 1, k - 1)):
        if near.any():
            rate = max(rate, float(np.linalg.norm(collider[j + 1][near] - collider[j][near], axis=1).max()))
        if pin_keys.shape[1]:
            rate = max(rate, float(np.linalg.norm(pin_keys[j + 1] - pin_keys[j], axis=1).max()))
    step = st.max_body_step / rate if rate > 0.0 else float(k)
    return min(float(k), x + max(step, k / st.max_move_steps))


def simulate_into_pose(garments: Sequence[DrapedGarment], phenotype: Mapping[str, float],
                       bone_deltas: Mapping[str, np.ndarray] | None,
                       settings: ClothPoseSettings = ClothPoseSettings(),
                       fabric: DrapeSettings | Sequence[DrapeSettings] = DrapeSettings(), stats: dict | None = None
                       ) -> list[np.ndarray]:
    """Posed vertices of each garment (list of (V_i, 3) float64, anny's posed space), simulated from the draped
    rest state while the body moves into the pose (module docstring). `fabric`: the cloth's material and contact
    parameters (`pose_fabric`: those it was draped with), one for all garments or one per garment; each garment
    moves as its own material (density, membrane and bending stiffness, particle radius), and the soft contact with
    the body, which newton keeps one of, is the stiffest of them (no layer is let further into the body than its
    own drape let it). The rest pose (no delta, e.g. a turntable frame) has nothing to move:
    the drape is returned as it is. `stats`, if given, receives the step counts (`move_steps`, `settle_steps`)."""
    import warp as wp

    import newton

    _check_garments(garments, simulated=True)
    if _is_rest(bone_deltas):
        if stats is not None:
            stats.update(move_steps=0, settle_steps=0)
        return [np.array(g.vertices, np.float64) for g in garments]
    st = settings
    motion = body_motion(phenotype, bone_deltas, st.keyframes)
    pinned = np.concatenate([g.pinned for g in garments])
    rest = np.concatenate([g.vertices for g in garments]).astype(np.float64)
    pins = bind_to_skeleton(rest[pinned], phenotype)
    pin_keys = np.stack([skin_points(pins, W, motion.rest_bone_poses) for W in motion.bone_poses])
    # The cloth's rest shape is its pattern; it starts where the drape settled.
    fabrics = [fabric] * len(garments) if isinstance(fabric, DrapeSettings) else list(fabric)
    if len(fabrics) != len(garments) or not all(isinstance(f, DrapeSettings) for f in fabrics):
        raise ValueError("cloth_pose: fabric must be a DrapeSettings or one DrapeSettings per garment")
    contact = max(fabrics, key=lambda f: f.contact_ke)  # newton has one soft contact for all particles
    model, body = cloth_model([(g.pattern, g.faces, g.pinned) for g in garments], motion.collider[0],
                              motion.collider_faces, contact, fabrics)
    mesh = body.mesh  # the Warp mesh the model's shape queries; moved in place below
    # The shape's bounds are fixed when the model is built: widen them to the whole motion, or the contact
    # broad phase would skip particles where the body has moved beyond its rest-pose box.
    lo = motion.collider.reshape(-1, 3).min(0) - st.contact_gap
    hi = motion.collider.reshape(-1, 3).max(0) + st.contact_gap
    model.shape_collision_aabb_lower.assign(lo[None].astype(np.float32))
    model.shape_collision_aabb_upper.assign(hi[None].astype(np.float32))
    solver = cloth_solver(model, contact, st.iterations)
    pipe = newton.CollisionPipeline(model, soft_contact_gap=st.contact_gap, deterministic=True)
    contacts = pipe.contacts()
    s0, s1, ctrl = model.state(), model.state(), model.control()
    s0.particle_q.assign(wp.array(rest.astype(np.float32), dtype=wp.vec3, device="cpu"))
    s1.particle_q.assign(s0.particle_q)
    pin_idx = np.flatnonzero(pinned)
    prev = motion.collider[0]
    k = len(motion.times) - 1
    x, moves, settled = 0.0, 0, 0
    while x < k or settled < st.settle_steps:
        if x < k:
            x = _next_time(x, motion.collider, s0.particle_q.numpy(), pin_keys, st)
            moves += 1
        else:
            settled += 1
        i = min(int(x), k - 1)
        f = x - i
        cur = motion.collider[i] * (1.0 - f) + motion.collider[i + 1] * f
        mesh.points.assign(cur.astype(np.float32))
        mesh.velocities.assign(((cur - prev) / st.dt).astype(np.float32))  # the contact's surface velocity
        mesh.refit()
        prev = cur
        q = s0.particle_q.numpy().copy()
        q[pin_idx] = pin_keys[i] * (1.0 - f) + pin_keys[i + 1] * f
        s0.particle_q.assign(wp.array(q, dtype=wp.vec3, device="cpu"))
        s1.particle_q.assign(s0.particle_q)
        pipe.collide(s0, contacts)
        s0.clear_forces()
        solver.step(s0, s1, ctrl, contacts, st.dt)
        s0, s1 = s1, s0
        if settled:  # the body is still: damp the cloth's swing towards the rest a static frame shows
            s0.particle_qd.assign(s0.particle_qd.numpy() * np.float32(st.settle_damping))
    if stats is not None:
        stats.update(move_steps=moves, settle_steps=settled)
    q = s0.particle_q.numpy().astype(np.float64)
    if not np.all(np.isfinite(q)):
        raise RuntimeError("simulate_into_pose: newton's VBD solver diverged (non-finite particle positions); "
                           "lower ClothPoseSettings.dt or max_body_step")
    return np.split(q @ motion.heading.T, np.cumsum([len(g.vertices) for g in garments])[:-1])


def skin_into_pose(garments: Sequence[DrapedGarment], phenotype: Mapping[str, float],
                   bone_deltas: Mapping[str, np.ndarray] | None) -> list[np.ndarray]:
    """Posed vertices of each garment by the skinned path: linear-blend skinning, `push_out` on the posed body, and
    for LIFT_KINDS `lift_over_skin` (what `pose_character` does for a draped part)."""
    _check_garments(garments)
    run = run_anny(phenotype, dict(bone_deltas or {}))
    faces = body_topology().faces
    normals = vertex_normals(run["vertices"], faces)
    out = []
    rest = run_anny(phenotype)["vertices"] if any(g.kind in LIFT_KINDS for g in garments) else None
    for g in garments:
        v = skin_points(bind_loose(g, phenotype), run["bone_poses"], run["rest_bone_poses"])
        v = push_out(v, run["vertices"], normals, faces, push_clearance(g.kind))
        if g.kind in LIFT_KINDS:
            inside = skin_inside(g.vertices, g.faces, rest, vertex_normals(rest, faces))
            v = lift_over_skin(v, g.faces, inside, run["vertices"], normals, faces, push_clearance(g.kind))
        out.append(v)
    return out


def simulated_parts(character, bone_deltas: Mapping[str, np.ndarray] | None,
                    settings: ClothPoseSettings = ClothPoseSettings(), stats: dict | None = None
                    ) -> dict[str, np.ndarray]:
    """{part name: posed vertices (V, 3) float64} of a `Character`'s draped parts of `SIMULATED_KINDS`, all
    simulated together by `simulate_into_pose` (anny's posed space, before a root_transform). A part's vertices are
    copies of its draped garment's (a seam column duplicated for its UVs): each takes the simulated position of the
    garment vertex it sits on in the rest pose. `stats`: as `simulate_into_pose`'s."""
    from scipy.spatial import cKDTree

    from rh_common.body_model import load_anny
    from rh_dataset.poses.rig import rig_for

    parts = [p for p in character.parts if p.name in SIMULATED_KINDS]
    if not parts:
        return {}
    phenotype = character.phenotype
    draped = {}  # each part draped as build_character draped it: a loose top over the draped cloth under it
    for p in parts:
        draped[p.name] = drape_garment(p.name, phenotype, p.drape, over=draped_over(p.name, draped))
    garments = list(draped.values())
    posed = simulate_into_pose(garments, phenotype, bone_deltas, settings,
                               fabric=[pose_fabric(p.name, p.drape) for p in parts], stats=stats)
    rig = rig_for(load_anny(), phenotype)
    reference = rig.world_poses(np.tile(np.eye(4), (len(rig.bone_labels), 1, 1)))  # the rest (A-)pose
    out = {}
    for part, g, v in zip(parts, garments, posed):
        dist, idx = cKDTree(g.vertices).query(skin_points(part.skinning, reference, rig.rest_poses))
        if dist.max() > 1e-6:
            raise ValueError(f"cloth_pose: part {part.name!r} is not a copy of its draped garment's vertices "
                             f"({1e3 * dist.max():.3f} mm off in the rest pose); rebuild the character")
        out[part.name] = v[idx]
    return out


def self_crossings(vertices: np.ndarray, faces: np.ndarray) -> int:
    """How many edges of a cloth mesh pass through one of its own triangles (one not sharing a corner with the
    edge): trimesh rays along each edge, hits strictly inside the edge. 0 for cloth that does not pass through
    itself; a fold pushed through another fold crosses it along a line of edges."""
    return edges_through(vertices, faces)


def edges_through(vertices: np.ndarray, faces: np.ndarray, other_vertices: np.ndarray | None = None,
                  other_faces: np.ndarray | None = None) -> int:
    """How many edges of the mesh (`vertices`, `faces`) pass through a triangle of the other mesh (trimesh rays along
    each edge, hits strictly inside the edge); without another mesh, through one of its own triangles that shares
    no corner with the edge (`self_crossings`). Two surfaces that do not pass through each other: 0 both ways."""
    ray = _edge_hits(vertices, faces, other_vertices, other_faces)[0]
    return int(len(np.unique(ray)))


def crossing_points(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where a cloth mesh passes through itself (`self_crossings`' hits): (points (K, 3), the unit normals (K, 3) of
    the triangles pierced there), one per edge and triangle it passes through. For asking whether a camera sees a
    crossing (bench/bench_sleeves.py's `cross seen`)."""
    _, tri, loc, ov, of = _edge_hits(vertices, faces)
    if not len(tri):
        return np.zeros((0, 3)), np.zeros((0, 3))
    a, b, c = ov[of[tri, 0]], ov[of[tri, 1]], ov[of[tri, 2]]
    n = np.cross(b - a, c - a)
    return loc, n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-18)


def _edge_hits(vertices, faces, other_vertices=None, other_faces=None):
    """`edges_through`'s hits strictly inside the edges: (the edge of each hit (K,), the triangle hit (K,), where
    (K, 3), and the other mesh's vertices (float64) and faces)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces)
    own = other_vertices is None
    ov, of = (v, f) if own else (np.asarray(other_vertices, np.float64), np.asarray(other_faces))
    none = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), ov, of)
    e = edge_counts(f)[0]
    if not len(e) or not len(of):
        return none
    d = v[e[:, 1]] - v[e[:, 0]]
    e = e[np.linalg.norm(d, axis=1) > 0.0]  # an edge pushed to nothing (both ends onto one skin point) has no ray
    origin = v[e[:, 0]]
    d = v[e[:, 1]] - origin
    length = np.linalg.norm(d, axis=1)
    d = d / length[:, None]
    tri, ray, loc = query_mesh(ov, of).ray.intersects_id(origin, d, multiple_hits=True, return_locations=True)
    if len(ray) == 0:
        return none
    loc = np.asarray(loc, np.float64)
    t = ((loc - origin[ray]) * d[ray]).sum(1)
    inside = (t > 1e-9) & (t < length[ray] - 1e-9)
    if own:
        corners = of[tri]
        inside &= ~((corners == e[ray, :1]).any(1) | (corners == e[ray, 1:]).any(1))
    return ray[inside], tri[inside], loc[inside], ov, of


def hem_split(vertices: np.ndarray, n_around: int) -> tuple[float, float]:
    """How far a draped garment's hem (its last ring of `n_around` vertices, `DrapeSettings.n_around`) has split
    around the legs, seen from below: (pinch, deficit). pinch (metres): how deep the deepest hem vertex lies inside
    the convex hull of the hem's ground-plane (XY) projection, the hem first averaged over 1/12 of its way around
    so that the drape's own folds (a few cm, a few vertices wide) do not count; deficit in [0, 1]: 1 - the area
    the averaged hem encloses / its hull's. A hem wrapped round each leg like a trouser leg folds back between the
    legs (deep pinch, large deficit); one piece of cloth round both legs is near convex."""
    from scipy.spatial import ConvexHull

    hem = np.asarray(vertices, np.float64)[-int(n_around):, :2]
    k = max(1, int(n_around) // 12)
    hem = np.mean([np.roll(hem, i, axis=0) for i in range(-(k // 2), k - k // 2)], axis=0)
    hull = ConvexHull(hem)
    eq = hull.equations  # a x + b y + c <= 0 inside, (a, b) unit
    depth = -(hem @ eq[:, :2].T + eq[:, 2]).max(1)
    x, y = hem[:, 0], hem[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    return float(depth.max()), float(1.0 - area / hull.volume)


def covers(vertices: np.ndarray, faces: np.ndarray, skin: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(P,) bool: does the cloth (`vertices`, `faces`) lie over each skin point, i.e. does the ray out along the
    skin's normal (`normals`, unit, outward), from 1 mm off the skin, meet it (trimesh)? Taken over the skin a
    garment covers in the rest pose, the share still covered in a pose: a thigh that rose out through its trouser
    leg is bare."""
    n = np.asarray(normals, np.float64)
    origin = np.asarray(skin, np.float64) + 1e-3 * n
    return query_mesh(vertices, faces).ray.intersects_any(origin, n)


def layer_depth(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, near: float = 0.02) -> np.ndarray:
    """Depth (metres, > 0 under it) of `points` (an outer layer's vertices) under a garment surface (`vertices`,
    `faces`, outward), as `drape.penetration` measures cloth under the skin: the distance to the closest surface
    point signed by the surface's interpolated normals. NaN for points farther than `near` from the surface, and
    for points whose closest surface point is on the surface's open edge (a hem, a cuff, a sheet's edge): beyond an
    edge the side a point is on says nothing about whether it is under the cloth."""
    return _layer_closest(points, _surface(vertices, faces), near)[0]


RIM_TOLERANCE = 1e-6  # metres: a closest surface point this near an open edge is on it (`_layer_closest`)


@dataclasses.dataclass(frozen=True)
class _Surface:
    """A garment surface prepared once for `_layer_closest`'s queries: its vertices (float64), faces and vertex
    normals (`mesh.vertex_normals`), the trimesh whose search tree answers them (`geometry.query_mesh`), and its
    open edges as segments (start `rim_a`, start-to-end `rim_d`, (R, 3)) with a k-d tree of their midpoints and
    their longest half length. Why: the pushes query the same surface two rounds, and `push_over_layers` the same
    layers every cycle; building the tree and finding the open edges (a sort of every edge) each time, and measuring
    every closest point against every open edge, cost 0.11-0.15 of a loose subject's posing (docs/TRADEOFFS.md, "The
    layers' surfaces, prepared once")."""
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    mesh: object
    rim_a: np.ndarray
    rim_d: np.ndarray
    rim_tree: object
    rim_reach: float


def _surface(vertices: np.ndarray, faces: np.ndarray) -> _Surface:
    """`_Surface` of (`vertices`, `faces`)."""
    from scipy.spatial import cKDTree

    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces)
    edges, counts = edge_counts(f)
    rim = edges[counts == 1]
    a, d = v[rim[:, 0]], v[rim[:, 1]] - v[rim[:, 0]]
    tree = cKDTree(a + 0.5 * d) if len(rim) else None
    reach = float(0.5 * np.linalg.norm(d, axis=1).max()) if len(rim) else 0.0
    return _Surface(v, f, vertex_normals(v, f), query_mesh(v, f), a, d, tree, reach)


def _layer_closest(points, surface: _Surface, near: float, triangles: bool = False):
    """`layer_depth`'s (depth, closest surface points (P, 3), unit interpolated normals there (P, 3)) on `surface`
    (`_surface`), and with `triangles` the faces the closest points lie on (P,) as a fourth."""
    from .drape import closest_on_surface

    v, a, d = surface.vertices, surface.rim_a, surface.rim_d
    depth, closest, normal, tri = closest_on_surface(v, surface.faces, points, surface.normals, surface.mesh,
                                                     triangles=True)
    on_rim = np.zeros(len(closest), bool)
    if len(a):
        # A closest point can lie on an open edge only within the longest half edge (and the tolerance) of that
        # edge's midpoint: only those (point, edge) pairs are measured, each as every pair was before (the same
        # arithmetic, so the same bits), not every point near some edge against every open edge.
        reach = surface.rim_reach + 2 * RIM_TOLERANCE
        gap = surface.rim_tree.query(closest, distance_upper_bound=reach)[0]
        cand = np.flatnonzero(np.isfinite(gap))
        if len(cand):
            lists = surface.rim_tree.query_ball_point(closest[cand], reach)
            counts = np.fromiter(map(len, lists), np.int64, len(lists))
            edge = np.fromiter(itertools.chain.from_iterable(lists), np.int64, int(counts.sum()))
            row = np.repeat(cand, counts)
            c, ea, ed = closest[row], a[edge], d[edge]
            t = np.clip(((c - ea) * ed).sum(-1) / np.maximum((ed * ed).sum(-1), 1e-18), 0.0, 1.0)
            on_rim[row[np.linalg.norm(c - (ea + t[:, None] * ed), axis=-1) < RIM_TOLERANCE]] = True
    far = np.linalg.norm(np.asarray(points, np.float64) - closest, axis=1) > near
    depth = np.where(far | on_rim, np.nan, depth)
    return (depth, closest, normal, tri) if triangles else (depth, closest, normal)


LAYER_REACH = 0.03  # metres: how far under an inner garment `push_over` looks for an outer layer's points


def push_over(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, clearance: float,
              near: float = LAYER_REACH, rounds: int = 2) -> np.ndarray:
    """An outer layer's points moved out over an inner garment's surface (`vertices`, `faces`, outward): those under
    it or closer than `clearance` above it (`layer_depth`, within `near`, not beyond its open edges) go to their
    closest surface point plus `clearance` along its interpolated normal there, as `drape.push_out` does with the
    skin; the points it moved are looked at again, `rounds` times in all (a point moved off one fold of a creased
    skirt can land under the next). For a loose top over draped cloth (`drape.DRAPED_OVER`), after push_out: each
    layer is skinned on its own, and where a thigh swings, the skirt and the top over it can pass through each
    other."""
    return _push_over(points, _surface(vertices, faces), clearance, near, rounds)


def _push_over(points: np.ndarray, surface: _Surface, clearance: float, near: float = LAYER_REACH,
               rounds: int = 2) -> np.ndarray:
    """`push_over` on a prepared surface (`_surface`)."""
    p = np.array(points, dtype=np.float64)
    todo = np.arange(len(p))
    for _ in range(int(rounds)):
        if not len(todo):
            break
        depth, closest, normal = _layer_closest(p[todo], surface, near)
        bad = np.isfinite(depth) & (depth > -clearance + 1e-6)
        todo = todo[bad]
        p[todo] = closest[bad] + clearance * normal[bad]
    return p


def push_under(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, gap: float, near: float = LAYER_REACH,
               rounds: int = 2, below: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """An inner layer's points put back under an outer garment's surface (`vertices`, `faces`, outward): those above
    it (`layer_depth` < 0, within `near`, not beyond its open edges) go to their closest surface point and `gap`
    under it along its interpolated normal; the moved points are looked at again, `rounds` times in all. Returns
    (the points, the indices moved). For the coat's shell under its draped panels: the two are posed apart (the shell
    anchored to the skin, the panels skinned and pushed out of it), and where an arm presses a panel against the
    trunk the shell came out through it (bench/bench_coat_shell.py --poses). `below` (P,): a point moves only where
    its depth is also less than this (`tuck_skin`: skin out farther than at rest)."""
    p = np.array(points, dtype=np.float64)
    v = np.asarray(vertices, np.float64)
    if below is not None and np.shape(below) != (len(p),):
        raise ValueError(f"push_under: below must be ({len(p)},), got {np.shape(below)}")
    # Only points within `near` of the garment's box can be under it (the shoulders above a coat's ring are not).
    todo = (np.flatnonzero(np.all((p >= v.min(0) - near) & (p <= v.max(0) + near), axis=1)) if len(v)
            else np.zeros(0, np.int64))
    moved = []
    surface = _surface(v, faces) if len(todo) else None
    for _ in range(int(rounds)):
        if not len(todo):
            break
        depth, closest, normal = _layer_closest(p[todo], surface, near)
        bad = np.isfinite(depth) & (depth < 0.0)
        if below is not None:
            bad &= depth < below[todo]
        todo = todo[bad]
        p[todo] = closest[bad] - gap * normal[bad]
        moved.append(todo)
    return p, (np.unique(np.concatenate(moved)) if moved else np.zeros(0, np.int64))


LAYER_CYCLES = 2  # passes over the inner layers in turn, for an outer layer over two draped cloths
# Passes at most, while a point is left more than LAYER_TOLERANCE (metres) under an inner layer after LAYER_CYCLES:
# an open jacket over a loose long sleeve over wide trousers, sitting (pool recipe 4 of seed 0, its third test pose),
# kept 10 vertices under the trousers after two passes, one 29.7 mm deep, and 5, at most 2.1 mm, after four; at
# most six did no better there and cost 40 % more (bench/bench_cloth_layers.py --pool --max-passes; ARCHITECTURE).
LAYER_CYCLES_MAX = 4
LAYER_TOLERANCE = 0.001


def push_over_layers(points: np.ndarray, layers: list[tuple[np.ndarray, np.ndarray]], clearance: float,
                     cycles: int = LAYER_CYCLES, max_cycles: int = LAYER_CYCLES_MAX) -> np.ndarray:
    """An outer layer's points pushed out over each inner draped cloth in `layers` ((vertices, faces), innermost
    first) with `push_over`. Over one layer, one push. Over two (a jacket over a loose top over a skirt), the pushes
    go round `cycles` times: where the thigh swings, the skirt and the top over it cross, and a point pushed out
    over the top can land under the skirt (subject 26 of seed 0, its `random` test pose: one pass left 1 vertex
    3.1 mm under the skirt and 1 vertex 3.4 mm under the top; two passes, none deeper than 1 mm). Then, while a
    point still lies more than LAYER_TOLERANCE under a layer, another pass, up to `max_cycles` in all: where nothing
    is left under after `cycles`, the result is that of `cycles` passes, bit for bit."""
    p = np.asarray(points, np.float64)
    if len(layers) < 2:
        return push_over(p, *layers[0], clearance) if layers else p.copy()
    p = p.copy()
    moved = np.ones(len(p), bool)
    surfaces = [_surface(v, f) for v, f in layers]
    for done in range(int(max(cycles, max_cycles))):
        # A point the last pass did not move was found clear of every layer where it still lies (the layers stay
        # where they are): no push can move it again, and it cannot be left under one. So each pass looks only at
        # the points the pass before moved (the first at all of them): the same bits as pushing every point every
        # pass (`push_over` treats each point on its own), for a fraction of the closest-point queries.
        if done >= cycles and (not moved.any() or not _under_a_layer(p[moved], surfaces)):
            break
        at = np.flatnonzero(moved)
        moved[:] = False
        for surface in surfaces:
            q = _push_over(p[at], surface, clearance)
            moved[at[np.any(q != p[at], axis=1)]] = True
            p[at] = q
    return p


def _under_a_layer(points: np.ndarray, surfaces: list[_Surface]) -> bool:
    """Does any point lie more than LAYER_TOLERANCE under one of the layers' `surfaces` (`layer_depth`, within
    LAYER_REACH)?"""
    for surface in surfaces:
        d = _layer_closest(points, surface, LAYER_REACH)[0]
        if np.any(np.nan_to_num(d, nan=-1.0) > LAYER_TOLERANCE):
            return True
    return False


# Skin that came out through draped cloth in a pose (bench/bench_cloth_pose.py's `through` and `seen`): the cloth's
# triangles are ~2 cm across, the skin's ~1 cm, and where a knee bends or a thigh lifts the skin bulges between the
# cloth's vertices, which push_out has put `push_clearance` off the skin, or the skinned cloth cuts across a limb.
# `lift_over_skin` lifts the cloth there. Applied to the kinds below (pose_character, after push_out, in both cloth
# modes), chosen by bench/bench_cloth_pose.py with and without --no-lift (--lift-all for the others; docs/TRADEOFFS.md,
# "Skin through draped cloth, lifted"), skin vertices a camera sees through the cloth over 6 posed frames, skinned:
# the dress 37 -> 3, the wide trousers 57 -> 10 (simulated 22 -> 0). Not the open coat (36 -> 37, with more skin
# through and more of the cloth through itself) or the jacket (1 -> 1); the loose tops let none be seen. Not the skirt
# either (6 -> 0): a loose top and an open jacket can be worn over it, and where the lifted skirt crossed itself a
# jacket vertex stayed 4.8 mm under it after push_over_layers (tests/test_drape_jacket.py, subject 26's `random`
# pose; 4.3 mm after 5 cycles). (Those counts predate taking the lifted skin from the pushed-out rest cloth,
# garments.build_garments, 5 December; the straight trousers' 29 seen went to 1 with it; remeasured, the dress's
# stayed 3, the wide trousers' 13 -> 14 and the shorts' 2 -> 1: docs/TRADEOFFS.md.)
LIFT_KINDS = ("draped_dress", "draped_trousers", "draped_shorts", "draped_straight_trousers")
# Metres: how far under the cloth `lift_over_skin` leaves the skin it lifts the cloth over. Only skin out through
# the cloth is lifted over: lifting also skin less than this under it moved 24 vertices of benchmark subject 0's dress
# by up to 0.5 mm at rest, and changed its turntable frames' images.
LIFT_GAP = 0.002
# Skin farther out through the cloth than this is not lifted over: there the cloth lies across a limb that swung
# through it, and a lift as large tears the fold pattern. bench/bench_cloth_lift.py --reaches 0.008 0.015 0.025 (the
# test body's leg in 4 seated poses, 4 December): bare skin through the trousers 77 / 54 / 120 (unlifted 222).
LIFT_REACH = 0.015
LIFT_SLOPE = 0.5  # metres of lift lost per metre of cloth away from a lifted triangle: the lift fades over ~1 edge
LIFT_SPREAD = 4  # edges the fade runs over at most
LIFT_ROUNDS = 2  # lift, look again (a lifted triangle can leave the skin under its neighbour), lift
LIFT_WAYS = ("bisector", "skin", "cloth")  # the directions `lift_over_skin` can move cloth in (the first is used)
INSIDE_NEAR = 0.1  # metres: skin deeper than this inside the cloth at rest is not `skin_inside` it


def skin_inside(vertices: np.ndarray, faces: np.ndarray, body_vertices: np.ndarray,
                body_normals: np.ndarray) -> np.ndarray:
    """Indices (int64, ascending) of the body vertices inside a draped garment (`vertices`, `faces`, outward) in the
    rest pose: the cloth lies over them (`covers`) and they lie under its surface (`layer_depth` > 0 within
    INSIDE_NEAR). A hand hanging beside a skirt is covered by the skirt seen along its normal, but not inside it.
    The skin `lift_over_skin` lifts the cloth over and `tuck_skin` tucks back under it in a pose, and what
    bench/bench_cloth_pose.py counts through."""
    body = np.asarray(body_vertices, np.float64)
    under = np.flatnonzero(covers(vertices, faces, body, body_normals))
    depth = layer_depth(body[under], vertices, faces, near=INSIDE_NEAR)
    return under[np.isfinite(depth) & (depth > 0)].astype(np.int64)


# Skin still out through draped cloth after the lift: beyond its reach (the seat of a forward bend, 16 mm out at the
# median), or bulging between the cloth's vertices (the skin's triangles ~1 cm, the cloth's ~2 cm). `tuck_skin`
# puts the body's render mesh back under the cloth there, TUCK_DEPTH deep, as the layers are tucked under each other
# (`push_under`). Only the render mesh moves, and only skin a garment covers at rest that is out through its cloth,
# and farther out than at rest: no camera should see it (the cloth is in front), the frame's pose, fits and exports
# keep anny's body, and a rest-pose frame keeps its bits. Chosen by bench/skin_seen.py (seed 0's subjects 14, 18, 9,
# 0, 1; 3 test poses each, 4 views, 512x512; pixels where a quarter of the samples saw skin that came out through
# the cloth; `--tuck-depth`): 938 untucked; tucked 2 mm under, 357; 6 mm, 278; 12 mm, 232 (subject 18's bend
# 692 -> 16); 20 mm, 246. Tucking also the skin that came nearer the cloth though still under it (a scratch
# prototype, not kept) moved skin a camera sees through a hem: a sitting dress's inner thighs. What is left is skin
# seen through gaps where the skinned cloth folds through itself (subject 14's `random` pose) and at a dress's hem
# sitting: no tuck reaches it.
TUCK_DEPTH = 0.012  # metres under the cloth that tucked skin is put
TUCK_REACH = 0.04  # metres: skin farther out than this is left (a limb beside the cloth, or swung across it)
TUCK_TOLERANCE = 0.001  # metres farther out than at rest before skin counts as having come out
TUCK_ROUNDS = 2  # tuck, look again (skin tucked under one fold can lie out of the next), tuck


def tuck_skin(skin: np.ndarray, rest_depth: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
              depth: float = TUCK_DEPTH, reach: float = TUCK_REACH, tolerance: float = TUCK_TOLERANCE,
              rounds: int = TUCK_ROUNDS) -> tuple[np.ndarray, np.ndarray]:
    """Skin points inside a draped garment (`skin` (N, 3): its `skin_inside` vertices, posed, with their depths
    under the cloth at rest `rest_depth` (N,)) put back `depth` under the garment's posed surface (`vertices`,
    `faces`, outward) where they lie out through it (`layer_depth` < 0 within `reach`, not beyond its open edges) and
    more than `tolerance` farther out than at rest; the moved points are looked at again, `rounds` times in all.
    Returns (the points, the indices moved); points not moved keep their bits. In the rest pose nothing has come
    out, so nothing moves. `push_under` with a bound per point."""
    rest = np.asarray(rest_depth, np.float64)
    if rest.shape != (len(skin),):
        raise ValueError(f"tuck_skin: rest_depth must be ({len(skin)},), got {rest.shape}")
    return push_under(skin, vertices, faces, depth, near=reach, rounds=rounds, below=rest - tolerance)


# The "auto" cloth mode (`pose_character`): skin still out through skinned cloth after the lift and the tuck, where
# a limb was carried through it (a leg raised through an open coat, which no lift or tuck reaches) or the skinned
# cloth folded through itself. Counted within SKIN_OUT_REACH of the cloth (farther: a limb beside it), as
# bench/bench_cloth_pose.py counts skin through. A frame with more than SIMULATE_ABOVE such vertices is simulated.
# Chosen by bench/skin_seen.py --cloth auto over seed 0's 49 subjects, rest and 3 test poses (docs/TRADEOFFS.md,
# "Simulated where skinning fails"): three posed frames of 147 stand apart (96, 94, 90: a leg raised through subject
# 25's open coat, a thigh into subject 27's skirt), the next 59 and below (sits, whose skin shows under a hem);
# simulated, the three leave 10-31 and show 512 / 271 / 55 -> 0 / 0 / 4 pixels of skin through the cloth, for
# 25-40 s a frame. Over 20 test poses a subject there is no gap: 24 of 980 posed frames are over 75 (2.4 %, up to
# 121: sits, `random` poses, bends), ~+10 % on the benchmark. Counted over the kinds the simulation poses
# (SIMULATED_KINDS, `character.skin_out_count`): skin out through the draped sleeves, skinned in every mode, would
# stay out simulated (8 crossed-arms frames were simulated for it before).
SKIN_OUT_REACH = 0.03  # metres
SIMULATE_ABOVE = 75  # body vertices

# The "auto" mode's second trigger: skirts and dresses that skinning stretches. Skinned, each cloth vertex follows its
# nearest body point's bones, so the cloth between the legs is carried apart with the thighs: in a sitting or bending
# frame the skirt is pulled taut from knee to knee (and over the seat), where fabric, which gives a few per cent,
# would hang between the knees and ride up. Measured as the share of a part's edges longer than 1 + STRETCH_LIMIT
# times their draped length (its skinning bind; 0 edges past it at rest). bench/skin_seen.py --cloth auto prints it
# per frame (docs/TRADEOFFS.md, "Stretched skirts simulated"): skinned, seed 0's skirts and dresses have 8-19 % of their
# edges past 20 % in sits, bends and `random` poses, 0-2 % standing, walking or reaching; simulated, the same frames
# keep 0-2.5 %. A frame with more than STRETCHED_ABOVE is simulated: mostly sits, the pose whose missing sag between
# the knees shows most. Other kinds are not weighed yet. Measured (`skin_seen.py --stretch-by-kind`, docs/TRADEOFFS.md,
# "The other draped kinds weighed"): shorts, trousers and the open coat stretch in sits as skirts do and relax as
# much simulated (the straight-leg trousers least, 16 -> 12 %); tops, jackets and the hoodie stay under the threshold.
STRETCH_LIMIT = 0.2  # an edge 20 % longer than draped
STRETCH_KINDS = ("draped_skirt", "draped_dress")
STRETCHED_ABOVE = 0.14  # share of a part's edges


def skin_out(skin: np.ndarray, vertices: np.ndarray, faces: np.ndarray, rest_depth: np.ndarray | None = None,
             reach: float = SKIN_OUT_REACH, tolerance: float = TUCK_TOLERANCE) -> np.ndarray:
    """(N,) bool: which skin points (`skin` (N, 3): a draped garment's `covered_skin`, posed) lie out through the
    garment's posed surface (`vertices`, `faces`, outward): `layer_depth` < 0 within `reach`, not beyond an open
    edge; with `rest_depth` (N,) (a lifted part's `inside_depth`: its skin's depths under the cloth as posed at rest,
    where a layer over it can leave a few out) only those also more than `tolerance` farther out than at rest, as
    `tuck_skin` counts them."""
    d = layer_depth(np.asarray(skin, np.float64), np.asarray(vertices, np.float64), faces, near=reach)
    out = np.isfinite(d) & (d < 0.0)
    if rest_depth is not None:
        out &= d < np.asarray(rest_depth, np.float64) - tolerance
    return out


def overstretched(bind: np.ndarray, posed: np.ndarray, faces: np.ndarray, limit: float = STRETCH_LIMIT) -> float:
    """The share of a cloth's edges (those of `faces`, each counted once) longer in `posed` than 1 + `limit` times
    their length in `bind` ((V, 3) each, the same vertices: a draped part's skinning bind and its posed vertices);
    0 for an empty mesh. Rigid motions keep it: only lengths are compared."""
    edges = edge_counts(faces)[0]
    if not len(edges):
        return 0.0
    b, p = np.asarray(bind, np.float64), np.asarray(posed, np.float64)
    if b.shape != p.shape or b.ndim != 2 or b.shape[1] != 3:
        raise ValueError(f"overstretched: bind and posed must be the same (V, 3), got {b.shape} and {p.shape}")
    rest = np.linalg.norm(b[edges[:, 0]] - b[edges[:, 1]], axis=1)
    now = np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1)
    return float(np.mean(now > (1.0 + limit) * rest))


def _largest_per(keys: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Index of the largest value for each distinct key (ties: the later index), in order of the keys."""
    order = np.lexsort((np.arange(len(keys)), values, keys))
    k = keys[order]
    return order[np.r_[k[1:] != k[:-1], True]]


def lift_over_skin(points: np.ndarray, faces: np.ndarray, inside: np.ndarray, body_vertices: np.ndarray,
                   body_normals: np.ndarray, body_faces: np.ndarray, clearance: float, gap: float = LIFT_GAP,
                   reach: float = LIFT_REACH, rounds: int = LIFT_ROUNDS, way: str = "bisector") -> np.ndarray:
    """A draped garment's posed points (`points`, `faces`, outward) lifted where skin that lies inside it at rest
    (`inside`: `skin_inside`'s body vertex indices) came out through it, by at most `reach`: the cloth triangle
    closest to each such skin vertex moves out (`way`, LIFT_WAYS: along the bisector of the skin's and the cloth's
    normals, or either alone) until the skin lies `gap` under it, and its neighbours follow, the lift fading by
    LIFT_SLOPE per metre of cloth over at most LIFT_SPREAD edges. Skin under the cloth, however close, is left (in
    the rest pose all of `inside` is, so a rest-pose frame keeps its bits), and so is skin inside the body itself (a
    calf pressed into a thigh behind a bent knee: the ray out along its normal crosses the body's surface an odd
    number of times; trimesh): no camera sees it, and lifting the cloth over it would puff the fabric out over the
    other limb. Vertices at the same position (a seam's duplicated column) move together. The moved points are then
    pushed out of the skin again at `clearance` (`drape.push_out`, as the caller pushed them before: a lift can carry
    cloth into another limb); the others are returned bit for bit."""
    from .drape import closest_on_surface

    if way not in LIFT_WAYS:
        raise ValueError(f"lift_over_skin: way must be one of {LIFT_WAYS}, got {way!r}")
    p = np.asarray(points, np.float64)
    inside = np.asarray(inside, np.int64)
    if not len(p) or not len(inside):
        return p.copy()
    v, weld = unique_rows(p)
    f = weld[np.asarray(faces)]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    skin = np.asarray(body_vertices, np.float64)[inside]
    skin_n = np.asarray(body_normals, np.float64)[inside]
    near = np.all((skin >= v.min(0) - reach) & (skin <= v.max(0) + reach), axis=1)
    skin, skin_n = skin[near], skin_n[near]
    edges = edge_counts(f)[0]
    src, dst = np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]]
    body = None
    for _ in range(int(rounds)):
        if not len(skin):
            break
        # The closest cloth points of all the skin, then the open-edge test (`layer_depth`'s) for the few near it,
        # both on the one search tree.
        surface = _surface(v, f)
        depth, closest, _ = closest_on_surface(v, f, skin, surface.normals, surface.mesh)
        sel = np.flatnonzero((depth < 0.0) & (np.linalg.norm(skin - closest, axis=1) <= reach))
        if len(sel):
            depth, _, normal, tri = _layer_closest(skin[sel], surface, reach, triangles=True)
            keep = np.isfinite(depth) & (depth < 0.0)
            sel, depth, normal, tri = sel[keep], depth[keep], normal[keep], tri[keep]
        if not len(sel):
            break
        if body is None:
            body = query_mesh(body_vertices, body_faces)
        hit = body.ray.intersects_location(skin[sel] + 1e-3 * skin_n[sel], skin_n[sel], multiple_hits=True)[1]
        inner = np.flatnonzero(np.bincount(hit, minlength=len(sel)) % 2 == 0)
        if not len(inner):
            break
        # Along the bisector of the skin's normal and the cloth's (bench/bench_cloth_lift.py): along the cloth's
        # normal, which in a bend leans along the fold, the lift slid the cloth off other skin; along the skin's, a
        # skirt hanging over a raised thigh was lifted up rather than out.
        skin_way = skin_n[sel[inner]]
        out_n = {"skin": skin_way, "cloth": normal[inner], "bisector": skin_way + normal[inner]}[way]
        size = np.linalg.norm(out_n, axis=1, keepdims=True)
        out_n = np.where(size > 1e-6, out_n / np.maximum(size, 1e-12), skin_way)
        lean = np.maximum((out_n * normal[inner]).sum(1), 0.5)
        corner = f[tri[inner]].ravel()
        need = np.repeat((gap - depth[inner]) / lean, 3)
        heading = np.repeat(out_n, 3, axis=0)
        win = _largest_per(corner, need)
        lift = np.zeros(len(v))
        along = np.zeros_like(v)
        lift[corner[win]] = need[win]
        along[corner[win]] = heading[win]
        fade = LIFT_SLOPE * np.linalg.norm(v[src] - v[dst], axis=1)
        for _ in range(LIFT_SPREAD):
            reached = lift[src] - fade
            more = np.flatnonzero(reached > lift[dst])
            if not len(more):
                break
            win = more[_largest_per(dst[more], reached[more])]
            lift[dst[win]] = reached[win]
            along[dst[win]] = along[src[win]]
        v = v + lift[:, None] * along
    out = v[weld]
    moved = np.flatnonzero(np.any(out != p, axis=1))
    if len(moved):
        out[moved] = push_out(out[moved], body_vertices, body_normals, body_faces, clearance)
    return out
