"""Motion files (rh_dataset.poses.motion), retargeting (rh_dataset.poses.retarget) and motion-driven generation.

Every BVH here is written by the test itself, with known channel values; reading goes through Blender's importer.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rh_common.body_model import load_anny
from rh_dataset.poses import BodyPose, sample_pose
from rh_dataset.poses.motion import Motion, MotionError, read_motion
from rh_dataset.poses.retarget import CMU_TO_ANNY, MIXAMO_TO_ANNY, anny_skeleton, guess_bone_map, motion_to_anny, \
    retarget
from rh_dataset.poses.rig import rig_for
from rh_dataset.poses.skeleton import Skeleton, posed_heads, posed_rotations

# A CMU-named T-pose skeleton in centimetres, BVH axes (Y up, facing +Z, the character's left = +X).
CMU_JOINTS = [
    ("Hips", None, (0, 0, 0)),
    ("LHipJoint", "Hips", (0, 0, 0)), ("LeftUpLeg", "LHipJoint", (9, -5, 0)), ("LeftLeg", "LeftUpLeg", (0, -42, 0)),
    ("LeftFoot", "LeftLeg", (0, -40, 0)), ("LeftToeBase", "LeftFoot", (0, -6, 12)),
    ("RHipJoint", "Hips", (0, 0, 0)), ("RightUpLeg", "RHipJoint", (-9, -5, 0)),
    ("RightLeg", "RightUpLeg", (0, -42, 0)), ("RightFoot", "RightLeg", (0, -40, 0)),
    ("RightToeBase", "RightFoot", (0, -6, 12)),
    ("LowerBack", "Hips", (0, 8, 0)), ("Spine", "LowerBack", (0, 14, 0)), ("Spine1", "Spine", (0, 14, 0)),
    ("Neck", "Spine1", (0, 14, 0)), ("Neck1", "Neck", (0, 5, 0)), ("Head", "Neck1", (0, 5, 0)),
    ("LeftShoulder", "Spine1", (2, 11, 0)), ("LeftArm", "LeftShoulder", (15, 0, 0)),
    ("LeftForeArm", "LeftArm", (28, 0, 0)), ("LeftHand", "LeftForeArm", (25, 0, 0)),
    ("RightShoulder", "Spine1", (-2, 11, 0)), ("RightArm", "RightShoulder", (-15, 0, 0)),
    ("RightForeArm", "RightArm", (-28, 0, 0)), ("RightHand", "RightForeArm", (-25, 0, 0)),
]
CMU_ENDS = {"LeftToeBase": (0, 0, 5), "RightToeBase": (0, 0, 5), "Head": (0, 18, 0), "LeftHand": (8, 0, 0),
            "RightHand": (-8, 0, 0)}
# Frames: rest; left knee bent 90°; left arm raised straight up (+90° about the BVH's Z, i.e. towards +Y = up);
# the root lowered by 10 cm and moved 5 cm sideways, and turned 90° about the vertical.
CMU_FRAMES = [{}, {"LeftLeg": (0, 0, 90)}, {"LeftArm": (90, 0, 0)},
              {"_root": (5, 80, 3), "Hips": (0, 90, 0)}]


def write_bvh(path: Path, joints, ends, frames, frame_time=1 / 30) -> Path:
    """joints: (name, parent, offset in the parent); frames: dicts name -> (Zrot, Yrot, Xrot) degrees, '_root' ->
    root position (default 90 up). Channels in CMU's order."""
    kids: dict = {}
    for name, parent, _ in joints:
        kids.setdefault(parent, []).append(name)
    offset = {name: o for name, _, o in joints}
    lines, order = ["HIERARCHY"], []

    def emit(name, depth):
        ind = "  " * depth
        lines.extend([f"{ind}{'ROOT' if depth == 0 else 'JOINT'} {name}", f"{ind}{{",
                      f"{ind}  OFFSET {' '.join(f'{v:.6f}' for v in offset[name])}",
                      f"{ind}  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation" if depth == 0
                      else f"{ind}  CHANNELS 3 Zrotation Yrotation Xrotation"])
        order.append(name)
        for k in kids.get(name, []):
            emit(k, depth + 1)
        if name in ends:
            lines.extend([f"{ind}  End Site", f"{ind}  {{",
                          f"{ind}    OFFSET {' '.join(f'{v:.6f}' for v in ends[name])}", f"{ind}  }}"])
        lines.append(f"{ind}}}")

    emit(joints[0][0], 0)
    lines += ["MOTION", f"Frames: {len(frames)}", f"Frame Time: {frame_time:.6f}"]
    for fr in frames:
        values = []
        for name in order:
            if name == joints[0][0]:
                values += list(fr.get("_root", (0, 90, 0)))
            values += list(fr.get(name, (0, 0, 0)))
        lines.append(" ".join(f"{v:.6f}" for v in values))
    path.write_text("\n".join(lines) + "\n")
    return path


