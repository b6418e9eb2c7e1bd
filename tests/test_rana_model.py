"""RANA's model pieces without the body model: SH shading of known normal maps, gradient flow, one step."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch

from rh_common import sh
from rana.config import get_preset
from rana.model import AMBIENT_L0, RanaModel, shade
from rana.nets import UNet, gaussian_blur, positional_encoding, srgb_encode_t
from rana.train import build_training_state, cosine_lr, training_step

K1 = math.sqrt(3.0 / (4.0 * math.pi))


def _normal_map(H: int = 8, W: int = 8, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    n = torch.randn(1, 3, H, W, generator=g)
    return torch.nn.functional.normalize(n, dim=1)


def test_uniform_light_gives_unit_shading():
    light = torch.zeros(1, 9, 3)
    light[0, 0] = AMBIENT_L0  # constant radiance 1: E = pi, S = E/pi = 1
    s = shade(light, _normal_map())
    assert torch.allclose(s, torch.ones_like(s), atol=1e-6)


def test_band1_light_matches_analytic_cosine():
    # L_2 = c (the z-linear term) gives E(n) = (2pi/3) c K1 n_z, S = E/pi; clamped at 0 where negative.
    c = 1.7
    light = torch.zeros(1, 9, 3)
    light[0, 2] = c
    n = _normal_map(seed=1)
    s = shade(light, n)
    expect = ((2.0 / 3.0) * c * K1 * n[:, 2:3]).clamp_min(0).expand_as(s)
    assert torch.allclose(s, expect, atol=1e-6)
    assert (s >= 0).all()


def test_shade_agrees_with_rh_common_numpy():
    rng = np.random.default_rng(3)
    coeffs = rng.normal(size=(9, 3))
    n = _normal_map(seed=2)
    s = shade(torch.as_tensor(coeffs, dtype=torch.float32)[None], n)[0].permute(1, 2, 0).numpy()
    ref = np.maximum(sh.shading(coeffs, n[0].permute(1, 2, 0).numpy().astype(np.float64)), 0)
    assert np.allclose(s, ref, atol=1e-5)


def _tiny_cfg(**loss):
    cfg = get_preset("tiny")
    return dataclasses.replace(cfg, loss=dataclasses.replace(cfg.loss, **loss))


def _fake_batch(cfg, B: int = 1, seed: int = 0) -> dict:
    g = torch.Generator().manual_seed(seed)
    H = W = cfg.model.resolution
    yy, xx = torch.meshgrid(torch.linspace(-1, 1, H), torch.linspace(-1, 1, W), indexing="ij")
    m = ((xx / 0.4) ** 2 + (yy / 0.8) ** 2 < 1).float()[None, None].repeat(B, 1, 1, 1)
    uv = torch.stack([(xx + 1) / 2, (1 - yy) / 2])[None].repeat(B, 1, 1, 1) * m
    n = torch.nn.functional.normalize(torch.stack([xx, -yy, torch.ones_like(xx)])[None].repeat(B, 1, 1, 1), dim=1) * m
    alb = torch.rand(B, 3, 1, 1, generator=g) * m
    img = 0.3 + 0.5 * torch.rand(B, 3, H, W, generator=g) * m
    return {"uv": uv, "smpl_mask": m, "coarse_normal": n, "coarse_albedo": alb, "image": img, "mask": m,
            "face_centre": torch.tensor([[W / 2, H / 4]] * B)}


@pytest.mark.parametrize("frozen_a", [True, False])
def test_gradients_reach_z_e_and_albedo_net_not_frozen_normal_net(frozen_a):
    cfg = _tiny_cfg(lambda_vgg=0.0)
    st = build_training_state(cfg, use_vgg=False)
    model = st.model
    model.G_A.requires_grad_(not frozen_a)
    batch = _fake_batch(cfg)
    L = model.get_loss_dict(model.get_outputs(batch), batch, cfg.loss, None, st.disc)
    L["total"].backward()
    assert model.Z.grad is not None and model.Z.grad.abs().sum() > 0
    assert model.E.grad is not None and model.E.grad.abs().sum() > 0
    assert all(p.grad is None for p in model.G_N.parameters())  # G_N frozen (finetune_normal=False)
    ga = [p.grad for p in model.G_A.parameters()]
    if frozen_a:
        assert all(g is None for g in ga)
    else:
        assert any(g is not None and g.abs().sum() > 0 for g in ga)


def test_untrained_avatar_renders_the_coarse_stage():
    # From scratch (no pretraining) G_A and G_N output corrections of the coarse albedo, normal and SMPL+D mask: at
    # step 0 the avatar is SMPL+D. (Before: albedo sigmoid(~0) = 0.5, normals of a random U-Net (cos 0.15 with the
    # coarse ones) that stayed random since G_N is frozen, mask ~0.4 everywhere -- 6 dB below SMPL+D after training.)
    cfg = _tiny_cfg()
    model = build_training_state(cfg, use_vgg=False).model
    batch = _fake_batch(cfg, B=2)
    with torch.no_grad():
        out = model.get_outputs(batch)
    m = batch["smpl_mask"].bool()
    ca = batch["coarse_albedo"].clamp(1e-3, 1 - 1e-3)
    assert (out["albedo"] - ca).abs().masked_select(m.expand_as(ca)).max() < 0.01
    cos = (out["normal"] * batch["coarse_normal"]).sum(1, keepdim=True)
    assert cos.masked_select(m).min() > 0.999
    assert out["mask"].masked_select(m).min() > 0.95 and out["mask"].masked_select(~m).max() < 0.05


def test_configs_written_before_residual_heads_read_as_direct_outputs():
    from rana.config_json import config_from_json, config_to_json

    d = config_to_json(get_preset("tiny"))
    assert config_from_json(d).model.residual_coarse is True
    del d["schema"], d["model"]["residual_coarse"]  # as written then: unversioned
    assert config_from_json(d).model.residual_coarse is False


def test_configs_written_before_the_delit_texturenet_input_read_as_the_paper_s():
    from rana.config_json import config_from_json, config_to_json

    d = config_to_json(get_preset("cpu"))
    assert config_from_json(d).texture.texturenet_input == "exposure-sh"
    assert config_from_json(d).pretrain.light_source == "dataset"
    del d["schema"], d["texture"]["texturenet_input"], d["pretrain"]["light_source"]  # as written then
    assert config_from_json(d).texture.texturenet_input == "shaded"
    assert config_from_json(d).pretrain.light_source == "random-sh"
    assert get_preset("paper").texture.texturenet_input == "shaded"


def test_untrained_delit_texturenet_returns_its_input_and_the_shaded_one_does_not():
    from rana.texture import fill_holes
    from rana.texturenet import TextureNet

    cfg = get_preset("tiny").texture
    torch.manual_seed(0)
    tex = torch.rand(3, 32, 32) * 0.9
    valid = torch.rand(32, 32) > 0.3
    out = TextureNet(cfg, input_mode="exposure-sh").apply(tex, valid)
    assert torch.allclose(out, fill_holes(tex, valid), atol=1e-5)  # sRGB encode then decode: identity
    assert not torch.allclose(TextureNet(cfg, input_mode="shaded").apply(tex, valid), out, atol=1e-2)
    with pytest.raises(ValueError, match="texturenet_input"):
        TextureNet(cfg, input_mode="median")


def test_srgb_decode_inverts_encode():
    from rana.nets import srgb_decode_t

    v = torch.linspace(0, 1, 1001)
    assert torch.allclose(srgb_decode_t(srgb_encode_t(v)), v, atol=1e-6)


def test_pretraining_shades_world_lights_with_camera_normals_as_a_rotated_light_would():
    """prepare_character shades camera-axes normals n_cam with a world-axes light as S(L_world; n_cam R); that must
    equal the shading of n_cam under the light rotated into camera axes, S(rotate(L_world, R); n_cam)."""
    from scipy.spatial.transform import Rotation

    R = torch.as_tensor(Rotation.from_euler("xyz", [20, -75, 10], degrees=True).as_matrix(), dtype=torch.float32)
    rng = np.random.default_rng(3)
    L = torch.as_tensor(rng.normal(size=(9, 3)), dtype=torch.float32)
    n = torch.nn.functional.normalize(torch.randn(500, 3), dim=-1)
    a = sh.shading(L, n @ R)
    b = sh.shading(torch.as_tensor(sh.rotate(L, R), dtype=torch.float32), n)
    assert torch.allclose(a, b, atol=1e-4)


def test_light_init_sets_e():
    cfg = _tiny_cfg()
    light = torch.randn(9, 3)
    model = build_training_state(cfg, use_vgg=False, light_init=light).model
    assert torch.equal(model.E.data[0], light)


def test_one_personalization_step_decreases_the_loss():
    cfg = _tiny_cfg(lambda_gan=0.0)  # the GAN term is a moving target; the rest must go down
    st = build_training_state(cfg, use_vgg=True)
    batch = _fake_batch(cfg)

    def total():
        with torch.no_grad():
            return float(st.model.get_loss_dict(st.model.get_outputs(batch), batch, cfg.loss, st.vgg, None)["total"])

    before = total()
    training_step(st, batch, cfg, step=cfg.personalize.freeze_albedo_steps)  # phase 2: Z, E and G_A move
    after = total()
    assert after < before


def test_unet_keeps_odd_sizes_and_pe_is_zero_off_body():
    net = UNet(5, 2, base=4, depth=2)
    assert net(torch.zeros(1, 5, 13, 21)).shape == (1, 2, 13, 21)
    uv = torch.rand(1, 2, 6, 6)
    m = torch.zeros(1, 1, 6, 6)
    assert positional_encoding(uv, 3, m).abs().sum() == 0
    assert positional_encoding(uv, 3).shape[1] == 2 + 4 * 3


def test_blur_preserves_constants_and_srgb_matches_colourspace():
    x = torch.full((1, 3, 20, 20), 0.4)
    assert torch.allclose(gaussian_blur(x, 7), x, atol=1e-6)
    from rh_common.colourspace import srgb_encode

    v = np.linspace(0, 1, 101, dtype=np.float32)
    assert np.allclose(srgb_encode_t(torch.from_numpy(v)).numpy(), srgb_encode(v), atol=1e-5)


def test_cosine_schedule_endpoints():
    assert cosine_lr(10, 10, 110, 1e-4, 1e-5) == pytest.approx(1e-4)
    assert cosine_lr(110, 10, 110, 1e-4, 1e-5) == pytest.approx(1e-5)


def test_cached_vgg_targets_give_the_same_loss_and_gradients():
    """The training frames' VGG features are computed once (rana.train._cache_vgg_targets); the loss and the
    gradients must equal those of computing them every step."""
    from rana.train import _cache_vgg_targets

    cfg = _tiny_cfg(lambda_gan=0.0)
    st = build_training_state(cfg, use_vgg=True)
    batch = _fake_batch(cfg, B=2)
    items = [{"image": batch["image"][i]} for i in range(2)]  # per-frame buffers, as personalize keeps them
    _cache_vgg_targets(st, items)
    cached = {**batch, **{k: torch.stack([it[k] for it in items]) for k in items[0] if k.startswith("vgg_target_")}}
    assert len([k for k in cached if k.startswith("vgg_target_")]) == 4

    def loss_and_grad(b):
        st.model.zero_grad(set_to_none=True)
        L = st.model.get_loss_dict(st.model.get_outputs(b), b, cfg.loss, st.vgg, None)
        L["total"].backward()
        return float(L["vgg"].detach()), st.model.Z.grad.clone()

    v0, g0 = loss_and_grad(batch)
    v1, g1 = loss_and_grad(cached)
    assert v0 > 0
    assert v1 == pytest.approx(v0, rel=1e-6)
    torch.testing.assert_close(g1, g0, rtol=1e-5, atol=1e-8)


def test_finish_layers_threshold_keeps_the_person_whole_and_blends_only_coverage():
    from rana.predict import finish_layers

    H = W = 4
    person = torch.full((H, W, 3), 0.8)
    bg = torch.full((H, W, 3), 0.1)
    albedo = torch.full((H, W, 3), 0.5)
    normal = torch.zeros(H, W, 3)
    normal[..., 2] = 1.0
    mask = torch.zeros(H, W)
    mask[:, :2] = 0.7  # the person, with a network that is only 70% sure
    mask[:, 3] = 0.3
    thr = finish_layers(person, albedo, normal, mask, H, W, bg, "threshold")
    prob = finish_layers(person, albedo, normal, mask, H, W, bg, "probability")
    cov = finish_layers(person, albedo, normal, mask, H, W, bg, "coverage")
    np.testing.assert_allclose(thr["image"][:, :2], 0.8, atol=1e-6)  # the person's own colour, no background in it
    np.testing.assert_allclose(thr["image"][:, 2:], 0.1, atol=1e-6)  # p <= 0.5: background only
    np.testing.assert_allclose(prob["image"][:, :2], 0.7 * 0.8 + 0.3 * 0.1, atol=1e-6)
    np.testing.assert_allclose(prob["image"][:, 3], 0.3 * 0.8 + 0.7 * 0.1, atol=1e-6)
    np.testing.assert_array_equal(cov["image"], prob["image"])
    for out in (thr, prob):  # albedo and normal make the same decision whatever the image does
        np.testing.assert_array_equal(out["albedo"][:, 2:], 0.0)
        np.testing.assert_allclose(out["albedo"][:, :2], 0.5, atol=1e-6)
    with pytest.raises(ValueError, match="mask_composite"):
        finish_layers(person, albedo, normal, mask, H, W, bg, "soft")
