"""Blender side of character import: read a rigged glTF/FBX character and write its rest pose, rig and clips.

Runs inside Blender's own Python only (`rh_common.blender.run_blender_script`); our package never imports it (bpy
pins numpy 1.26, we need numpy 2). Usage:

    python bpy_read_character.py MODEL.glb|.gltf|.fbx OUT_DIR [--deformed]

Writes into OUT_DIR (the main side, `rh_dataset.characters.imported_reader`, validates everything):
  character.npz   plain arrays, no pickles:
      skeleton_heads, skeleton_tails (J, 3) rest bone heads/tails in world metres; skeleton_parents (J,)
      part{i}_positions, part{i}_normals (V, 3) rest pose, world; part{i}_uvs (V, 2) v up; part{i}_faces (F, 3);
      part{i}_bone_ids (V, 4), part{i}_weights (V, 4) (top 4 influences, rows sum to 1)
      anim{k}_rotations (N, J, 3, 3) each bone's world rotation relative to rest (skeleton.py's G);
      anim{k}_heads (N, J, 3) posed bone heads in world metres;
      with --deformed: anim{k}_part{i}_deformed (V, 3), Blender's own skinning of the clip's last frame (tests
      compare our skinning with it).
  tex_XX.png      base-colour textures, 8-bit, row 0 = top (v = 1), as stored in the file (see `colourspace`).
  character.json  names, materials, clips, warnings; written last, so its presence means the folder is complete.

"World" is Blender's after import: Z up, metres (Blender's glTF importer turns glTF's Y-up into Z-up; its FBX
importer applies the file's axes and unit scale to the objects, so a centimetre FBX arrives with a 0.01 object
scale). Everything is read through `matrix_world`, so those conversions are applied exactly once.

Failures exit with status 2 and one line on stderr that names the file and the problem.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import bpy
import numpy as np

FORMAT = "rh-imported-character/1"
MAX_INFLUENCES = 4


class ImportFailure(Exception):
    pass


def _np(m) -> np.ndarray:
    return np.array([list(r) for r in m], dtype=np.float64)


def _import(path: Path) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    ext = path.suffix.lower()
    if ext in (".glb", ".gltf"):
        bpy.ops.import_scene.gltf(filepath=str(path))
    elif ext == ".fbx":
        bpy.ops.import_scene.fbx(filepath=str(path))
    else:
        raise ImportFailure(f"{path}: unsupported file type {ext!r}; expected .glb, .gltf or .fbx")


# ---------------------------------------------------------------------------------------------------------------
# Rig


def _armature_and_meshes(path: Path, warnings: list[str]):
    objs = list(bpy.context.scene.objects)
    arms = [o for o in objs if o.type == "ARMATURE"]
    if not arms:
        raise ImportFailure(f"{path}: no armature (skeleton) in the file; a character needs a rig with its meshes "
                            f"skinned to it (objects found: {sorted(o.name for o in objs)[:12]})")
    # Meshes used as bone display shapes (the glTF importer adds an icosphere) are not part of the character.
    shapes = {pb.custom_shape.name for a in arms for pb in a.pose.bones if pb.custom_shape is not None}
    by_arm: dict[str, list] = {a.name: [] for a in arms}
    ignored = []
    for o in objs:
        if o.type != "MESH" or o.name in shapes:
            continue
        arm = None
        for m in o.modifiers:
            if m.type == "ARMATURE" and m.object is not None and m.show_render:
                arm = m.object
                if m.use_deform_preserve_volume:
                    warnings.append(f"mesh {o.name!r}: Blender skins it with dual quaternions (preserve volume); "
                                    "we use linear blend skinning, so bent joints may look thinner")
                break
        if arm is None and o.parent is not None and o.parent.type == "ARMATURE" and o.parent_type == "BONE":
            arm = o.parent  # rigidly attached to one bone (eyes, hats)
        if arm is None:
            ignored.append(o.name)
        else:
            by_arm[arm.name].append(o)
    best = max(arms, key=lambda a: sum(len(m.data.polygons) for m in by_arm[a.name]))
    if not by_arm[best.name]:
        raise ImportFailure(f"{path}: no skinned mesh: armature {best.name!r} deforms no mesh (no mesh has an "
                            f"Armature modifier or a bone parent); meshes found: {ignored[:12]}")
    if ignored:
        warnings.append(f"meshes not skinned to the armature are left out: {ignored[:12]}")
    for a in arms:
        if a is not best and by_arm[a.name]:
            warnings.append(f"second armature {a.name!r} and its meshes are left out (one rig per character)")
    return best, by_arm[best.name]


def _bone_order(arm) -> list:
    """Bones with every parent before its children (Blender does not promise that order)."""
    order = []

    def visit(b):
        order.append(b)
        for c in b.children:
            visit(c)

    for b in arm.data.bones:
        if b.parent is None:
            visit(b)
    return order


# ---------------------------------------------------------------------------------------------------------------
# Materials


def _upstream(socket, kinds: set[str], depth: int = 0):
    """The first node of one of `kinds` feeding `socket`, looking through a few intermediate nodes (mix, separate
    colour, normal map...) depth first; None if there is none."""
    if depth > 6 or not socket.is_linked:
        return None
    node = socket.links[0].from_node
    if node.bl_idname in kinds:
        return node
    for s in node.inputs:
        found = _upstream(s, kinds, depth + 1)
        if found is not None:
            return found
    return None


def _principled(mat):
    if mat is None or mat.node_tree is None:
        return None
    out = next((n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial" and n.is_active_output),
               None)
    if out is not None:
        node = _upstream(out.inputs["Surface"], {"ShaderNodeBsdfPrincipled"})
        if node is not None:
            return node
    return next((n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"), None)


def _image_pixels(img) -> np.ndarray:
    w, h = img.size
    c = img.channels
    px = np.empty(w * h * c, dtype=np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, c)


def _scalar_input(bsdf, name: str, channel_hint: int, path: Path, mat_name: str, warnings: list[str]) -> float:
    sock = bsdf.inputs[name]
    if not sock.is_linked:
        return float(sock.default_value)
    node = _upstream(sock, {"ShaderNodeTexImage"})
    if node is None or node.image is None or not node.image.has_data:
        warnings.append(f"material {mat_name!r}: {name} is driven by nodes we cannot read; using its default "
                        f"{float(sock.default_value):.2f}")
        return float(sock.default_value)
    # glTF packs roughness in green, metallic in blue; a plain greyscale map has them all equal. One number per
    # material: our Material has no roughness map.
    px = _image_pixels(node.image)
    ch = min(channel_hint, px.shape[2] - 1) if px.shape[2] >= 3 else 0
    v = float(px[..., ch].mean())
    warnings.append(f"material {mat_name!r}: {name} comes from texture {node.image.name!r}; using its mean {v:.3f} "
                    "(per-texel values are not supported)")
    return v


def _material(mat, out_dir: Path, path: Path, textures: dict, warnings: list[str]) -> dict:
    name = mat.name if mat is not None else "(none)"
    rec = {"name": name, "texture": None, "texture_colourspace": None, "base_colour": [0.8, 0.8, 0.8],
           "roughness": 0.5, "metallic": 0.0, "specular": 0.5,
           "two_sided": bool(mat is None or not mat.use_backface_culling)}
    bsdf = _principled(mat)
    if bsdf is None:
        warnings.append(f"material {name!r} has no Principled BSDF; rendered as a grey (0.8) rough dielectric")
        return rec
    base = bsdf.inputs["Base Color"]
    rec["base_colour"] = [float(x) for x in base.default_value[:3]]
    node = _upstream(base, {"ShaderNodeTexImage"})
    if base.is_linked and node is None:
        warnings.append(f"material {name!r}: base colour comes from nodes other than an image texture (vertex "
                        "colours, procedurals); using its constant value")
    if node is not None:
        img = node.image
        where = (img.filepath_from_user() or img.filepath) if img is not None else ""
        # `size` first: asking for it loads the image, and `has_data` is only true once loaded.
        if img is None or img.size[0] == 0 or img.size[1] == 0 or not img.has_data:
            shown = f"{img.name!r} ({where})" if img is not None else "(no image assigned)"
            raise ImportFailure(f"{path}: texture missing: material {name!r} uses base-colour image {shown}, which "
                                "could not be read; put the texture next to the model (or embed it) and retry")
        key = img.name
        if key not in textures:
            px = _image_pixels(img)[::-1]  # Blender stores rows bottom-up; files are top-down
            if img.is_float:
                # Float images hold scene-linear values: store them sRGB-encoded like an 8-bit colour texture.
                lin = np.clip(px[..., :3], 0.0, 1.0)
                px = px.copy()
                px[..., :3] = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.power(lin, 1 / 2.4) - 0.055)
                space = "sRGB"
            else:
                space = "sRGB" if img.colorspace_settings.name.lower().startswith("srgb") else "linear"
            rgba = np.ones(px.shape[:2] + (4,), np.float32)
            rgba[..., :min(px.shape[2], 4)] = px[..., :4]
            if px.shape[2] == 1:
                rgba[..., 1] = rgba[..., 2] = rgba[..., 0]
            fname = f"tex_{len(textures):02d}.png"
            out = bpy.data.images.new(f"rh_out_{len(textures)}", px.shape[1], px.shape[0], alpha=True)
            out.pixels.foreach_set(np.ascontiguousarray(rgba[::-1]).ravel())  # back to Blender's bottom-up rows
            out.filepath_raw = str(out_dir / fname)
            out.file_format = "PNG"
            out.save()
            textures[key] = (fname, space)
        rec["texture"], rec["texture_colourspace"] = textures[key]
    rec["roughness"] = _scalar_input(bsdf, "Roughness", 1, path, name, warnings)
    rec["metallic"] = _scalar_input(bsdf, "Metallic", 2, path, name, warnings)
    # Blender 4+'s principled: F0 = ((ior - 1) / (ior + 1))^2 * 2 * "Specular IOR Level"; ours (Disney/Mitsuba):
    # F0 = 0.08 * specular. Both give 0.5 for a plain IOR-1.5 dielectric.
    ior = float(bsdf.inputs["IOR"].default_value)
    level = float(bsdf.inputs["Specular IOR Level"].default_value)
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * level
    rec["specular"] = float(min(max(f0 / 0.08, 0.0), 1.0))
    alpha = bsdf.inputs["Alpha"]
    anode = _upstream(alpha, {"ShaderNodeTexImage"})
    if anode is not None and anode.image is not None and anode.image.size[0] > 0 and anode.image.channels == 4:
        cut = float(_image_pixels(anode.image)[..., 3].min()) < 0.99  # an opaque alpha channel changes nothing
    else:
        cut = alpha.is_linked or float(alpha.default_value) < 1.0
    if cut:
        warnings.append(f"material {name!r} uses alpha (cut-out or transparent); it is rendered opaque")
    if rec["metallic"] > 0.5:
        warnings.append(f"material {name!r} is metallic ({rec['metallic']:.2f}); it is rendered as a dielectric")
    return rec


# ---------------------------------------------------------------------------------------------------------------
# Meshes


def _mesh_parts(obj, arm, bone_index: dict[str, int], rest_world: np.ndarray, path: Path, warnings: list[str]):
    """Split-vertex triangle arrays per material of one mesh object, in the rest pose (world)."""
    me = obj.data
    me.calc_loop_triangles()
    nv = len(me.vertices)
    co = np.empty(nv * 3, np.float64)
    me.vertices.foreach_get("co", co)
    co = co.reshape(nv, 3)
    if me.shape_keys is not None:
        warnings.append(f"mesh {obj.name!r}: shape keys are ignored (the basis shape is used)")
    if any(m.type not in ("ARMATURE",) and m.show_render for m in obj.modifiers):
        warnings.append(f"mesh {obj.name!r}: modifiers other than the armature are ignored: "
                        f"{[m.type for m in obj.modifiers if m.type != 'ARMATURE']}")
    M = rest_world
    pos_w = co @ M[:3, :3].T + M[:3, 3]
    nrm_mat = np.linalg.inv(M[:3, :3]).T  # normals transform by the inverse transpose (objects may be scaled)

    nt = len(me.loop_triangles)
    tri_loops = np.empty(nt * 3, np.int64)
    me.loop_triangles.foreach_get("loops", tri_loops)
    tri_loops = tri_loops.reshape(nt, 3)
    tri_mat = np.empty(nt, np.int64)
    me.loop_triangles.foreach_get("material_index", tri_mat)
    nl = len(me.loops)
    loop_vert = np.empty(nl, np.int64)
    me.loops.foreach_get("vertex_index", loop_vert)
    cn = np.empty(nl * 3, np.float64)
    me.corner_normals.foreach_get("vector", cn)
    cn = cn.reshape(nl, 3) @ nrm_mat.T
    cn /= np.maximum(np.linalg.norm(cn, axis=1, keepdims=True), 1e-12)
    uvl = next((u for u in me.uv_layers if u.active_render), me.uv_layers.active)
    if uvl is None:
        warnings.append(f"mesh {obj.name!r} has no UV map; its texture (if any) is sampled at (0, 0)")
        luv = np.zeros((nl, 2), np.float64)
    else:
        luv = np.empty(nl * 2, np.float32)
        uvl.data.foreach_get("uv", luv)
        luv = luv.reshape(nl, 2).astype(np.float64)

    # Influences: vertex groups named after bones; a bone-parented mesh follows its bone rigidly.
    rigid = None
    if obj.parent is arm and obj.parent_type == "BONE" and obj.parent_bone in bone_index:
        rigid = bone_index[obj.parent_bone]
    group_bone = {g.index: bone_index.get(g.name, -1) for g in obj.vertex_groups}
    ids = np.zeros((nv, MAX_INFLUENCES), np.int64)
    wts = np.zeros((nv, MAX_INFLUENCES), np.float64)
    unweighted = 0
    root = 0
    for v in me.vertices:
        if rigid is not None:
            ids[v.index, 0], wts[v.index, 0] = rigid, 1.0
            continue
        infl: dict[int, float] = {}
        for g in v.groups:
            b = group_bone.get(g.group, -1)
            if b >= 0 and g.weight > 0.0:
                infl[b] = infl.get(b, 0.0) + g.weight
        if not infl:
            # Blender leaves such a vertex where it is; following the root keeps it with the body instead.
            unweighted += 1
            ids[v.index, 0], wts[v.index, 0] = root, 1.0
            continue
        top = sorted(infl.items(), key=lambda kv: -kv[1])[:MAX_INFLUENCES]
        s = sum(w for _, w in top)
        for k, (b, w) in enumerate(top):
            ids[v.index, k], wts[v.index, k] = b, w / s
    if unweighted:
        warnings.append(f"mesh {obj.name!r}: {unweighted} of {nv} vertices have no bone weights; they follow the "
                        "root bone")

    # One output vertex per distinct (vertex, uv, normal) corner: UV seams and hard edges split vertices.
    key = np.concatenate([loop_vert[:, None].astype(np.float64), np.round(luv, 7), np.round(cn, 5)], axis=1)
    parts = []
    for mi in np.unique(tri_mat):
        loops = tri_loops[tri_mat == mi]
        used = np.unique(loops)
        uniq, first, inv = np.unique(key[used], axis=0, return_index=True, return_inverse=True)
        remap = np.full(nl, -1, np.int64)
        remap[used] = inv.ravel()
        src = used[first]  # a representative loop per output vertex
        vi = loop_vert[src]
        parts.append({
            "material_index": int(mi),
            "positions": pos_w[vi], "normals": cn[src], "uvs": luv[src],
            "faces": remap[loops].astype(np.int32),
            "bone_ids": ids[vi].astype(np.int32), "weights": wts[vi],
            "vertex_index": vi,  # into the mesh's own vertices (for --deformed)
            "unweighted": unweighted, "rigid_bone": rigid,
        })
    return parts


# ---------------------------------------------------------------------------------------------------------------
# Animation


def _bone_actions(arm) -> list:
    """Actions that animate this armature's bones (the glTF importer stashes clips in NLA tracks, FBX assigns)."""
    from bpy_extras import anim_utils

    names = {b.name for b in arm.data.bones}
    found = []
    for act in bpy.data.actions:
        for slot in act.slots:
            if slot.target_id_type != "OBJECT":
                continue
            bag = anim_utils.action_get_channelbag_for_slot(act, slot)
            if bag is None:
                continue
            if any(fc.data_path.startswith("pose.bones[") and fc.data_path.split('"')[1] in names
                   for fc in bag.fcurves):
                found.append((act, slot))
                break
    return found


