"""The SMPL stand-in built from anny, measured: what docs/INTEROP.md quotes about it.

    python bench/smpl_standin.py

Prints, per gender: build time (the first includes anny's load and the shared vertex resampling), height, face
count, the J_regressor's residual against anny's joints (max on the template; max and mean over the 64 shape
samples), the shape variance its 10 directions keep; then, for the neutral model, the stand-in's LBS of a moderate
pose against anny's own forward pass posed by the same joint rotations (mean / median / 90th percentile / max
vertex distance in mm, and the joints' max distance), and how well its betas reproduce 8 held-out anny bodies
(T-posed; least-squares betas; mean vertex error). Machine shared with other jobs: read seconds as +-30 %.
"""
from __future__ import annotations

import time

import numpy as np

def main() -> None:
    import torch

    from rh_common.body_model import load_anny
    from rh_dataset.characters.body import run_anny
    from rh_dataset.poses.rig import rig_for
    from rh_dataset.smpl import standin as S
    from rh_dataset.smpl import standin_pose as P
    from rh_dataset.smpl.model import forward

    print(f"load average {open('/proc/loadavg').read().split()[0]}")
    for gender in ("neutral", "male", "female"):
        t0 = time.perf_counter()
        m = S.build_standin(gender)
        dt = time.perf_counter() - t0
        r = S.standin_report(gender)
        h = np.ptp(m.v_template[:, 1])
        print(f"{gender:8s} build {dt:5.1f} s  height {h:.3f} m  faces {r.n_faces}  joint residual: template max "
              f"{r.joint_residual_template_mm:.2f} mm, samples max {r.joint_residual_samples_mm:.1f} / mean "
              f"{r.joint_residual_samples_mean_mm:.1f} mm  shape variance kept {100 * r.shape_variance_kept:.2f} %")
    m = S.build_standin("neutral")
    pheno, pose = S.default_phenotype("neutral"), P.example_pose()
    out = run_anny(pheno, P.anny_pose_from_smpl(rig_for(load_anny(), pheno), pose))
    expected = S.to_smpl_axes(out["vertices"][m.extra["rh_standin"]["anny_vertex_ids"]])
    t = lambda a: torch.as_tensor(np.asarray(a, np.float64).reshape(1, -1))  # noqa: E731
    verts, joints = forward(m, t(np.zeros(10)), t(pose[1:]), t(pose[0]))
    err = np.linalg.norm(verts[0].numpy() - expected, axis=1) * 1e3
    heads = S.to_smpl_axes(out["bone_poses"][:, :3, 3])
    idx = rig_for(load_anny(), pheno).index
    anny_j = np.stack([heads[[idx[b] for b in S.JOINT_BONES[j]]].mean(0) for j in S.SMPL_JOINT_NAMES])
    jerr = np.linalg.norm(joints[0].numpy() - anny_j, axis=1).max() * 1e3
    print(f"moderate pose, stand-in LBS vs anny: vertices mean {err.mean():.2f} / median {np.median(err):.2f} / "
          f"p90 {np.percentile(err, 90):.2f} / max {err.max():.1f} mm; joints max {jerr:.2f} mm")
    from rh_dataset.characters.body import sample_phenotype

    rng = np.random.default_rng(12345)  # the test's held-out bodies
    bodies, _ = S.anny_tpose_bodies([sample_phenotype(rng) for _ in range(8)])
    D = m.shapedirs.reshape(-1, 10)
    errs = []
    for body in bodies:
        off = (body - m.v_template).ravel()
        fit = D @ np.linalg.lstsq(D, off, rcond=None)[0]
        errs.append(np.linalg.norm((fit - off).reshape(-1, 3), axis=1).mean() * 1e3)
    print(f"8 held-out anny bodies (T-posed) by their best betas: mean vertex error {np.mean(errs):.2f} mm, "
          f"worst body {max(errs):.2f} mm")


if __name__ == "__main__":
    main()
