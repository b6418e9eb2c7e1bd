"""Per-subject pipeline: coarse stage (SMPL+D offsets, coarse albedo texture) then personalization of RANA.

Personalization (appendix): Z and E start from scratch; G_A and G_N come from pretraining (or from scratch when no
pretrained weights are given). For the first `freeze_albedo_steps` steps only Z and E are optimised, then G_A, Z
and E jointly; G_N stays frozen unless `finetune_normal`. Every step's frames are drawn from a generator seeded by
(seed, step), so a resumed run draws exactly what an uninterrupted one would.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from .body import body_topology
from .config import RanaConfig
from .data import FrameData, load_split
from .geometry import fit_offsets, silhouette_iou
from .model import RanaModel, coarse_buffers, stack_batch
from .nets import PatchDiscriminator, VGGPerceptual, hinge_d_loss
from .runs import Pretrained, RunDir, load_tensors
from .texture import exposure_sh_delight, extract_texture, fill_holes, grey_world_delight, texel_observations

__all__ = ["Coarse", "coarse_stage", "load_coarse", "save_coarse", "personalize", "cosine_lr",
           "build_training_state", "training_step", "ensure_coarse"]


@dataclass
class Coarse:
    """A subject's SMPL+D fit and coarse textures (saved as `<run>/coarse.pt`)."""

    offsets: torch.Tensor  # (V, 3) rest-space metres
    shaded_texture: torch.Tensor  # (3, S, S) median of the most camera-facing observations (exposure-scaled)
    valid: torch.Tensor  # (S, S) observed texels
    albedo_texture: torch.Tensor  # (3, S, S) coarse albedo T_A (linear)
    albedo_source: str  # "texturenet", "texturenet(exposure-sh)", "exposure-sh", "grey-world" or "shaded"
    iou_before: float
    iou_after: float
    light_world: torch.Tensor | None = None  # (9, 3) training light estimated by 'exposure-sh' (exposure units)

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def load_coarse(path: Path) -> Coarse:
    return Coarse(**load_tensors(path, "delete it and run `rana train` again to recompute the coarse stage"))


def save_coarse(coarse: Coarse, path: Path) -> None:
    """Atomically: a run killed while writing it recomputes the coarse stage instead of reading half a file."""
    from rh_common.imageio import atomic_path

    with atomic_path(path) as tmp:
        torch.save(coarse.to_dict(), tmp)


def coarse_stage(frames: list[FrameData], cfg: RanaConfig, *, texturenet=None, progress: bool = False,
                 log: list | None = None) -> Coarse:
    topo = body_topology()
    iou0 = silhouette_iou(frames, topo, None)
    D = fit_offsets(frames, topo, cfg.geometry, seed=cfg.seed, progress=progress, log=log)
    iou1 = silhouette_iou(frames, topo, D)
    tc = cfg.texture
    obs = texel_observations(frames, topo, D, tc, layer="image")
    shaded, valid = extract_texture(frames, topo, D, tc, obs=obs)
    light = None
    if texturenet is not None and tc.use_texturenet:
        from .texturenet import input_texture

        tex, tvalid, light = input_texture(texturenet.input_mode, obs, tc)
        albedo = texturenet.apply(tex, tvalid)
        source = "texturenet" if texturenet.input_mode == "shaded" else f"texturenet({texturenet.input_mode})"
    elif not tc.delight:
        albedo, source = fill_holes(shaded, valid).clamp(0, 1), "shaded"
    elif tc.delight_mode == "exposure-sh":
        tex, tvalid, light = exposure_sh_delight(obs, tc, ridge=tc.delight_ridge)
        albedo, source = fill_holes(tex, tvalid).clamp(0, 1), "exposure-sh"
    else:  # 'grey-world', the one other mode TextureConfig admits
        albedo = grey_world_delight(fill_holes(shaded, valid), valid, tc.assumed_mean_albedo)
        source = "grey-world"
    return Coarse(D, shaded, valid, albedo.contiguous(), source, iou0, iou1, light)


def cosine_lr(step: int, start: int, total: int, lr: float, lr_min: float) -> float:
    """Cosine annealing from lr (at `start`) to lr_min (at `total`); stateless, so resuming needs no scheduler."""
    if total <= start:
        return lr
    t = min(max((step - start) / (total - start), 0.0), 1.0)
    return lr_min + 0.5 * (lr - lr_min) * (1 + math.cos(math.pi * t))