def _rot(axis, deg):
    a = np.radians(deg)
    x, y, z = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


def _angle(a, b):
    return float(np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


@pytest.fixture(scope="module")
def cmu_motion(tmp_path_factory) -> Motion:
    return read_motion(write_bvh(tmp_path_factory.mktemp("bvh") / "cmu.bvh", CMU_JOINTS, CMU_ENDS, CMU_FRAMES))


@pytest.fixture(scope="module")
def anny_rig():
    return rig_for(load_anny())


def _anny_joints(rig, pose):
    return rig.world_poses(pose.deltas())[:, :3, 3]


# -- reading ----------------------------------------------------------------------------------------------------

def test_read_motion_gives_the_channels_rotations(cmu_motion):
    m = cmu_motion
    sk = m.skeleton
    assert len(m) == 4 and m.first_frame == 1 and m.fps == pytest.approx(30.0, rel=1e-4)
    assert sk.names[:3] == ("Hips", "LHipJoint", "LeftUpLeg") and sk.parents[sk.index["LeftLeg"]] == 2
    # 197 cm of skeleton (toe to head end) reads as centimetres; Y up becomes Z up, +Z (forward) becomes -Y.
    assert m.unit_rule == "centimetres" and m.unit_scale == 0.01
    np.testing.assert_allclose(sk.heads[sk.index["LeftLeg"]], [0.09, 0, -0.47], atol=1e-6)
    np.testing.assert_allclose(sk.heads[sk.index["LeftToeBase"]], [0.09, -0.12, -0.93], atol=1e-6)
    np.testing.assert_allclose(m.root_positions, [[0, 0, 0.9]] * 3 + [[0.05, -0.03, 0.8]], atol=1e-6)
    G = m.rotations
    moved = {1: {"LeftLeg": _rot([1, 0, 0], 90), "LeftFoot": _rot([1, 0, 0], 90), "LeftToeBase": _rot([1, 0, 0], 90)},
             2: {n: _rot([0, -1, 0], 90) for n in ("LeftArm", "LeftForeArm", "LeftHand")}}
    for f in range(3):
        for name in sk.names:
            np.testing.assert_allclose(G[f, sk.index[name]], moved.get(f, {}).get(name, np.eye(3)), atol=1e-6,
                                       err_msg=f"frame {f} bone {name}")
    np.testing.assert_allclose(G[3], np.tile(_rot([0, 0, 1], 90), (len(sk), 1, 1)), atol=1e-6)
    # Our forward kinematics of frame 1 puts the left ankle behind the knee at knee height.
    heads = m.posed_heads(1)
    np.testing.assert_allclose(heads[sk.index["LeftFoot"]], [0.09, 0.40, 0.43], atol=1e-6)


def test_missing_and_corrupt_files_name_the_file(tmp_path):
    with pytest.raises(MotionError, match="nowhere.bvh.*does not exist"):
        read_motion(tmp_path / "nowhere.bvh")
    bad = tmp_path / "broken_take.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition\n")
    with pytest.raises(MotionError, match="broken_take.bvh.*valid BVH"):
        read_motion(bad)
    junk = tmp_path / "notes.bvh"
    junk.write_text("these are not motion capture data\n")
    with pytest.raises(MotionError, match="notes.bvh"):
        read_motion(junk)
    (tmp_path / "take.txt").write_text("x")
    with pytest.raises(MotionError, match="take.txt.*unsupported type"):
        read_motion(tmp_path / "take.txt")


