"""rh_common.layout, the one owner of the dataset layout: the frame record reproduces the bytes of a written frame,
rana's synthetic datasets are real datasets (rh-verify accepts them), the manifest and the completeness check catch
tampering, and the names are the ones docs/ARCHITECTURE.md documents."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from rh_common import layout
from rh_common.imageio import dumps_json, read_json, sha256_file, write_json

DOCS = Path(__file__).resolve().parent.parent / "docs" / "ARCHITECTURE.md"


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    from rana.synthetic import make_dataset

    return make_dataset(tmp_path_factory.mktemp("syn") / "ds", subjects=1, train_frames=2, test_frames=1,
                        resolution=24, texture_size=32)


def _layers(rng, h=6, w=8):
    n = rng.normal(size=(h, w, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    mask = np.clip(rng.random((h, w)) * 1.5 - 0.25, 0, 1).astype(np.float32)
    n[mask == 0] = 0
    return {"image": rng.random((h, w, 3)).astype(np.float32), "mask": mask,
            "albedo": rng.random((h, w, 3)).astype(np.float32), "normal": n.astype(np.float32),
            "depth": rng.random((h, w)).astype(np.float32)}


def _meta(h=6, w=8, **kw):
    return {"subject": "subject_000", "protocol": "a", "split": "test", "width": w, "height": h, "exposure": 0.5,
            **kw}


def test_frame_record_round_trip_is_byte_exact_on_written_frames(synthetic):
    paths = list(layout.iter_frame_jsons(synthetic))
    assert len(paths) == 3
    for p in paths:
        rec = layout.read_frame_record(p)
        assert rec.to_json() == read_json(p)  # same keys, same values
        assert dumps_json(rec.to_json()).encode() == p.read_bytes()  # and written back, the same bytes
        assert rec.subject == "subject_000" and rec.protocol == "a" and rec.index == layout.frame_index_of(p.name)
        # Every file the record lists is there with the recorded sha256, and belongs to a documented layer.
        for name, entry in rec.files.items():
            assert sha256_file(p.parent / name) == entry.sha256
            assert name in layout.layer_files(rec.index, entry.layer)
        # The body pose reads back into the arrays the frame was posed with.
        pose = rec.pose()
        np.testing.assert_array_equal(pose.root_transform, np.array(rec.body["pose"]["root_transform"]))


def test_the_generator_writer_round_trips_numpy_metadata_exactly(tmp_path, rng):
    from rh_dataset.writer import write_frame

    sh_world = rng.normal(size=(9, 3))
    meta = _meta(light={"sh_world": sh_world, "kind": "sh"}, render={"spp": 4, "denoised": False},
                 camera={"K": np.eye(3) * 1.5}, versions={"rh": "test"})
    p = write_frame(tmp_path, 7, _layers(rng), meta)
    rec = layout.read_frame_record(p)
    assert dumps_json(rec.to_json()).encode() == p.read_bytes()
    np.testing.assert_array_equal(np.array(rec.light["sh_world"]), sh_world)  # float64 survives JSON exactly
    assert rec.render["fireflies"] >= 0 and rec.format == layout.FRAME_FORMAT and rec.index == 7
    out = layout.write_frame_record(tmp_path / "copy.json", rec)
    assert out.read_bytes() == p.read_bytes()


def test_a_synthetic_rana_dataset_passes_rh_verify(synthetic):
    from rh_dataset.verify import verify

    rep = verify(synthetic, progress=False)
    assert rep.problems == [] and rep.frames_checked == 3
    assert rep.files_checked == len(layout.read_manifest(synthetic))
    for p in layout.iter_frame_jsons(synthetic):
        rec = layout.read_frame_record(p)
        assert layout.frame_is_complete(p.parent, rec.index, rec.layers)


def test_rh_verify_rejects_the_old_flat_manifest_and_an_invalid_frame_record(tmp_path, rng):
    from rh_dataset.verify import verify

    root = tmp_path / "ds"
    layout.write_frame(layout.split_dir(root, 0, "a", "test"), 0, _layers(rng), _meta())
    layout.write_manifest(root)
    flat = {k: {"sha256": e.sha256, "bytes": e.bytes} for k, e in layout.read_manifest(root).items()}
    write_json(root / layout.MANIFEST_JSON, flat)  # the flat variant rana.synthetic used to write
    assert any("unreadable manifest" in pr.what for pr in verify(root, progress=False).problems)
    jp = layout.frame_json_path(layout.split_dir(root, 0, "a", "test"), 0)
    data = read_json(jp)
    data["layers"] = data.pop("files")  # the variant rana.synthetic used to write
    write_json(jp, data)
    layout.write_manifest(root)
    probs = verify(root, progress=False).problems
    assert len(probs) == 1 and "not a frame record" in probs[0].what and "layers" in probs[0].what


def test_manifest_round_trip_and_checks(tmp_path):
    root = tmp_path / "ds"
    write_json(root / "dataset.json", {"format": "rh-dataset/1"})
    (root / "subject_000").mkdir()
    (root / "subject_000" / "a.bin").write_bytes(b"0123456789")
    (root / "subject_000" / ".x.tmp").write_bytes(b"t")  # a temporary is never listed
    layout.write_manifest(root)
    raw = read_json(root / layout.MANIFEST_JSON)
    assert raw["format"] == layout.MANIFEST_FORMAT and sorted(raw["files"]) == ["dataset.json", "subject_000/a.bin"]
    listed = layout.read_manifest(root)
    assert listed["subject_000/a.bin"] == layout.ManifestEntry(sha256_file(root / "subject_000/a.bin"), 10)
    assert all(layout.check_entry(root, rel, e) is None for rel, e in listed.items())
    assert layout.unlisted_files(root, listed) == ["subject_000/.x.tmp"]
    # Rewriting an unchanged folder gives the same bytes (the manifest is deterministic).
    before = (root / layout.MANIFEST_JSON).read_bytes()
    (root / "subject_000" / ".x.tmp").unlink()
    layout.write_manifest(root)
    assert (root / layout.MANIFEST_JSON).read_bytes() == before
    (root / "subject_000" / "a.bin").write_bytes(b"01234")
    assert layout.check_entry(root, "subject_000/a.bin", listed["subject_000/a.bin"]).startswith("truncated")
    (root / "subject_000" / "a.bin").write_bytes(b"0123456780")
    assert layout.check_entry(root, "subject_000/a.bin", listed["subject_000/a.bin"]).startswith("altered")
    (root / "subject_000" / "a.bin").unlink()
    assert layout.check_entry(root, "subject_000/a.bin", listed["subject_000/a.bin"]) == "missing"


def test_frame_is_complete_rejects_a_tampered_file_or_record(tmp_path, rng):
    L = _layers(rng)
    jp = layout.write_frame(tmp_path, 2, L, _meta())
    assert layout.frame_is_complete(tmp_path, 2, L)
    assert not layout.frame_is_complete(tmp_path, 2, ["image", "mask"])  # another layer set
    png = tmp_path / "frame_000002_normal.png"
    good = png.read_bytes()
    png.write_bytes(good[:-1] + bytes([good[-1] ^ 1]))
    assert not layout.frame_is_complete(tmp_path, 2, L)
    png.write_bytes(good)
    assert layout.frame_is_complete(tmp_path, 2, L)
    data = read_json(jp)
    data["files"]["frame_000002_depth.exr"]["sha256"] = "0" * 64
    write_json(jp, data)
    assert not layout.frame_is_complete(tmp_path, 2, L)
    jp.write_text("{not json")
    assert not layout.frame_is_complete(tmp_path, 2, L)


def test_write_frame_checks_the_record_before_writing_anything(tmp_path, rng):
    with pytest.raises(ValueError, match="unknown keys"):
        layout.write_frame(tmp_path, 0, _layers(rng), _meta(lights={}))
    with pytest.raises(ValueError, match="missing keys"):
        layout.write_frame(tmp_path, 0, _layers(rng), {"exposure": 1.0})
    with pytest.raises(ValueError, match="frame record says 9x6"):
        layout.write_frame(tmp_path, 0, _layers(rng), _meta(w=9))
    assert list(tmp_path.iterdir()) == []


def test_paths_agree_with_the_documented_layout(tmp_path):
    doc = DOCS.read_text()
    block = doc[doc.index("## Dataset layout"):doc.index("### Frame JSON")]
    documented = set(re.findall(r"\bframe_000000[\w.]*", block))
    written = {n for layer in layout.LAYERS for n in layout.layer_files(0, layer)} | {layout.frame_json_name(0)}
    # Every file the writer makes is documented, and the tree shows no file it does not make.
    assert {n for n in written if n.endswith((".json", ".exr")) or n.endswith("mask.png")} <= documented
    assert documented <= written | {"frame_000000_image.png"}
    for name in (layout.DATASET_JSON, layout.MANIFEST_JSON, layout.CHARACTER_JSON, layout.CONTACT_SHEET):
        assert name in block
    assert '{"format": "rh-manifest/2", "files"' in block and "rh_common.layout" in doc
    assert layout.split_dir(tmp_path, 0, "a", "test") == tmp_path / "subject_000" / "protocol_a" / "test"
    assert layout.split_dir(tmp_path, "subject_012", "protocol_b", "train") == \
        tmp_path / "subject_012" / "protocol_b" / "train"
    assert layout.subject_index(layout.subject_name(12)) == 12 and layout.protocol_of("protocol_b") == "b"
    for bad in ("A", "a/b", "", "protocol_"):
        with pytest.raises(ValueError):
            layout.protocol_dir(bad)
    pred = doc[doc.index("## Predictions layout"):]
    assert layout.METHOD_JSON in pred and "<subject>/<protocol>/<split>/" in pred and "rh-eval --split" in pred
    assert layout.prediction_dir(tmp_path, "subject_000", "a") == layout.split_dir(tmp_path, 0, "a", "test")
    assert layout.prediction_dir(tmp_path, "subject_000", "a", "olat") == layout.split_dir(tmp_path, 0, "a", "olat")
    for layer in layout.PREDICTION_LAYERS:
        assert f"frame_000000_{layer}.exr | .png" in pred
        assert layout.PREDICTION_FILE_RE.match(layout.prediction_file(tmp_path, "subject_000", "a", 0, layer).name)
    assert layout.prediction_file(tmp_path, "subject_001", "a", 3, "albedo", "png") == \
        tmp_path / "subject_001" / "protocol_a" / "test" / "frame_000003_albedo.png"


def test_the_body_pose_reader_agrees_with_the_generator_pose():
    from rh_dataset.poses import ANNY_BONE_LABELS, BodyPose
    from rh_dataset.poses.pose import rotation_about_z

    bones = {"upperarm01.L": rotation_about_z(30.0), "root": np.eye(4)}
    bones["root"][:3, 3] = (0.1, -0.2, 0.9)
    bp = BodyPose(bones=bones, root_transform=rotation_about_z(75.0), turntable_deg=75.0, label="walk")
    pose = layout.read_body_pose(json.loads(json.dumps(bp.to_json())))
    np.testing.assert_array_equal(pose.deltas(ANNY_BONE_LABELS), bp.deltas())
    np.testing.assert_array_equal(pose.root_transform, bp.root_transform)
    assert (pose.turntable_deg, pose.label) == (75.0, "walk")
    with pytest.raises(ValueError, match="unknown keys"):
        layout.read_body_pose({**bp.to_json(), "scale": 1.0})
    with pytest.raises(ValueError, match="unknown bone"):
        layout.read_body_pose({"bones": {"tail": np.eye(4).tolist()}}).deltas(ANNY_BONE_LABELS)
    with pytest.raises(ValueError, match="proper rotation"):
        layout.read_body_pose({"bones": {"root": np.diag([2.0, 2.0, 2.0, 1.0]).tolist()}})
