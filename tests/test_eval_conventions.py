"""Named evaluation conventions (`rh-eval --convention`): `rana` is today's default bit for bit; `intrinsicavatar` and
`relightableavatar` give the numbers those methods' own evaluation code prints.

The constants below were computed by running their code on `synthetic_frame()` below, outside the repository:
taconite/IntrinsicAvatar @ d243d20c4bfa5df10e6613c986a32bd76e7d1d3e (systems/criterions.py, models/utils.py
compute_albedo_rescale_factor, the region lines of datasets/rana.py, scikit-image 0.18.1's structural_similarity,
the version it pins) and zju3dv/RelightableAvatar @ 3504fde081489c6288df800ffd1719da1230d6af
(lib/evaluators/base_evaluator.py); LPIPS as the official code in torchmetrics 1.9.0, fed rh-eval's backbone
weights. docs/EVALUATION.md ("Named conventions") describes the check. Their float32 arithmetic differs from ours
by < 3e-5 (normal degrees, acos in float32) and < 1e-6 elsewhere; the required agreement is 1e-4.
"""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from rh_eval import Convention, FrameGroundTruth, FramePrediction, score_frame
from rh_eval.cli import main
from rh_eval.conventions import CONVENTIONS, align_albedo, compute_region, named_convention
from rh_eval.metrics import lpips, ssim
from test_eval_fake import make_dataset, make_predictions

THEIRS = {  # their code's output on synthetic_frame() (see the module docstring)
    "intrinsicavatar": {
        "albedo_aligned_lpips": 0.39046967029571533, "albedo_aligned_psnr": 15.946224212646484,
        "albedo_aligned_ssim": 0.6986556526919031, "albedo_lpips": 0.4133049249649048,
        "albedo_psnr": 9.845677375793457, "albedo_ssim": 0.6548474079194685, "image_lpips": 0.683625340461731,
        "image_psnr": 10.150794982910156, "image_ssim": 0.4966476506905175, "normal_deg": 14.38815689086914,
    },
    "relightableavatar": {
        "image_lpips": 0.8680503368377686, "image_psnr": 4.096243671591817, "image_ssim": 0.09266841411590576,
    },
}


