"""The content identity (rh_common.identity, recorded in the manifest) and `rh-verify --against`: the identity
follows decoded values and cameras/poses/lights, never file bytes or package versions; the comparison tells
identical, within tolerance and different datasets apart, with the documented thresholds."""
from __future__ import annotations

import json
import math
import shutil

import numpy as np
import OpenEXR
import pytest
from PIL import Image

from rh_common import identity, layout
from rh_common.imageio import read_exr, read_json, write_json
from rh_dataset.verify import main as verify_main, verify
from test_layout import _layers


def _meta(split="test", **kw):
    return {"subject": "subject_000", "protocol": "a", "split": split, "width": 8, "height": 6, "exposure": 0.5,
            "camera": {"fov_y_deg": 40.0}, "light": {"kind": "sh", "sh_world": [[0.1, 0.2, 0.3]]},
            "render": {"spp": 4}, "versions": {"rh": "test", "numpy": "2.4.6"}, **kw}


def _dataset(root, frames, split_layers=("test",)):
    """`frames`: {(split, index): layers}; writes frames and the manifest."""
    for (split, i), layers in frames.items():
        h, w = layers["image"].shape[:2]
        layout.write_frame(layout.split_dir(root, 0, "a", split), i, layers, _meta(split, width=w, height=h))
    layout.write_manifest(root)
    return root


@pytest.fixture
def frames(rng):
    return {("test", 0): _layers(rng), ("test", 1): _layers(rng), ("train", 0): _layers(rng)}


def test_array_bytes_follow_values_not_memory_layout():
    a = np.arange(12, dtype=np.float32).reshape(3, 4)
    assert identity.array_bytes(np.asfortranarray(a)) == identity.array_bytes(a)
    assert identity.array_bytes(a.astype(">f4")) == identity.array_bytes(a)  # big-endian storage, same values
    assert identity.array_bytes(a.reshape(4, 3)) != identity.array_bytes(a)
    assert identity.array_bytes(a.astype(np.float64)) != identity.array_bytes(a)
    assert identity.canonical_json({"b": 0.1, "a": [1, 2]}) == b'{"a":[1,2],"b":0.1}'


def test_frame_digest_ignores_encoders_versions_and_render_but_not_content(tmp_path, rng):
    jp = layout.write_frame(tmp_path, 0, _layers(rng), _meta())
    d0 = identity.frame_digest(jp)
    # Another EXR compression and another PNG compression level: other bytes, the same decoded values.
    exr, png = tmp_path / "frame_000000_image.exr", tmp_path / "frame_000000_mask.png"
    before = exr.read_bytes(), png.read_bytes()
    img = read_exr(exr)
    with OpenEXR.File({"compression": OpenEXR.PIZ_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {c: np.ascontiguousarray(img[..., k]) for k, c in enumerate("RGB")}) as f:
        f.write(str(exr))
    Image.open(png).save(png, compress_level=0)
    assert (exr.read_bytes(), png.read_bytes()) != before
    rec = read_json(jp)
    rec["versions"] = {"rh": "other", "numpy": "9.9"}
    rec["render"] = {"spp": 4096}
    write_json(jp, rec)
    assert identity.frame_digest(jp) == d0
    # What a method sees or is scored on changes it: a light coefficient, one pixel.
    rec["light"]["sh_world"][0][0] = 0.1000000001
    write_json(jp, rec)
    assert identity.frame_digest(jp) != d0
    rec["light"]["sh_world"][0][0] = 0.1
    write_json(jp, rec)
    img[0, 0, 0] = np.nextafter(img[0, 0, 0], np.float32(2))
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {c: np.ascontiguousarray(img[..., k]) for k, c in enumerate("RGB")}) as f:
        f.write(str(exr))
    assert identity.frame_digest(jp) != d0


def test_manifest_records_the_identity_per_split_and_reads_format_1(tmp_path, frames):
    root = _dataset(tmp_path / "ds", frames)
    raw = read_json(root / layout.MANIFEST_JSON)
    ident = layout.read_identity(root)
    assert raw["format"] == "rh-manifest/2" and ident == raw["identity"]
    assert {k: v["frames"] for k, v in ident["splits"].items()} == {"protocol_a/test": 2, "protocol_a/train": 1}
    assert ident["splits"]["protocol_a/test"]["digest"] == identity.combine(
        {f"subject_000/frame_00000{i}": identity.frame_digest(layout.frame_json_path(
            layout.split_dir(root, 0, "a", "test"), i)) for i in (0, 1)})
    assert ident["dataset"] == identity.combine({k: v["digest"] for k, v in ident["splits"].items()})
    assert verify(root, progress=False).problems == []
    # Rewritten by itself: the same manifest bytes.
    before = (root / layout.MANIFEST_JSON).read_bytes()
    layout.write_manifest(root)
    assert (root / layout.MANIFEST_JSON).read_bytes() == before
    # A format-1 manifest still reads; it has no identity, which rh-verify reports with the fix.
    write_json(root / layout.MANIFEST_JSON, {"format": "rh-manifest/1", "files": raw["files"]})
    assert layout.read_manifest(root).keys() == raw["files"].keys() and layout.read_identity(root) is None
    probs = verify(root, progress=False).problems
    assert len(probs) == 1 and "format-1 manifest" in probs[0].what and "rerun rh-generate" in probs[0].what
    # A tampered identity is caught.
    raw["identity"]["frames"]["subject_000/protocol_a/test/frame_000001.json"] = "0" * 64
    write_json(root / layout.MANIFEST_JSON, raw)
    probs = verify(root, progress=False).problems
    assert [p.path for p in probs] == ["subject_000/protocol_a/test/frame_000001.json"]


