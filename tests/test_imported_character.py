"""Imported characters: a two-bone textured tube written by Blender itself, read back, posed and checked."""
from __future__ import annotations

import numpy as np
import pytest

from rh_dataset.characters.imported_model import CharacterImportError, pose_imported
from rh_dataset.characters.imported_reader import _build, read_character_file

MAKE_LIMB = r"""
# Blender side: build a two-bone skinned, UV-mapped, textured tube limb and export it (glb, fbx, gltf).
import math
import sys
from pathlib import Path

import bpy
import numpy as np

out_dir = Path(sys.argv[1])
kind = sys.argv[2] if len(sys.argv) > 2 else "skinned"
out_dir.mkdir(parents=True, exist_ok=True)
bpy.ops.wm.read_factory_settings(use_empty=True)

N_SEG, RINGS, R, H = 12, 9, 0.1, 1.6
OFFSET = (0.3, -0.2, 0.5)

# Texture: bottom half (v < 0.5) colour A, top half colour B, as 8-bit sRGB.
A, B = (40, 120, 200), (200, 60, 40)
img = bpy.data.images.new("limb_tex", 16, 16, alpha=True)
px = np.zeros((16, 16, 4), np.float32)  # Blender rows go bottom to top
px[:8, :, :3] = np.array(A) / 255.0
px[8:, :, :3] = np.array(B) / 255.0
px[..., 3] = 1.0
img.pixels.foreach_set(px.ravel())
img.filepath_raw = str(out_dir / "limb_tex.png")
img.file_format = "PNG"
img.save()

verts, faces = [], []
for r in range(RINGS):
    z = H * r / (RINGS - 1)
    for s in range(N_SEG):
        a = 2 * math.pi * s / N_SEG
        verts.append((R * math.cos(a), R * math.sin(a), z))
for r in range(RINGS - 1):
    for s in range(N_SEG):
        a0, a1 = r * N_SEG + s, r * N_SEG + (s + 1) % N_SEG
        faces.append((a0, a1, a1 + N_SEG, a0 + N_SEG))
me = bpy.data.meshes.new("limb")
me.from_pydata(verts, [], faces)
uv = me.uv_layers.new(name="UVMap")
for poly in me.polygons:
    for li in poly.loop_indices:
        vi = me.loops[li].vertex_index
        r, s = divmod(vi, N_SEG)
        # the closing column of quads gets u = 1, not 0: the seam splits those vertices
        if s == 0 and any(me.loops[k].vertex_index % N_SEG == N_SEG - 1 for k in poly.loop_indices):
            s = N_SEG
        uv.data[li].uv = (s / N_SEG, r / (RINGS - 1))
for p in me.polygons:
    p.use_smooth = True
obj = bpy.data.objects.new("limb", me)
bpy.context.scene.collection.objects.link(obj)

mat = bpy.data.materials.new("skin")
mat.use_nodes = True
bsdf = mat.node_tree.nodes["Principled BSDF"]
tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
tex.image = img
mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
bsdf.inputs["Roughness"].default_value = 0.6
me.materials.append(mat)

if kind != "noarmature":
    arm_data = bpy.data.armatures.new("rig")
    arm = bpy.data.objects.new("rig", arm_data)
    bpy.context.scene.collection.objects.link(arm)
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode="EDIT")
    lo = arm_data.edit_bones.new("lower")
    lo.head, lo.tail = (0, 0, 0), (0, 0, 0.8)
    up = arm_data.edit_bones.new("upper")
    up.head, up.tail = (0, 0, 0.8), (0, 0, 1.6)
    up.parent, up.use_connect = lo, True
    bpy.ops.object.mode_set(mode="OBJECT")
    g_lo, g_up = obj.vertex_groups.new(name="lower"), obj.vertex_groups.new(name="upper")
    for i, (x, y, z) in enumerate(verts):
        w = min(max((z - 0.6) / 0.4, 0.0), 1.0)  # lower only below 0.6 m, upper only above 1.0 m
        if w < 1:
            g_lo.add([i], 1 - w, "REPLACE")
        if w > 0:
            g_up.add([i], w, "REPLACE")
    obj.parent = arm
    mod = obj.modifiers.new("Armature", "ARMATURE")
    mod.object = arm
    arm.location = OFFSET
    if kind == "skinned":
        # A 3-frame clip: the upper bone bends 0, 45, 90 degrees about its local X; the root rises 0.1 m.
        arm.animation_data_create()
        act = bpy.data.actions.new("bend")
        arm.animation_data.action = act
        pb_up, pb_lo = arm.pose.bones["upper"], arm.pose.bones["lower"]
        for f, deg in ((1, 0), (2, 45), (3, 90)):
            pb_up.rotation_mode = "XYZ"
            pb_up.rotation_euler = (math.radians(deg), 0, 0)
            pb_up.keyframe_insert("rotation_euler", frame=f)
            pb_lo.location = (0, 0.05 * (f - 1), 0)  # bone-local Y = world +Z for this bone
            pb_lo.keyframe_insert("location", frame=f)
        bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 3
        bpy.context.scene.frame_set(1)
else:
    obj.location = OFFSET

bpy.ops.object.select_all(action="SELECT")
bpy.ops.export_scene.gltf(filepath=str(out_dir / "limb.glb"), export_format="GLB")
bpy.ops.export_scene.gltf(filepath=str(out_dir / "limb.gltf"), export_format="GLTF_SEPARATE")
bpy.ops.export_scene.fbx(filepath=str(out_dir / "limb.fbx"), path_mode="COPY", embed_textures=True,
                         add_leaf_bones=False)
print("ok")
"""


