"""Why SMPL+D's coarse albedo is too bright: the exposure-SH de-lighting against the true training light.

    python bench/rana_delight_diag.py --dataset D --subject subject_000 --protocol a --run runs/subject_000

Reads the run's `coarse.pt` (offsets, estimated light) and the subject's training frames, and, for a diagnosis
only, two things no method may read: the training light's true SH (`light.sh_world` x `exposure` of the training
frames) and the ground-truth albedo texture (back-projected from the test frames' albedo layer exactly as the
coarse texture is from the training images). For several candidate lights it prints:

- albedo/GT: sum over the texels valid in both of (observed / S(n; light)) (the coarse albedo that light gives)
  over the ground-truth albedo texture, per channel — 1 is right;
- log-resid std: per texel, the standard deviation over its visible frames of log(observed / S(n)), averaged over
  texels seen >= 3 times — how consistent the observations are with a Lambertian model under that light;
- the light's DC and the norms of its bands 1 and 2.

Candidates: the estimate in coarse.pt; the truth; DC only; the truth's zonal terms only (constant along a
turntable path); the truth without them; and a frame-aggregate fit (each frame's mean observed colour against the
mean SH basis of its visible texels, one uniform albedo) at two ridges.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rh_common import sh  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument("--dataset", required=True, type=Path, help="dataset holding the subject (rh-generate output)")
    ap.add_argument("--subject", default="subject_000", help="subject diagnosed (default subject_000)")
    ap.add_argument("--protocol", default="a",
                    help="protocol letter (a or b): its train frames are observed, its test frames give the "
                         "ground-truth albedo (default a)")
    ap.add_argument("--run", required=True, type=Path, help="run folder holding the subject's coarse.pt")
    ap.add_argument("--preset", default="cpu",
                    help="the run's rana preset: paper, cpu, demo or tiny (default cpu); its model resolution and "
                         "texture settings read the frames")
    args = ap.parse_args(argv)

    from rana.body import body_topology
    from rana.config import get_preset
    from rana.data import load_split
    from rana.texture import _most_facing, exposure_sh_delight, extract_texture, texel_observations
    from rana.train import load_coarse

    torch.set_num_threads(1)
    cfg = get_preset(args.preset)
    topo = body_topology()
    co = load_coarse(args.run / "coarse.pt")
    res = cfg.model.resolution
    train = load_split(args.dataset, args.subject, args.protocol, "train", res, ("image", "mask"))
    test = load_split(args.dataset, args.subject, args.protocol, "test", res, ("albedo", "mask"))
    obs = texel_observations(train, topo, co.offsets, cfg.texture)
    gt_tex, gt_valid = extract_texture(test, topo, co.offsets, cfg.texture, layer="albedo")
    meta = train[0].meta  # the first train frame's record (load_split reads them in frame order)
    L_true = torch.tensor(np.array(meta["light"]["sh_world"]) * meta["exposure"], dtype=torch.float32)
    L_est = co.light_world.float() if co.light_world is not None else exposure_sh_delight(obs, cfg.texture)[2]
    Y = sh.basis(obs.normal) * (torch.tensor(np.array(sh.A_HAT), dtype=torch.float32) / math.pi)
    vis = obs.facing > 0
    I = obs.colour
    idx = torch.nonzero(obs.sel)[:, 0]
    gt = gt_tex.permute(1, 2, 0).reshape(-1, 3)[idx]
    use = _most_facing(obs, cfg.texture.facing_quantile)
    both = gt_valid.reshape(-1)[idx] & use.any(0)

    def report(name: str, L: torch.Tensor) -> None:
        S = (Y @ L).clamp_min(0.05)
        med = torch.nanmedian(torch.where(use[..., None], I / S, torch.full_like(I, float("nan"))), 0).values
        ratio = (med[both].sum(0) / gt[both].sum(0)).numpy()
        lr = torch.log(I.clamp_min(1e-4)) - torch.log(S)
        w = vis.float()[..., None]
        n = w.sum(0).clamp_min(1)
        var = (((lr - (lr * w).sum(0) / n) ** 2) * w).sum(0) / n
        ok = n[:, 0] >= 3
        print(f"{name:26s} albedo/GT {np.array2string(ratio, precision=2)}  log-resid std "
              f"{float(var[ok].mean().sqrt()):.3f}  DC {np.array2string(L[0].numpy(), precision=2)}  |band1| "
              f"{np.array2string(L[1:4].norm(dim=0).numpy(), precision=2)}  |band2| "
              f"{np.array2string(L[4:].norm(dim=0).numpy(), precision=2)}")

    def aggregate_fit(ridge: float) -> torch.Tensor:
        w = obs.facing.clamp_min(0)  # a texel's share of the image ~ its facing
        B = (w[..., None] * I).sum(1) / w.sum(1, keepdim=True)  # (F, 3) mean observed colour per frame
        M = (w[..., None] * Y).sum(1) / w.sum(1, keepdim=True)  # (F, 9) mean basis of the visible texels
        XtX = M.T @ M
        reg = ridge * XtX.diagonal().mean() * torch.diag(torch.tensor([0.0] + [1.0] * 8))
        L = torch.zeros(9, 3)
        for c in range(3):
            u = torch.linalg.solve(XtX + reg, M.T @ B[:, c])
            L[:, c] = u * (L_est[0, c] / u[0])  # DC fixed by the exposure convention
        return L

    zonal = [2, 6]  # Y_1^0, Y_2^0 about world +Z (up): constant along every texel's turntable path
    L_dc = torch.zeros(9, 3)
    L_dc[0] = L_est[0]
    L_zonal = torch.zeros(9, 3)
    L_zonal[[0] + zonal] = L_true[[0] + zonal]
    L_nonzonal = L_true.clone()
    L_nonzonal[zonal] = 0
    print(f"{args.subject} protocol {args.protocol}: {len(train)} training frames, {int(both.sum())} texels compared")
    report("estimate (coarse.pt)", L_est)
    report("true light", L_true)
    report("DC only", L_dc)
    report("true zonal terms only", L_zonal)
    report("true without zonal terms", L_nonzonal)
    for r in (1e-1, 1e-2):
        report(f"frame-aggregate fit {r:g}", aggregate_fit(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
