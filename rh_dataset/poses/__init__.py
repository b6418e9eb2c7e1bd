"""Body poses on anny's rig: the protocol-A turntable and a procedural pose prior (see ARCHITECTURE.md)."""
from .collision import DEPTH_TOL_M, MIN_POINTS, Intersection, find_intersections, intersects
from .joints import JointSpec, joint_specs
from .motion import Motion, MotionError, read_motion
from .pose import ANNY_BONE_LABELS, POSE_LABELS, BodyPose, rotation_about_z, turntable
from .prior import ARCHETYPE_WEIGHTS, pose_from_angles, propose_pose, sample_pose, sample_poses
from .retarget import CMU_TO_ANNY, MIXAMO_TO_ANNY, anny_skeleton, guess_bone_map, motion_to_anny, retarget
from .rig import Rig, rig_for
from .skeleton import Skeleton, SkeletonPose

__all__ = [
    "ANNY_BONE_LABELS", "ARCHETYPE_WEIGHTS", "BodyPose", "CMU_TO_ANNY", "DEPTH_TOL_M", "Intersection", "JointSpec",
    "MIN_POINTS", "MIXAMO_TO_ANNY", "Motion", "MotionError", "POSE_LABELS", "Rig", "Skeleton", "SkeletonPose",
    "anny_skeleton", "find_intersections", "guess_bone_map", "intersects", "joint_specs", "motion_to_anny",
    "pose_from_angles", "propose_pose", "read_motion", "retarget", "rig_for", "rotation_about_z", "sample_pose",
    "sample_poses", "turntable",
]