@dataclass
class TrainingState:
    model: RanaModel
    disc: PatchDiscriminator | None
    vgg: VGGPerceptual | None
    opt_latent: torch.optim.Optimizer
    opt_net: torch.optim.Optimizer
    opt_disc: torch.optim.Optimizer | None

    def state_dict(self) -> dict:
        return {"model": self.model.state_dict(), "disc": self.disc.state_dict() if self.disc else None,
                "opt_latent": self.opt_latent.state_dict(), "opt_net": self.opt_net.state_dict(),
                "opt_disc": self.opt_disc.state_dict() if self.opt_disc else None}

    def load_state_dict(self, d: dict) -> None:
        self.model.load_state_dict(d["model"])
        if self.disc is not None and d.get("disc") is not None:
            self.disc.load_state_dict(d["disc"])
        self.opt_latent.load_state_dict(d["opt_latent"])
        self.opt_net.load_state_dict(d["opt_net"])
        if self.opt_disc is not None and d.get("opt_disc") is not None:
            self.opt_disc.load_state_dict(d["opt_disc"])


def build_training_state(cfg: RanaConfig, pretrained: Pretrained | None = None, use_vgg: bool = True,
                         light_init: torch.Tensor | None = None) -> TrainingState:
    """`light_init` (9, 3): E's starting value in OpenGL camera axes (default: uniform white, shading 1)."""
    torch.manual_seed(cfg.seed)
    model = RanaModel(cfg.model, n_subjects=1, n_lights=1, seed=cfg.seed)
    if light_init is not None:
        with torch.no_grad():
            model.E.copy_(light_init.to(model.E.dtype).expand_as(model.E))
    if pretrained is not None:
        pre_residual = pretrained.config.model.residual_coarse
        if pre_residual != cfg.model.residual_coarse:
            raise ValueError(f"pretrained G_N/G_A were trained with model.residual_coarse={pre_residual} but this run "
                             f"uses {cfg.model.residual_coarse}: pretrain again, or pass --model.residual_coarse "
                             f"{str(pre_residual).lower()}")
        # Only the networks transfer; Z and E of a new subject start from scratch.
        model.G_N.load_state_dict(pretrained.G_N)
        model.G_A.load_state_dict(pretrained.G_A)
    pc = cfg.personalize
    model.G_N.requires_grad_(pc.finetune_normal)
    disc = PatchDiscriminator(3, cfg.model.disc_base, cfg.model.disc_layers) if cfg.loss.lambda_gan > 0 else None
    vgg = VGGPerceptual() if (use_vgg and cfg.loss.lambda_vgg > 0) else None
    opt_latent = torch.optim.Adam([{"params": [model.Z], "lr": pc.lr_latent},
                                   {"params": [model.E], "lr": pc.lr_light}])
    nets = list(model.G_A.parameters()) + (list(model.G_N.parameters()) if pc.finetune_normal else [])
    opt_net = torch.optim.Adam(nets, lr=pc.lr_net)
    opt_disc = torch.optim.Adam(disc.parameters(), lr=pc.lr_disc, betas=(0.5, 0.999)) if disc else None
    return TrainingState(model, disc, vgg, opt_latent, opt_net, opt_disc)


def training_step(st: TrainingState, batch: dict, cfg: RanaConfig, step: int) -> dict:
    """One personalization step; returns the loss terms as floats."""
    pc = cfg.personalize
    frozen_a = step < pc.freeze_albedo_steps
    st.model.G_A.requires_grad_(not frozen_a)
    lr = cosine_lr(step, pc.freeze_albedo_steps, pc.steps, pc.lr_net, pc.lr_min)
    for g in st.opt_net.param_groups:
        g["lr"] = lr
    out = st.model.get_outputs(batch)
    if st.disc is not None:
        st.disc.requires_grad_(False)  # the generator's GAN term must not update the discriminator
    L = st.model.get_loss_dict(out, batch, cfg.loss, st.vgg, st.disc)
    st.opt_latent.zero_grad(set_to_none=True)
    st.opt_net.zero_grad(set_to_none=True)
    L["total"].backward()
    st.opt_latent.step()
    if not frozen_a:
        st.opt_net.step()
    rec = {k: float(v.detach()) if torch.is_tensor(v) else float(v) for k, v in L.items()}
    if st.disc is not None:
        from .nets import srgb_encode_t

        st.disc.requires_grad_(True)
        real = srgb_encode_t(batch["image"])
        fake = srgb_encode_t(out["composite"].detach())
        d_loss = hinge_d_loss(st.disc(real), st.disc(fake))
        st.opt_disc.zero_grad(set_to_none=True)
        d_loss.backward()
        st.opt_disc.step()
        rec["disc"] = float(d_loss.detach())
    rec["lr_net"] = lr
    rec["phase"] = 1 if frozen_a else 2
    return rec


def initial_light(coarse: Coarse, frames: list[FrameData]) -> torch.Tensor | None:
    """E's start: the coarse stage's estimated training light (world axes, exposure units) in the first training
    frame's OpenGL camera axes, so that at step 0 the avatar reproduces the coarse albedo x shading the coarse
    albedo was de-lit with. None when the coarse stage estimated no light (shaded-input TextureNet, grey-world)."""
    if coarse.light_world is None or not frames:
        return None
    from rh_common import sh

    return sh.rotate(coarse.light_world.float(), frames[0].world_to_opengl).float()


