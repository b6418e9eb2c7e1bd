"""Blender-side reader of motion files (BVH, FBX, glTF): runs inside Blender's Python only, never imported by us.

    <blender python> bpy_read_motion.py IN_FILE OUT.npz

Imports the file with Blender's own importer, bakes every frame of the armature's animation and writes plain numpy
arrays (no pickles, so bpy's numpy 1.26 and ours never meet) in Blender's world frame (Z up; BVH files are
converted from their Y-up with Blender's default forward -Z / up Y, which puts a BVH character facing +Z onto -Y,
the way anny faces):

    names (J,) str, parents (J,) int (-1 = root; parents before children),
    rest_heads, rest_tails (J, 3): the rest skeleton in world units of the file (BVH: the file's own units),
    rotations (F, J, 3, 3): G, each bone's posed world rotation relative to its rest orientation,
    posed_heads (F, J, 3): each bone's posed head (the main side checks its forward kinematics against these),
    fps (), frame_start (), frame_end () (inclusive, the file's frames as Blender numbers them), importer () str.

Fails with exit status 2 and one line on stderr that says what is wrong with the file.
"""
import os
import sys

import bpy
import numpy as np


def fail(message):
    sys.stderr.write(message.rstrip() + "\n")
    sys.exit(2)


def import_file(path):
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext == ".bvh":
            # global_scale 1: units are decided on the main side (BVH units vary: cm, inches, CMU's own).
            # update_scene_fps: one Blender frame per BVH frame, and the scene's fps is the file's.
            bpy.ops.import_anim.bvh(filepath=path, global_scale=1.0, rotate_mode="NATIVE", axis_forward="-Z",
                                    axis_up="Y", update_scene_fps=True, update_scene_duration=True,
                                    use_fps_scale=False, frame_start=1)
            return "bvh"
        if ext == ".fbx":
            bpy.ops.import_scene.fbx(filepath=path)
            return "fbx"
        if ext in (".glb", ".gltf"):
            bpy.ops.import_scene.gltf(filepath=path)
            return "gltf"
    except Exception as exc:  # the importers raise plain RuntimeErrors carrying their own message
        fail(f"Blender could not import {os.path.basename(path)} as {ext[1:].upper()}: "
             f"{str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__}")
    fail(f"{os.path.basename(path)}: unsupported motion file type {ext!r} (use .bvh, .fbx, .glb or .gltf)")


def topological(bones):
    """Bones ordered parents before children (Blender's own order is creation order, not guaranteed so)."""
    order, seen = [], set()

    def visit(b):
        if b.name in seen:
            return
        if b.parent is not None:
            visit(b.parent)
        seen.add(b.name)
        order.append(b)

    for b in bones:
        visit(b)
    return order


def rotation_part(M):
    """The rotation of a 3x3 that may carry (object) scale: the nearest orthonormal matrix, via SVD."""
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        U[:, -1] *= -1
        R = U @ Vt
    return R


def main():
    if len(sys.argv) != 3:
        fail("usage: bpy_read_motion.py IN_FILE OUT.npz")
    src, out = sys.argv[1], sys.argv[2]
    if not os.path.isfile(src):
        fail(f"{src}: no such file")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    importer = import_file(src)
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE" and len(o.data.bones)]
    if not arms:
        fail(f"{os.path.basename(src)} holds no armature (no skeleton to read motion from)")
    arm = max(arms, key=lambda o: len(o.data.bones))  # a file with props: the character has the most bones
    scene = bpy.context.scene
    action = arm.animation_data.action if arm.animation_data else None
    if action is not None:
        f0, f1 = (int(round(x)) for x in action.frame_range)
    else:  # a skeleton without animation: its rest pose as a one-frame motion
        f0 = f1 = scene.frame_current
    bones = topological(list(arm.data.bones))
    index = {b.name: i for i, b in enumerate(bones)}
    parents = np.array([index[b.parent.name] if b.parent is not None else -1 for b in bones], dtype=np.int64)
    Mw = np.array(arm.matrix_world, dtype=np.float64)
    A, t = Mw[:3, :3], Mw[:3, 3]
    heads = np.array([A @ np.array(b.head_local) + t for b in bones])
    tails = np.array([A @ np.array(b.tail_local) + t for b in bones])
    rest_R = np.array([rotation_part(A @ np.array(b.matrix_local)[:3, :3]) for b in bones])
    pbones = [arm.pose.bones[b.name] for b in bones]
    F = f1 - f0 + 1
    rotations = np.empty((F, len(bones), 3, 3))
    posed = np.empty((F, len(bones), 3))
    for k, f in enumerate(range(f0, f1 + 1)):
        scene.frame_set(f)
        for j, pb in enumerate(pbones):
            M = np.array(pb.matrix, dtype=np.float64)
            rotations[k, j] = rotation_part(A @ M[:3, :3]) @ rest_R[j].T
            posed[k, j] = A @ M[:3, 3] + t
    fps = scene.render.fps / scene.render.fps_base
    np.savez(out, names=np.array([b.name for b in bones]), parents=parents, rest_heads=heads, rest_tails=tails,
             rotations=rotations, posed_heads=posed, fps=np.array(float(fps)), frame_start=np.array(f0),
             frame_end=np.array(f1), importer=np.array(importer))


main()
