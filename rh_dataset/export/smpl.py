"""SMPL and SMPL-X numbers for the exports (`rh-export --smpl-model DIR`, `--smplx-model DIR`): the fit of every
frame's anny body, cached.

In: the frames of the exported protocol, the user's model folder, a gender. Out: `SmplFits`, which gives for each
frame the Relighting Humans `smpl_data` (or `smplx_data`) block (`rh_block`), the ZJU-MoCap params and vertices
(`zju_params`) and the USD stage's SMPL mesh (`usd_mesh`). A SMPL-X block also splits the fitted pose the way
smplx's forward takes it (`smplx_pose_parts`: body_pose 63, jaw/leye/reye_pose 3, left/right_hand_pose 45) and
carries a zero `expression` (10).

The fit (`rh_dataset.smpl.fit`) runs once per subject over ALL its frames of the protocol (every split, whatever
--split / --subjects select), so its one `betas` does not depend on what is exported. Each subject's result is
cached in `<out>/smpl_fit/<subject>.json` (SMPL-X: `smplx_fit/`; atomic write; floats in JSON's exact round-trip
form, so the cached betas are bit-identical), keyed by the model file's sha256, the gender, the fit settings and a
hash of what the fit reads of the frames (bodies, cameras): a rerun reuses it and refits nothing. Posed vertices
and joints are always recomputed from the cached parameters, one frame at a time, so a fresh run and a rerun write
the same numbers.
"""
from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from rh_common.imageio import read_json, write_json
from rh_common.threads import torch_threads
from rh_dataset.smpl.fit import (FitInput, FitQuality, FitRefused, FitSettings, FrameTarget, anny_joints,
                                 camera_frame, check_quality, fit_subject)
from rh_dataset.smpl.model import BodyModel, SmplModelError, find_model_file, load_body_model
from rh_dataset.poses.joints import axis_angle, axis_angle_matrix

from .common import ExportError, FrameRef

__all__ = ["SmplFits", "frame_target", "load_model", "smplx_pose_parts", "CACHE_DIR", "CACHE_DIRS",
           "VERTEX_DECIMALS_MM"]

CACHE_DIR = "smpl_fit"
CACHE_DIRS = {"smpl": CACHE_DIR, "smplx": "smplx_fit"}
N_VERTICES = {"smpl": 6890, "smplx": 10475}
CACHE_FORMAT = "rh-export/smpl-fit/1"
VERTEX_DECIMALS_MM = 4  # vertices/joints in the frame JSON: 0.1 µm, far below the fit error, a third of the text


def load_model(folder: str | Path, gender: str = "neutral", kind: str = "smpl") -> BodyModel:
    """The user's model file of `gender` in `folder`, checked (one-line ExportError naming the file otherwise)."""
    try:
        model = load_body_model(find_model_file(folder, kind, gender), kind, gender)
    except SmplModelError as exc:
        raise ExportError(str(exc)) from None
    if model.n_vertices != N_VERTICES[kind]:
        name, flag = ("SMPL", "smpl") if kind == "smpl" else ("SMPL-X", "smplx")
        raise ExportError(f"{model.path}: {model.n_vertices} vertices, not {name}'s {N_VERTICES[kind]} (the clients "
                          f"pick joints at fixed vertex ids); pass the folder holding "
                          f"{find_model_file(folder, kind, gender).name} of {name} itself, or write the stand-in "
                          f"with rh-export --write-test-{flag} DIR")
    return model


def smplx_pose_parts(pose) -> dict:
    """A SMPL-X pose of joints 1-54 (162 values) split as smplx's forward takes it."""
    p = [float(x) for x in pose]
    return {"body_pose": p[:63], "jaw_pose": p[63:66], "leye_pose": p[66:69], "reye_pose": p[69:72],
            "left_hand_pose": p[72:117], "right_hand_pose": p[117:162]}


def frame_target(f: FrameRef, kind: str = "smpl") -> FrameTarget:
    """The frame's posed unclothed anny body and its SMPL-ordered joints, in the frame's OpenCV camera frame."""
    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.poses import BodyPose

    body = f.meta.get("body") or {}
    if "pose" not in body or "phenotype" not in body:
        raise ExportError(f"{f.split_dir}: frame {f.index} has no anny body (phenotype, pose); the SMPL fit needs a "
                          "dataset of anny characters")
    pose = BodyPose.from_json(body["pose"])
    out = run_anny(body["phenotype"], dict(pose.bones) or None)
    topo = body_topology()
    w2c = np.asarray(f.meta["camera"]["world_to_camera"], np.float64)

    def cam(x):
        return pose.apply_root_transform(x) @ w2c[:3, :3].T + w2c[:3, 3]

    return FrameTarget(_key(f), cam(out["vertices"]), np.asarray(topo.faces),
                       anny_joints(cam(out["bone_poses"][:, :3, 3]), topo.bone_labels, kind))


