"""Blender-side half of bench/bench_cycles.py: rebuild an exported frame in Blender and render it with Cycles (CPU).

Runs inside Blender's Python (`rh_common.blender.run_blender_script`), which has bpy 5.0.1 and numpy 1.26 but none of
this project's packages, so it imports nothing from the repository. Contract (see rh_common.blender):

    python cycles_render_bpy.py JOB.json

JOB.json: {"scene": path to the scene .npz written by bench_cycles.export_scene,
           "material": "diffuse" | "principled", "max_depth": Mitsuba-style max path depth (>= 2),
           "threads": int, "renders": [{"spp": int, "seed": int, "out": path.exr, "mask": bool}, ...],
           "report": path of the JSON this script writes, "camera_check": bool}
Each render writes a float32 RGBA EXR (linear Rec.709, no view transform); the report holds, per render, the wall
time split into scene sync/BVH build (from the render call to Cycles' first sample) and path tracing (first sample to
"Finished"), read from Cycles' own status updates (bpy.app.handlers.render_stats).

Conventions follow docs/ARCHITECTURE.md: world +Z up; OpenCV camera (x right, y down, z forward); equirectangular
map with u = 0.5 - atan2(y, x)/2pi, row 0 = +Z; textures row 0 = top (v = 1), UVs v up; linear Rec.709 everywhere.
"""
from __future__ import annotations

import json
import math
import sys
import time

import bpy
import numpy as np


def _fail(msg: str) -> None:
    sys.stderr.write(f"cycles_render_bpy: {msg}\n")
    sys.exit(2)


# ------------------------------------------------------------------------------------------------- conversions

# OpenCV camera axes (y down, z forward) -> Blender camera axes (y up, looking down -z): negate y and z.
_CV_TO_BLENDER_CAM = np.diag([1.0, -1.0, -1.0, 1.0])


def camera_setup(scene, K: np.ndarray, w2c: np.ndarray, width: int, height: int, near: float, far: float):
    """A Blender camera that projects exactly as K @ world_to_camera (pinhole, square pixels)."""
    fx, fy, cx, cy = float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])
    if abs(fx - fy) > 1e-6 * fx or abs(K[0, 1]) > 1e-9:
        _fail(f"only square pixels without skew are supported (fx={fx}, fy={fy}, skew={K[0, 1]})")
    cam = bpy.data.cameras.new("cam")
    cam.type = "PERSP"
    # Sensor and focal length in the same arbitrary unit: a sensor W wide with lens fx gives fx pixels of focal length.
    cam.sensor_fit = "HORIZONTAL"
    cam.sensor_width = float(width)
    cam.lens = fx
    # Blender's shift is a fraction of the larger image side; +x moves the frame right (the principal point left),
    # +y moves it up (the principal point down in an image whose v grows downwards).
    side = float(max(width, height))
    cam.shift_x = (width / 2.0 - cx) / side
    cam.shift_y = (cy - height / 2.0) / side
    cam.clip_start, cam.clip_end = near, far
    obj = bpy.data.objects.new("cam", cam)
    scene.collection.objects.link(obj)
    c2w = np.linalg.inv(np.asarray(w2c, dtype=np.float64)) @ _CV_TO_BLENDER_CAM
    from mathutils import Matrix

    # Through mathutils.Matrix (rows): a plain nested list assigned to matrix_world is read column by column.
    obj.matrix_world = Matrix([tuple(map(float, row)) for row in c2w])
    scene.camera = obj
    return obj


