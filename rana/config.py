"""RANA's configuration: one frozen, validated dataclass per component, and named presets.

In: field values (a preset, command-line flags, a stored config). Out: a `RanaConfig` whose fields were checked on
construction: each field's type, each `Literal` mode among its values, counts and weights within their bounds. A
bad value raises `ValueError` naming `section.field`, the value and what is allowed, before any work starts rather
than steps later where the value is first used.

Every field carries a docstring, the help text of its `--section.field` flag (`rana.config_flags`). Two levels at
most: `RanaConfig.<section>.<field>`. Stored configs (JSON with a schema version): `rana.config_json`.
"""
from __future__ import annotations

import dataclasses
import functools
import typing
from dataclasses import dataclass, field
from typing import Any, Literal

__all__ = [
    "GeometryConfig",
    "TextureConfig",
    "ModelConfig",
    "LossConfig",
    "PersonalizeConfig",
    "PretrainConfig",
    "RanaConfig",
    "SECTIONS",
    "TextureNetInput",
    "DelightMode",
    "LightSource",
    "PRESETS",
    "get_preset",
    "field_types",
]

# The mode fields' values, defined once: the dataclasses, the flags' choices and TextureNet read them here.
TextureNetInput = Literal["shaded", "exposure-sh"]
DelightMode = Literal["exposure-sh", "grey-world"]
LightSource = Literal["dataset", "random-sh"]


@functools.lru_cache(maxsize=None)
def field_types(cls: type) -> dict[str, Any]:
    """A config dataclass's field types, resolved (the annotations are strings here) once per class."""
    return typing.get_type_hints(cls)


def _check(obj, *, positive: tuple[str, ...] = (), nonneg: tuple[str, ...] = (), unit: tuple[str, ...] = ()) -> None:
    """Validate a config dataclass on construction: every field's type (a `Literal` field: one of its values), then
    the bounds. An int given for a float field becomes a float, so a config read back from JSON equals the one
    written."""
    sec = _SECTION_OF.get(type(obj))
    where = (lambda n: f"{sec}.{n}") if sec else (lambda n: n)  # noqa: E731
    for f in dataclasses.fields(obj):
        v, t = getattr(obj, f.name), field_types(type(obj))[f.name]
        if typing.get_origin(t) is Literal:
            if not isinstance(v, str) or v not in typing.get_args(t):
                raise ValueError(f"{where(f.name)}: {v!r} is not one of {', '.join(map(repr, typing.get_args(t)))}")
        elif t is float and isinstance(v, int) and not isinstance(v, bool):
            object.__setattr__(obj, f.name, float(v))  # frozen: the one sanctioned write, during construction
        elif not isinstance(v, t) or (isinstance(v, bool) and t is not bool):
            raise ValueError(f"{where(f.name)}: expected {t.__name__}, got {v!r}")
    for names, ok, rule in ((positive, lambda v: v > 0, "> 0"), (nonneg, lambda v: v >= 0, ">= 0"),
                            (unit, lambda v: 0 <= v <= 1, "in [0, 1]")):
        for n in names:
            if not ok(getattr(obj, n)):  # NaN fails every rule
                raise ValueError(f"{where(n)}: must be {rule}, got {getattr(obj, n)!r}")


@dataclass(frozen=True)
class GeometryConfig:
    """SMPL+D on anny: per-vertex offsets D fitted to the training masks (paper Sec. 3.1)."""

    resolution: int = 128
    """Image height (px) at which the soft silhouette is rendered and compared with the masks."""
    steps: int = 300
    """Adam steps of the offset fit."""
    frames_per_step: int = 4
    """Training frames whose silhouettes enter each step (drawn at random, seeded)."""
    lr: float = 3e-3
    """Adam learning rate for D (metres per step, roughly)."""
    sigma_px: float = 0.3
    """Softness of the silhouette edge (pixels at `resolution`): coverage = sigmoid(signed distance / sigma)."""
    laplacian_weight: float = 1.0
    """Weight of the Laplacian smoothness term ||L D||^2 (mean over vertices, D in cm, L uniform); the silhouette
    term is the relative area error (sum |S - mask| / sum mask)."""
    offset_weight: float = 1e-3
    """Weight of a small ||D||^2 (cm^2) pull toward the naked body (keeps unobserved regions, e.g. soles, in
    place)."""
    max_frames: int = 0
    """Use at most this many training frames (evenly spaced); 0 = all."""

    def __post_init__(self) -> None:
        _check(self, positive=("resolution", "steps", "frames_per_step", "lr", "sigma_px"),
               nonneg=("laplacian_weight", "offset_weight", "max_frames"))


