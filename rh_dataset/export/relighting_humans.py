"""Export to the published Relighting Humans (RANA) layout, so code written for that dataset reads ours.

In: the frames of one protocol of a finished dataset. Out (docs/INTEROP.md "Relighting Humans" has every field):

    <out>/train_p1/subject_01/frame_000000.png            display-space sRGB render (our _image.png)
                              frame_000000_semantic.png   RGBA; alpha 0/255 = our mask (coverage >= 0.5)
                              frame_000000_albedo.png     linear 8-bit   } when the source split has the layer
                              frame_000000_normals.png    OpenGL camera  } (scenes published_a/b: every split)
                              frame_000000.json           K, fov, yaw, bg_file, body parameters, our record
    <out>/test/subject_01/    ... the same
    <out>/hdri/rh_<light>_<hash>.hdr|.exr                 each frame's light, baked (export/rh_light.py)
    <out>/README.md                                       what this export can and cannot serve

Protocol a maps to train_p1/ + test/, protocol b to train_p2_p3/ + test/, as the published folders are named.
With --smpl-model, `skeleton_0.smpl_data` holds SMPL fitted to the frame's anny body (export/smpl.py) and anny's
numbers move to `anny_*` keys; without it, anny's numbers stand in SMPL's keys and the README says who fails.
With --smplx-model, `skeleton_0.smplx_data` holds SMPL-X fitted the same way (beside smpl_data, which is unchanged).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rh_common import layout
from rh_common.colourspace import quantize8
from rh_common.imageio import atomic_path, read_exr, read_png, write_json, write_png
from rh_dataset.poses import ANNY_BONE_LABELS
from rh_dataset.poses.joints import axis_angle

from .common import FrameRef, client_K, root_motion, subject_index
from .rh_light import bake_frame_light

__all__ = ["export_frame", "split_folder", "subject_folder", "rh_json", "write_readme", "PUBLISHED_SIZE"]

PUBLISHED_SIZE = (1280, 720)
"""Width, height of the published frames: IntrinsicAvatar's test camera and Gaussian Shadow Casting assume it."""

PHENOTYPE_ORDER = ("gender", "age", "muscle", "weight", "height", "proportions")


def split_folder(protocol: str, split: str) -> str:
    """The published folder names: `test/` is shared by every protocol there, so one protocol goes to one --out."""
    if split == "test":
        return "test"
    if split == "train":
        return {"a": "train_p1", "b": "train_p2_p3"}[protocol]
    return f"{split}_p{protocol}"


def subject_folder(subject: str) -> str:
    """subject_000 → subject_01 (two digits, 1-based, as the published folders are named)."""
    return f"subject_{subject_index(subject) + 1:02d}"


def _copy(src: Path, dst: Path) -> None:
    data = src.read_bytes()
    with atomic_path(dst) as tmp:
        tmp.write_bytes(data)


def rh_json(f: FrameRef, bake: dict, smpl: dict | None = None, smplx: dict | None = None) -> dict:
    """The frame JSON in the published key layout, plus our full record under 'rh'. `bake` is the frame's baked
    light (`rh_light.bake_frame_light`). `smpl`: the frame's SMPL block (export/smpl.py `SmplFits.rh_block`); then
    `smpl_data` holds SMPL's numbers and anny's keep their place under `anny_*` names; without it, anny's numbers
    stand in SMPL's keys (and the README says which clients that cannot serve). `smplx`: the frame's SMPL-X block,
    written as `skeleton_0.smplx_data` (with the client camera's K)."""
    m = f.meta
    K = client_K(m["camera"]["K"])
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
    if smpl is not None:
        anny = {f"anny_{k}": v for k, v in smpl_data.items() if k not in ("model", "K", "scale")}
        smpl_data = {**smpl, "K": K.tolist(), **anny}
    rec = {k: v for k, v in m.items() if k != "files"}
    out = {
        "format": "rh-export/relighting-humans/1",
        "skeleton_0": {"smpl_data": smpl_data,
                       **({} if smplx is None else {"smplx_data": {**smplx, "K": K.tolist()}})},
        "camera": {
            # The loaders build the test camera as f = 0.5 · width / tan(fov / 2): the horizontal fov, radians.
            "fov": 2.0 * math.atan(0.5 * m["width"] / K[0, 0]),
            "fov_axis": "horizontal",
            "fov_y": 2.0 * math.atan(0.5 * m["height"] / K[1, 1]),
            "yaw": 0.0,
            "width": m["width"],
            "height": m["height"],
            "K": K.tolist(),
            "pixel_centres": "integer (K's cx, cy = ours - 0.5)",
            "extrinsic": np.eye(4).tolist(),
        },
        "bg_file": bake["file"],
        "hdri_name": m["light"]["name"],
        "rh_bake": bake,
        "rh": rec,
    }
    return out