def _perturbed(frames, layer, delta, key=("test", 1)):
    out = {k: dict(v) for k, v in frames.items()}
    out[key][layer] = (out[key][layer] + delta).astype(np.float32)
    return out


def test_against_tells_identical_within_tolerance_and_different(tmp_path, frames, capsys):
    a = _dataset(tmp_path / "a", frames)
    same = tmp_path / "same"
    shutil.copytree(a, same)
    cmp = layout.compare_datasets(a, same, layout.read_identity(a), layout.read_identity(same))
    assert cmp.identical and cmp.within_tolerance and cmp.frames_differing == []
    # A float rounding-level difference (what another LLVM vector width gives, ~140 dB): within tolerance.
    tiny = _dataset(tmp_path / "tiny", _perturbed(frames, "image", 1e-6))
    cmp = layout.compare_datasets(a, tiny, layout.read_identity(a), layout.read_identity(tiny))
    assert not cmp.identical and cmp.within_tolerance
    assert cmp.frames_differing == ["subject_000/protocol_a/test/frame_000001.json"]
    d = cmp.layers["protocol_a/test/image.exr"]
    assert d.frames == 2 and d.frames_differing == 1 and 1e-6 * 0.9 < d.max_abs < 1e-6 * 1.1
    peak = float(np.abs(frames[("test", 1)]["image"]).max())
    expect = 10 * np.log10(peak ** 2 / np.mean((frames[("test", 1)]["image"].astype(np.float64) + 1e-6
                                                  - frames[("test", 1)]["image"]).astype(np.float32) ** 2))
    assert abs(d.min_psnr_db - expect) < 0.5 and d.min_psnr_db > layout.TOLERANCE["min_psnr_db"]
    # A difference a method could see (1e-3, ~60 dB): not the same benchmark.
    big = _dataset(tmp_path / "big", _perturbed(frames, "albedo", 1e-3))
    cmp = layout.compare_datasets(a, big)
    assert not cmp.within_tolerance and not cmp.layers["protocol_a/test/albedo.exr"].within()
    # Exit status and the record rh-leaderboard reads.
    rec = tmp_path / "cmp.json"
    assert verify_main([str(a), "--against", str(tiny), "--record", str(rec), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "protocol_a/test/image.exr" in out and "differs: subject_000/protocol_a/test/frame_000001.json" in out
    assert "the same benchmark within rounding" in out
    r = layout.read_comparison(rec)
    assert r["within_tolerance"] and not r["identical"]
    assert r["a"]["identity"]["splits"] == layout.read_identity(a)["splits"]
    assert r["b"]["identity"]["dataset"] == layout.read_identity(tiny)["dataset"]
    assert verify_main([str(a), "--against", str(big), "--no-progress"]) == 1
    assert "NOT the same benchmark" in capsys.readouterr().out


def test_against_reports_missing_frames_other_metadata_and_8bit_levels(tmp_path, frames, capsys):
    a = _dataset(tmp_path / "a", frames)
    fewer = _dataset(tmp_path / "fewer", {k: v for k, v in frames.items() if k != ("test", 1)})
    cmp = layout.compare_datasets(a, fewer)
    assert cmp.mismatches == [f"subject_000/protocol_a/test/frame_000001.json: only in {a}"]
    assert not cmp.within_tolerance
    # Another light in the JSON: refused even though every pixel is equal.
    other = tmp_path / "other"
    shutil.copytree(a, other)
    jp = other / "subject_000/protocol_a/test/frame_000000.json"
    rec = read_json(jp)
    rec["light"]["sh_world"][0][1] = 0.25
    write_json(jp, rec)
    cmp = layout.compare_datasets(a, other)
    assert any("'light' differs" in m for m in cmp.mismatches) and not cmp.within_tolerance
    # The 8-bit mask: one level is a rounding flip (within), two are not.
    for levels, ok in ((1, True), (2, False)):
        m = tmp_path / f"mask{levels}"
        shutil.copytree(a, m)
        png = m / "subject_000/protocol_a/test/frame_000000_mask.png"
        arr = np.asarray(Image.open(png)).copy()
        arr[0, 0] = arr[0, 0] + levels if arr[0, 0] < 200 else arr[0, 0] - levels
        Image.fromarray(arr).save(png)
        d = layout.compare_datasets(a, m).layers["protocol_a/test/mask.png"]
        assert d.is_8bit and d.max_abs == levels and d.within() is ok
    # A comparison record is checked for its format.
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "rh-eval/1"}))
    with pytest.raises(ValueError, match="rh-verify A --against B"):
        layout.read_comparison(bad)


