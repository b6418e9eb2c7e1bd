"""Reading one subject's frames (docs/ARCHITECTURE.md layout) at RANA's working resolution.

Images are linear HDR radiance; RANA works on ``exposure * radiance`` (the frame's `exposure` field), so a training
video's values sit around [0, 1] whatever the light's absolute scale. The learned light E is then in those units;
at prediction the target light (`light.sh_camera`, radiance units) gives radiance directly, because albedo and
normals carry no scale.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from rh_common import layout
from rh_common.imageio import read_exr, read_png

from .body import PosedBody, pose_body

__all__ = ["FrameData", "list_frames", "load_frame", "load_split", "resize_image", "working_size", "subjects_of"]

OPENCV_TO_OPENGL = np.diag([1.0, -1.0, -1.0])


@dataclass
class FrameData:
    """One frame at working resolution (H, W); tensors are float32, channels last."""

    path: Path
    meta: dict
    index: int
    H: int
    W: int
    K: torch.Tensor  # (3, 3) scaled to (H, W)
    world_to_camera: torch.Tensor  # (4, 4) OpenCV
    body: PosedBody
    exposure: float
    image: torch.Tensor | None = None  # (H, W, 3) exposure * radiance
    mask: torch.Tensor | None = None  # (H, W) coverage in [0, 1]
    albedo: torch.Tensor | None = None  # (H, W, 3) linear
    normal: torch.Tensor | None = None  # (H, W, 3) OpenGL camera space
    extra: dict = field(default_factory=dict)

    @property
    def world_to_opengl(self) -> torch.Tensor:
        """3x3 rotation world → OpenGL camera axes (the frame normals and `sh_camera` live in)."""
        return torch.as_tensor(OPENCV_TO_OPENGL, dtype=torch.float32) @ self.world_to_camera[:3, :3]

    @property
    def camera_centre(self) -> torch.Tensor:
        R, t = self.world_to_camera[:3, :3], self.world_to_camera[:3, 3]
        return -(R.T @ t)

    @property
    def sh_camera(self) -> torch.Tensor:
        return torch.as_tensor(np.asarray(self.meta["light"]["sh_camera"], dtype=np.float32))


def working_size(height: int, width: int, resolution: int) -> tuple[int, int]:
    """(H, W) with H = resolution and the frame's aspect ratio kept (rounded to an even width)."""
    w = max(2, int(round(width * resolution / height / 2.0)) * 2)
    return resolution, w


def resize_image(img: torch.Tensor, H: int, W: int) -> torch.Tensor:
    """(h, w, C) → (H, W, C); anti-aliased (area-like) when shrinking, bilinear when growing."""
    if img.shape[0] == H and img.shape[1] == W:
        return img
    x = img.permute(2, 0, 1)[None]
    shrink = H < img.shape[0]
    y = F.interpolate(x, size=(H, W), mode="bilinear", align_corners=False, antialias=shrink)
    return y[0].permute(1, 2, 0).contiguous()


def list_frames(dataset: str | Path, subject: str, protocol: str, split: str) -> list[Path]:
    d = layout.split_dir(dataset, subject, protocol, split)
    paths = sorted(p for p in d.glob("frame_*.json") if layout.frame_index_of(p.name) is not None)
    if not paths:
        raise FileNotFoundError(f"{d}: no frames (expected frame_*.json)")
    return paths


def subjects_of(dataset: str | Path, protocol: str, split: str = "train") -> list[str]:
    root = Path(dataset)
    return sorted(p.name for p in root.glob("subject_*") if layout.split_dir(root, p.name, protocol, split).is_dir())


def _layer(meta: dict, split_dir: Path, index: int, name: str, ext: str) -> Path:
    return split_dir / layout.layer_file_name(index, name, ext)


def load_frame(path: str | Path, resolution: int, layers: tuple[str, ...] = ("image", "mask"),
               body: bool = True) -> FrameData:
    path = Path(path)
    record = layout.read_frame_record(path)  # checks the record; FrameData keeps its JSON form for the callers
    meta, idx = record.to_json(), record.index
    h0, w0 = int(meta["height"]), int(meta["width"])
    H, W = working_size(h0, w0, resolution)
    K = np.asarray(meta["camera"]["K"], dtype=np.float64).copy()
    # Pixel-edge convention (centre at W/2): scaling the image scales fx, cx (and fy, cy) by the same factor.
    K[0] *= W / w0
    K[1] *= H / h0
    pb = pose_body(meta["body"]["phenotype"], meta["body"]["pose"]) if body else None
    fr = FrameData(path=path, meta=meta, index=idx, H=H, W=W, K=torch.as_tensor(K, dtype=torch.float32),
                   world_to_camera=torch.as_tensor(np.asarray(meta["camera"]["world_to_camera"]), dtype=torch.float32),
                   body=pb, exposure=float(meta.get("exposure", 1.0)))
    d = path.parent
    for name in layers:
        if name == "image":
            img = torch.from_numpy(read_exr(_layer(meta, d, idx, "image", "exr"))[..., :3].copy())
            fr.image = resize_image(img * fr.exposure, H, W)
        elif name == "mask":
            m = read_png(_layer(meta, d, idx, "mask", "png")).astype(np.float32) / 255.0
            if m.ndim == 3:
                m = m[..., 0]
            fr.mask = resize_image(torch.from_numpy(m)[..., None], H, W)[..., 0]
        elif name == "albedo":
            fr.albedo = resize_image(torch.from_numpy(read_exr(_layer(meta, d, idx, "albedo", "exr"))[..., :3].copy()),
                                     H, W)
        elif name == "normal":
            n = resize_image(torch.from_numpy(read_exr(_layer(meta, d, idx, "normal", "exr"))[..., :3].copy()), H, W)
            fr.normal = F.normalize(n, dim=-1, eps=1e-8)  # averaged normals are renormalised (ARCHITECTURE.md)
        else:
            raise ValueError(f"unknown layer {name!r}")
    return fr


def _evenly(paths: list[Path], n: int) -> list[Path]:
    if n <= 0 or n >= len(paths):
        return paths
    idx = np.unique(np.round(np.linspace(0, len(paths) - 1, n)).astype(int))
    return [paths[i] for i in idx]


def load_split(dataset: str | Path, subject: str, protocol: str, split: str, resolution: int,
               layers: tuple[str, ...] = ("image", "mask"), max_frames: int = 0, progress: bool = False
               ) -> list[FrameData]:
    paths = _evenly(list_frames(dataset, subject, protocol, split), max_frames)
    it = paths
    if progress:
        from tqdm import tqdm

        it = tqdm(paths, desc=f"load {subject}/{split}", unit="frame", leave=False)
    return [load_frame(p, resolution, layers) for p in it]
