"""Predictions for `rh-eval`: RANA and the SMPL+D baseline, through `rana.predictions.PredictionWriter`.

For every test frame: the target pose (frame metadata) and the target light (`light.sh_camera`, radiance SH in the
OpenGL camera frame) → image (linear HDR radiance EXR; rh-eval applies the frame's exposure), albedo, normal.
Nothing of the test frame's images is read.

Both methods render at the run's working resolution and are resized to the frame's size. Outside the predicted
person the image is the order-2 SH environment seen through each pixel (`background='sh'`): the only background
knowledge the target light gives; `'black'` writes zeros instead.

* RANA: albedo and normal from the networks, mask from AlbedoNet, image = albedo x max(0, S(normal)).
* SMPL+D (paper Sec. 4.4): the coarse albedo texture and coarse normals rasterised in the target pose, SH-shaded
  the same way, mask = the mesh's coverage.

How the person meets the background (`mask_composite`): SMPL+D's mask is a rasteriser's coverage, so its edge
pixels are coverage-weighted blends, as a camera's are. AlbedoNet's mask is a probability (trained with BCE), not
a coverage: blending by it mixes the SH background into the person wherever the network is unsure (11% of the
ground-truth person's pixels have p < 0.9 on the small leaderboard), and that background is a poor stand-in for
the real one. So RANA's image is the person where p > 0.5 and the background elsewhere (`'threshold'`, the same
decision as its albedo and normal layers); `'probability'` blends by p (docs/RANA.md, "Compositing RANA's image").
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from .body import body_topology
from .config import RanaConfig
from .data import load_frame, resize_image
from .model import RanaModel, coarse_buffers, shade, stack_batch
from .predictions import PredictionWriter, TestFrame, iter_test_frames
from .runs import RunDir
from .synthetic import sh_background
from .train import Coarse, load_coarse

__all__ = ["predict_rana", "predict_smpld", "render_rana_frame", "render_smpld_frame", "finish_layers", "load_trained"]


MASK_COMPOSITES = ("threshold", "probability", "coverage")


def finish_layers(image: torch.Tensor, albedo: torch.Tensor, normal: torch.Tensor, mask: torch.Tensor, h0: int,
                  w0: int, background: torch.Tensor, mask_composite: str) -> dict:
    """Working-resolution (H, W, C) layers → frame-resolution numpy arrays in the dataset's conventions: albedo and
    normal zero outside the person (mask > 0.5), normals unit length, image over `background` either where
    mask > 0.5 (`'threshold'`) or blended by the mask (`'probability'`, `'coverage'`; module docstring)."""
    if mask_composite not in MASK_COMPOSITES:
        raise ValueError(f"mask_composite {mask_composite!r}: expected one of {', '.join(MASK_COMPOSITES)}")
    img = resize_image(image, h0, w0)
    alb = resize_image(albedo, h0, w0)
    nrm = F.normalize(resize_image(normal, h0, w0), dim=-1, eps=1e-8)
    m = resize_image(mask[..., None], h0, w0).clamp(0, 1)
    bg = resize_image(background, h0, w0)
    inside = (m > 0.5).float()
    alpha = inside if mask_composite == "threshold" else m
    return {"image": (alpha * img + (1 - alpha) * bg).clamp_min(0).numpy(),
            "albedo": (alb.clamp(0, 1) * inside).numpy(),
            "normal": (nrm * inside).numpy()}


def _frame_inputs(tf: TestFrame, cfg: RanaConfig):
    fr = load_frame(tf.json_path, cfg.model.resolution, layers=())
    sh_cam = torch.as_tensor(np.asarray(tf.meta["light"]["sh_camera"], dtype=np.float32))
    return fr, sh_cam


def _background(kind: str, sh_cam: torch.Tensor, fr) -> torch.Tensor:
    if kind == "sh":
        return sh_background(sh_cam, fr.K, fr.H, fr.W)
    return torch.zeros(fr.H, fr.W, 3)


@torch.no_grad()
def rana_outputs(model: RanaModel, coarse: Coarse, tf: TestFrame, cfg: RanaConfig):
    """The model's outputs (batch of 1, working resolution) for a test frame's pose and light, with the frame
    buffers and the light they used."""
    fr, sh_cam = _frame_inputs(tf, cfg)
    buf = coarse_buffers(fr, body_topology(), coarse.offsets, coarse.albedo_texture)
    return model.get_outputs(stack_batch([buf]), light=sh_cam[None]), fr, sh_cam


@torch.no_grad()
def render_rana_frame(model: RanaModel, coarse: Coarse, tf: TestFrame, cfg: RanaConfig, background: str = "sh",
                      mask_composite: str = "threshold") -> dict:
    out, fr, sh_cam = rana_outputs(model, coarse, tf, cfg)
    hw = lambda t: t[0].permute(1, 2, 0)  # noqa: E731
    return finish_layers(hw(out["image"]), hw(out["albedo"]), hw(out["normal"]), out["mask"][0, 0],
                         int(tf.meta["height"]), int(tf.meta["width"]), _background(background, sh_cam, fr),
                         mask_composite)


@torch.no_grad()
def render_smpld_frame(coarse: Coarse, tf: TestFrame, cfg: RanaConfig, background: str = "sh", ss: int = 2,
                       mask_composite: str = "coverage") -> dict:
    """The SMPL+D baseline, rasterised at ss x ss samples per pixel for an anti-aliased mask (its coverage)."""
    fr, sh_cam = _frame_inputs(tf, cfg)
    fr.H, fr.W = fr.H * ss, fr.W * ss
    fr.K = fr.K.clone()
    fr.K[:2] *= ss
    buf = coarse_buffers(fr, body_topology(), coarse.offsets, coarse.albedo_texture)
    n = buf["coarse_normal"][None]
    img = buf["coarse_albedo"][None] * shade(sh_cam[None], n)
    down = lambda t: F.avg_pool2d(t, ss)[0].permute(1, 2, 0)  # noqa: E731
    m = F.avg_pool2d(buf["smpl_mask"][None], ss)[0, 0]
    cov = m.clamp_min(1e-6)[..., None]
    fr.H, fr.W = fr.H // ss, fr.W // ss
    fr.K[:2] /= ss
    return finish_layers(down(img) / cov, down(buf["coarse_albedo"][None]) / cov, down(n), m,
                         int(tf.meta["height"]), int(tf.meta["width"]), _background(background, sh_cam, fr),
                         mask_composite)


def _run_for(runs_root: Path, subject: str) -> RunDir:
    run = RunDir(runs_root / subject)
    if not (run.path / "config.json").is_file():
        raise FileNotFoundError(f"{run.path}: no run for {subject} (train it: rana train --subject {subject} ...)")
    return run


def load_trained(run: RunDir) -> tuple[RanaConfig, Coarse, RanaModel]:
    """A personalized subject's config, coarse stage and model (newest checkpoint, eval mode)."""
    cfg, _ = run.read_config()
    coarse = load_coarse(run.path / "coarse.pt")
    model = RanaModel(cfg.model)
    model.load_state_dict(run.load()["model"])
    model.eval()
    return cfg, coarse, model


