"""`rana-pretrain`: TextureNet, then NormalNet and AlbedoNet, on generated pretraining characters (paper Sec. 3.2,
3.4 and appendix).

Input: a dataset whose train split carries AOV-only frames (albedo, normal, mask; no path tracing) of characters
disjoint from the benchmark's test subjects — `rh-generate --protocol rana_pretrain` (its JSON in
rh_dataset/scenes/, character_pool "pretrain"). Stages, each cached in the output folder so an interrupted run resumes:

1. per character (`cache/<subject>.pt`): SMPL+D offsets fitted to the masks; Lambertian frames
   ``albedo x max(0, S(normal; light))`` made from the AOVs, one light per character (`pretrain.light_source`:
   the dataset's HDRI light of its first frame, or a seeded random SH light), from which TextureNet's input is
   extracted exactly as for a real subject (the shaded median texture, or that texture de-lit, per
   `texture.texturenet_input`); the target albedo texture is the same extraction applied to the ground-truth albedo
   frames (so it lives in anny's UV layout and includes garments).
2. TextureNet (`texturenet.pt`; checkpoints and loss log in `texturenet/`, resumable): L1 + VGG + PatchGAN with
   MixUp, coarse dropout, noise and brightness jitter.
3. G_N, G_A with one latent Z per character (`checkpoints/step-%09d.pt`, resumable): L_normal + lambda_a L_albedo
   + lambda_m BCE, each of L1 + VGG + GAN, against the ground-truth normal, albedo and mask frames.

Output: `<out>/pretrained.pt` (`rana.runs.Pretrained`: G_N, G_A, TextureNet, the config as JSON), what
`rana train --pretrained` loads.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

from rh_common import sh
from rh_common.colourspace import luminance
from rh_common.imageio import atomic_path
from rh_common.threads import torch_threads
from rh_common.interrupt import add_debug_flag, checkpoint, command, on_stop

from .body import body_topology
from .config import RanaConfig, get_preset, PRESETS
from .config_flags import add_config_flags, apply_config_flags
from .data import load_split, subjects_of
from .geometry import fit_offsets
from .model import AMBIENT_L0, RanaModel, coarse_buffers, stack_batch
from .nets import PatchDiscriminator, VGGPerceptual, hinge_d_loss
from .runs import Pretrained, RunDir, load_tensors
from .synthetic import random_sh
from .texture import extract_texture, texel_observations
from .texturenet import TextureNet, augment, input_texture, texturenet_input, texturenet_loss
from .train import cosine_lr

__all__ = ["prepare_character", "load_or_prepare_character", "train_texturenet", "pretrain", "main"]


def _save(path: Path, obj) -> None:
    with atomic_path(path) as tmp:
        torch.save(obj, tmp)


def prepare_character(dataset: Path, subject: str, protocol: str, cfg: RanaConfig, progress: bool = False) -> dict:
    frames = load_split(dataset, subject, protocol, "train", cfg.model.resolution, ("albedo", "normal", "mask"),
                        max_frames=cfg.pretrain.max_frames)
    topo = body_topology()
    D = fit_offsets(frames, topo, cfg.geometry, seed=cfg.seed, progress=progress)
    light = character_light(frames, subject, cfg)
    for fr in frames:
        # Lambertian, shadow-free frames from the AOVs: the shading TextureNet must learn to remove. The light is
        # in world axes; the frame's normals in its OpenGL camera axes (n_cam = R n_world, so n_world = n_cam R).
        shade = sh.shading(light, fr.normal @ fr.world_to_opengl).clamp_min(0)  # radiance is never negative
        fr.image = fr.albedo * shade * fr.mask[..., None]
    tc = cfg.texture
    obs = texel_observations(frames, topo, D, tc, layer="image")
    net_input, valid, _ = input_texture(tc.texturenet_input, obs, tc)
    target, target_valid = extract_texture(frames, topo, D, tc, layer="albedo")
    return {"subject": subject, "offsets": D, "net_input": net_input, "valid": valid, "target": target,
            "target_valid": target_valid, "texturenet_input": tc.texturenet_input,
            "light_source": cfg.pretrain.light_source, "light": light}


def load_or_prepare_character(dataset: Path, subject: str, protocol: str, cfg: RanaConfig, cache: Path,
                              force: bool = False) -> dict:
    """`prepare_character`, cached as `cache/<subject>.pt`."""
    p = Path(cache) / f"{subject}.pt"
    if p.is_file() and not force:
        try:
            c = load_tensors(p, "it is redone")
        except ValueError:
            c = {}  # not a cache this version can read
        # A cache made with another input mode or light (or by an older version) is redone, not reused.
        if (c.get("texturenet_input"), c.get("light_source")) == (cfg.texture.texturenet_input,
                                                                   cfg.pretrain.light_source):
            return c
    c = prepare_character(Path(dataset), subject, protocol, cfg)
    _save(p, c)
    return c


def character_light(frames: list, subject: str, cfg: RanaConfig) -> torch.Tensor:
    """(9, 3) world-axes SH radiance that shades one pretraining character, in the frames' exposure units (the
    light's mean luminance over the sphere is 1; docs/ARCHITECTURE.md, "Exposure"), so TextureNet learns the
    brightness real frames have."""
    src = cfg.pretrain.light_source
    if src == "dataset":
        fr = frames[0]
        sh_world = fr.meta.get("light", {}).get("sh_world")
        if sh_world is None:
            raise ValueError(f"{fr.path}: no light.sh_world in the frame's metadata; regenerate the pretraining "
                             f"data with this rh-generate, or pass --pretrain.light_source random-sh")
        return torch.as_tensor(np.asarray(sh_world, dtype=np.float64) * fr.exposure, dtype=torch.float32)
    # 'random-sh', the one other source PretrainConfig admits.
    rng = np.random.default_rng([cfg.pretrain.light_seed,
                                 int(subject.split("_")[-1]) if subject[-1].isdigit() else 0])
    light = random_sh(rng)
    return torch.as_tensor(light * (AMBIENT_L0 / float(luminance(light[0]))), dtype=torch.float32)


def train_texturenet(chars: list[dict], cfg: RanaConfig, run: RunDir | None = None,
                     progress: bool = True) -> TextureNet:
    """TextureNet on (shaded texture, albedo texture) pairs. With a `run` folder: checkpoints every
    `pretrain.checkpoint_every` steps, resume from the newest, losses in its `losses.jsonl`. Each step draws its
    batch and augmentation from a generator seeded by (seed, step), so a resumed run equals an uninterrupted one."""
    from tqdm import tqdm

    tc = cfg.texture
    torch.manual_seed(cfg.seed)
    net = TextureNet(tc)
    disc = PatchDiscriminator(3, cfg.model.disc_base, cfg.model.disc_layers) if tc.lambda_gan > 0 else None
    vgg = VGGPerceptual() if tc.lambda_vgg > 0 else None
    opt = torch.optim.Adam(net.parameters(), lr=tc.lr)
    opt_d = torch.optim.Adam(disc.parameters(), lr=tc.lr, betas=(0.5, 0.999)) if disc else None
    start = run.resume({"net": net, "opt": opt, "disc": disc, "opt_d": opt_d}) if run is not None else 0
    X = torch.stack([texturenet_input(c["net_input"], c["valid"]) for c in chars])
    Y = torch.stack([c["target"] for c in chars])
    M = torch.stack([c["target_valid"] for c in chars])
    t0 = time.perf_counter()
    bar = tqdm(range(start, tc.steps), initial=start, total=tc.steps, desc="TextureNet", unit="step",
               disable=not progress, dynamic_ncols=True)
    for step in bar:
        rng = np.random.default_rng([cfg.seed, 7, step])
        for g in opt.param_groups:
            g["lr"] = cosine_lr(step, 0, tc.steps, tc.lr, tc.lr_min)
        idx = rng.choice(len(chars), size=min(tc.batch_size, len(chars)), replace=len(chars) < tc.batch_size)
        x, y, m = X[idx], Y[idx], M[idx]
        if tc.mixup_beta > 0 and len(chars) > 1:
            lam = float(rng.beta(tc.mixup_beta, tc.mixup_beta))
            perm = torch.as_tensor(rng.permutation(len(idx)))
            x = lam * x + (1 - lam) * x[perm]
            y = lam * y + (1 - lam) * y[perm]
            m = m & m[perm]
        x = augment(x, rng)
        if disc is not None:
            disc.requires_grad_(False)
        L = texturenet_loss(net, disc, vgg, x, y, m, tc)
        opt.zero_grad(set_to_none=True)
        L["total"].backward()
        opt.step()
        rec = {k: float(v.detach()) if torch.is_tensor(v) else float(v) for k, v in L.items() if not k.startswith("_")}
        if disc is not None:
            disc.requires_grad_(True)
            d = hinge_d_loss(disc(L["_gt"]), disc(L["_pred"].detach()))
            opt_d.zero_grad(set_to_none=True)
            d.backward()
            opt_d.step()
            rec["disc"] = float(d.detach())
        if run is not None:
            if step % cfg.pretrain.log_every == 0 or step == tc.steps - 1:
                run.log({"step": step, "seconds": time.perf_counter() - t0, **rec})
            done = step + 1
            if done % cfg.pretrain.checkpoint_every == 0 or done == tc.steps:
                state = {"net": net.state_dict(), "opt": opt.state_dict()}
                if disc is not None:
                    state.update(disc=disc.state_dict(), opt_d=opt_d.state_dict())
                run.save(done, state, keep=2)
        bar.set_postfix(loss=f"{rec['total']:.4f}", refresh=False)
    bar.close()
    return net.eval()


def pretrain(dataset: str | Path, protocol: str, out: str | Path, cfg: RanaConfig, *, progress: bool = True,
             force: bool = False) -> Path:
    from tqdm import tqdm

    dataset, out = Path(dataset), Path(out)
    run = RunDir(out)
    if force:
        run.clear()
        RunDir(out / "texturenet").clear()
    run.init_config(cfg, {"dataset": str(dataset.resolve()), "protocol": protocol, "kind": "pretrain"}, force=force)
    subjects = subjects_of(dataset, protocol, "train")
    if cfg.pretrain.max_subjects > 0:
        subjects = subjects[: cfg.pretrain.max_subjects]
    if not subjects:
        raise FileNotFoundError(f"{dataset}: no subject_*/protocol_{protocol}/train folders")
    # Stage 1: per-character coarse data.
    chars = [load_or_prepare_character(dataset, s, protocol, cfg, out / "cache", force=force)
             for s in tqdm(subjects, desc="characters", unit="char", disable=not progress, dynamic_ncols=True)]
    # Stage 2: TextureNet.
    tex_path = out / "texturenet.pt"
    texnet = TextureNet(cfg.texture)
    if tex_path.is_file() and not force:
        texnet.load_state_dict(load_tensors(tex_path, "delete it, or pass --force, to train TextureNet again"))
    else:
        texnet = train_texturenet(chars, cfg, RunDir(out / "texturenet"), progress)
        _save(tex_path, texnet.state_dict())
    albedo_tex = [texnet.apply(c["net_input"], c["valid"]) for c in chars]
    # Stage 3: G_N and G_A with per-character Z.
    topo = body_topology()
    bufs = []
    for ci, (c, s) in enumerate(zip(chars, subjects)):
        frames = load_split(dataset, s, protocol, "train", cfg.model.resolution, ("albedo", "normal", "mask"),
                            max_frames=cfg.pretrain.max_frames)
        for fr in frames:
            b = coarse_buffers(fr, topo, c["offsets"], albedo_tex[ci])
            b["subject"] = torch.tensor(ci)
            bufs.append(b)
    pc = cfg.pretrain
    torch.manual_seed(cfg.seed)
    model = RanaModel(cfg.model, n_subjects=len(chars), n_lights=1, seed=cfg.seed)
    disc_n = PatchDiscriminator(3, cfg.model.disc_base, cfg.model.disc_layers) if pc.lambda_gan > 0 else None
    disc_a = PatchDiscriminator(3, cfg.model.disc_base, cfg.model.disc_layers) if pc.lambda_gan > 0 else None
    vgg = VGGPerceptual() if pc.lambda_vgg > 0 else None
    opt = torch.optim.Adam([{"params": list(model.G_N.parameters()) + list(model.G_A.parameters()), "lr": pc.lr},
                            {"params": [model.Z], "lr": pc.lr_latent}])
    opt_d = torch.optim.Adam(list(disc_n.parameters()) + list(disc_a.parameters()), lr=pc.lr, betas=(0.5, 0.999)) \
        if disc_n else None
    start = 0 if force else run.resume({"model": model, "opt": opt, "disc_n": disc_n, "disc_a": disc_a,
                                        "opt_d": opt_d})
    t0 = time.perf_counter()
    bar = tqdm(range(start, pc.steps), initial=start, total=pc.steps, desc="pretrain G_N, G_A", unit="step",
               disable=not progress, dynamic_ncols=True)
    for step in bar:
        opt.param_groups[0]["lr"] = cosine_lr(step, 0, pc.steps, pc.lr, pc.lr_min)
        rng = np.random.default_rng([cfg.seed, 11, step])
        idx = rng.choice(len(bufs), size=min(pc.batch_size, len(bufs)), replace=False)
        batch = stack_batch([bufs[i] for i in idx])
        out_ = model.get_outputs(batch, light=torch.zeros(len(idx), 9, 3))  # no light: AOV supervision only
        for d in (disc_n, disc_a):
            if d is not None:
                d.requires_grad_(False)
        L = model.get_pretrain_loss_dict(out_, batch, pc, vgg, disc_n, disc_a)
        n_pred, n_gt, a_pred, a_gt = L.pop("_disc_inputs")
        opt.zero_grad(set_to_none=True)
        L["total"].backward()
        opt.step()
        rec = {k: float(v.detach()) if torch.is_tensor(v) else float(v) for k, v in L.items()}
        if disc_n is not None:
            disc_n.requires_grad_(True)
            disc_a.requires_grad_(True)
            dl = hinge_d_loss(disc_n(n_gt), disc_n(n_pred.detach())) + \
                hinge_d_loss(disc_a(a_gt), disc_a(a_pred.detach()))
            opt_d.zero_grad(set_to_none=True)
            dl.backward()
            opt_d.step()
            rec["disc"] = float(dl.detach())
        if step % pc.log_every == 0 or step == pc.steps - 1:
            run.log({"step": step, "seconds": time.perf_counter() - t0, **rec})
            bar.set_postfix(loss=f"{rec['total']:.4f}", refresh=False)
        done = step + 1
        if done % pc.checkpoint_every == 0 or done == pc.steps:
            state = {"model": model.state_dict(), "opt": opt.state_dict()}
            if disc_n is not None:
                state.update(disc_n=disc_n.state_dict(), disc_a=disc_a.state_dict(), opt_d=opt_d.state_dict())
            run.save(done, state, keep=3)
    bar.close()
    return Pretrained(model.G_N.state_dict(), model.G_A.state_dict(), cfg, texnet.state_dict(),
                      subjects).save(out / "pretrained.pt")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="rana-pretrain", description=__doc__.strip().splitlines()[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="Every knob below overrides the preset; see rana/config.py for the defaults.")
    p.add_argument("--dataset", required=True, type=Path,
                   help="AOV-only pretraining dataset (rh-generate --protocol rana_pretrain)")
    p.add_argument("--protocol", default="a", help="protocol folder of that dataset (default a)")
    p.add_argument("--out", required=True, type=Path, help="output folder (resumable)")
    p.add_argument("--preset", default="cpu", choices=sorted(PRESETS), help="starting configuration")
    p.add_argument("--force", action="store_true", help="restart instead of resuming")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_config_flags(p)
    add_debug_flag(p)
    return p


@command("rana-pretrain", not_on_resume=("--force",))
def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    on_stop(lambda: f"the checkpoints in {args.out} are kept; a rerun resumes from the newest")
    try:
        cfg = apply_config_flags(get_preset(args.preset), args)
        with torch_threads(cfg.threads):  # the command's own count, restored when it returns
            path = pretrain(args.dataset, args.protocol, args.out, cfg, progress=not args.no_progress, force=args.force)
    except (FileNotFoundError, ValueError) as exc:
        checkpoint()  # an error that follows a stop lost in a C callback is that stop (rh_common.interrupt)
        print(f"rana-pretrain: error: {exc}", file=sys.stderr)
        return 2
    print(f"rana-pretrain: wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