def synthetic_frame(seed: int = 20, h: int = 200, w: int = 240):
    """A seeded frame: a soft-edged ellipse of a person, the box of its 100x100 dilation inside the frame."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    r = np.sqrt(((yy - 95.0) / 55.0) ** 2 + ((xx - 130.0) / 35.0) ** 2)
    mask = np.round(np.clip((1.15 - r) / 0.3, 0.0, 1.0) * 255.0).astype(np.uint8)
    ramp = (0.2 + 0.5 * xx / w)[..., None] * np.array([1.0, 0.8, 0.6])
    gt_image = (ramp + rng.uniform(0.0, 0.3, (h, w, 3))).astype(np.float32)
    pred_image = np.clip(gt_image * 0.8 + rng.normal(0.0, 0.05, (h, w, 3)), 0.0, None).astype(np.float32)
    gt_albedo = rng.uniform(0.1, 0.9, (h, w, 3)).astype(np.float32)
    pred_albedo = np.clip(gt_albedo * np.array([0.6, 0.8, 1.1]) + rng.normal(0.0, 0.05, (h, w, 3)),
                          0.0, 1.0).astype(np.float32)
    n = rng.normal(0.0, 1.0, (h, w, 3)) + np.array([0.0, 0.0, 2.0])
    gt_normal = (n / np.linalg.norm(n, axis=-1, keepdims=True)).astype(np.float32)
    pred_normal = (gt_normal + rng.normal(0.0, 0.2, (h, w, 3))).astype(np.float32)
    pred_normal[:40] = 0.0  # rows without a predicted normal (just above the mask)
    return dict(mask=mask, exposure=1.0, gt_image=gt_image, pred_image=pred_image, gt_albedo=gt_albedo,
                pred_albedo=pred_albedo, gt_normal=gt_normal, pred_normal=pred_normal)


def _frame():
    s = synthetic_frame()
    return (FramePrediction(image=s["pred_image"], albedo=s["pred_albedo"], normal=s["pred_normal"]),
            FrameGroundTruth(mask=s["mask"], exposure=s["exposure"], image=s["gt_image"], albedo=s["gt_albedo"],
                             normal=s["gt_normal"]))


@pytest.mark.parametrize("name", ["intrinsicavatar", "relightableavatar"])
def test_agrees_with_their_code(name):
    cols = score_frame(*_frame(), named_convention(name), metrics=("lpips", "ssim", "psnr", "normal")).columns()
    for key, want in THEIRS[name].items():
        assert cols[key] == pytest.approx(want, abs=1e-4), key


def test_rana_is_the_default_bit_for_bit():
    assert named_convention("rana") == Convention()
    pred, gt = _frame()
    metrics = ("lpips", "ssim", "psnr", "normal")
    a = score_frame(pred, gt, Convention(align_albedo=True), metrics).columns()
    b = score_frame(pred, gt, named_convention("rana", align_albedo="lsq"), metrics).columns()
    assert a == b
    assert "image_aligned_psnr" not in a


def test_old_result_conventions_read_as_rana():
    old = {"albedo_space": "srgb", "align_albedo": True, "background": "white", "backbone": "alex",
           "flip_ppd": 67.02064514160156, "gt_image": "exr", "image_space": "display",
           "margin_rule": "round(50 * min(H, W) / 720)", "mask_threshold": 128, "region": "default"}
    c = Convention.from_json(old)
    assert c == named_convention("rana", align_albedo="lsq") and c.align_albedo == "lsq"
    assert Convention.from_json(c.to_json()) == c


def test_unknown_name_lists_the_known_ones():
    with pytest.raises(ValueError, match="known conventions: rana, intrinsicavatar, relightableavatar"):
        named_convention("nerfactor")


def test_every_field_of_every_bundle_is_a_field():
    fields = set(Convention.__dataclass_fields__)
    for name, bundle in CONVENTIONS.items():
        assert set(bundle) <= fields, name
        assert named_convention(name).name == name


def test_box100_is_opencvs_dilation_bounding_rect():
    # cv2.boundingRect(cv2.dilate(one pixel at (150, 150), np.ones((100, 100)))) == (101, 101, 100, 100)
    m = np.zeros((300, 300), np.uint8)
    m[150, 150] = 255
    r = compute_region(m, named_convention("intrinsicavatar"))
    assert (r.x0, r.y0, r.x1 - r.x0, r.y1 - r.y0) == (101, 101, 100, 100)
    m[:] = 0
    m[10:20, 280:290] = 255  # clipped to the frame
    r = compute_region(m, named_convention("intrinsicavatar"))
    assert (r.y0, r.y1, r.x0, r.x1) == (0, 70, 231, 300)


def test_median_and_least_squares_alignment():
    rng = np.random.default_rng(3)
    g = rng.uniform(0.1, 0.4, (20, 20, 3))
    p = g / np.array([2.0, 0.5, 1.0])
    inside = np.ones((20, 20), bool)
    for method in ("lsq", "median"):
        out, s = align_albedo(p, g, inside, method)
        assert s == pytest.approx([2.0, 0.5, 1.0], abs=1e-12)
        np.testing.assert_allclose(out, g, atol=1e-12)
    p2 = p.copy()
    p2[0, :5] = 5.0  # outliers: a median ignores them, least squares does not
    assert align_albedo(p2, g, inside, "median")[1] == pytest.approx([2.0, 0.5, 1.0], abs=1e-12)
    assert align_albedo(p2, g, inside, "lsq")[1][1] != pytest.approx(0.5, abs=1e-3)
    assert align_albedo(np.zeros_like(g), g, inside, "median")[1] == [1.0, 1.0, 1.0]


def test_lpips_without_normalize_takes_values_as_minus_one_to_one():
    rng = np.random.default_rng(5)
    a, b = rng.uniform(0, 1, (2, 64, 64, 3))
    # normalize=False feeds x as is; normalize=True feeds 2 y - 1: the same network input for y = (x + 1) / 2
    assert lpips(a, b, normalize=False) == pytest.approx(lpips((a + 1) / 2, (b + 1) / 2), abs=1e-6)
    assert lpips(a, b, normalize=False) != pytest.approx(lpips(a, b), abs=1e-3)


def test_ssim_uniform_window_and_range():
    rng = np.random.default_rng(6)
    a = rng.uniform(0, 1, (32, 32, 3))
    b = np.clip(a + rng.normal(0, 0.1, a.shape), 0, 1)
    assert ssim(a, a, window="uniform7") == 1.0
    s1, s2 = ssim(a, b, window="uniform7"), ssim(a, b, data_range=2.0, window="uniform7")
    assert s2 > s1  # the larger range's constants weigh the same error less
    with pytest.raises(ValueError, match="window"):
        ssim(a, b, window="box")


def test_normal_mask_rule():
    pred, gt = _frame()
    n = pred.normal.copy()
    n[:, :130] = 0.0  # the left half of the person has no predicted normal
    pred = FramePrediction(image=None, normal=n)
    inside = gt.mask >= 128
    left = inside[:, :130].sum()
    right_err = score_frame(FramePrediction(image=None, normal=pred.normal[:, 130:].copy()),
                            FrameGroundTruth(mask=gt.mask[:, 130:].copy(), exposure=1.0,
                                             normal=gt.normal[:, 130:].copy()), Convention(), ("normal",)).normal_deg
    full = score_frame(pred, gt, Convention(), ("normal",)).normal_deg
    both = score_frame(pred, gt, Convention(normal_mask="gt_and_pred"), ("normal",)).normal_deg
    assert both == pytest.approx(right_err, abs=1e-12)  # the pixels without a prediction are left out
    assert full == pytest.approx((90.0 * left + right_err * (inside.sum() - left)) / inside.sum(), abs=1e-9)


# --------------------------------------------------------------------------------------------- the CLI
@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("ds") / "data")


@pytest.fixture(scope="module")
def noisy(ds, tmp_path_factory):
    return make_predictions(ds, tmp_path_factory.mktemp("pred") / "noisy", name="noisy", noise=0.05,
                            albedo_scale=0.8)


def _run(args, capsys):
    code = main([str(a) for a in args] + ["--no-progress", "--metrics", "psnr,ssim,normal"])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_records_the_convention_and_flags_override_it(ds, noisy, tmp_path, capsys):
    out = tmp_path / "r.json"
    code, _, err = _run([noisy, "--dataset", ds, "--out", out, "--convention", "relightableavatar",
                         "--align-albedo", "lsq"], capsys)
    assert code == 0, err
    r = json.loads(out.read_text())
    want = named_convention("relightableavatar", align_albedo="lsq")
    assert r["convention"] == want.to_json() and r["convention"]["name"] == "relightableavatar"
    assert r["convention"]["align_image"] == "median" and "image_aligned_psnr" in r["overall"]
    assert "albedo_aligned_psnr" in r["overall"]
    code, _, err = _run([noisy, "--dataset", ds, "--out", out, "--align-image", "--align-albedo", "median"], capsys)
    assert code == 0, err
    c = json.loads(out.read_text())["convention"]
    assert (c["name"], c["align_image"], c["align_albedo"]) == ("rana", "median", "median")


def test_cli_unknown_convention(ds, noisy, tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main([str(noisy), "--dataset", str(ds), "--out", str(tmp_path / "r.json"), "--convention", "nerf"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'nerf'" in err and "rana" in err and "intrinsicavatar" in err


def test_cli_convention_needing_a_missing_layer(ds, tmp_path, capsys):
    pred = make_predictions(ds, tmp_path / "noalbedo", name="no albedo", layers=("image", "normal"))
    code, _, err = _run([pred, "--dataset", ds, "--out", tmp_path / "r.json", "--convention", "intrinsicavatar"],
                        capsys)
    assert code == 2 and not (tmp_path / "r.json").exists()
    assert "needs the albedo layer" in err and "aligned to the ground truth" in err


# --------------------------------------------------------------------------------------------- the leaderboard
def _result(path, name, conv: dict, lpips_value: float):
    r = {"format": "rh-eval/1", "method": {"name": name}, "kind": "method", "complete": True, "missing": [],
         "dataset": {"manifest_sha256": "ab" * 32, "protocol": "protocol_a", "n_frames": 2}, "n_frames_evaluated": 2,
         "convention": conv, "overall": {"image_lpips": {"mean": lpips_value}, "image_psnr": {"mean": 20.0}},
         "per_subject": {}}
    path.write_text(json.dumps(r))
    return path


def test_leaderboard_one_table_per_convention_and_side_by_side(tmp_path):
    from rh_eval.leaderboard import build_html, build_markdown, load_results
    old = {k: v for k, v in Convention().to_json().items() if k not in set(Convention.__dataclass_fields__)
           - {"region", "background", "albedo_space", "align_albedo", "backbone", "flip_ppd", "image_space",
              "gt_image", "margin_rule", "mask_threshold"}}
    old["align_albedo"] = False  # a result file written before the named conventions
    files = [_result(tmp_path / "a.json", "A", old, 0.1),
             _result(tmp_path / "b.json", "B", Convention().to_json(), 0.2),
             _result(tmp_path / "a_ia.json", "A", named_convention("intrinsicavatar").to_json(), 0.3)]
    entries, problems = load_results(files)
    assert problems == []
    md = build_markdown(entries)
    assert "## Convention `rana`" in md and "## Convention `intrinsicavatar`" in md and "## Side by side" in md
    side = md.split("## Side by side")[1]
    row = next(line for line in side.splitlines() if line.startswith("| A |"))
    assert "0.1000" in row and "0.3000" in row  # A under both conventions, one row
    assert "(a.json)" not in md  # the same name under two conventions is not a name clash
    ra = json.loads(files[1].read_text())
    ra["convention"] = named_convention("relightableavatar").to_json()
    ra["overall"]["image_aligned_psnr"] = {"mean": 21.5}
    (tmp_path / "b_ra.json").write_text(json.dumps(ra))
    entries, _ = load_results(files + [tmp_path / "b_ra.json"])
    md = build_markdown(entries)
    assert "### Relit images after per-channel median scale" in md.split("## Convention `relightableavatar`")[1]
    assert "21.50" in md
    page = build_html(entries)
    assert 'id="relightableavatar-image-aligned"' in page
    assert 'id="rana-methods"' in page and 'id="intrinsicavatar-methods"' in page and 'id="side-by-side"' in page
    # within one named convention a different setting is still refused
    files.append(_result(tmp_path / "c.json", "C", named_convention("rana", region="full").to_json(), 0.4))
    with pytest.raises(ValueError, match="region"):
        load_results(files)


def test_a_crop_too_small_for_the_backbone_is_one_line(tmp_path):
    from rh_eval.scoring import CropTooSmallError
    s = synthetic_frame(h=120, w=120)
    m = np.zeros((120, 120), np.uint8)
    m[50:70, 50:70] = 255  # 20 px: enough for VGG (16), not for AlexNet (31); relightableavatar never grows crops
    pred = FramePrediction(image=s["pred_image"], albedo=s["pred_albedo"])
    gt = FrameGroundTruth(mask=m, exposure=1.0, image=s["gt_image"], albedo=s["gt_albedo"])
    with pytest.raises(CropTooSmallError, match="albedo region is 20x20 px, smaller than the 31 px LPIPS-alex"):
        score_frame(pred, gt, named_convention("relightableavatar"), ("lpips",))
    assert score_frame(pred, gt, named_convention("intrinsicavatar"), ("lpips",)).albedo.lpips > 0
    assert score_frame(pred, gt, named_convention("relightableavatar"), ("psnr",)).albedo.psnr > 0


def test_cli_half_size_predictions_under_area_resampling(ds, noisy, tmp_path, capsys):
    """relightableavatar reads predictions at half the ground truth's size (their cfg.ratio 0.5); rana refuses."""
    from rh_common.imageio import read_exr, read_png, write_exr, write_png
    from rh_eval.resample import shrink_area

    half = tmp_path / "half"
    shutil.copytree(noisy, half)
    for f in sorted(half.rglob("*")):
        if f.suffix == ".png":
            a = read_png(f)
            write_png(f, np.clip(np.round(shrink_area(a, (a.shape[0] // 2, a.shape[1] // 2))), 0, 255).astype(np.uint8))
        elif f.suffix == ".exr":
            a = read_exr(f)
            write_exr(f, shrink_area(a, (a.shape[0] // 2, a.shape[1] // 2)).astype(np.float32))
    code, _, err = _run([half, "--dataset", ds, "--out", tmp_path / "ra.json", "--convention", "relightableavatar"],
                        capsys)
    assert code == 0, err
    r = json.loads((tmp_path / "ra.json").read_text())
    code, _, err = _run([noisy, "--dataset", ds, "--out", tmp_path / "full.json", "--convention", "relightableavatar"],
                        capsys)
    full = json.loads((tmp_path / "full.json").read_text())
    assert r["convention"]["resampling"] == "area" and r["n_frames_evaluated"] == full["n_frames_evaluated"]
    # the same predictions, shrunk as the ground truth is: about the same score (the noise averages down a little)
    assert abs(r["overall"]["image_psnr"]["mean"] - full["overall"]["image_psnr"]["mean"]) < 1.0
    code, _, err = _run([half, "--dataset", ds, "--out", tmp_path / "rana.json"], capsys)
    assert code != 0 and "differs from the ground truth's" in err