def _world_deforms(arm, order, A0: np.ndarray) -> np.ndarray:
    """(J, 4, 4) world matrices taking rest-pose world points to posed ones, as Blender's armature modifier does:
    A_t P B^-1 A_0^-1 (A = armature world matrix, P posed and B rest bone matrix in armature space)."""
    dg = bpy.context.evaluated_depsgraph_get()
    ev = arm.evaluated_get(dg)
    A = _np(ev.matrix_world)
    A0_inv = np.linalg.inv(A0)
    out = np.empty((len(order), 4, 4))
    for j, b in enumerate(order):
        P = _np(ev.pose.bones[b.name].matrix)
        B = _np(b.matrix_local)
        out[j] = A @ P @ np.linalg.inv(B) @ A0_inv
    return out


def _sample_clips(arm, order, heads_rest: np.ndarray, A0: np.ndarray, meshes, parts_src, deformed: bool,
                  warnings: list[str]):
    scene = bpy.context.scene
    clips, arrays = [], {}
    ad = arm.animation_data or arm.animation_data_create()
    for t in ad.nla_tracks:  # evaluate one clip at a time
        t.mute = True
    arm.data.pose_position = "POSE"
    for k, (act, slot) in enumerate(_bone_actions(arm)):
        ad.action = act
        ad.action_slot = slot
        f0, f1 = (int(round(x)) for x in act.frame_range)
        frames = list(range(f0, f1 + 1))
        rots = np.empty((len(frames), len(order), 3, 3))
        heads = np.empty((len(frames), len(order), 3))
        scale_err = 0.0
        for n, f in enumerate(frames):
            scene.frame_set(f)
            T = _world_deforms(arm, order, A0)
            R = T[:, :3, :3]
            # Scaled bones are outside skeleton.py's model (rigid rotations); keep the nearest rotation and report.
            U, S, Vt = np.linalg.svd(R)
            scale_err = max(scale_err, float(np.abs(S - 1.0).max()))
            U[:, :, 2] *= np.sign(np.linalg.det(U @ Vt))[:, None]  # a proper rotation, never a reflection
            rots[n] = U @ Vt
            heads[n] = np.einsum("jab,jb->ja", T[:, :3, :3], heads_rest) + T[:, :3, 3]
        if scale_err > 1e-4:
            warnings.append(f"clip {act.name!r}: bones are scaled (up to {scale_err:.3g}); scale is dropped")
        fps = scene.render.fps / scene.render.fps_base
        clips.append({"name": act.name, "frame_start": f0, "frames": len(frames), "fps": fps})
        arrays[f"anim{k}_rotations"] = rots
        arrays[f"anim{k}_heads"] = heads
        if deformed:
            dg = bpy.context.evaluated_depsgraph_get()
            for i, (obj, part) in enumerate(parts_src):
                ev = obj.evaluated_get(dg)
                me = ev.to_mesh()
                co = np.empty(len(me.vertices) * 3)
                me.vertices.foreach_get("co", co)
                ev.to_mesh_clear()
                Mw = _np(ev.matrix_world)
                co = co.reshape(-1, 3) @ Mw[:3, :3].T + Mw[:3, 3]
                arrays[f"anim{k}_part{i}_deformed"] = co[part["vertex_index"]]
    return clips, arrays