@dataclass(frozen=True)
class TextureConfig:
    """Coarse albedo texture: back-projection + median of the most camera-facing texels, then TextureNet (Sec. 3.2)."""

    size: int = 256
    """UV texture size (texels per side)."""
    facing_quantile: float = 0.8
    """A texel's colour is the median over the frames whose facing (cos of normal to view ray) is at least this
    fraction of that texel's best facing: 'the most orthogonal texels'."""
    min_facing: float = 0.2
    """Observations more grazing than this cosine are never used."""
    unet_base: int = 32
    """TextureNet U-Net: channels of the first level (doubled per level)."""
    unet_depth: int = 4
    """TextureNet U-Net: number of down-sampling levels."""
    steps: int = 2000
    """TextureNet training steps (pretraining)."""
    batch_size: int = 8
    """TextureNet batch size (paper: 8)."""
    lr: float = 1e-4
    """TextureNet Adam learning rate (paper: 1e-4, cosine-annealed to `lr_min`)."""
    lr_min: float = 1e-5
    """Final learning rate of the cosine schedule (paper: 1e-5)."""
    lambda_vgg: float = 1.0
    """Weight of the VGG term (paper: 1)."""
    lambda_gan: float = 10.0
    """Weight of the PatchGAN term (paper: 10)."""
    mixup_beta: float = 0.4
    """MixUp Beta(a, a) parameter of the input augmentation (paper: 0.4); 0 disables MixUp."""
    texturenet_input: TextureNetInput = "exposure-sh"
    """What TextureNet starts from. 'shaded' (the paper) = the shaded median texture; the network must learn to
    remove the light. 'exposure-sh' = the texture de-lit by `exposure_sh_delight` (see `delight_mode`), with a
    residual output initialised to zero: the network only corrects that estimate, so a TextureNet trained on few
    characters cannot make the albedo worse than the estimate it starts from. Ours; measured in docs/RANA.md
    (a 150-step 'shaded' TextureNet cost 5.7 dB of albedo PSNR against the de-lit texture alone)."""
    use_texturenet: bool = True
    """Apply a pretrained TextureNet when one is given; without one the coarse albedo is the de-lit median
    texture (`delight`)."""
    delight: bool = True
    """Without TextureNet: remove the training light from the median texture (see `delight_mode`); false keeps the
    shaded median texture as the albedo."""
    delight_mode: DelightMode = "exposure-sh"
    """Without TextureNet: 'exposure-sh' = the training light's order-2 SH and per-texel albedo fitted jointly to
    every observation with the coarse normals (albedo x S(n) = observed), the scale fixed by the exposure
    convention (the light's mean luminance is 1 in the frames' units, DC term taken white); 'grey-world' = scale
    each channel so the observed texels average `assumed_mean_albedo` (the older fallback)."""
    delight_ridge: float = 1e-2
    """'exposure-sh': ridge on the light's bands 1-2, relative to the mean diagonal of the normal equations."""
    assumed_mean_albedo: float = 0.5
    """'grey-world' only: the mean albedo it assumes (sets the albedo/light scale ambiguity)."""

    def __post_init__(self) -> None:
        _check(self, positive=("size", "unet_base", "steps", "batch_size", "lr", "assumed_mean_albedo"),
               nonneg=("unet_depth", "lr_min", "lambda_vgg", "lambda_gan", "mixup_beta", "delight_ridge"),
               unit=("facing_quantile", "min_facing"))


