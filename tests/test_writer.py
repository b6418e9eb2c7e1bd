"""Frame writer and verifier: files as documented, atomic writes, completeness by checksum, corruption found."""
from __future__ import annotations

import os

import numpy as np
import pytest

from rh_common.imageio import read_exr, read_json, read_png, write_json
from rh_dataset.verify import verify
from rh_common.layout import frame_is_complete, layer_files, write_manifest
from rh_dataset.writer import write_frame


def layers(rng, h=8, w=10):
    n = rng.normal(size=(h, w, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    mask = np.clip(rng.random((h, w)) * 1.5 - 0.25, 0, 1).astype(np.float32)
    n[mask == 0] = 0
    return {
        "image": (rng.random((h, w, 3)) * 1e5).astype(np.float32),  # beyond half-float range on purpose
        "mask": mask,
        "albedo": rng.random((h, w, 3)).astype(np.float32),
        "normal": n.astype(np.float32),
        "depth": (rng.random((h, w)) * 3).astype(np.float32),
    }


def frame_meta(L, exposure=1.0):
    """The frame metadata rh-generate's writer needs (a FrameRecord but its index and file list)."""
    h, w = L["image"].shape[:2]
    return {"subject": "subject_000", "protocol": "a", "split": "test", "width": w, "height": h,
            "exposure": exposure}


def test_frame_round_trip_keeps_float32_hdr_and_documented_encodings(tmp_path, rng):
    L = layers(rng)
    write_frame(tmp_path, 3, L, frame_meta(L, 1e-5))
    assert np.array_equal(read_exr(tmp_path / "frame_000003_image.exr")[..., :3], L["image"])
    assert np.array_equal(read_exr(tmp_path / "frame_000003_depth.exr")[..., 0], L["depth"])
    m = read_png(tmp_path / "frame_000003_mask.png")
    assert m.dtype == np.uint8 and np.abs(m / 255.0 - L["mask"]).max() <= 0.5 / 255 + 1e-6
    npng = read_png(tmp_path / "frame_000003_normal.png").astype(np.float64)
    decoded = 2 * npng / 255 - 1
    inside = np.any(L["normal"] != 0, axis=-1)
    assert np.abs(decoded[inside] - L["normal"][inside]).max() <= 1 / 255 + 1e-6
    assert np.all(npng[~inside] == 0)
    meta = read_json(tmp_path / "frame_000003.json")
    assert set(meta["files"]) == {f for l in L for f in layer_files(3, l)}
    assert frame_is_complete(tmp_path, 3, L.keys())


def test_non_finite_layers_are_refused_and_leave_no_json(tmp_path, rng):
    L = layers(rng)
    L["image"][0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN/Inf"):
        write_frame(tmp_path, 0, L, frame_meta(L))
    assert not (tmp_path / "frame_000000.json").exists()
    assert not frame_is_complete(tmp_path, 0, L.keys())


def test_layers_written_in_threads_are_the_bytes_written_one_after_another(tmp_path, rng):
    L = layers(rng, 64, 48)
    for workers in (1, None, 3):
        write_frame(tmp_path / str(workers), 0, L, frame_meta(L, 0.5), workers=workers)
    names = sorted(p.name for p in (tmp_path / "1").iterdir())
    assert len(names) == 9 and not any(n.endswith(".tmp") for n in names)
    for other in ("None", "3"):
        assert sorted(p.name for p in (tmp_path / other).iterdir()) == names
        for n in names:
            assert (tmp_path / other / n).read_bytes() == (tmp_path / "1" / n).read_bytes(), n


def test_a_layer_failing_in_a_thread_leaves_no_json_and_no_temporary(tmp_path, rng):
    L = layers(rng)
    L["depth"] = L["depth"].copy()
    L["depth"][0, 0] = np.nan  # the last layer fails while the others are being written
    with pytest.raises(ValueError, match="NaN"):
        write_frame(tmp_path, 0, L, frame_meta(L), workers=5)
    assert not (tmp_path / "frame_000000.json").exists()
    assert not list(tmp_path.glob("*.tmp")) and not list(tmp_path.glob(".*.tmp"))


def test_a_damaged_or_partial_frame_is_not_complete(tmp_path, rng):
    L = layers(rng)
    write_frame(tmp_path, 0, L, frame_meta(L))
    assert frame_is_complete(tmp_path, 0, L.keys())
    assert not frame_is_complete(tmp_path, 0, ["image", "mask"])  # layer set differs from the request
    p = tmp_path / "frame_000000_albedo.exr"
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    assert not frame_is_complete(tmp_path, 0, L.keys())


def test_verify_finds_missing_truncated_altered_extra_and_nonfinite_files(tmp_path, rng):
    root = tmp_path / "ds"
    split = root / "subject_000" / "protocol_a" / "test"
    for i in range(3):
        L = layers(rng)
        write_frame(split, i, L, frame_meta(L))
    write_json(root / "dataset.json", {"format": "rh-dataset/1"})
    write_manifest(root)
    assert verify(root).problems == []
    (split / "frame_000000_mask.png").unlink()
    p = split / "frame_000001_image.exr"
    p.write_bytes(p.read_bytes()[:100])
    q = split / "frame_000002_depth.exr"
    b = bytearray(q.read_bytes())
    b[-1] ^= 0xFF
    q.write_bytes(bytes(b))
    (split / ".frame_000002_image.exr.abc.tmp").write_bytes(b"x")
    found = {(pr.path.split("/")[-1], pr.what.split(":")[0].split(" ")[0]) for pr in verify(root).problems}
    assert ("frame_000000_mask.png", "missing") in found
    assert ("frame_000001_image.exr", "truncated") in found
    assert ("frame_000002_depth.exr", "altered") in found
    assert (".frame_000002_image.exr.abc.tmp", "leftover") in found


def test_verify_reports_nan_inside_a_listed_exr(tmp_path, rng):
    from rh_common.imageio import write_exr

    root = tmp_path / "ds"
    a = np.ones((4, 4, 3), np.float32)
    a[1, 1] = np.inf
    write_exr(root / "x.exr", a)
    write_manifest(root)
    probs = verify(root).problems
    assert len(probs) == 1 and "NaN/Inf" in probs[0].what


def test_atomic_write_leaves_no_temporary_on_failure(tmp_path):
    from rh_common.imageio import atomic_path

    with pytest.raises(RuntimeError):
        with atomic_path(tmp_path / "a.bin") as tmp:
            tmp.write_bytes(b"half")
            raise RuntimeError("killed")
    assert os.listdir(tmp_path) == []


def test_a_16_bit_png_is_refused_not_truncated(tmp_path):
    from PIL import Image

    from rh_common.imageio import ImageFileError

    p = tmp_path / "deep.png"
    Image.fromarray(np.full((4, 4), 40000, np.uint16)).save(p)
    with pytest.raises(ImageFileError, match="16-bit"):
        read_png(p)
    # 16-bit RGB is the case Pillow decodes to 8 bits silently: build one by hand.
    import struct
    import zlib

    raw = b"".join(b"\x00" + b"\x12\x34" * 3 * 2 for _ in range(2))
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 2, 16, 2, 0, 0, 0)) + \
        chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
    q = tmp_path / "deep_rgb.png"
    q.write_bytes(png)
    with pytest.raises(ImageFileError, match="16-bit"):
        read_png(q)
