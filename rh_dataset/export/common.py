"""What every exporter shares: finding a dataset's frames, its subjects' characters and lights, atomic writers.

Exporters read a finished dataset only through the files docs/ARCHITECTURE.md describes (frame JSON, layer files,
character.json, dataset.json); they never re-render.
"""
from __future__ import annotations

import functools
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from rh_common import layout
from rh_common.imageio import atomic_path, read_json

__all__ = ["ExportError", "FrameRef", "iter_frames", "check_dataset", "save_npy",
           "root_motion", "hdri_path", "subject_index", "client_K"]


class ExportError(RuntimeError):
    """An export that cannot proceed; the message names the problem and the fix."""


@dataclass(frozen=True)
class FrameRef:
    """One frame of the source dataset: where it lives and its parsed JSON."""

    subject: str
    split: str
    index: int
    split_dir: Path
    """The folder holding the frame's files (a multi-view split's camera folder, `<split>/cam_NN`)."""
    meta: dict
    view: str | None = None
    """The camera (cam_NN) of a multi-view split's frame (protocol c); None for a single-camera split."""

    def layer(self, suffix: str) -> Path:
        """`suffix` is '<layer>.<ext>', e.g. 'image.png'."""
        name, ext = suffix.rsplit(".", 1)
        return self.split_dir / layout.layer_file_name(self.index, name, ext)


def check_dataset(root: Path, protocol: str) -> dict:
    """dataset.json of a finished dataset holding `protocol`; raises ExportError otherwise."""
    root = Path(root)
    ds_path = root / layout.DATASET_JSON
    if not ds_path.is_file():
        raise ExportError(f"{root} holds no dataset.json: not an rh dataset (make one with rh-generate)")
    if not (root / layout.MANIFEST_JSON).is_file():
        raise ExportError(f"{root} has no manifest.json: the run is unfinished; rerun rh-generate with the same flags")
    ds = read_json(ds_path)
    if layout.protocol_dir(protocol) not in ds.get("protocols", {}):
        raise ExportError(f"{root} holds no protocol {protocol!r} (it holds {sorted(ds.get('protocols', {}))})")
    imported = ds["protocols"][layout.protocol_dir(protocol)].get("spec", {}).get("character")
    if imported:
        # Every export format carries the body model's parameters (anny's phenotype and pose); an imported rig has
        # its own skeleton, which none of these layouts can describe.
        raise ExportError(f"{root} protocol {protocol} renders an imported character ({imported.get('file')}, "
                          f"rh-generate --character): rh-export needs anny body parameters, which it does not have; "
                          f"export a dataset of anny characters, or read the frames directly (docs/ARCHITECTURE.md)")
    return ds


subject_index = layout.subject_index


def iter_frames(root: Path, protocol: str, splits: tuple[str, ...] | None = None,
                subjects: int | None = None) -> Iterator[FrameRef]:
    """Frames in (subject, split as in the scene description, camera, index) order."""
    root = Path(root)
    ds = check_dataset(root, protocol)
    spec = ds["protocols"][layout.protocol_dir(protocol)]["spec"]
    split_names = [s["name"] for s in spec["splits"] if splits is None or s["name"] in splits]
    subject_dirs = sorted(root.glob("subject_*"))
    if subjects is not None:
        subject_dirs = subject_dirs[:subjects]
    for sd in subject_dirs:
        for split in split_names:
            for view, folder in layout.frame_folders(layout.split_dir(root, sd.name, protocol, split)):
                for fj in sorted(folder.glob("frame_*.json")):
                    if layout.frame_index_of(fj.name) is None:
                        continue
                    record = layout.read_frame_record(fj)
                    yield FrameRef(sd.name, split, record.index, folder, record.to_json(), view)


def client_K(K: np.ndarray) -> np.ndarray:
    """Our K (pixel (u, v) covers [u, u+1), ARCHITECTURE.md) in the loaders' convention, whose rays go through
    integer pixel coordinates: the same camera has its principal point half a pixel up and left."""
    K = np.array(K, dtype=np.float64)
    K[0, 2] -= 0.5
    K[1, 2] -= 0.5
    return K


def save_npy(path: Path, obj) -> None:
    """np.save, atomically; dicts are saved as a 0-d object array (read back with allow_pickle=True).item())."""
    buf = io.BytesIO()
    if isinstance(obj, dict):
        np.save(buf, np.array(obj, dtype=object), allow_pickle=True)
    else:
        np.save(buf, np.asarray(obj), allow_pickle=False)
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.getvalue())


def root_motion(pose_json: dict) -> np.ndarray:
    """4x4 rigid world motion of the body's root (pelvis) relative to anny's reference pose.

    In the 'local-ref' parameterisation the root delta is a rigid transform about the root head, which sits at
    the world origin in the reference pose; `root_transform` (the turntable) is applied after skinning. So every
    vertex of the reference body that moves rigidly with the pelvis goes to ``root_transform @ root_delta @ x``.
    """
    pose = layout.read_body_pose(pose_json)
    return pose.root_transform @ pose.bones.get("root", np.eye(4))


@functools.lru_cache(maxsize=4)
def _library(hdri_folder: str | None) -> dict[str, Path]:
    from rh_dataset.lights import bundled_hdris, hdri_library

    try:
        return dict(hdri_library(hdri_folder)) if hdri_folder else dict(bundled_hdris())
    except (FileNotFoundError, ValueError):
        return {}


def hdri_path(light: dict, hdri_folder: str | None) -> Path | None:
    """The HDRI file a frame's light came from on this machine, or None (sunsky, or the map is not here)."""
    if light.get("kind") != "envmap":
        return None
    p = _library(hdri_folder).get(light["name"])
    if p is not None and Path(p).name == light.get("source", Path(p).name):
        return Path(p)
    if hdri_folder and (Path(hdri_folder) / light.get("source", "")).is_file():
        return Path(hdri_folder) / light["source"]
    return None