def _key(f: FrameRef) -> str:
    return f"{f.subject}/{f.split}/{f.index:06d}"


def _inputs_sha256(frames: list[FrameRef]) -> str:
    """What the fit reads of a subject's frames (names, bodies, cameras): a cache made from other frames is stale."""
    import hashlib
    import json

    h = hashlib.sha256()
    for f in frames:
        record = [_key(f), f.meta.get("body"), f.meta["camera"]["world_to_camera"]]
        h.update(json.dumps(record, sort_keys=True).encode())
    return h.hexdigest()


class SmplFits:
    """Fits of the exported subjects, made or read from the cache on first use of each subject."""

    def __init__(self, model: BodyModel, out: Path, all_frames: list[FrameRef], settings: FitSettings | None = None,
                 log=print):
        self.model, self.out, self.settings, self.log = model, Path(out), settings or FitSettings(), log
        self._frames: dict[str, list[FrameRef]] = {}
        for f in all_frames:
            self._frames.setdefault(f.subject, []).append(f)
        self._subjects: dict[str, dict] = {}
        self.seconds = 0.0
        self.fitted_frames = 0
        self.label = "SMPL" if model.kind == "smpl" else "SMPL-X"

    # ------------------------------------------------------------------ cache
    def _cache_path(self, subject: str) -> Path:
        return self.out / CACHE_DIRS[self.model.kind] / f"{subject}.json"

    def _identity(self) -> dict:
        s = asdict(self.settings)
        for k in ("max_mean_mm", "max_max_mm"):
            s.pop(k)  # thresholds judge a fit; they do not change it
        return {"format": CACHE_FORMAT, "model_sha256": self.model.sha256, "kind": self.model.kind,
                "gender": self.model.gender, "settings": s}

    def _subject(self, subject: str) -> dict:
        if subject in self._subjects:
            return self._subjects[subject]
        frames = self._frames.get(subject)
        if not frames:
            raise ExportError(f"{subject}: no frames to fit {self.model.kind.upper()} to")
        path = self._cache_path(subject)
        rec = read_json(path) if path.is_file() else None
        inputs = _inputs_sha256(frames)
        if rec and {k: rec.get(k) for k in self._identity()} == self._identity() and rec.get("inputs_sha256") == inputs:
            self.log(f"{self.label} fit of {subject}: cached in {path} (delete it to refit)")
        else:
            t0 = time.perf_counter()
            targets = tuple(frame_target(f, self.model.kind) for f in frames)
            fit = fit_subject(FitInput(self.model, targets, self.settings), log=None)
            self.seconds += time.perf_counter() - t0
            self.fitted_frames += len(frames)
            seconds = time.perf_counter() - t0
            self.log(f"{self.label} fit of {subject}: {len(frames)} frames in {seconds:.1f} s "
                     f"({seconds / len(frames):.2f} s per frame)")
            rec = {**self._identity(), "inputs_sha256": inputs, "model_file": Path(self.model.path).name,
                   "betas": fit.betas.tolist(),
                   "scale": fit.scale, "seconds": seconds,
                   "frames": {ff.name: {"pose": ff.pose.tolist(), "global_orient": ff.global_orient.tolist(),
                                        "global_trans": ff.global_trans.tolist(), "quality": ff.quality.to_json()}
                              for ff in fit.frames}}
            write_json(path, rec)
        self._subjects[subject] = rec
        self._check(subject, rec)
        return rec

    def _check(self, subject: str, rec: dict) -> None:
        try:
            check_quality(((k, FitQuality(**v["quality"])) for k, v in rec["frames"].items()), self.settings,
                          where="frame ", name=self.label)
        except FitRefused as exc:
            raise ExportError(f"{exc} (the fit is cached in {self._cache_path(subject)})") from None

    # ------------------------------------------------------------------ per frame
    def posed(self, f: FrameRef) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray]:
        """(cached record of the frame, betas, camera-frame vertices (V,3) m, joints (J,3) m)."""
        import torch

        rec = self._subject(f.subject)
        fr = rec["frames"][_key(f)]
        betas = np.asarray(rec["betas"], np.float64)
        t = lambda a: torch.as_tensor(np.asarray(a, np.float64)[None])  # noqa: E731
        with torch.no_grad(), torch_threads(self.settings.threads):  # the fit's thread count: the same last bits
            V, J = camera_frame(self.model, t(betas), t(fr["pose"]), t(fr["global_orient"]), t(fr["global_trans"]),
                                float(rec["scale"]))
        return fr, betas, V[0].numpy(), J[0].numpy()

    def rh_block(self, f: FrameRef) -> dict:
        """The SMPL keys of `skeleton_0.smpl_data` (docs/research/clients_relighting_humans.md §7.4); for SMPL-X
        the same keys (`pose`: joints 1-54, 162 values) plus the pose split as smplx takes it and `expression`."""
        fr, betas, V, J = self.posed(f)
        rec = self._subjects[f.subject]
        parts = {} if self.model.kind == "smpl" else {**smplx_pose_parts(fr["pose"]), "expression": [0.0] * 10}
        return {
            "model": self.model.kind, "gender": self.model.gender, "model_file": rec["model_file"],
            "model_sha256": self.model.sha256, "standin": bool(self.model.extra.get("rh_standin")),
            "pose": list(fr["pose"]), "betas": list(rec["betas"]), "global_orient": list(fr["global_orient"]),
            "global_trans": list(fr["global_trans"]), "scale": float(rec["scale"]),
            "vertices": np.round(V * 1000.0, VERTEX_DECIMALS_MM).tolist(),
            "joints": np.round(J * 1000.0, VERTEX_DECIMALS_MM).tolist(),
            "units": {"vertices": "mm", "joints": "mm", "global_trans": "m"},
            "fit": fr["quality"], **parts,
        }

    def zju_params(self, f: FrameRef) -> tuple[dict, np.ndarray]:
        """ZJU-MoCap / EasyMocap params in the world frame and the matching (V, 3) float32 world vertices:
        `vertices = SMPL(poses with the root zero, shapes) · R(Rh)ᵀ + Th` (rotation about SMPL's origin)."""
        import torch

        fr, betas, _, _ = self.posed(f)
        c2w = np.linalg.inv(np.asarray(f.meta["camera"]["world_to_camera"], np.float64))
        Rw, tw = c2w[:3, :3], c2w[:3, 3]
        t = lambda a: torch.as_tensor(np.asarray(a, np.float64)[None])  # noqa: E731
        from rh_dataset.smpl.model import forward

        with torch.no_grad(), torch_threads(self.settings.threads):
            V0, J0 = forward(self.model, t(betas), t(fr["pose"]), t(np.zeros(3)), None)
        V0, j0 = V0[0].numpy(), J0[0, 0].numpy()
        R = Rw @ axis_angle_matrix(np.asarray(fr["global_orient"]))
        Th = Rw @ np.asarray(fr["global_trans"]) + tw - R @ j0
        verts = (V0 @ R.T + Th).astype(np.float32)
        params = {"poses": np.concatenate([np.zeros(3), np.asarray(fr["pose"])])[None],
                  "Rh": axis_angle(R)[None], "Th": Th[None], "shapes": betas[None].copy(),
                  "model": self.model.kind, "gender": self.model.gender, "model_sha256": self.model.sha256,
                  "fit": fr["quality"]}
        if self.model.kind == "smplx":
            params.update({k: np.asarray(v)[None] for k, v in smplx_pose_parts(fr["pose"]).items()})
            params["expression"] = np.zeros((1, 10))
        return params, verts

    def usd_mesh(self, f: FrameRef) -> tuple[np.ndarray, np.ndarray, dict]:
        """(world vertices, faces, a record of the parameters) for the USD stage's /World/SMPL prim."""
        params, verts = self.zju_params(f)
        rec = {"model": self.model.kind, "gender": self.model.gender, "model_sha256": self.model.sha256,
               "betas": [float(x) for x in params["shapes"][0]], "poses": [float(x) for x in params["poses"][0]],
               "Rh": [float(x) for x in params["Rh"][0]], "Th": [float(x) for x in params["Th"][0]],
               "relation": "points = SMPL(poses, betas) · R(Rh)ᵀ + Th, world metres"}
        return verts, self.model.faces, rec

