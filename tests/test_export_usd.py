"""rh-export --format usd: stages read back with pxr; the camera projects like K @ world_to_camera."""
from __future__ import annotations

import math

import numpy as np
import pytest

import pxr

from export_data import tiny_dataset  # noqa: E402
from rh_common.imageio import read_json, read_png  # noqa: E402
from rh_dataset.export import main as export_main  # noqa: E402
from rh_dataset.export import usd as rh_usd  # noqa: E402


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    ds = tiny_dataset(tmp_path_factory)
    out = tmp_path_factory.mktemp("usd") / "out"
    assert export_main(["--dataset", str(ds), "--format", "usd", "--out", str(out), "--no-progress"]) == 0
    return ds, out


def _project_k(meta: dict, pts: np.ndarray) -> np.ndarray:
    K, w2c = np.array(meta["camera"]["K"]), np.array(meta["camera"]["world_to_camera"])
    p = (pts @ w2c[:3, :3].T + w2c[:3, 3]) @ K.T
    return p[:, :2] / p[:, 2:]


@pytest.mark.parametrize("split", ["train", "test"])
def test_stage_meshes_camera_and_light(exported, split):
    from pxr import Usd, UsdGeom, UsdLux, UsdShade

    from rh_dataset.characters import CharacterRecipe, build_character, pose_character
    from rh_dataset.poses import BodyPose

    ds, out = exported
    meta = read_json(ds / "subject_000" / "protocol_a" / split / "frame_000001.json")
    path = out / "subject_000" / "protocol_a" / split / "frame_000001.usdc"
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    # Meshes: one per character part, with the posed vertices and the faces pose_character gives.
    character = build_character(CharacterRecipe.from_json(read_json(ds / "subject_000" / "character.json")),
                                drape="coarse")  # export_data generates with --drape coarse
    pose = BodyPose.from_json(meta["body"]["pose"])
    posed = pose_character(character, dict(pose.bones), pose.root_transform)
    strands = [p for p in posed if hasattr(p, "fibre")]
    posed = [p for p in posed if not hasattr(p, "fibre")]
    meshes = [UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert sorted(m.GetPrim().GetName() for m in meshes) == sorted(p.name for p in posed)
    # Hair: one BasisCurves per fibre, the renderer's control points (ends repeated twice more) and 2 x radius.
    assert strands
    for ps in strands:
        c = UsdGeom.BasisCurves(stage.GetPrimAtPath(f"/World/Character/{ps.name}"))
        assert c.GetBasisAttr().Get() == UsdGeom.Tokens.bspline
        counts = np.array(c.GetCurveVertexCountsAttr().Get())
        assert len(counts) == len(ps.points) and set(counts) == {ps.points.shape[1] + 4}
        pts = np.array(c.GetPointsAttr().Get()).reshape(len(ps.points), -1, 3)
        np.testing.assert_array_equal(pts[:, 2:-2], ps.points)
        np.testing.assert_allclose(np.array(c.GetWidthsAttr().Get()).reshape(len(ps.points), -1)[:, 2:-2],
                                   2 * ps.radius, rtol=1e-6)
    for pm in posed:
        m = UsdGeom.Mesh(stage.GetPrimAtPath(f"/World/Character/{pm.name}"))
        pts = np.array(m.GetPointsAttr().Get())
        assert pts.shape == pm.vertices.shape
        np.testing.assert_array_equal(pts, pm.vertices)
        np.testing.assert_array_equal(np.array(m.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3), pm.faces)
        assert set(m.GetFaceVertexCountsAttr().Get()) == {3}
        assert len(UsdGeom.PrimvarsAPI(m).GetPrimvar("st").Get()) == len(pm.vertices)
        mat, _ = UsdShade.MaterialBindingAPI(m.GetPrim()).ComputeBoundMaterial()
        tex = UsdShade.Shader(stage.GetPrimAtPath(mat.GetPath().AppendChild("albedoTexture")))
        asset = tex.GetInput("file").Get()
        png = (path.parent / asset.path).resolve()
        assert png.is_file() and read_png(png).shape == pm.material.albedo.shape
    # Camera: USD's frustum maths projects a vertex where K @ world_to_camera does.
    body = posed[0].vertices[::997].astype(np.float64)
    np.testing.assert_allclose(rh_usd.usd_project(path, body), _project_k(meta, body), atol=1e-3)
    # Dome light: the frame's HDRI, intensity = scale.
    dome = UsdLux.DomeLight(stage.GetPrimAtPath("/World/DomeLight"))
    assert dome.GetTextureFileAttr().Get().path.endswith(meta["light"]["source"])
    assert dome.GetIntensityAttr().Get() == pytest.approx(meta["light"]["scale"])


def test_an_off_centre_non_square_camera_projects_like_k(tmp_path):
    """camera_attributes / camera_xform alone, with a principal point off the centre and fx != fy."""
    from pxr import Gf, Usd, UsdGeom

    W, H = 40, 30
    K = np.array([[55.0, 0, 23.5], [0, 48.0, 12.25], [0, 0, 1]])
    a = math.radians(25)
    w2c = np.eye(4)
    w2c[:3, :3] = np.array([[math.cos(a), 0, -math.sin(a)], [0, 1, 0], [math.sin(a), 0, math.cos(a)]]) @ \
        np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    w2c[:3, 3] = (0.1, -0.2, 4.0)
    path = tmp_path / "cam.usda"
    stage = Usd.Stage.CreateNew(str(path))
    world = UsdGeom.Xform.Define(stage, "/World")
    world.GetPrim().SetCustomDataByKey("rh", {"width": W, "height": H})
    cam = UsdGeom.Camera.Define(stage, "/World/Camera")
    for k, v in rh_usd.camera_attributes(K, W, H).items():
        cam.GetPrim().GetAttribute(k).Set(v)
    cam.AddTransformOp().Set(Gf.Matrix4d(rh_usd.camera_xform(w2c).T.tolist()))
    stage.GetRootLayer().Save()
    pts = np.random.default_rng(0).uniform(-0.8, 0.8, (20, 3))
    meta = {"camera": {"K": K, "world_to_camera": w2c}}
    np.testing.assert_allclose(rh_usd.usd_project(path, pts), _project_k(meta, pts), atol=1e-3)  # float32 attributes


def test_dome_light_transform_maps_directions_to_our_equirect_pixels():
    """OpenEXR latlong (USD's DomeLight, pole +Y) under dome_xform = our mapping (ARCHITECTURE.md) rotated."""
    rng = np.random.default_rng(1)
    for rot in (0.0, 37.5, 290.0):
        T = rh_usd.dome_xform(rot)[:3, :3]
        d = rng.normal(size=(200, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        local = d @ T  # = T^T d: world → dome-local
        lon, lat = np.arctan2(local[:, 0], local[:, 2]), np.arcsin(np.clip(local[:, 1], -1, 1))
        u_usd, v_usd = (math.pi - lon) / (2 * math.pi), (math.pi / 2 - lat) / math.pi
        c, s = math.cos(math.radians(-rot)), math.sin(math.radians(-rot))
        lf = d @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T  # world → the light's own frame
        u_rh = (0.5 - np.arctan2(lf[:, 1], lf[:, 0]) / (2 * math.pi)) % 1.0
        v_rh = np.arccos(np.clip(lf[:, 2], -1, 1)) / math.pi
        du = (u_usd - u_rh + 0.5) % 1.0 - 0.5
        np.testing.assert_allclose(du, 0, atol=1e-9)
        np.testing.assert_allclose(v_usd, v_rh, atol=1e-9)