_GLTF_WRITER = """
import bpy, sys, math
bpy.ops.wm.read_factory_settings(use_empty=True)
arm = bpy.data.armatures.new("Rig")
ob = bpy.data.objects.new("Rig", arm)
bpy.context.collection.objects.link(ob)
bpy.context.view_layer.objects.active = ob
bpy.ops.object.mode_set(mode="EDIT")
a = arm.edit_bones.new("thigh.L"); a.head = (0.1, 0, 1.0); a.tail = (0.1, 0, 0.55)
b = arm.edit_bones.new("shin.L"); b.head = (0.1, 0, 0.55); b.tail = (0.1, 0, 0.1); b.parent = a
bpy.ops.object.mode_set(mode="POSE")
pb = ob.pose.bones["shin.L"]
pb.rotation_mode = "XYZ"
for frame, deg in ((1, 0.0), (2, 90.0)):
    pb.rotation_euler = (math.radians(deg), 0, 0)
    pb.keyframe_insert("rotation_euler", frame=frame)
bpy.ops.object.mode_set(mode="OBJECT")
bpy.ops.export_scene.gltf(filepath=sys.argv[1], export_format="GLB")
"""


def test_gltf_animation_reads_like_bvh(tmp_path):
    """A two-bone glTF leg (written here through Blender's exporter) whose knee bends 90° about +X in frame 2."""
    from rh_common.blender import run_blender_script

    script = tmp_path / "write_leg.py"
    script.write_text(_GLTF_WRITER)
    run_blender_script(script, [str(tmp_path / "leg.glb")], timeout=300, threads=1)
    m = read_motion(tmp_path / "leg.glb")
    assert m.skeleton.names == ("thigh.L", "shin.L") and len(m) == 2 and m.unit_rule == "metres"
    np.testing.assert_allclose(m.rotations[0], np.tile(np.eye(3), (2, 1, 1)), atol=1e-6)
    np.testing.assert_allclose(m.rotations[1, 1], _rot([1, 0, 0], 90), atol=1e-6)
    np.testing.assert_allclose(m.rotations[1, 0], np.eye(3), atol=1e-6)
    np.testing.assert_allclose(m.posed_heads(1), [[0.1, 0, 1.0], [0.1, 0, 0.55]], atol=1e-6)


# -- retargeting onto anny --------------------------------------------------------------------------------------

def test_cmu_map_covers_the_body_and_is_guessed(cmu_motion):
    target = anny_skeleton()
    assert guess_bone_map(cmu_motion.skeleton, target) == {k: v for k, v in CMU_TO_ANNY.items()
                                                            if k in cmu_motion.skeleton.index}
    for bone in ("root", "spine01", "head", "upperarm01.L", "lowerarm01.R", "upperleg01.L", "lowerleg01.R",
                 "foot.L"):
        assert bone in CMU_TO_ANNY.values()


def test_knee_and_arm_survive_retargeting(cmu_motion, anny_rig):
    L = anny_rig.index
    poses = motion_to_anny(cmu_motion)
    assert len(poses) == 4 and all(p.label == "motion" for p in poses)
    J = [_anny_joints(anny_rig, p) for p in poses]

    def knee(j):
        return _angle(j[L["lowerleg01.L"]] - j[L["upperleg01.L"]], j[L["foot.L"]] - j[L["lowerleg01.L"]])

    def arm_elevation(j, side="L"):  # degrees above the horizontal, shoulder -> elbow
        return 90.0 - _angle(j[L[f"lowerarm01.{side}"]] - j[L[f"upperarm01.{side}"]], np.array([0, 0, 1.0]))

    assert knee(J[0]) < 1.0 and knee(J[1]) == pytest.approx(90.0, abs=1.0)
    # The shin swings backwards (+Y: anny faces -Y), as a knee bends.
    assert (J[1][L["foot.L"]] - J[1][L["lowerleg01.L"]])[1] > 0.3
    # BVH rest is a T-pose: anny's A-pose arms come up to horizontal; frame 2 raises the left arm straight up.
    assert arm_elevation(J[0]) == pytest.approx(0.0, abs=1.0)
    assert arm_elevation(J[2]) == pytest.approx(90.0, abs=1.0)
    assert arm_elevation(J[2], "R") == pytest.approx(0.0, abs=1.0)
    # Frame 3: turned 90° about +Z, the left arm now points to +Y.
    upper = J[3][L["lowerarm01.L"]] - J[3][L["upperarm01.L"]]
    np.testing.assert_allclose(upper / np.linalg.norm(upper), [0, 1, 0], atol=0.02)
    # Standing frames stand on the clip's floor: the pelvis rises by the scaled 10 cm the root went down in frame 3.
    # Leg lengths (root above the lowest joint at rest): the BVH's toe base is 0.93 m below its root.
    scale = -anny_skeleton().heads[:, 2].min() / 0.93
    assert J[0][L["root"]][2] - J[3][L["root"]][2] == pytest.approx(0.1 * scale, abs=1e-5)