def camera_projection_error(scene, cam_obj, K, w2c, width, height, n: int = 200) -> float:
    """Largest pixel distance between Blender's projection of random points in front of the camera and K @ w2c."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    bpy.context.view_layer.update()
    rng = np.random.default_rng(0)
    c2w = np.linalg.inv(w2c)
    # points in the camera frustum (OpenCV camera frame), mapped to the world
    u = rng.uniform(0, width, n)
    v = rng.uniform(0, height, n)
    z = rng.uniform(0.5, 5.0, n)
    pc = np.stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z], 1)
    pw = pc @ c2w[:3, :3].T + c2w[:3, 3]
    worst = 0.0
    for p, uu, vv in zip(pw, u, v):
        ndc = world_to_camera_view(scene, cam_obj, Vector(tuple(map(float, p))))
        # Blender's view coordinates: x right, y up, both in [0, 1] over the frame
        bu, bv = ndc.x * width, (1.0 - ndc.y) * height
        worst = max(worst, math.hypot(bu - uu, bv - vv))
    return worst


def float_image(name: str, rgb: np.ndarray):
    """A float Blender image holding `rgb` (H, W, 3), row 0 = top, taken as linear Rec.709 (no transform)."""
    rgb = np.asarray(rgb, dtype=np.float32)
    H, W = rgb.shape[:2]
    img = bpy.data.images.new(name, W, H, alpha=False, float_buffer=True)
    img.colorspace_settings.name = "Linear Rec.709"  # the scene-linear space: values pass through unchanged
    rgba = np.ones((H, W, 4), dtype=np.float32)
    rgba[..., :3] = rgb
    img.pixels.foreach_set(np.ascontiguousarray(rgba[::-1]).ravel())  # Blender stores the bottom row first
    img.pack()  # keep the pixels as data; a generated image could otherwise be regenerated blank
    return img


def build_world(scene, radiance: np.ndarray, rotation_deg: float):
    """Background = our equirect map rotated by `rotation_deg` about +Z (ARCHITECTURE.md mapping).

    Cycles' equirect lookup of a direction d is u = 0.5 - atan2(d.y, d.x)/2pi, v = 0.5 + asin(d.z)/pi with v = 1
    at the image's top row: our mapping exactly (checked against Mitsuba by tests/test_cycles_peer.py). A rotated
    environment shows, in direction d, our map at Rz(-rotation) d, so the Mapping node rotates the lookup direction
    by -rotation about Z.
    """
    world = bpy.data.worlds.new("env")
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    coord = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.vector_type = "VECTOR"
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(-rotation_deg))
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = float_image("envmap", radiance)
    env.interpolation = "Linear"  # Mitsuba's envmap is bilinear too
    env.projection = "EQUIRECTANGULAR"
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = 1.0
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    world.cycles.sampling_method = "AUTOMATIC"  # importance-sample the map, as Mitsuba's envmap does
    scene.world = world


def specular_to_ior(specular: float) -> float:
    """Mitsuba principled's `specular` -> IOR: specular = ((eta - 1)/(eta + 1))^2 / 0.08 (0.5 -> 1.5)."""
    r = math.sqrt(max(0.08 * specular, 0.0))
    return (1.0 + r) / (1.0 - r) if r < 1.0 else 100.0


