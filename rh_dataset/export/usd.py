"""Export each frame as a USD stage (usd-core / pxr): posed meshes, UsdPreviewSurface materials, camera, dome light.

    <out>/<subject>/textures/<part>_albedo.png          albedo textures, sRGB-encoded 8-bit, written once per subject
    <out>/<subject>/protocol_<p>/<split>/frame_000000.usdc   (.usda with --usd-ext usda)

Stage: upAxis Z, metersPerUnit 1 (our world, docs/ARCHITECTURE.md). Prims:
    /World                       default prim; customData holds the frame's K, world_to_camera, exposure, light
    /World/Character/<part>      UsdGeom.Mesh (points, normals and st per vertex, subdivisionScheme none)
    /World/Character/<hair>      UsdGeom.BasisCurves (cubic B-spline, ends repeated as the renderer does, widths =
                                 2 x radius per control point, displayColor = the fibre's albedo; customData holds
                                 the fibre's melanin concentrations)
    /World/Looks/<material>      UsdPreviewSurface ← UsdUVTexture(albedo PNG, sRGB) ← UsdPrimvarReader_float2(st)
    /World/SMPL                  with --smpl-model: the SMPL fit (UsdGeom.Mesh, world metres, purpose guide)
    /World/Camera                UsdGeom.Camera matching K and world_to_camera
    /World/DomeLight             UsdLux.DomeLight, texture = the HDRI file, intensity = light scale

Conventions (see docs/INTEROP.md, "USD"):
* Camera: a USD camera looks down its local −Z with +Y up (OpenGL axes), so its transform is
  camera_to_world(OpenCV) · diag(1, −1, −1, 1). focalLength/aperture are chosen so that fx = focalLength ·
  W / horizontalAperture and fy = focalLength · H / verticalAperture; the principal point goes into the aperture
  offsets.
* DomeLight (the original schema, not DomeLight_1): its pole is its local +Y and its latlong texture follows the
  OpenEXR convention (longitude atan2(x, z), u = 0.5 − longitude/2π). With the transform Rz(rotation_deg) · B,
  B = [[0,0,1],[1,0,0],[0,1,0]] (local +Z → world +X, local +X → world +Y, local +Y → world +Z), a world direction
  looks up exactly the texel our equirect convention gives it (the same B Mitsuba's envmap gets).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from rh_common import layout
from rh_common.colourspace import quantize8, srgb_encode
from rh_common.imageio import read_json, write_exr, write_png

from .common import ExportError, FrameRef, hdri_path

__all__ = ["DOME_BASIS", "HORIZONTAL_APERTURE", "camera_attributes", "camera_xform", "dome_xform", "export_frame",
           "SubjectAssets", "subject_assets", "usd_project"]

HORIZONTAL_APERTURE = 20.955  # USD's fallback (35 mm academy, in tenths of a scene unit by USD's convention)
DOME_BASIS = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])


def _pxr():
    try:
        from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, Vt
    except ImportError as exc:
        raise ExportError("the usd export needs usd-core: pip install usd-core==26.11") from exc
    return Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, Vt


def camera_attributes(K: np.ndarray, width: int, height: int,
                      horizontal_aperture: float = HORIZONTAL_APERTURE) -> dict[str, float]:
    """UsdGeom.Camera attributes reproducing pinhole intrinsics K for a width x height image."""
    K = np.asarray(K, dtype=np.float64)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    focal = fx * horizontal_aperture / width
    vertical_aperture = focal * height / fy
    return {
        "focalLength": float(focal),
        "horizontalAperture": float(horizontal_aperture),
        "verticalAperture": float(vertical_aperture),
        # Offsets shift the film back (the window moves the other way in the image): u goes right like camera x,
        # v goes down unlike camera y. A test checks an off-centre principal point.
        "horizontalApertureOffset": float((width / 2.0 - cx) * horizontal_aperture / width),
        "verticalApertureOffset": float((cy - height / 2.0) * vertical_aperture / height),
    }


def camera_xform(world_to_camera: np.ndarray) -> np.ndarray:
    """4x4 (column-vector convention) local-to-world transform of the USD camera for an OpenCV world_to_camera."""
    return np.linalg.inv(np.asarray(world_to_camera, dtype=np.float64)) @ _GL_FROM_CV


def dome_xform(rotation_deg: float) -> np.ndarray:
    from rh_dataset.lights.mitsuba_env import rotation_z

    T = np.eye(4)
    T[:3, :3] = rotation_z(rotation_deg) @ DOME_BASIS
    return T


def _gf_matrix(M: np.ndarray):
    Gf = _pxr()[0]
    return Gf.Matrix4d(np.asarray(M, dtype=np.float64).T.tolist())  # Gf matrices act on row vectors


def usd_project(stage_path: str | Path, points_world: np.ndarray, camera_path: str = "/World/Camera") -> np.ndarray:
    """Project world points through the stage's camera with USD's own frustum maths → (N, 2) pixel coordinates
    (pixel centres at +0.5, v down). For tests and users checking a stage."""
    Gf, Sdf, Usd, UsdGeom, *_ = _pxr()
    stage = Usd.Stage.Open(str(stage_path))
    prim = stage.GetPrimAtPath(camera_path)
    cam = UsdGeom.Camera(prim).GetCamera(Usd.TimeCode.Default())
    fr = cam.frustum
    M = fr.ComputeViewMatrix() * fr.ComputeProjectionMatrix()
    world = stage.GetPrimAtPath("/World").GetCustomDataByKey("rh")
    W, H = int(world["width"]), int(world["height"])
    out = []
    for p in np.asarray(points_world, dtype=np.float64):
        q = M.Transform(Gf.Vec3d(*p.tolist()))  # homogeneous divide included
        out.append(((q[0] + 1.0) * 0.5 * W, (1.0 - q[1]) * 0.5 * H))
    return np.array(out)


class SubjectAssets:
    """A subject's rebuilt character and its albedo textures (written once, shared by all its stages)."""

    def __init__(self, character, texture_files: dict[int, Path]):
        self.character = character
        self.texture_files = texture_files  # id(material.albedo) -> PNG path