def _subject_frames(dataset: Path, protocol: str, subjects: list[str] | None,
                    split: str = "test") -> dict[str, list[TestFrame]]:
    by: dict[str, list[TestFrame]] = {}
    for tf in iter_test_frames(dataset, protocol, split):
        if subjects is None or tf.subject in subjects:
            by.setdefault(tf.subject, []).append(tf)
    return by


def predict_rana(dataset: str | Path, protocol: str, runs_root: str | Path, out: str | Path, *,
                 subjects: list[str] | None = None, background: str = "sh", progress: bool = True,
                 name: str | None = None, mask_composite: str = "threshold", split: str = "test") -> int:
    from tqdm import tqdm

    runs_root, dataset = Path(runs_root), Path(dataset)
    by = _subject_frames(dataset, protocol, subjects, split)
    writer = PredictionWriter(out, {"name": name or "RANA", "kind": "method", "runs": str(runs_root.resolve()),
                                    "background": background, "mask_composite": mask_composite,
                                    "description": "RANA (Iqbal et al. 2023) on anny, rana/ in this repository"})
    n = 0
    for subject, tfs in by.items():
        cfg, coarse, model = load_trained(_run_for(runs_root, subject))
        for tf in tqdm(tfs, desc=f"predict {subject}", unit="frame", disable=not progress, leave=False):
            writer.write(tf, **render_rana_frame(model, coarse, tf, cfg, background, mask_composite))
            n += 1
    return n


def predict_smpld(dataset: str | Path, protocol: str, runs_root: str | Path, out: str | Path, *,
                  subjects: list[str] | None = None, background: str = "sh", progress: bool = True,
                  name: str | None = None, mask_composite: str = "coverage", split: str = "test") -> int:
    """SMPL+D for every subject that has a coarse stage (`<runs>/<subject>/coarse.pt`)."""
    from tqdm import tqdm

    runs_root, dataset = Path(runs_root), Path(dataset)
    by = _subject_frames(dataset, protocol, subjects, split)
    writer = PredictionWriter(out, {"name": name or "SMPL+D", "kind": "method", "runs": str(runs_root.resolve()),
                                    "background": background,
                                    "description": "coarse albedo texture x SH2 shading of coarse SMPL+D normals"})
    n = 0
    for subject, tfs in by.items():
        run = _run_for(runs_root, subject)
        cfg, _ = run.read_config()
        coarse = load_coarse(run.path / "coarse.pt")
        for tf in tqdm(tfs, desc=f"smpl+d {subject}", unit="frame", disable=not progress, leave=False):
            writer.write(tf, **render_smpld_frame(coarse, tf, cfg, background, mask_composite=mask_composite))
            n += 1
    return n