@dataclass(frozen=True)
class ModelConfig:
    """The neural avatar: latent texture Z, NormalNet G_N, AlbedoNet G_A, SH light E (Sec. 3.3)."""

    resolution: int = 128
    """Image height (px) the avatar is trained and rendered at; predictions are resized to the frame's size."""
    latent_size: int = 128
    """Z: texels per side (paper: 256)."""
    latent_channels: int = 16
    """Z: channels (paper: 16)."""
    pe_frequencies: int = 6
    """Positional encoding of UV: sin/cos at 2^0..2^(L-1) times pi (NeRF's gamma)."""
    unet_base: int = 32
    """G_A and G_N U-Nets: channels of the first level (doubled per level, capped at 8x)."""
    unet_depth: int = 4
    """G_A and G_N U-Nets: number of down-sampling levels."""
    residual_coarse: bool = True
    """G_N, G_A output corrections of the coarse (SMPL+D) normal, albedo and mask, their last layers zero-initialised,
    so an untrained avatar renders exactly SMPL+D (ours; False = the paper's direct outputs, which from scratch start
    at albedo 0.5, random normals and a random mask)."""
    disc_base: int = 32
    """PatchGAN discriminator: channels of the first layer."""
    disc_layers: int = 3
    """PatchGAN discriminator: strided layers (3 = the 70x70 PatchGAN of pix2pix)."""

    def __post_init__(self) -> None:
        _check(self, positive=("resolution", "latent_size", "latent_channels", "unet_base", "disc_base",
                               "disc_layers"), nonneg=("pe_frequencies", "unet_depth"))


@dataclass(frozen=True)
class LossConfig:
    """Personalization objective (paper Eq. 7 and appendix weights)."""

    lambda_pixel: float = 1.0
    """L1 between the composited image and the training frame, display space."""
    lambda_face: float = 1.0
    """L1 on a crop around the projected head (paper: 1)."""
    lambda_mask: float = 10.0
    """BCE between AlbedoNet's mask and the training mask (paper: 10)."""
    lambda_vgg: float = 5.0
    """L1 between VGG16 relu1_2/2_2/3_3/4_3 features (paper: 5)."""
    lambda_gan: float = 0.1
    """PatchGAN hinge loss (paper: 0.1)."""
    lambda_albedo_reg: float = 0.5
    """||blur(I_A) - blur(coarse albedo)||^2, Gaussian k=51 at 512 px (paper: 0.5)."""
    lambda_normal_reg: float = 0.25
    """|S_smpl (I_N - coarse normal)| inside the SMPL+D mask (paper: 0.25)."""
    face_crop_px: int = 100
    """Face crop side at 512 px (paper: 100); scaled with the resolution."""
    blur_kernel: int = 51
    """Gaussian kernel of the albedo regulariser at 512 px (paper: 51); scaled with the resolution, kept odd."""

    def __post_init__(self) -> None:
        _check(self, positive=("face_crop_px", "blur_kernel"),
               nonneg=tuple(f.name for f in dataclasses.fields(self) if f.name.startswith("lambda_")))