def _anny_shaped_bvh(path: Path, frames) -> Path:
    """A CMU-named BVH whose rest skeleton is anny's reference pose (metres -> cm, Z up -> BVH Y up)."""
    target = anny_skeleton()
    to_bvh = lambda v: 100.0 * np.array([v[0], v[2], -v[1]])  # noqa: E731  Blender (x, y, z) -> BVH (x, z, -y)
    parents = {n: p for n, p, _ in CMU_JOINTS}
    names = [n for n, _, _ in CMU_JOINTS if n in CMU_TO_ANNY]
    head = {n: target.heads[target.index[CMU_TO_ANNY[n]]] for n in names}
    joints = [(n, parents[n], tuple(to_bvh(head[n] - (head[parents[n]] if parents[n] else 0)))) for n in names]
    ends = {n: tuple(to_bvh(target.tails[target.index[CMU_TO_ANNY[n]]] - head[n]))
            for n in ("LeftFoot", "RightFoot", "Head", "LeftHand", "RightHand")}
    return write_bvh(path, joints, ends, frames)


def test_rest_matching_anny_gives_the_reference_pose(tmp_path, anny_rig):
    motion = read_motion(_anny_shaped_bvh(tmp_path / "anny_rest.bvh", [{}, {"LeftLeg": (0, 0, 90)}]))
    rest, bent = motion_to_anny(motion)
    reference = _anny_joints(anny_rig, BodyPose(bones={}))
    np.testing.assert_allclose(rest.deltas(), np.tile(np.eye(4), (104, 1, 1)), atol=1e-5)
    np.testing.assert_allclose(_anny_joints(anny_rig, rest), reference, atol=2e-4)
    # Only the knee's own bone moves in the second frame, by 90° about +X.
    moved = {anny_rig.bone_labels[i] for i in
             np.flatnonzero(np.abs(bent.deltas()[:, :3, :3] - np.eye(3)).max(axis=(1, 2)) > 1e-5)}
    assert moved == {"lowerleg01.L"}
    np.testing.assert_allclose(bent.bones["lowerleg01.L"][:3, :3], _rot([1, 0, 0], 90), atol=1e-5)


# -- retargeting between synthetic rigs (no Blender) -------------------------------------------------------------

def _motion_on(skeleton: Skeleton, G, roots, name="synthetic") -> Motion:
    return Motion(skeleton, G, roots, 30.0, name, "0" * 64)


def _posed_segment(skel, pose, a, b):
    h = posed_heads(skel, pose)
    return h[skel.index[b]] - h[skel.index[a]]