def build_material(name: str, texture: np.ndarray, roughness: float, specular: float, two_sided: bool, kind: str):
    """A Cycles material equivalent to rh_dataset.render.scene.mitsuba_bsdf (kind 'principled') or its Lambertian
    variant (kind 'diffuse': every part a `diffuse` BSDF with the same texture, as Mitsuba's diffuse variant)."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = float_image(f"{name}_albedo", texture)
    tex.interpolation = "Linear"  # Mitsuba bitmap filter_type 'bilinear'
    tex.extension = "REPEAT"  # Mitsuba bitmap wrap_mode default 'repeat'
    if kind == "diffuse" or specular <= 0.0:
        bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Roughness"].default_value = 0.0  # 0 = Lambertian (>0 would be Oren-Nayar)
        nt.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
        shader_out = bsdf.outputs["BSDF"]
    else:
        bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
        bsdf.distribution = "GGX"  # Mitsuba's principled uses single-scattering GGX
        nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
        bsdf.inputs["Roughness"].default_value = float(np.clip(roughness, 0.02, 1.0))
        bsdf.inputs["IOR"].default_value = specular_to_ior(float(np.clip(specular, 0.0, 1.0)))
        bsdf.inputs["Specular IOR Level"].default_value = 0.5  # 0.5 = the IOR's own Fresnel, unscaled
        bsdf.inputs["Metallic"].default_value = 0.0
        shader_out = bsdf.outputs["BSDF"]
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    if two_sided:
        nt.links.new(shader_out, out.inputs["Surface"])
    else:
        # Mitsuba shades a one-sided BSDF's back face as black (zero BSDF, the path ends); Cycles would flip the
        # normal and shade it. Reproduce Mitsuba: a black diffuse surface when the ray hits the back.
        geo = nt.nodes.new("ShaderNodeNewGeometry")
        black = nt.nodes.new("ShaderNodeBsdfDiffuse")
        black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        mix = nt.nodes.new("ShaderNodeMixShader")
        nt.links.new(geo.outputs["Backfacing"], mix.inputs["Fac"])
        nt.links.new(shader_out, mix.inputs[1])
        nt.links.new(black.outputs["BSDF"], mix.inputs[2])
        nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return mat


def build_mesh(scene, name: str, V, N, F, UV, mat):
    """A smooth-shaded mesh with per-vertex UVs and our vertex normals as Blender custom normals."""
    me = bpy.data.meshes.new(name)
    nv, nf = len(V), len(F)
    me.vertices.add(nv)
    me.vertices.foreach_set("co", np.ascontiguousarray(V, dtype=np.float32).ravel())
    me.loops.add(3 * nf)
    me.loops.foreach_set("vertex_index", np.ascontiguousarray(F, dtype=np.int32).ravel())
    me.polygons.add(nf)
    me.polygons.foreach_set("loop_start", np.arange(0, 3 * nf, 3, dtype=np.int32))
    me.polygons.foreach_set("use_smooth", np.ones(nf, dtype=bool))
    me.update(calc_edges=True)
    uvl = me.uv_layers.new(name="uv")
    uvl.data.foreach_set("uv", np.ascontiguousarray(UV[F.ravel()], dtype=np.float32).ravel())
    # Mitsuba shades with the interpolated vertex normals it is given; so must Cycles.
    me.normals_split_custom_set_from_vertices([tuple(map(float, n)) for n in N])
    me.materials.append(mat)
    obj = bpy.data.objects.new(name, me)
    # Cycles by default lifts shadow-ray origins off smooth-shaded low-poly surfaces (geometry offset 0.1) to hide
    # the shadow terminator; Mitsuba does not, and on the 45k-triangle character it made Cycles 0.45 % brighter
    # than Mitsuba (Lambertian, converged). Off, the two agree to 0.1 % (docs/TRADEOFFS.md).
    obj.shadow_terminator_geometry_offset = 0.0
    obj.shadow_terminator_normal_offset = 0.0
    obj.shadow_terminator_shading_offset = 0.0
    scene.collection.objects.link(obj)
    return obj


def configure_cycles(scene, max_depth: int, threads: int, width: int, height: int):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    scene.render.threads_mode = "FIXED"
    scene.render.threads = int(threads)
    scene.render.resolution_x, scene.render.resolution_y = int(width), int(height)
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    # Mitsuba max_depth counts path segments (2 = direct light only); Cycles counts bounces (0 = direct only).
    bounces = int(max_depth) - 2
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
    c.volume_bounces = 0
    c.transparent_max_bounces = 0
    # Unbiased estimator like Mitsuba's path tracer: no clamping, no glossy blur, no adaptive sampling, no denoiser,
    # no light-sampling threshold. (Cycles' defaults clamp indirect light at 10 and blur glossy paths.)
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.light_sampling_threshold = 0.0
    c.use_light_tree = True  # the default; with one environment light it changes nothing
    c.direct_light_sampling_type = "MULTIPLE_IMPORTANCE_SAMPLING"  # Mitsuba's path integrator uses MIS too
    c.use_animated_seed = False
    c.use_guiding = False
    c.use_auto_tile = False
    # Box filter one pixel wide: every sample counts equally inside its own pixel, exactly Mitsuba's `box` rfilter.
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    scene.render.film_transparent = False
    # Linear output, no view transform (EXR is scene-linear anyway; 'Standard' keeps any preview honest).
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.dither_intensity = 0.0
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    scene.render.use_persistent_data = False  # every render pays its own sync/BVH, reported separately
    ims = scene.render.image_settings
    ims.media_type = "IMAGE"
    ims.file_format = "OPEN_EXR"
    ims.color_depth = "32"  # float32: half overflows at 65504, a sun exceeds it
    ims.color_mode = "RGBA"
    ims.exr_codec = "ZIP"


def render_once(scene, spp: int, seed: int, out: str) -> dict:
    """One F12 render; wall time split at Cycles' first sample and at 'Finished' (from its status updates)."""
    events: list[tuple[float, str]] = []

    def on_stats(text):
        events.append((time.perf_counter(), str(text)))

    scene.cycles.samples = int(spp)
    scene.cycles.seed = int(seed)
    scene.render.filepath = out
    bpy.app.handlers.render_stats.append(on_stats)
    try:
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        t1 = time.perf_counter()
    finally:
        bpy.app.handlers.render_stats.remove(on_stats)
    start = next((t for t, m in events if m.rstrip().endswith(f"Sample 0/{spp}")), None)
    end = next((t for t, m in reversed(events) if m.rstrip().endswith("Finished")), None)
    if start is None or end is None:
        _fail(f"could not find Cycles' 'Sample 0/{spp}' and 'Finished' status lines; last: "
              f"{[m for _, m in events[-3:]]}")
    return {"spp": int(spp), "seed": int(seed), "out": out, "wall_s": t1 - t0, "sync_s": start - t0,
            "render_s": end - start, "write_s": t1 - end}