@dataclass(frozen=True)
class PersonalizeConfig:
    """Per-subject training: new Z and E, G_A frozen first, then G_A, Z, E jointly; G_N frozen (appendix)."""

    steps: int = 15000
    """Total iterations (paper: 15k)."""
    freeze_albedo_steps: int = 1000
    """Iterations with G_A frozen, optimising only Z and E (paper: 1000)."""
    finetune_normal: bool = False
    """Also fine-tune G_N (paper's ablation: negligible effect)."""
    batch_size: int = 1
    """Frames per step."""
    lr_net: float = 1e-4
    """Adam learning rate of G_A (and G_N if fine-tuned), cosine-annealed to `lr_min`."""
    lr_min: float = 1e-5
    """Final network learning rate."""
    lr_latent: float = 5e-3
    """Adam learning rate of Z."""
    lr_light: float = 5e-3
    """Adam learning rate of E."""
    lr_disc: float = 1e-4
    """Adam learning rate of the discriminator."""
    checkpoint_every: int = 1000
    """Write `checkpoints/step-%09d.pt` every this many steps (and at the end)."""
    log_every: int = 10
    """Append a line to `losses.jsonl` every this many steps."""
    keep_checkpoints: int = 3
    """Keep only the newest this many checkpoints (0 keeps all)."""
    max_frames: int = 0
    """Use at most this many training frames (evenly spaced); 0 = all."""

    def __post_init__(self) -> None:
        _check(self, positive=("steps", "batch_size", "lr_net", "lr_latent", "lr_light", "lr_disc",
                               "checkpoint_every", "log_every"),
               nonneg=("freeze_albedo_steps", "lr_min", "keep_checkpoints", "max_frames"))


@dataclass(frozen=True)
class PretrainConfig:
    """Pretraining G_A and G_N (with per-character Z) on generated characters' albedo, normal and mask (Sec. 3.4)."""

    steps: int = 50000
    """Iterations (paper: 230 epochs of 400 x 150 frames at batch 16)."""
    batch_size: int = 16
    """Frames per step (paper: 16)."""
    lr: float = 1e-4
    """Adam learning rate of the networks (paper: 1e-4, cosine to `lr_min`)."""
    lr_min: float = 1e-5
    """Final learning rate (paper: 1e-5)."""
    lr_latent: float = 5e-3
    """Adam learning rate of the per-character latents Z."""
    lambda_albedo: float = 0.5
    """Weight of the albedo terms (paper: lambda_a = 0.5)."""
    lambda_mask: float = 10.0
    """Weight of the mask BCE (paper: 10)."""
    lambda_vgg: float = 5.0
    """Weight of the VGG terms (paper: 5)."""
    lambda_gan: float = 0.1
    """Weight of the GAN terms (paper: 0.1)."""
    light_source: LightSource = "dataset"
    """The light that shades a pretraining character's AOV-only frames for TextureNet's inputs (one per character,
    as one training video has one light): 'dataset' = the generator's HDRI light of the character's first frame
    (its order-2 SH, at that frame's exposure), so the lights come from the same pool as the benchmark's;
    'random-sh' = an ambient term plus a soft coloured lobe drawn with `light_seed` (the older choice)."""
    light_seed: int = 0
    """Seed of the 'random-sh' lights."""
    checkpoint_every: int = 2000
    """Checkpoint period (steps)."""
    log_every: int = 10
    """Loss-log period (steps)."""
    max_subjects: int = 0
    """Use at most this many pretraining characters; 0 = all."""
    max_frames: int = 0
    """Use at most this many frames per character; 0 = all."""

    def __post_init__(self) -> None:
        # light_seed and the top-level seed seed numpy generators, which refuse negative seeds.
        _check(self, positive=("steps", "batch_size", "lr", "lr_latent", "checkpoint_every", "log_every"),
               nonneg=("lr_min", "lambda_albedo", "lambda_mask", "lambda_vgg", "lambda_gan", "light_seed",
                       "max_subjects", "max_frames"))


@dataclass(frozen=True)
class RanaConfig:
    """Everything a RANA run needs; saved as `config.json` beside its checkpoints."""

    preset: str = "cpu"
    """Name of the preset the run started from (informational)."""
    seed: int = 0
    """Seed of every random choice (frame sampling, initialisation, augmentation)."""
    threads: int = 0
    """torch intra-op threads; 0 = torch's default."""
    geometry: GeometryConfig = field(default_factory=GeometryConfig)
    """Coarse geometry."""
    texture: TextureConfig = field(default_factory=TextureConfig)
    """Coarse albedo texture."""
    model: ModelConfig = field(default_factory=ModelConfig)
    """Neural avatar."""
    loss: LossConfig = field(default_factory=LossConfig)
    """Personalization losses."""
    personalize: PersonalizeConfig = field(default_factory=PersonalizeConfig)
    """Personalization schedule."""
    pretrain: PretrainConfig = field(default_factory=PretrainConfig)
    """Pretraining schedule."""

    def __post_init__(self) -> None:
        _check(self, nonneg=("seed", "threads"))