_ASSETS: dict[str, SubjectAssets] = {}


def subject_assets(dataset: Path, subject: str, out: Path, drape: str = "full") -> SubjectAssets:
    """`drape`: the drape level the frames were rendered with (their JSON's render.drape)."""
    from rh_dataset.characters import CharacterRecipe, build_character

    key = f"{Path(dataset).resolve()}::{subject}::{Path(out).resolve()}::{drape}"
    if key in _ASSETS:
        return _ASSETS[key]
    recipe = CharacterRecipe.from_json(read_json(Path(dataset) / subject / layout.CHARACTER_JSON))
    character = build_character(recipe, drape=drape)
    files: dict[int, Path] = {}
    tex_dir = Path(out) / subject / "textures"
    for part in character.parts:
        k = id(part.material.albedo)
        if k in files:
            continue  # hair sheets share one material
        path = tex_dir / f"{part.name}_albedo.png"
        write_png(path, quantize8(srgb_encode(part.material.albedo)))
        files[k] = path
    _ASSETS.clear()  # one subject at a time: a character holds ~100 MB of textures
    _ASSETS[key] = SubjectAssets(character, files)
    return _ASSETS[key]


def _rel(path: Path, start: Path) -> str:
    import os

    return "./" + os.path.relpath(path, start).replace(os.sep, "/")


def _light_texture(f: FrameRef, stage_dir: Path, hdri_folder: str | None) -> tuple[str, float]:
    """(texture asset path, intensity) of the frame's light."""
    light = f.meta["light"]
    p = hdri_path(light, hdri_folder)
    if p is not None:
        return str(p), float(light["scale"])
    if light["kind"] == "envmap":
        return light["source"], float(light["scale"])  # the map is not on this machine: name it, resolve later
    # sunsky or procedural: bake it as the generator does and write it beside the stage (scale already applied)
    from rh_dataset.lights import LightSpec, build_light

    built = build_light(LightSpec.from_json(light, str(layout.frame_json_path(f.split_dir, f.index))))
    path = stage_dir / layout.layer_file_name(f.index, "sky", "exr")
    write_exr(path, built.radiance)
    return _rel(path, stage_dir), 1.0