# Above this many bytes of cached VGG features (about 100 frames at 256 px) the targets' features are recomputed
# every step instead.
VGG_CACHE_BYTES = 2 << 30


def _cache_vgg_targets(st: TrainingState, bufs: list[dict]) -> None:
    """The training frames never change: compute their VGG features once (~1/6 of a step at 128 px, batch 1)."""
    if st.vgg is None or not bufs:
        return
    from .nets import srgb_encode_t

    first = st.vgg.target_buffers(srgb_encode_t(bufs[0]["image"]))
    if sum(t.numel() * t.element_size() for t in first.values()) * len(bufs) > VGG_CACHE_BYTES:
        return
    bufs[0].update(first)
    for b in bufs[1:]:
        b.update(st.vgg.target_buffers(srgb_encode_t(b["image"])))


def _frame_buffers(frames: list[FrameData], coarse: Coarse) -> list[dict]:
    topo = body_topology()
    return [coarse_buffers(fr, topo, coarse.offsets, coarse.albedo_texture) for fr in frames]


def ensure_coarse(dataset: str | Path, subject: str, protocol: str, run_dir: str | Path, cfg: RanaConfig, *,
                  pretrained: str | Path | None = None, progress: bool = True, force: bool = False):
    """The run folder (config written or checked) and the subject's coarse stage, computed once into
    `<run>/coarse.pt`. Returns (run, coarse, training frames, pretrained weights or None)."""
    run = RunDir(run_dir)
    if force:
        run.clear()
    run.init_config(cfg, {"dataset": str(Path(dataset).resolve()), "subject": subject, "protocol": protocol,
                          "pretrained": str(pretrained) if pretrained else None}, force=force)
    pre = Pretrained.load(pretrained) if pretrained else None
    frames = load_split(dataset, subject, protocol, "train", cfg.model.resolution, ("image", "mask"),
                        max_frames=cfg.personalize.max_frames, progress=progress)
    coarse_path = run.path / "coarse.pt"
    if coarse_path.is_file():
        return run, load_coarse(coarse_path), frames, pre
    texnet = None
    if pre is not None and pre.texturenet is not None:
        from .texturenet import TextureNet

        # The input mode it was trained with (its pretraining config), not this run's.
        texnet = TextureNet(cfg.texture, input_mode=pre.texturenet_input)
        texnet.load_state_dict(pre.texturenet)
    t0 = time.perf_counter()
    coarse = coarse_stage(frames, cfg, texturenet=texnet, progress=progress)
    save_coarse(coarse, coarse_path)
    run.log({"step": -1, "phase": 0, "seconds": time.perf_counter() - t0, "iou_before": coarse.iou_before,
             "iou_after": coarse.iou_after, "albedo_source": coarse.albedo_source})
    return run, coarse, frames, pre


def personalize(dataset: str | Path, subject: str, protocol: str, run_dir: str | Path, cfg: RanaConfig, *,
                pretrained: str | Path | None = None, progress: bool = True, force: bool = False,
                max_steps: int | None = None) -> RunDir:
    """Coarse stage (cached in `<run>/coarse.pt`) then personalization with checkpoints and resume.

    `max_steps` stops early (for tests of interruption) without changing the schedule."""
    from tqdm import tqdm

    run, coarse, frames, pre = ensure_coarse(dataset, subject, protocol, run_dir, cfg, pretrained=pretrained,
                                             progress=progress, force=force)
    bufs = _frame_buffers(frames, coarse)
    st = build_training_state(cfg, pre, light_init=initial_light(coarse, frames))
    _cache_vgg_targets(st, bufs)
    start = 0
    latest = run.latest()
    if latest is not None and not force:
        st.load_state_dict(run.load(latest[1]))
        start = latest[0]
        run.truncate_log(start)
    pc = cfg.personalize
    end = pc.steps if max_steps is None else min(pc.steps, max_steps)
    bar = tqdm(range(start, end), initial=start, total=pc.steps, desc=f"personalize {subject}", unit="step",
               disable=not progress, dynamic_ncols=True)
    t0 = time.perf_counter()
    for step in bar:
        rng = np.random.default_rng([cfg.seed, step])
        idx = rng.choice(len(bufs), size=min(pc.batch_size, len(bufs)), replace=False)
        batch = stack_batch([bufs[i] for i in idx])
        rec = training_step(st, batch, cfg, step)
        if step % pc.log_every == 0 or step == pc.steps - 1:
            run.log({"step": step, "seconds": time.perf_counter() - t0, **rec})
            bar.set_postfix(loss=f"{rec['total']:.4f}", pix=f"{rec['pixel']:.4f}", phase=rec["phase"], refresh=False)
        done = step + 1
        if done % pc.checkpoint_every == 0 or done == pc.steps:
            run.save(done, st.state_dict(), keep=pc.keep_checkpoints)
    bar.close()
    return run