def test_cameras_poses_and_lights_that_differ_in_their_last_bits_are_within_rounding(tmp_path, frames, capsys):
    """Another CPU's BLAS kernel changes the last bits of the float64 pose matrices and SH coefficients in the frame
    JSON (measured: the same pixels, OpenBLAS's Zen against its SkylakeX kernel, up to 1e-14 relative, the light's
    scale 8e-9): the same benchmark within rounding, not identical. A change of a millionth and more is another
    light; so are another key, a string or an integer."""
    a = _dataset(tmp_path / "a", frames)

    def variant(name, change):
        out = tmp_path / name
        shutil.copytree(a, out)
        jp = out / "subject_000/protocol_a/test/frame_000000.json"
        rec = read_json(jp)
        change(rec)
        write_json(jp, rec)
        layout.write_manifest(out)
        return layout.compare_datasets(a, out, layout.read_identity(a), layout.read_identity(out))

    def bits(rec):
        rec["light"]["sh_world"][0][1] = float(np.nextafter(0.2, 1.0))
        rec["camera"]["fov_y_deg"] = 40.0 * (1 + 8e-9)

    cmp = variant("bits", bits)
    assert not cmp.identical and cmp.within_rounding and cmp.mismatches == [] and cmp.frames_differing == []
    assert cmp.metadata_frames_differing == 1 and 0.005 < cmp.metadata_max < 0.02
    assert cmp.to_json()["metadata"]["frames_differing_within_rounding"] == 1
    for name, change in (("light", lambda r: r["light"]["sh_world"][0].__setitem__(1, 0.2 * (1 + 2e-6))),
                         ("kind", lambda r: r["light"].__setitem__("kind", "envmap")),
                         ("size", lambda r: r.__setitem__("width", 9)),
                         ("key", lambda r: r["camera"].__setitem__("fov_x_deg", 50.0))):
        cmp = variant(name, change)
        assert not cmp.within("noise") and any("differs (another camera, pose or light)" in m for m in cmp.mismatches)
    assert layout.metadata_difference({"a": [1.0, 2]}, {"a": [1.0, 2.0]}) == math.inf  # an int is not a float
    assert layout.metadata_difference(1e-12, -1e-12) == pytest.approx(2e-3)  # the absolute floor near zero
    assert verify_main([str(a), "--against", str(tmp_path / "bits"), "--no-progress"]) == 0
    assert "1 frame(s) differ within rounding" in capsys.readouterr().out


def test_a_few_pixels_that_took_another_path_are_within_sampling_noise_not_rounding(tmp_path, rng, capsys):
    """What another LLVM vector width does with strand hair: a handful of pixels' paths diverge (any difference),
    the rest agree to rounding. Up to NOISE_TOLERANCE's share of a file's pixels: the same benchmark within sampling
    noise; more, or every pixel by a little: not."""
    frames = {("test", 0): _layers(rng, 20, 20), ("test", 1): _layers(rng, 20, 20)}
    a = _dataset(tmp_path / "a", frames)

    def resampled(name, count):
        out = {k: dict(v) for k, v in frames.items()}
        img = out[("test", 1)]["image"].copy()
        ys, xs = np.unravel_index(rng.choice(400, size=count, replace=False), (20, 20))
        img[ys, xs] = rng.random((count, 3), dtype=np.float32)  # another sample: any value
        out[("test", 1)]["image"] = img + np.float32(1e-7)  # and rounding everywhere
        return _dataset(tmp_path / name, out)

    few = resampled("few", 6)     # 1.5 % of the pixels
    cmp = layout.compare_datasets(a, few, layout.read_identity(a), layout.read_identity(few))
    d = cmp.layers["protocol_a/test/image.exr"]
    assert d.pixels == 800 and d.pixels_diverged == 6 and d.max_diverged_fraction == 6 / 400
    assert d.min_psnr_db < TOLERANCE_DB and not d.within("rounding") and d.within("noise")
    assert cmp.within_tolerance and not cmp.within_rounding and "within sampling noise" in cmp.verdict
    strict = layout.compare_datasets(a, few, tier="rounding")
    assert not strict.within_tolerance and "it is within sampling noise" in strict.verdict
    rec = tmp_path / "noise.json"
    assert verify_main([str(a), "--against", str(few), "--record", str(rec), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "1.50 %" in out and "within sampling noise" in out
    r = layout.read_comparison(rec)
    assert r["within_tolerance"] and not r["within_rounding"] and r["tolerance"]["tier"] == "noise"
    assert verify_main([str(a), "--against", str(few), "--tolerance", "rounding", "--no-progress"]) == 1
    capsys.readouterr()
    many = resampled("many", 12)  # 3 %
    assert not layout.compare_datasets(a, many).within_tolerance
    with pytest.raises(ValueError, match="rounding, noise"):
        layout.compare_datasets(a, few, tier="loose")


TOLERANCE_DB = layout.TOLERANCE["min_psnr_db"]