def export_frame(f: FrameRef, out: Path, protocol: str, *, dataset: Path, hdri_folder: str | None = None,
                 ext: str = "usdc", smpl: tuple[np.ndarray, np.ndarray, dict] | None = None) -> list[Path]:
    """Write one frame's stage. `smpl`: (world vertices (6890, 3), faces, record) of the frame's SMPL fit
    (export/smpl.py), written as /World/SMPL beside the clothed character, purpose 'guide' (not rendered)."""
    from rh_dataset.characters import pose_character
    from rh_dataset.poses import BodyPose

    Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, Vt = _pxr()
    # The loose garments as the frame's render draped them (frames made before render.drape existed: "full").
    assets = subject_assets(dataset, f.subject, out, f.meta.get("render", {}).get("drape", "full"))
    pose = BodyPose.from_json(f.meta["body"]["pose"])
    meshes = pose_character(assets.character, dict(pose.bones), pose.root_transform)

    stage_dir = layout.split_dir(out, f.subject, protocol, f.split)  # the source dataset's layout, mirrored
    stage_dir.mkdir(parents=True, exist_ok=True)
    final = stage_dir / f"{layout.frame_stem(f.index)}.{ext}"
    tmp = stage_dir / f".{layout.frame_stem(f.index)}.tmp.{ext}"  # USD picks the file format from the extension
    try:
        stage = Usd.Stage.CreateNew(str(tmp))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        world = UsdGeom.Xform.Define(stage, "/World")
        stage.SetDefaultPrim(world.GetPrim())
        m = f.meta
        world.GetPrim().SetCustomDataByKey("rh", {
            "subject": m["subject"], "protocol": m["protocol"], "split": m["split"], "index": int(m["index"]),
            "width": int(m["width"]), "height": int(m["height"]), "exposure": float(m["exposure"]),
            "K": Gf.Matrix3d(np.asarray(m["camera"]["K"]).tolist()),
            "world_to_camera": Gf.Matrix4d(np.asarray(m["camera"]["world_to_camera"]).tolist()),
            "world_to_camera_convention": "OpenCV, column vectors (x_cam = M @ x_world)",
            "light_name": m["light"]["name"], "light_rotation_deg": float(m["light"]["rotation_deg"]),
            "light_scale": float(m["light"]["scale"]),
        })

        UsdGeom.Scope.Define(stage, "/World/Looks")
        UsdGeom.Xform.Define(stage, "/World/Character")
        materials: dict[int, object] = {}
        for mesh in meshes:
            if hasattr(mesh, "fibre"):
                _curves(stage, UsdGeom, Vt, Gf, mesh)
                continue
            k = id(mesh.material.albedo)
            if k not in materials:
                materials[k] = _material(stage, f"/World/Looks/{mesh.name}_mat", mesh.material,
                                         _rel(assets.texture_files[k], stage_dir))
            prim = UsdGeom.Mesh.Define(stage, f"/World/Character/{mesh.name}")
            V = np.asarray(mesh.vertices, dtype=np.float32)
            prim.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(V))
            prim.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(mesh.faces), 3, dtype=np.int32)))
            prim.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(mesh.faces, np.int32).ravel()))
            prim.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(mesh.normals, dtype=np.float32)))
            prim.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
            prim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            prim.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
            prim.CreateDoubleSidedAttr(bool(mesh.material.two_sided))
            prim.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*V.min(0).tolist()), Gf.Vec3f(*V.max(0).tolist())]))
            st = UsdGeom.PrimvarsAPI(prim).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                         UsdGeom.Tokens.vertex)
            st.Set(Vt.Vec2fArray.FromNumpy(np.asarray(mesh.uvs, dtype=np.float32)))  # v up, as USD's st
            UsdShade.MaterialBindingAPI.Apply(prim.GetPrim()).Bind(materials[k])

        if smpl is not None:
            V, F, record = smpl
            body = UsdGeom.Mesh.Define(stage, "/World/SMPL")
            body.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(V, dtype=np.float32)))
            body.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(F), 3, dtype=np.int32)))
            body.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(F, np.int32).ravel()))
            body.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            body.CreatePurposeAttr(UsdGeom.Tokens.guide)  # the fitted body under the clothes: shown, not rendered
            body.GetPrim().SetCustomDataByKey("rh_smpl", record)

        cam = UsdGeom.Camera.Define(stage, "/World/Camera")
        for name, value in camera_attributes(m["camera"]["K"], m["width"], m["height"]).items():
            cam.GetPrim().GetAttribute(name).Set(value)
        cam.CreateProjectionAttr(UsdGeom.Tokens.perspective)
        cam.CreateClippingRangeAttr(Gf.Vec2f(0.01, 1000.0))
        cam.AddTransformOp().Set(_gf_matrix(camera_xform(m["camera"]["world_to_camera"])))

        texture, intensity = _light_texture(f, stage_dir, hdri_folder)
        dome = UsdLux.DomeLight.Define(stage, "/World/DomeLight")
        dome.CreateTextureFileAttr(Sdf.AssetPath(texture))
        dome.CreateTextureFormatAttr(UsdLux.Tokens.latlong)
        dome.CreateIntensityAttr(intensity)
        dome.AddTransformOp().Set(_gf_matrix(dome_xform(m["light"]["rotation_deg"])))

        stage.GetRootLayer().Save()
        del stage
        tmp.replace(final)  # atomic; relative asset paths stay valid (same folder)
        return [final]
    finally:
        if tmp.exists():  # interrupted (rh_common.interrupt) or failed before the rename: keep no partial stage
            tmp.unlink()