def main() -> None:
    if len(sys.argv) != 2:
        _fail("usage: cycles_render_bpy.py JOB.json")
    with open(sys.argv[1]) as f:
        job = json.load(f)
    t_build = time.perf_counter()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    with np.load(job["scene"], allow_pickle=False) as z:
        S = {k: z[k] for k in z.files}
    W, H = int(S["width"]), int(S["height"])
    configure_cycles(scene, int(job["max_depth"]), int(job["threads"]), W, H)
    cam = camera_setup(scene, S["K"], S["world_to_camera"], W, H, float(S["near"]), float(S["far"]))
    build_world(scene, S["env_radiance"], float(S["env_rotation_deg"]))
    kind = job["material"]
    if kind not in ("diffuse", "principled"):
        _fail(f"material must be 'diffuse' or 'principled', got {kind!r}")
    for i in range(int(S["n_meshes"])):
        p = f"mesh{i}_"
        rough, spec, two = (float(x) for x in S[p + "material"])
        mat = build_material(f"m{i}", S[p + "texture"], rough, spec, bool(two), kind)
        build_mesh(scene, f"mesh{i}", S[p + "vertices"], S[p + "normals"], S[p + "faces"], S[p + "uvs"], mat)
    report = {"blender": bpy.app.version_string, "build_s": time.perf_counter() - t_build,
              "view_transform": scene.view_settings.view_transform, "renders": []}
    if job.get("camera_check"):
        report["camera_max_px_error"] = camera_projection_error(scene, cam, S["K"], S["world_to_camera"], W, H)
    for r in job["renders"]:
        if r.get("mask"):
            # Coverage: film transparent makes alpha = the fraction of the pixel (box filter) covered by geometry.
            scene.render.film_transparent = True
            c = scene.cycles
            saved = c.max_bounces
            c.max_bounces = 0
            report["renders"].append({**render_once(scene, r["spp"], r["seed"], r["out"]), "mask": True})
            c.max_bounces = saved
            scene.render.film_transparent = False
        else:
            report["renders"].append(render_once(scene, r["spp"], r["seed"], r["out"]))
    with open(job["report"] + ".tmp", "w") as f:
        json.dump(report, f, indent=1)
    import os

    os.replace(job["report"] + ".tmp", job["report"])


if __name__ == "__main__":
    main()
