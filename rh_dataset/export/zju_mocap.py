"""Export to the ZJU-MoCap layout the NeuralBody family (NeuralBody, Animatable NeRF, Relighting4D...) reads.

One sequence per (subject, split), one camera ('Camera_B1', our fixed per-subject camera):

    <out>/<subject>/<split>/annots.npy            {'cams': {'K','R','T','D'} one entry each, 'ims': [{'ims': [path]}]}
                            Camera_B1/000000.png  display-space sRGB render
                            mask/Camera_B1/000000.png, mask_cihp/...  0/255, coverage > 0.5
                            params/0.npy          {'poses','Rh','Th','shapes', ...} (anny, see docs/INTEROP.md)
                            vertices/0.npy        (V, 3) float32 posed anny body in world metres
    with --smpl-model:      params/0.npy          SMPL: poses (1,72) root zero, Rh, Th, shapes (1,10); anny_* keys
                            vertices/0.npy        (6890, 3) float32 that SMPL body in world metres
                            vertices_anny/0.npy   the posed anny body
    with --smplx-model:     params_smplx/0.npy    SMPL-X: poses (1,165) root zero, Rh, Th, shapes (1,10), expression
                                                  (1,10), and the pose split as smplx takes it (body_pose, ...)
                            vertices_smplx/0.npy  (10475, 3) float32 that SMPL-X body in world metres
                            rh/frame_000000.json  our frame record (light, SH, exposure)

As in ZJU-MoCap, cams['T'] is in millimetres (NeuralBody divides it by 1000), R/T map world to OpenCV camera
coordinates, and params/<i>.npy belongs to image <i>.png (NeuralBody parses the index from the file name).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from rh_common import layout
from rh_common.imageio import atomic_path, read_png, write_json, write_png
from rh_dataset.poses import ANNY_BONE_LABELS, BodyPose
from rh_dataset.poses.joints import axis_angle

from .common import FrameRef, client_K, root_motion, save_npy

__all__ = ["CAMERA", "export_frame", "write_annots", "read_annots", "frame_params", "posed_body_vertices"]

CAMERA = "Camera_B1"
PHENOTYPE_ORDER = ("gender", "age", "muscle", "weight", "height", "proportions")


def sequence_dir(out: Path, f: FrameRef) -> Path:
    return Path(out) / f.subject / f.split


def frame_params(meta: dict) -> dict:
    """The params/<i>.npy dict: ZJU's keys with anny's content.

    poses (1, 312): axis-angle of anny's 104 'local-ref' bone deltas in ANNY_BONE_LABELS order, the root's 3
    entries zero (its motion is in Rh/Th); Rh (1, 3) axis-angle and Th (1, 3) metres: the rigid world motion of
    the pelvis (x_world = R(Rh) x + Th for the body posed with `poses`); shapes (1, 6): the anny phenotype in
    `shape_labels` order. `rh_pose` is the exact BodyPose JSON text (lossless).
    """
    pose = meta["body"]["pose"]
    G = root_motion(pose)
    bones = pose["bones"]
    poses = np.zeros((1, 3 * len(ANNY_BONE_LABELS)))
    for j, b in enumerate(ANNY_BONE_LABELS):
        if b in bones and b != "root":
            poses[0, 3 * j:3 * j + 3] = axis_angle(np.array(bones[b])[:3, :3])
    phen = meta["body"]["phenotype"]
    import json

    return {
        "poses": poses,
        "Rh": axis_angle(G[:3, :3])[None],
        "Th": G[:3, 3][None].copy(),
        "shapes": np.array([[float(phen[k]) for k in PHENOTYPE_ORDER]]),
        "shape_labels": list(PHENOTYPE_ORDER),
        "bone_labels": list(ANNY_BONE_LABELS),
        "model": "anny",
        "rh_pose": json.dumps(pose, sort_keys=True),
    }


def posed_body_vertices(meta: dict) -> np.ndarray:
    """(V, 3) float32 world vertices of the posed anny body (topology anny-noeyes-notongue), as rendered."""
    from rh_dataset.characters.body import run_anny

    pose = BodyPose.from_json(meta["body"]["pose"])
    v = run_anny(meta["body"]["phenotype"], dict(pose.bones) or None)["vertices"]
    return pose.apply_root_transform(v).astype(np.float32)


def export_frame(f: FrameRef, out: Path, protocol: str, *, vertices: bool = True,
                 smpl: tuple[dict, np.ndarray] | None = None, smplx: tuple[dict, np.ndarray] | None = None
                 ) -> list[Path]:
    """Write one frame. `smpl`: (params, (6890, 3) world vertices) of the frame's SMPL fit (export/smpl.py
    `SmplFits.zju_params`); then params/ and vertices/ hold SMPL as NeuralBody reads them, and anny's numbers move
    to `anny_*` keys and vertices_anny/. `smplx`: the same for SMPL-X, in params_smplx/ and vertices_smplx/."""
    d = sequence_dir(out, f)
    name = f"{f.index:06d}.png"
    img = d / CAMERA / name
    with atomic_path(img) as tmp:
        tmp.write_bytes(f.layer("image.png").read_bytes())
    mask = np.where(read_png(f.layer("mask.png")) >= 128, 255, 0).astype(np.uint8)
    write_png(d / "mask" / CAMERA / name, mask)
    write_png(d / "mask_cihp" / CAMERA / name, mask)
    params = frame_params(f.meta)
    anny_vertices = "vertices"
    if smpl is not None:
        params = {**smpl[0], **{f"anny_{k}": v for k, v in params.items() if k != "model"}}
        anny_vertices = "vertices_anny"
    save_npy(d / "params" / f"{f.index}.npy", params)
    written = [img, d / "mask" / CAMERA / name, d / "mask_cihp" / CAMERA / name, d / "params" / f"{f.index}.npy"]
    if vertices:
        save_npy(d / anny_vertices / f"{f.index}.npy", posed_body_vertices(f.meta))
        written.append(d / anny_vertices / f"{f.index}.npy")
        if smpl is not None:
            save_npy(d / "vertices" / f"{f.index}.npy", smpl[1])
            written.append(d / "vertices" / f"{f.index}.npy")
    if smplx is not None:
        save_npy(d / "params_smplx" / f"{f.index}.npy", smplx[0])
        written.append(d / "params_smplx" / f"{f.index}.npy")
        if vertices:
            save_npy(d / "vertices_smplx" / f"{f.index}.npy", smplx[1])
            written.append(d / "vertices_smplx" / f"{f.index}.npy")
    write_json(d / "rh" / layout.frame_json_name(f.index), {k: v for k, v in f.meta.items() if k != "files"})
    return written


def write_annots(seq_dir: Path, frames: list[FrameRef]) -> Path:
    """annots.npy of one sequence from its frames (all share the subject's camera)."""
    if not frames:
        raise ValueError(f"{seq_dir}: no frames")
    cam = frames[0].meta["camera"]
    w2c = np.array(cam["world_to_camera"], dtype=np.float64)
    for f in frames[1:]:
        if not np.array_equal(np.array(f.meta["camera"]["world_to_camera"]), w2c):
            raise ValueError(f"{f.split_dir}: frames of one sequence must share the camera")
    annots = {
        "cams": {
            "K": [client_K(cam["K"])],  # NeuralBody casts rays through integer pixel coordinates
            "R": [w2c[:3, :3].copy()],
            "T": [w2c[:3, 3:4] * 1000.0],  # millimetres, as ZJU-MoCap stores it
            "D": [np.zeros((5, 1))],
        },
        "ims": [{"ims": [f"{CAMERA}/{f.index:06d}.png"]} for f in sorted(frames, key=lambda f: f.index)],
        "rh": {"units_T": "mm", "camera": "OpenCV world_to_camera", "width": frames[0].meta["width"],
               "height": frames[0].meta["height"]},
    }
    path = Path(seq_dir) / "annots.npy"
    save_npy(path, annots)
    return path


def read_annots(seq_dir: Path) -> dict:
    return np.load(Path(seq_dir) / "annots.npy", allow_pickle=True).item()