@pytest.fixture(scope="module")
def limb_files(tmp_path_factory):
    from rh_common.blender import run_blender_script

    d = tmp_path_factory.mktemp("limb")
    (d / "make_limb.py").write_text(MAKE_LIMB)
    run_blender_script(d / "make_limb.py", [d / "skinned", "skinned"], timeout=300)
    run_blender_script(d / "make_limb.py", [d / "noarm", "noarmature"], timeout=300)
    return d


@pytest.mark.parametrize("ext", ["glb", "fbx"])
def test_import_matches_blenders_own_skinning(limb_files, ext):
    out = read_character_file(limb_files / "skinned" / f"limb.{ext}", limb_files / f"read_{ext}", deformed=True)
    ch = _build(out, f"limb.{ext}", "limb", "0" * 64, None)
    p = ch.parts[0]
    assert len(p.rest_vertices) == 117  # 9 rings x 12 + a UV seam column
    np.testing.assert_allclose(p.rest_vertices.min(0), [-0.1, -0.1, 0.0], atol=1e-5)  # placed: axis on Z, feet z=0
    np.testing.assert_allclose(p.rest_vertices.max(0), [0.1, 0.1, 1.6], atol=1e-5)
    np.testing.assert_allclose(p.weights.sum(1), 1.0, atol=1e-6)
    with np.load(out / "character.npz") as z:
        want = z["anim0_part0_deformed"] * ch.scale + ch.placement
    got = pose_imported(ch, ch.clips[0].poses[-1])[0].vertices
    np.testing.assert_allclose(got, want, atol=1e-5)
    np.testing.assert_allclose(p.material.albedo[0, 0], (np.array([200, 60, 40]) / 255.0) ** 2.2, atol=0.02)


def test_no_armature_names_the_file(limb_files):
    with pytest.raises(CharacterImportError, match=r"limb\.glb: no armature"):
        read_character_file(limb_files / "noarm" / "limb.glb", limb_files / "read_noarm")


def test_motion_retargets_onto_an_imported_rig(limb_files, tmp_path):
    """A clip read as motion and retargeted onto the rig it was made for must give back the rig's own clip (same
    rest, same bones: every rotation copies over), and `rh-generate --character --motion` renders those poses."""
    import json

    from rh_dataset.characters.imported_reader import load_character_file
    from rh_dataset.cli import main
    from rh_dataset.generate.subjects import imported_bone_map
    from rh_dataset.poses.motion import read_motion
    from rh_dataset.poses.retarget import retarget

    glb = limb_files / "skinned" / "limb.glb"
    char = load_character_file(glb)
    motion = read_motion(glb, scale=1.0)
    bone_map = imported_bone_map(motion.skeleton, char.skeleton, glb)
    assert set(bone_map.values()) == set(char.skeleton.names)
    clip = char.clips[0].poses
    assert len(motion) == len(clip) == 3
    for k in range(3):
        got = pose_imported(char, retarget(motion, char.skeleton, bone_map, frames=[k], in_place=False)[0])
        want = pose_imported(char, clip[k])
        for g, w in zip(got, want):
            np.testing.assert_allclose(g.vertices, w.vertices, atol=2e-4)

    out = tmp_path / "data"
    args = ["--protocol", "demo", "--out", str(out), "--resolution", "32", "--spp", "1", "--aov-spp", "1",
            "--frames", "2", "--no-progress", "--character", str(glb), "--motion", str(glb),
            "--motion-stride", "1"]
    assert main(args) == 0
    for i in range(2):
        meta = json.loads((out / "subject_000/protocol_a/test" / f"frame_{i:06d}.json").read_text())
        rec = meta["body"]["motion"]
        assert rec["file"] == "limb.glb" and rec["frame"] == i and "intersections" not in rec
        assert meta["body"]["pose"]["label"] == f"motion:limb.glb#{i}"


def test_export_refuses_an_imported_character_dataset(tmp_path, capsys):
    """The export formats carry anny's body parameters; a dataset of an imported rig is refused by name, not
    crashed on half-way (and nothing is written)."""
    from rh_dataset.export.cli import main as export_main
    from rh_common.imageio import write_json
    from rh_common.layout import write_manifest

    root = tmp_path / "ds"
    root.mkdir()
    write_json(root / "dataset.json", {"format": "rh-dataset/1", "protocols": {"protocol_a": {
        "spec": {"character": {"file": "scan.glb", "sha256": "0" * 64, "scale": None}}}}})
    write_manifest(root)
    out = tmp_path / "exported"
    assert export_main(["--dataset", str(root), "--protocol", "a", "--format", "usd", "--out", str(out)]) == 2
    assert "imported character (scan.glb" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())
