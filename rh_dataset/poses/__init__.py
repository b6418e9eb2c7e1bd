"""Body poses on anny's rig: the protocol-A turntable and a procedural pose prior (see ARCHITECTURE.md)."""
from .collision import DEPTH_TOL_M, MIN_POINTS, Intersection, find_intersections, intersects
from .joints import JointSpec, joint_specs
from .pose import ANNY_BONE_LABELS, POSE_LABELS, BodyPose, rotation_about_z, turntable
from .prior import ARCHETYPE_WEIGHTS, pose_from_angles, propose_pose, sample_pose, sample_poses
from .rig import Rig, rig_for

__all__ = [
    "ANNY_BONE_LABELS", "ARCHETYPE_WEIGHTS", "BodyPose", "DEPTH_TOL_M", "Intersection", "JointSpec", "MIN_POINTS",
    "POSE_LABELS", "Rig", "find_intersections", "intersects", "joint_specs", "pose_from_angles", "propose_pose",
    "rig_for", "rotation_about_z", "sample_pose", "sample_poses", "turntable",
]
