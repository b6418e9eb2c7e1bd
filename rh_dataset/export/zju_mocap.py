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

A multi-view split (protocol c) is one sequence with every camera of the split, as ZJU-MoCap's captures are: the
images of camera `cam_NN` in `cam_NN/`, `mask/cam_NN/`, `mask_cihp/cam_NN/`, the frame records in `rh/cam_NN/`,
cams K/R/T/D one entry per camera in the order of `annots['rh']['views']`, and ims[i]['ims'] frame i's image from
each camera in that order (NeuralBody's `training_view` indexes it); params/ and vertices/ once per frame (the body
is in world coordinates, the same in every view). Protocol c's train and novel_view splits show the same poses under
the same light from the 10 training and the 6 held-out cameras: `<subject>/capture/` holds them together as one
16-camera sequence, the way ZJU-MoCap's captures are split by NeuralBody (`annots['rh']['training_view']`: the
train split's cameras, NeuralBody's `cfg.training_view`; the other cameras are its test views).

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

__all__ = ["CAMERA", "CAPTURE", "capture_splits", "camera_name", "export_frame", "write_annots", "read_annots",
           "frame_params", "posed_body_vertices"]

CAMERA = "Camera_B1"
CAPTURE = "capture"
"""The sequence of protocol c's train split and the splits under its light (novel_view): every camera at once."""
PHENOTYPE_ORDER = ("gender", "age", "muscle", "weight", "height", "proportions")


def sequence_dir(out: Path, f: FrameRef) -> Path:
    return Path(out) / f.subject / f.split


def capture_splits(spec: dict) -> list[str]:
    """The splits of a dataset.json spec that form one multi-camera capture: a multi-view train split and every
    split showing its poses under its light from other cameras (protocol c: train, novel_view); [] if none."""
    splits = spec.get("splits", [])
    held = [s["name"] for s in splits if s.get("cameras") and s["light"] == "train" and s["poses"] == "train"]
    has_train = any(s["name"] == "train" and s.get("cameras") for s in splits)
    return ["train", *held] if held and has_train else []


def camera_name(f: FrameRef) -> str:
    """The image folder of the frame's camera: the camera of a multi-view split (cam_NN), else 'Camera_B1'."""
    return CAMERA if f.view is None else f.view


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
                 smpl: tuple[dict, np.ndarray] | None = None, smplx: tuple[dict, np.ndarray] | None = None,
                 body: bool = True) -> list[Path]:
    """Write one frame. `smpl`: (params, (6890, 3) world vertices) of the frame's SMPL fit (export/smpl.py
    `SmplFits.zju_params`); then params/ and vertices/ hold SMPL as NeuralBody reads them, and anny's numbers move
    to `anny_*` keys and vertices_anny/. `smplx`: the same for SMPL-X, in params_smplx/ and vertices_smplx/.
    `body=False` writes only the camera's images and record (a multi-view frame's body is written once)."""
    d = sequence_dir(out, f)
    name = f"{f.index:06d}.png"
    cam = camera_name(f)
    img = d / cam / name
    with atomic_path(img) as tmp:
        tmp.write_bytes(f.layer("image.png").read_bytes())
    mask = np.where(read_png(f.layer("mask.png")) >= 128, 255, 0).astype(np.uint8)
    write_png(d / "mask" / cam / name, mask)
    write_png(d / "mask_cihp" / cam / name, mask)
    written = [img, d / "mask" / cam / name, d / "mask_cihp" / cam / name]
    rh_dir = d / "rh" if f.view is None else d / "rh" / f.view
    write_json(rh_dir / layout.frame_json_name(f.index), {k: v for k, v in f.meta.items() if k != "files"})
    if not body:
        return written
    params = frame_params(f.meta)
    anny_vertices = "vertices"
    if smpl is not None:
        params = {**smpl[0], **{f"anny_{k}": v for k, v in params.items() if k != "model"}}
        anny_vertices = "vertices_anny"
    save_npy(d / "params" / f"{f.index}.npy", params)
    written.append(d / "params" / f"{f.index}.npy")
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
    return written


def write_annots(seq_dir: Path, frames: list[FrameRef], training: list[str] | None = None) -> Path:
    """annots.npy of one sequence from its frames: one camera (the subject's), or every camera of a multi-view
    split, each frame seen by all of them. `training`: the cameras a method trains on (the capture sequence),
    recorded as their indices in `annots['rh']['training_view']`."""
    if not frames:
        raise ValueError(f"{seq_dir}: no frames")
    views = sorted({camera_name(f) for f in frames})
    by_view = {v: sorted((f for f in frames if camera_name(f) == v), key=lambda f: f.index) for v in views}
    indices = [f.index for f in by_view[views[0]]]
    Ks, Rs, Ts = [], [], []
    for v in views:
        fs = by_view[v]
        if [f.index for f in fs] != indices:
            raise ValueError(f"{fs[0].split_dir}: camera {v} has frames {[f.index for f in fs]}, camera {views[0]} "
                             f"{indices}: every camera of a sequence must see every frame (rerun rh-generate)")
        cam = fs[0].meta["camera"]
        w2c = np.array(cam["world_to_camera"], dtype=np.float64)
        for f in fs[1:]:
            if not np.array_equal(np.array(f.meta["camera"]["world_to_camera"]), w2c):
                raise ValueError(f"{f.split_dir}: frames of one camera must share the camera")
        Ks.append(client_K(cam["K"]))  # NeuralBody casts rays through integer pixel coordinates
        Rs.append(w2c[:3, :3].copy())
        Ts.append(w2c[:3, 3:4] * 1000.0)  # millimetres, as ZJU-MoCap stores it
    annots = {
        "cams": {"K": Ks, "R": Rs, "T": Ts, "D": [np.zeros((5, 1)) for _ in views]},
        "ims": [{"ims": [f"{v}/{i:06d}.png" for v in views]} for i in indices],
        "rh": {"units_T": "mm", "camera": "OpenCV world_to_camera", "width": frames[0].meta["width"],
               "height": frames[0].meta["height"]},
    }
    if frames[0].view is not None:
        annots["rh"]["views"] = views  # the camera of each cams entry and ims position (multi-view only)
    if training is not None:
        annots["rh"]["training_view"] = [views.index(v) for v in training]
    path = Path(seq_dir) / "annots.npy"
    save_npy(path, annots)
    return path


def read_annots(seq_dir: Path) -> dict:
    return np.load(Path(seq_dir) / "annots.npy", allow_pickle=True).item()