def export_frame(f: FrameRef, out: Path, protocol: str, *, hdri_folder: str | None = None,
                 baked: dict | None = None, smpl: dict | None = None, smplx: dict | None = None) -> list[Path]:
    """Write one frame; `baked` (stem → record) is shared by the frames of one export so each light bakes once;
    `smpl`, `smplx` as in `rh_json`."""
    d = Path(out) / split_folder(protocol, f.split) / subject_folder(f.subject)
    stem = f"frame_{f.index:06d}"
    written = []
    _copy(f.layer("image.png"), d / f"{stem}.png")
    written.append(d / f"{stem}.png")
    cov = read_png(f.layer("mask.png"))
    # Binary alpha: one loader reads alpha > 0.5 as the person, another keeps an alpha of exactly 128 as 128;
    # 0/255 at our mask rule (coverage >= 128) reads the same in both. The coverage stays in the source dataset.
    person = np.where(cov >= 128, 255, 0).astype(np.uint8)
    rgba = np.repeat(person[..., None], 4, axis=-1)
    write_png(d / f"{stem}_semantic.png", rgba)
    written.append(d / f"{stem}_semantic.png")
    if f.layer("albedo.exr").is_file():
        # The published albedo is read as linear: store linear values (not our sRGB-encoded _albedo.png).
        write_png(d / f"{stem}_albedo.png", quantize8(read_exr(f.layer("albedo.exr"))))
        written.append(d / f"{stem}_albedo.png")
    if f.layer("normal.png").is_file():
        _copy(f.layer("normal.png"), d / f"{stem}_normals.png")  # same encoding: (n + 1) / 2 * 255, OpenGL axes
        written.append(d / f"{stem}_normals.png")
    bake = bake_frame_light(f.meta, hdri_folder, Path(out), {} if baked is None else baked,
                            str(layout.frame_json_path(f.split_dir, f.index)))
    write_json(d / f"{stem}.json", rh_json(f, bake, smpl, smplx))
    written.append(d / f"{stem}.json")
    return written


_CLIENTS = "IntrinsicAvatar and DNF-Avatar (scripts/preprocess_RANA.py), Gaussian Shadow Casting (rana_to_h5.ipynb)"


def write_readme(out: Path, protocol: str, frames: list[FrameRef], baked: dict, smpl=None, smplx=None) -> list[str]:
    """`<out>/README.md`: the layout, and plainly which published clients this export cannot serve and why.
    `smpl`: the SMPL model the frames were fitted with (a `BodyModel`), or None. Returns those limits (one line
    each), which the CLI also prints."""
    if smpl is None:
        limits = ["no SMPL parameters: `skeleton_0.smpl_data` holds anny's body (6 phenotype values, 309 pose "
                  f"values), so {_CLIENTS} stop where they evaluate SMPL; `joints` and `vertices` are absent "
                  "(export with --smpl-model DIR, the folder of your own SMPL files, to fit SMPL to every frame)"]
    elif smpl.extra.get("rh_standin"):
        limits = [f"`skeleton_0.smpl_data` was fitted with the stand-in model {Path(smpl.path).name} (sha256 "
                  f"{smpl.sha256[:12]}…, rh-export --write-test-smpl): a body built from anny in SMPL's file format, "
                  "NOT SMPL; the clients run with it, but nothing measured with it is an SMPL result (export with "
                  "your own SMPL files for that)"]
    else:
        limits = []
    if smplx is not None and smplx.extra.get("rh_standin"):
        limits.append(f"`skeleton_0.smplx_data` was fitted with the stand-in model {Path(smplx.path).name} (sha256 "
                      f"{smplx.sha256[:12]}…, rh-export --write-test-smplx): a body built from anny in SMPL-X's file "
                      "format, NOT SMPL-X; nothing measured with it is an SMPL-X result")
    no_gt = sorted({split_folder(protocol, f.split) for f in frames
                    if not (f.layer("albedo.exr").is_file() and f.layer("normal.png").is_file())})
    if no_gt:
        limits.append(f"{', '.join(no_gt)} has no _albedo.png / _normals.png (the source split does not render them): "
                      "IntrinsicAvatar and DNF-Avatar preprocessing copy both for every split and stop there; "
                      "generate with --protocol published_a / published_b, whose train split renders them")
    sizes = sorted({(f.meta["width"], f.meta["height"]) for f in frames})
    if sizes != [PUBLISHED_SIZE]:
        limits.append(f"frames are {', '.join(f'{w}x{h}' for w, h in sizes)}, not 1280x720: IntrinsicAvatar's test "
                      "camera and Gaussian Shadow Casting's reshape assume 1280x720 (generate with "
                      "--resolution 1280x720, the published_a / published_b default)")
    splits = sorted({split_folder(protocol, f.split) for f in frames})
    text = ["# Relighting Humans layout (rh-export --format relighting-humans)", "",
            f"Protocol {protocol}: {', '.join(f'`{s}/`' for s in splits)}; {len(frames)} frames; "
            f"{len(baked)} baked lights in `hdri/` (copy `hdri/*.hdr` into IntrinsicAvatar's `<out-dir>/hdri/`, "
            "`hdri/*.exr` into Gaussian Shadow Casting's `./data/HDRis/`).", "",
            "The fields and what still differs from the published data: docs/INTEROP.md, \"Relighting Humans\".", "",
            "## What this export cannot serve", ""]
    text += [f"- {x}" for x in limits] or ["- nothing known"]
    with atomic_path(Path(out) / "README.md") as tmp:
        tmp.write_text("\n".join(text) + "\n", encoding="utf-8")
    return limits
