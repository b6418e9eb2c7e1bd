"""The SMPL (or SMPL-X) fit of posed anny bodies, measured: what docs/INTEROP.md quotes about its error and cost.

    python bench/smpl_fit.py [--model DIR] [--frames N] [--gender neutral] [--kind smpl|smplx]

Fits one subject (a phenotype drawn from anny's calibrated distribution, seed 15) in N frames (the A-pose and
N-1 poses from the pose prior, each seen by a camera 3 m away) jointly, as rh-export --smpl-model does, with the
model in DIR (default: the stand-in, written to a temporary folder; a stand-in fit is NOT an SMPL result). Prints
per frame the vertex-to-surface distances both ways (mean / max, mm) and the joint error, the same with the wrist
and hand rotations zeroed as IntrinsicAvatar reads them (pose[57:] = 0; SMPL only), and the cost per frame. The
machine is shared with other jobs: the load average is printed; read seconds as +-30 %.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", type=Path, default=None, help="folder with SMPL_{NEUTRAL,MALE,FEMALE}.pkl")
    ap.add_argument("--frames", type=int, default=5,
                    help="frames fitted jointly: the A-pose and N-1 poses from the pose prior (default 5)")
    ap.add_argument("--gender", default="neutral",
                    help="which model file is fitted: neutral, male or female (default neutral)")
    ap.add_argument("--kind", default="smpl", choices=["smpl", "smplx"],
                    help="body model fitted: SMPL or SMPL-X (default smpl)")
    args = ap.parse_args()

    import torch

    from rh_common.body_model import load_anny
    from rh_dataset.characters.body import sample_phenotype
    from rh_dataset.export.common import FrameRef
    from rh_dataset.export.smpl import frame_target, load_model
    from rh_dataset.poses import sample_pose, turntable
    from rh_dataset.smpl.fit import FitInput, camera_frame, fit_subject, measure_quality

    folder = args.model
    if folder is None:
        from rh_dataset.smpl.model import MODEL_FILE_NAMES, write_smplx_npz, write_smpl_pickle
        from rh_dataset.smpl.standin import build_standin

        folder = Path(tempfile.mkdtemp(prefix="rh_smpl_standin_"))
        write = write_smpl_pickle if args.kind == "smpl" else write_smplx_npz
        write(folder / MODEL_FILE_NAMES[args.kind][args.gender][0], build_standin(args.gender, args.kind))
    model = load_model(folder, args.gender, args.kind)
    name = "SMPL" if args.kind == "smpl" else "SMPL-X"
    print(f"load average {open('/proc/loadavg').read().split()[0]}; model {model.path} "
          f"({f'stand-in, NOT {name}' if model.extra.get('rh_standin') else name})")
    rng = np.random.default_rng(15)
    phen = sample_phenotype(rng)
    poses = [turntable(1)[0]] + [sample_pose(rng, load_anny(), phenotype=phen) for _ in range(args.frames - 1)]
    w2c = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0.9], [0, 1, 0, 3.0], [0, 0, 0, 1]])  # Z-up world → OpenCV
    frames = [FrameRef("subject_000", "bench", i, Path("."), {
        "body": {"pose": p.to_json(), "phenotype": phen}, "camera": {"world_to_camera": w2c.tolist()}})
        for i, p in enumerate(poses)]
    targets = tuple(frame_target(f, args.kind) for f in frames)
    t0 = time.perf_counter()
    fit = fit_subject(FitInput(model, targets), log=None)
    seconds = time.perf_counter() - t0
    print(f"{len(frames)} frames fitted jointly in {seconds:.1f} s: {seconds / len(frames):.2f} s per frame "
          f"(quality measurement included); betas {np.round(fit.betas, 2).tolist()}")
    t = lambda a: torch.as_tensor(np.asarray(a, np.float64)[None])  # noqa: E731
    print("frame  label        model->anny mean/max mm  anny->model mean/max mm  joints mean/max mm | "
          "pose[57:]=0: mean both ways mm")
    for f, ff, target in zip(frames, fit.frames, targets):
        q = ff.quality
        if args.kind != "smpl":
            print(f"{f.index:5d}  {poses[f.index].label[:11]:11s}  "
                  f"{q.model_to_anny_mean_mm:8.2f} / {q.model_to_anny_max_mm:6.1f}"
                  f"        {q.anny_to_model_mean_mm:8.2f} / {q.anny_to_model_max_mm:6.1f}       "
                  f"{q.joint_mean_mm:6.1f} / {q.joint_max_mm:5.1f}    |  -")
            continue
        pose = ff.pose.copy()
        pose[57:] = 0.0
        with torch.no_grad():
            V, J = camera_frame(model, t(fit.betas), t(pose), t(ff.global_orient), t(ff.global_trans))
        q0 = measure_quality(V[0].numpy(), model.faces, J[0].numpy(), target)
        print(f"{f.index:5d}  {poses[f.index].label[:11]:11s}  "
              f"{q.model_to_anny_mean_mm:8.2f} / {q.model_to_anny_max_mm:6.1f}"
              f"        {q.anny_to_model_mean_mm:8.2f} / {q.anny_to_model_max_mm:6.1f}       "
              f"{q.joint_mean_mm:6.1f} / {q.joint_max_mm:5.1f}    | {q0.model_to_anny_mean_mm:6.2f} / "
              f"{q0.anny_to_model_mean_mm:6.2f}")


if __name__ == "__main__":
    main()
