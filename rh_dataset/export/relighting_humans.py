"""Export to the published Relighting Humans (RANA) layout, so code written for that dataset reads ours.

    <out>/train_p1/subject_01/frame_000000.png            display-space sRGB render (our _image.png)
                              frame_000000_semantic.png   RGBA; alpha = coverage (alpha > 0.5 is the mask)
                              frame_000000.json           camera K, body parameters ('skeleton_0.smpl_data')
    <out>/test/subject_01/    ... the same, plus _albedo.png (linear, 8-bit), _normals.png (OpenGL camera space),
                              and the HDRI name ('bg_file') and camera fov in the JSON

Protocol b maps to train_p2/ and test_p2/. Everything that differs from the published data is listed in
docs/INTEROP.md ("Relighting Humans layout").
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rh_common.colourspace import quantize8
from rh_common.imageio import atomic_path, read_exr, read_png, write_json, write_png
from rh_dataset.poses import ANNY_BONE_LABELS

from .common import FrameRef, axis_angle, root_motion, subject_index

__all__ = ["export_frame", "split_folder", "subject_folder", "rh_json"]

PHENOTYPE_ORDER = ("gender", "age", "muscle", "weight", "height", "proportions")


def split_folder(protocol: str, split: str) -> str:
    if protocol == "a":
        return {"train": "train_p1", "test": "test"}[split]
    return f"{split}_p2" if protocol == "b" else f"{split}_{protocol}"


def subject_folder(subject: str) -> str:
    """subject_000 → subject_01 (two digits, 1-based, as the published folders are named)."""
    return f"subject_{subject_index(subject) + 1:02d}"


def _copy(src: Path, dst: Path) -> None:
    data = src.read_bytes()
    with atomic_path(dst) as tmp:
        tmp.write_bytes(data)


def rh_json(f: FrameRef) -> dict:
    """The frame JSON in the published key layout (anny in place of SMPL), plus our full record under 'rh'."""
    m = f.meta
    K = np.array(m["camera"]["K"], dtype=np.float64)
    w2c = np.array(m["camera"]["world_to_camera"], dtype=np.float64)
    pose = m["body"]["pose"]
    G = root_motion(pose)  # world motion of the pelvis
    R_cam = w2c[:3, :3] @ G[:3, :3]
    t_cam = w2c[:3, :3] @ G[:3, 3] + w2c[:3, 3]
    bones = pose["bones"]
    body_pose = np.concatenate([axis_angle(np.array(bones[b])[:3, :3]) if b in bones else np.zeros(3)
                                for b in ANNY_BONE_LABELS[1:]])
    phen = m["body"]["phenotype"]
    smpl_data = {
        "model": "anny",
        "gender": "neutral",
        "anny_gender": float(phen["gender"]),
        "K": K.tolist(),
        "pose": body_pose.tolist(),
        "pose_bones": list(ANNY_BONE_LABELS[1:]),
        "pose_parameterization": "anny local-ref axis-angle (world-aligned bone axes), not SMPL parent-relative",
        "betas": [float(phen[k]) for k in PHENOTYPE_ORDER],
        "betas_labels": list(PHENOTYPE_ORDER),
        "global_orient": axis_angle(R_cam).tolist(),
        "global_trans": t_cam.tolist(),
        "scale": 1.0,
    }
    rec = {k: v for k, v in m.items() if k != "files"}
    out = {
        "format": "rh-export/relighting-humans/1",
        "skeleton_0": {"smpl_data": smpl_data},
        "camera": {
            "fov": 2.0 * math.atan(0.5 * m["height"] / K[1, 1]),
            "fov_axis": "vertical",
            "fov_x": 2.0 * math.atan(0.5 * m["width"] / K[0, 0]),
            "yaw": 0.0,
            "width": m["width"],
            "height": m["height"],
            "K": K.tolist(),
            "extrinsic": np.eye(4).tolist(),
        },
        "rh": rec,
    }
    if f.split == "test":
        out["bg_file"] = m["light"]["source"] if m["light"]["kind"] == "envmap" else ""
        out["hdri_name"] = m["light"]["name"]
    return out


def export_frame(f: FrameRef, out: Path, protocol: str) -> list[Path]:
    d = Path(out) / split_folder(protocol, f.split) / subject_folder(f.subject)
    stem = f"frame_{f.index:06d}"
    written = []
    _copy(f.layer("image.png"), d / f"{stem}.png")
    written.append(d / f"{stem}.png")
    cov = read_png(f.layer("mask.png"))
    rgba = np.zeros(cov.shape + (4,), np.uint8)
    rgba[..., :3] = np.where(cov[..., None] > 0, 255, 0)
    rgba[..., 3] = cov
    write_png(d / f"{stem}_semantic.png", rgba)
    written.append(d / f"{stem}_semantic.png")
    if f.layer("albedo.exr").is_file():
        # The published albedo is read as linear: store linear values (not our sRGB-encoded _albedo.png).
        write_png(d / f"{stem}_albedo.png", quantize8(read_exr(f.layer("albedo.exr"))))
        written.append(d / f"{stem}_albedo.png")
    if f.layer("normal.png").is_file():
        _copy(f.layer("normal.png"), d / f"{stem}_normals.png")  # same encoding: (n + 1) / 2 * 255, OpenGL axes
        written.append(d / f"{stem}_normals.png")
    write_json(d / f"{stem}.json", rh_json(f))
    written.append(d / f"{stem}.json")
    return written