# The sections of a RanaConfig by name; `_check` names a bad field `section.field` through the inverse.
SECTIONS: dict[str, type] = {"geometry": GeometryConfig, "texture": TextureConfig, "model": ModelConfig,
                             "loss": LossConfig, "personalize": PersonalizeConfig, "pretrain": PretrainConfig}
_SECTION_OF = {cls: name for name, cls in SECTIONS.items()}


def _r(cfg: RanaConfig, **sections: dict) -> RanaConfig:
    out = cfg
    for name, kw in sections.items():
        if isinstance(kw, dict):
            out = dataclasses.replace(out, **{name: dataclasses.replace(getattr(out, name), **kw)})
        else:
            out = dataclasses.replace(out, **{name: kw})
    return out


# The paper's sizes and iteration counts (appendix). Geometry steps and TextureNet steps are not given there.
_PAPER = _r(RanaConfig(), preset="paper",
            geometry=dict(resolution=256, steps=1000, frames_per_step=8),
            texture=dict(size=512, unet_base=64, unet_depth=5, steps=100000, texturenet_input="shaded"),
            model=dict(resolution=512, latent_size=256, unet_base=64, unet_depth=5, disc_base=64),
            personalize=dict(steps=15000, freeze_albedo_steps=1000, checkpoint_every=1000),
            pretrain=dict(steps=1_000_000, batch_size=16))

# Sized so one subject (coarse stage + personalization) fits well inside an hour on 2 CPU cores; see
# bench/bench_rana.py for the measured time per step.
_CPU = _r(RanaConfig(), preset="cpu",
          geometry=dict(resolution=128, steps=200, frames_per_step=2),
          # No GAN term for TextureNet: on 14 characters, 60 steps, it cost 0.37 dB of held-out albedo PSNR where
          # L1 + VGG alone gained 0.19 dB (bench/texturenet_check.py; docs/RANA.md).
          texture=dict(size=256, unet_base=16, unet_depth=4, steps=1500, batch_size=4, lambda_gan=0.0),
          model=dict(resolution=128, latent_size=128, unet_base=16, unet_depth=4, disc_base=32),
          personalize=dict(steps=2000, freeze_albedo_steps=200, checkpoint_every=250),
          pretrain=dict(steps=3000, batch_size=4, checkpoint_every=500))

# For tests and smoke runs only: seconds, not minutes.
_TINY = _r(RanaConfig(), preset="tiny",
           geometry=dict(resolution=48, steps=20, frames_per_step=2),
           texture=dict(size=32, unet_base=4, unet_depth=2, steps=4, batch_size=2),
           model=dict(resolution=48, latent_size=32, latent_channels=8, pe_frequencies=3, unet_base=8,
                      unet_depth=2, disc_base=8, disc_layers=2),
           personalize=dict(steps=6, freeze_albedo_steps=2, checkpoint_every=3, log_every=1),
           pretrain=dict(steps=4, batch_size=2, checkpoint_every=2, log_every=1))

# The README demo (rh-demo): SMPL+D on 12 turntable frames at 128 px in well under a minute of one core
# (coarse fit 100 steps; the rest as `cpu`, whose personalization it keeps).
_DEMO = _r(_CPU, preset="demo", geometry=dict(steps=100, frames_per_step=2))

PRESETS: dict[str, RanaConfig] = {"paper": _PAPER, "cpu": _CPU, "demo": _DEMO, "tiny": _TINY}


def get_preset(name: str) -> RanaConfig:
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; known: {sorted(PRESETS)}")
    return PRESETS[name]