def test_a_rig_facing_elsewhere_drives_the_target_bone_for_bone():
    """Source = anny's rig turned 90° about +Z (facing +X), half size: its rest drives anny to the same pose turned
    90°; a bent elbow stays bent by the same angle; translations scale by the leg ratio (2)."""
    anny = anny_skeleton()
    Rz = _rot([0, 0, 1], 90)
    src = Skeleton(anny.names, anny.parents, 0.5 * anny.heads @ Rz.T, 0.5 * anny.tails @ Rz.T)
    J = len(anny)
    G = np.tile(np.eye(3), (3, J, 1, 1))
    elbow = [anny.index[n] for n in ("lowerarm01.L", "lowerarm02.L", "wrist.L")]
    G[1, elbow] = _rot(Rz @ [1, 0, 0], 40)
    roots = np.array([src.heads[0], src.heads[0] - [0, 0, 0.05], src.heads[0] + [0.3, 0, 0]])
    motion = _motion_on(src, G, roots)
    bone_map = {n: n for n in anny.names}
    poses = retarget(motion, anny, bone_map)
    np.testing.assert_allclose(posed_rotations(anny, poses[0]), np.tile(Rz, (J, 1, 1)), atol=1e-9)
    seg = lambda p: (_posed_segment(anny, p, "upperarm01.L", "lowerarm01.L"),  # noqa: E731
                     _posed_segment(anny, p, "lowerarm01.L", "wrist.L"))
    src_pose = motion.pose(1)
    want = _angle(_posed_segment(src, src_pose, "upperarm01.L", "lowerarm01.L"),
                  _posed_segment(src, src_pose, "lowerarm01.L", "wrist.L"))
    assert _angle(*seg(poses[1])) == pytest.approx(want, abs=1e-6)
    # Frame 1 (5 cm lower at half size) is the clip's floor: it stands where anny stands; the others are 10 cm up.
    np.testing.assert_allclose(poses[1].translation, 0, atol=1e-9)
    np.testing.assert_allclose(poses[0].translation, [0, 0, 0.1], atol=1e-9)
    np.testing.assert_allclose(poses[2].translation, [0, 0, 0.1], atol=1e-9)  # in place: the step is dropped
    walked = retarget(motion, anny, bone_map, in_place=False)
    np.testing.assert_allclose(walked[2].translation, [0.6, 0, 0.1], atol=1e-9)
    # heading='front' turns the body back to face -Y.
    front = retarget(motion, anny, bone_map, heading="front")
    np.testing.assert_allclose(posed_rotations(anny, front[0]), np.tile(np.eye(3), (J, 1, 1)), atol=1e-9)


def test_unmapped_bones_follow_their_parent_and_bad_maps_are_refused():
    anny = anny_skeleton()
    G = np.tile(_rot([1, 0, 0], 30), (1, len(anny), 1, 1))
    motion = _motion_on(anny, G, anny.heads[:1])
    pose, = retarget(motion, anny, {"root": "root"})
    np.testing.assert_allclose(posed_rotations(anny, pose), G[0], atol=1e-12)  # everything rides on the root
    assert np.array_equal(pose.rotations[1:], np.tile(np.eye(3), (len(anny) - 1, 1, 1)))
    with pytest.raises(MotionError, match="not in the motion"):
        retarget(motion, anny, {"Hips": "root"})
    with pytest.raises(MotionError, match="one to one"):
        retarget(motion, anny, {"root": "root", "spine05": "root"})
    with pytest.raises(MotionError, match="proper rotations"):
        _motion_on(anny, G * 1.1, anny.heads[:1])
    with pytest.raises(MotionError, match="non-finite"):
        _motion_on(anny, np.where(np.arange(len(anny))[None, :, None, None] == 3, np.nan, G), anny.heads[:1])


def test_name_heuristics_for_other_rigs():
    def chain(names):
        return Skeleton(tuple(names), np.arange(-1, len(names) - 1), np.zeros((len(names), 3)),
                        np.ones((len(names), 3)))

    mixamo = chain(["mixamorig:Hips", "mixamorig:Spine", "mixamorig:Spine1", "mixamorig:Spine2", "mixamorig:Neck",
                    "mixamorig:Head", "mixamorig:LeftUpLeg", "mixamorig:LeftLeg", "mixamorig:RightArm",
                    "mixamorig:RightForeArm"])
    got = guess_bone_map(mixamo, anny_skeleton())
    assert got["mixamorig:Spine"] == "spine04" and got["mixamorig:Spine2"] == "spine01"
    assert got["mixamorig:LeftLeg"] == "lowerleg01.L" and got["mixamorig:RightForeArm"] == "lowerarm01.R"
    assert set(got.values()) <= set(MIXAMO_TO_ANNY.values())
    other = chain(["pelvis", "spine_01", "spine_02", "spine_03", "neck_01", "head", "thigh_l", "calf_l", "foot_l",
                   "clavicle_r", "upperarm_r", "lowerarm_r", "hand_r", "index_01_r", "upper_arm.L", "forearm.L"])
    got = guess_bone_map(other, anny_skeleton())
    assert got == {"pelvis": "root", "spine_01": "spine04", "spine_02": "spine02", "spine_03": "spine01",
                   "neck_01": "neck01", "head": "head", "thigh_l": "upperleg01.L", "calf_l": "lowerleg01.L",
                   "foot_l": "foot.L", "clavicle_r": "clavicle.R", "upperarm_r": "upperarm01.R",
                   "lowerarm_r": "lowerarm01.R", "hand_r": "wrist.R", "upper_arm.L": "upperarm01.L",
                   "forearm.L": "lowerarm01.L"}


