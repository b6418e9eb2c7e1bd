"""The SMPL+D coarse albedo's de-lighting ('exposure-sh'): the exposure convention fixes the albedo/light scale,
and a turntable's left-right shading variation is separated from the albedo."""
from __future__ import annotations

import math

import numpy as np
import torch

from rh_common import sh
from rana.config import get_preset
from rana.texture import EXPOSURE_L0, TexelObservations, exposure_sh_delight


def _turntable_obs(light: np.ndarray, n_texels: int = 3000, frames: int = 12, seed: int = 0):
    """Lambertian observations of random texels on a body turning about +Z in front of a camera at -Y."""
    rng = np.random.default_rng(seed)
    n0 = rng.normal(size=(n_texels, 3))
    n0[:, 2] *= 0.5
    n0 /= np.linalg.norm(n0, axis=1, keepdims=True)
    albedo = rng.uniform(0.05, 0.9, size=(n_texels, 3))
    normals, cols, facing = [], [], []
    for f in range(frames):
        t = 2 * math.pi * f / frames
        R = np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])
        n = n0 @ R.T
        fac = -n[:, 1]  # the camera looks along +Y from -Y
        normals.append(n)
        cols.append(albedo * np.maximum(sh.shading(light, n), 0))
        facing.append(np.where(fac > 0.2, fac, -1.0))
    S = int(math.ceil(math.sqrt(n_texels)))
    sel = torch.zeros(S * S, dtype=torch.bool)
    sel[:n_texels] = True
    t = lambda a: torch.as_tensor(np.stack(a), dtype=torch.float32)  # noqa: E731
    return TexelObservations(sel, t(cols), t(facing), t(normals), S), albedo


def test_uniform_exposure_light_returns_the_observation():
    light = np.zeros((9, 3))
    light[0] = EXPOSURE_L0  # mean luminance 1: what the exposure convention makes every training light
    obs, albedo = _turntable_obs(light)
    tex, valid, L = exposure_sh_delight(obs, get_preset("tiny").texture)
    got = tex.permute(1, 2, 0).reshape(-1, 3)[: len(albedo)]
    ok = valid.reshape(-1)[: len(albedo)].numpy()
    assert ok.mean() > 0.8
    np.testing.assert_allclose(got.numpy()[ok], albedo[ok], atol=2e-3)
    assert float(L[1:].abs().max()) < 0.05


def test_left_right_light_is_separated_from_the_albedo():
    light = np.zeros((9, 3))
    light[0] = EXPOSURE_L0
    light[3] = [1.2, 0.8, 0.4]  # band 1 along x: varies along every texel's turntable path
    obs, albedo = _turntable_obs(light, seed=1)
    tex, valid, L = exposure_sh_delight(obs, get_preset("tiny").texture)
    got = tex.permute(1, 2, 0).reshape(-1, 3)[: len(albedo)].numpy()
    ok = valid.reshape(-1)[: len(albedo)].numpy()
    np.testing.assert_allclose(L[3].numpy(), light[3], atol=0.15)
    rel = np.median(np.abs(got[ok] - albedo[ok]) / albedo[ok])
    assert rel < 0.05
    # the scale is the exposure convention's, not a grey-world guess: the mean albedo is recovered
    np.testing.assert_allclose(got[ok].mean(0), albedo[ok].mean(0), rtol=0.05)