# ---------------------------------------------------------------------------------------------------------------


def read(path: Path, out_dir: Path, deformed: bool) -> None:
    warnings: list[str] = []
    _import(path)
    arm, meshes = _armature_and_meshes(path, warnings)
    # The rest pose: the armature modifier does nothing in REST position, so mesh coordinates x matrix_world are
    # the bind shape; the matrices are read before any frame change (object animation may move them later).
    arm.data.pose_position = "REST"
    bpy.context.view_layer.update()
    A0 = _np(arm.matrix_world)
    order = _bone_order(arm)
    bone_index = {b.name: i for i, b in enumerate(order)}
    heads = np.array([A0[:3, :3] @ np.array(b.head_local) + A0[:3, 3] for b in order])
    tails = np.array([A0[:3, :3] @ np.array(b.tail_local) + A0[:3, 3] for b in order])
    parents = np.array([bone_index[b.parent.name] if b.parent is not None else -1 for b in order], np.int64)
    rest_world = {o.name: _np(o.matrix_world) for o in meshes}

    arrays = {"skeleton_heads": heads, "skeleton_tails": tails, "skeleton_parents": parents}
    textures: dict = {}
    parts_meta, parts_src = [], []
    for obj in sorted(meshes, key=lambda o: o.name):
        for part in _mesh_parts(obj, arm, bone_index, rest_world[obj.name], path, warnings):
            slots = obj.material_slots
            mat = slots[part["material_index"]].material if part["material_index"] < len(slots) else None
            i = len(parts_meta)
            name = obj.name if len(obj.data.materials) <= 1 else f"{obj.name}.{mat.name if mat else 'none'}"
            parts_meta.append({"name": name, "object": obj.name,
                               "material": _material(mat, out_dir, path, textures, warnings),
                               "unweighted_vertices": part["unweighted"],
                               "rigid_bone": None if part["rigid_bone"] is None else order[part["rigid_bone"]].name})
            for k in ("positions", "normals", "uvs", "faces", "bone_ids", "weights"):
                arrays[f"part{i}_{k}"] = part[k]
            parts_src.append((obj, part))
    clips, anim_arrays = _sample_clips(arm, order, heads, A0, meshes, parts_src, deformed, warnings)
    arrays.update(anim_arrays)
    np.savez(out_dir / "character.npz", **arrays)
    meta = {
        "format": FORMAT, "source": path.name, "blender": bpy.app.version_string, "armature": arm.name,
        "bones": [b.name for b in order], "parts": parts_meta, "animations": clips, "warnings": warnings,
        "unit_scale_length": float(bpy.context.scene.unit_settings.scale_length),
    }
    tmp = out_dir / "character.json.tmp"
    tmp.write_text(json.dumps(meta, indent=1, sort_keys=True))
    tmp.replace(out_dir / "character.json")


def main(argv: list[str]) -> int:
    if len(argv) < 2:
        sys.stderr.write("usage: bpy_read_character.py MODEL OUT_DIR [--deformed]\n")
        return 2
    path, out_dir = Path(argv[0]).resolve(), Path(argv[1])
    out_dir.mkdir(parents=True, exist_ok=True)
    if not path.is_file():
        sys.stderr.write(f"rh-import: {path}: no such file\n")
        return 2
    try:
        read(path, out_dir, "--deformed" in argv[2:])
    except ImportFailure as exc:
        sys.stderr.write(f"rh-import: {exc}\n")
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