# -- scene descriptions and generation ---------------------------------------------------------------------------

def test_motion_in_scene_files_and_overrides(tmp_path):
    from rh_dataset.spec import MotionSpec, SpecError, load_protocol

    bvh = write_bvh(tmp_path / "take.bvh", CMU_JOINTS, CMU_ENDS, CMU_FRAMES)
    scene = json.loads(Path(load_protocol("demo").source).read_text())
    scene["splits"]["test"].update(poses="motion", motion={"file": "take.bvh", "stride": 1})
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    spec = load_protocol(str(tmp_path / "scene.json"))
    assert spec.split("test").motion.stride == 1 and spec.split("test").motion.file == str(bvh)
    assert spec.to_json()["splits"][1]["motion"]["name"] == "take.bvh"
    base = load_protocol("demo")
    with_motion = base.with_overrides(motion=MotionSpec.from_file(bvh))
    assert with_motion.split("test").poses == "motion" and with_motion.split("train").poses == "turntable"
    assert len({base.digest(), with_motion.digest(), spec.digest()}) == 3
    b = load_protocol("b").with_overrides(motion=MotionSpec.from_file(bvh))
    assert b.split("train").poses == "motion" and b.split("test").poses == "train"  # b keeps its same poses
    scene["splits"]["test"]["motion"]["speed"] = 2
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    with pytest.raises(SpecError, match="speed"):
        load_protocol(str(tmp_path / "scene.json"))
    with pytest.raises(SpecError, match="does not exist"):
        MotionSpec.from_file(tmp_path / "gone.bvh")


def test_generation_from_motion(tmp_path, cmu_motion):
    from rh_dataset.cli import main
    from rh_dataset.generate import rng_for

    bvh = write_bvh(tmp_path / "take.bvh", CMU_JOINTS, CMU_ENDS, CMU_FRAMES)
    out = tmp_path / "data"
    args = ["--protocol", "demo", "--out", str(out), "--resolution", "32", "--spp", "1", "--aov-spp", "1",
            "--frames", "2", "--no-progress", "--motion", str(bvh), "--motion-start", "1", "--motion-stride", "2"]
    assert main(args) == 0
    test_dir = out / "subject_000" / "protocol_a" / "test"
    character = json.loads((out / "subject_000" / "character.json").read_text())
    for i, source_frame in ((0, 1), (1, 3)):
        meta = json.loads((test_dir / f"frame_{i:06d}.json").read_text())
        rec = meta["body"]["motion"]
        assert rec["file"] == "take.bvh" and rec["frame"] == source_frame and rec["stride"] == 2
        assert rec["sha256"] == cmu_motion.sha256 and isinstance(rec["intersections"], list)
        want = motion_to_anny(cmu_motion, character["phenotype"], frames=[source_frame])[0]
        got = BodyPose.from_json(meta["body"]["pose"])
        assert got == want
        prior = sample_pose(rng_for(0, "pose", 0, "test", i), load_anny())
        assert got != prior
    # The train split (turntable) has no motion record; a rerun resumes; another stride is another dataset.
    assert "motion" not in json.loads((out / "subject_000/protocol_a/train/frame_000000.json").read_text())["body"]
    assert main(args) == 0
    assert main(args[:-1] + ["1"]) == 2
    bvh.write_text(bvh.read_text().replace("Frame Time: 0.033333", "Frame Time: 0.040000"))
    assert main(args) == 2  # the file changed: its sha256 no longer matches the dataset's