def _curves(stage, UsdGeom, Vt, Gf, strands) -> None:
    """Hair strands as one BasisCurves prim (see the module docstring)."""
    P = np.asarray(strands.points, dtype=np.float32)
    R = np.asarray(strands.radius, dtype=np.float32)
    P = np.concatenate([P[:, :1], P[:, :1], P, P[:, -1:], P[:, -1:]], 1)
    R = np.concatenate([R[:, :1], R[:, :1], R, R[:, -1:], R[:, -1:]], 1)
    prim = UsdGeom.BasisCurves.Define(stage, f"/World/Character/{strands.name}")
    prim.CreateTypeAttr(UsdGeom.Tokens.cubic)
    prim.CreateBasisAttr(UsdGeom.Tokens.bspline)
    prim.CreateWrapAttr(UsdGeom.Tokens.nonperiodic)
    prim.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(P.reshape(-1, 3))))
    prim.CreateCurveVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(P), P.shape[1], dtype=np.int32)))
    prim.CreateWidthsAttr(Vt.FloatArray.FromNumpy(np.ascontiguousarray(2.0 * R.ravel())))
    prim.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    V = P.reshape(-1, 3)
    prim.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*(V.min(0) - R.max()).tolist()),
                                         Gf.Vec3f(*(V.max(0) + R.max()).tolist())]))
    prim.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*[float(x) for x in strands.fibre.albedo])]))
    prim.GetPrim().SetCustomDataByKey("rh_hair_fibre", {
        "eumelanin": float(strands.fibre.eumelanin), "pheomelanin": float(strands.fibre.pheomelanin),
        "longitudinal_roughness": float(strands.fibre.longitudinal_roughness),
        "azimuthal_roughness": float(strands.fibre.azimuthal_roughness)})


def specular_to_ior(specular: float) -> float:
    """Principled-BSDF convention: F0 = 0.08 · specular = ((ior − 1)/(ior + 1))², so 0.5 → IOR 1.5."""
    r = float(np.sqrt(0.08 * float(specular)))
    return float((1.0 + r) / (1.0 - r))


def _material(stage, path: str, material, texture: str):
    Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, Vt = _pxr()
    mat = UsdShade.Material.Define(stage, path)
    pbr = UsdShade.Shader.Define(stage, f"{path}/PreviewSurface")
    pbr.CreateIdAttr("UsdPreviewSurface")
    pbr.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(material.roughness))
    pbr.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    pbr.CreateInput("ior", Sdf.ValueTypeNames.Float).Set(specular_to_ior(material.specular))
    coat = float(getattr(material, "clearcoat", 0.0))
    if coat > 0.0:  # the eyes' tear film; Disney's clear-coat roughness is lerp(0.1, 0.001, gloss)
        pbr.CreateInput("clearcoat", Sdf.ValueTypeNames.Float).Set(coat)
        gloss = float(getattr(material, "clearcoat_gloss", 0.0))
        pbr.CreateInput("clearcoatRoughness", Sdf.ValueTypeNames.Float).Set(0.1 + (0.001 - 0.1) * gloss)
    reader = UsdShade.Shader.Define(stage, f"{path}/stReader")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set("st")
    tex = UsdShade.Shader.Define(stage, f"{path}/albedoTexture")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(texture))
    tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
    tex.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    pbr.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(tex.ConnectableAPI(), "rgb")
    mat.CreateSurfaceOutput().ConnectToSource(pbr.ConnectableAPI(), "surface")
    return mat
