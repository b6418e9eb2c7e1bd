"""A tiny fake Relighting Humans dataset (written by the real writer, rh_common.layout) and prediction sets in the
predictions layout of docs/ARCHITECTURE.md; used by the other test_eval_* files (and checked here)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from rh_common import layout
from rh_common.colourspace import quantize8, srgb_encode, to_display
from rh_common.imageio import read_json, sha256_file, write_exr, write_json, write_png

SIZE = 64
SUBJECTS = ("subject_000", "subject_001")
FRAMES = (0, 1)


def _sphere(size: int, cx: float, cy: float, r: float):
    v, u = np.mgrid[0:size, 0:size].astype(np.float64) + 0.5
    x, y = (u - cx) / r, -(v - cy) / r  # OpenGL camera: y up
    d2 = x * x + y * y
    inside = d2 < 1.0
    z = np.sqrt(np.clip(1.0 - d2, 0.0, 1.0))
    n = np.stack([x, y, z], axis=-1) * inside[..., None]
    cov = np.clip((1.0 - np.sqrt(d2)) * r + 0.5, 0.0, 1.0)  # anti-aliased coverage
    return n.astype(np.float32), cov


def fake_sh_camera() -> np.ndarray:
    """Order-2 SH (9, 3) whose shading `rh_common.sh.shading` is the fake's 2 (0.3 + 0.7 n_z + 0.2 n_y) exactly (a
    linear function of n is bands 0 and 1), fitted by least squares through the SH module itself."""
    from rh_common import sh

    n = sh.fibonacci_sphere(64)
    basis = np.stack([sh.shading(np.eye(9)[:, k:k + 1], n)[:, 0] for k in range(9)], axis=1)
    c, *_ = np.linalg.lstsq(basis, 2.0 * (0.3 + 0.7 * n[:, 2] + 0.2 * n[:, 1]), rcond=None)
    return np.repeat(c[:, None], 3, axis=1)


def make_dataset(root: Path, *, size: int = SIZE, subjects=SUBJECTS, frames=FRAMES, seed: int = 0,
                 empty_mask: tuple[str, int] | None = None, splits: tuple[str, ...] = ("test",),
                 with_light: bool = False) -> Path:
    """`splits`: the scored splits to write (each its own draws of albedo and noise, the test split's first and as
    before); `with_light`: frames record `light.sh_camera` = `fake_sh_camera()`, which is what rana-oracle reads."""
    rng = np.random.default_rng(seed)
    root = Path(root)
    for split, si, subject, f in ((sp, si, sub, f) for sp in splits for si, sub in enumerate(subjects)
                                  for f in frames):
        cx, cy, r = size * (0.45 + 0.1 * f), size * (0.5 + 0.05 * si), size * 0.3
        normal, cov = _sphere(size, cx, cy, r)
        if empty_mask == (subject, f):
            normal[:] = 0
            cov[:] = 0
        base = rng.uniform(0.2, 0.8, size=3)
        yy, xx = np.mgrid[0:size, 0:size] / size
        albedo = np.clip(base[None, None, :] * (0.7 + 0.3 * np.sin(6 * xx + 3 * yy + si))[..., None], 0, 1)
        albedo = (albedo * (cov > 0)[..., None]).astype(np.float32)
        shade = np.clip(0.3 + 0.7 * normal[..., 2:3] + 0.2 * normal[..., 1:2], 0, None)
        env = np.stack([0.3 + 0.2 * xx, 0.35 + 0.1 * yy, 0.5 - 0.2 * yy], axis=-1)
        image = (albedo * shade * cov[..., None] + env * (1 - cov[..., None])).astype(np.float32) * 2.0
        image += rng.normal(0, 0.01, image.shape).astype(np.float32).clip(-0.01, 0.01)
        image = np.clip(image, 0, None)
        exposure = 0.5
        # The real writer (rh_common.layout): the same frame record, layer files and manifest as rh-generate's.
        meta = {"subject": subject, "protocol": "a", "split": split, "width": size, "height": size,
                "exposure": exposure}
        if with_light:
            meta["light"] = {"kind": "sh", "sh_camera": fake_sh_camera().tolist()}
        layout.write_frame(layout.split_dir(root, subject, "a", split), f,
                           {"image": image, "mask": cov, "albedo": albedo, "normal": normal}, meta)
    write_json(root / layout.DATASET_JSON, {"protocol": "a", "subjects": list(subjects)})
    layout.write_manifest(root)
    return root


def gt_frames(ds: Path, split: str = "test"):
    for jp in layout.iter_frame_jsons(ds, "a", split):
        yield jp.parent, jp.stem, read_json(jp)


def make_predictions(ds: Path, out: Path, *, name: str = "oracle", kind: str | None = None, fmt: str = "exr",
                     layers=("image", "albedo", "normal"), noise: float = 0.0, seed: int = 1,
                     albedo_scale: float = 1.0, split: str = "test") -> Path:
    """A prediction set of one split: the ground truth itself (noise=0, fmt exr), or perturbed/quantised versions."""
    rng = np.random.default_rng(seed)
    out = Path(out)
    from rh_common.imageio import read_exr
    for folder, stem, meta in gt_frames(ds, split):
        rec = layout.FrameRecord.from_json(meta)

        def out_file(layer: str, ext: str) -> Path:
            return layout.prediction_file(out, rec.subject, rec.protocol, rec.index, layer, ext, split=split)

        out_file("image", "exr").parent.mkdir(parents=True, exist_ok=True)
        for layer in layers:
            src = folder / layout.layer_file_name(meta["index"], layer, "exr")
            if fmt == "exr" and noise == 0.0 and albedo_scale == 1.0:
                shutil.copyfile(src, out_file(layer, "exr"))
                continue
            arr = read_exr(src)
            if layer == "image":
                arr = np.clip(arr * (1 + noise * rng.normal(size=arr.shape)), 0, None).astype(np.float32)
                if fmt == "png":
                    write_png(out_file("image", "png"), quantize8(to_display(arr, meta["exposure"])))
                else:
                    write_exr(out_file("image", "exr"), arr)
            elif layer == "albedo":
                arr = np.clip(arr * albedo_scale + noise * rng.normal(size=arr.shape), 0, 1).astype(np.float32)
                if fmt == "png":
                    write_png(out_file("albedo", "png"), quantize8(srgb_encode(arr)))
                else:
                    write_exr(out_file("albedo", "exr"), arr)
            else:
                n = arr + noise * rng.normal(size=arr.shape) * np.any(arr != 0, axis=-1, keepdims=True)
                if fmt == "png":
                    write_png(out_file("normal", "png"), quantize8((np.clip(n, -1, 1) + 1) / 2))
                else:
                    write_exr(out_file("normal", "exr"), n.astype(np.float32))
    meta = {"name": name}
    if kind:
        meta["kind"] = kind
    write_json(out / "method.json", meta)
    return out


# ------------------------------------------------------------------------------------------------ self-checks
def test_fake_dataset_follows_layout(tmp_path):
    ds = make_dataset(tmp_path / "ds")
    jp = ds / "subject_000" / "protocol_a" / "test" / "frame_000000.json"
    meta = json.loads(jp.read_text())
    assert meta["width"] == SIZE and meta["height"] == SIZE and meta["exposure"] > 0
    manifest = layout.read_manifest(ds)
    assert "subject_001/protocol_a/test/frame_000001_normal.exr" in manifest
    for rel, entry in manifest.items():
        assert sha256_file(ds / rel) == entry.sha256
