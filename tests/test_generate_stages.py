"""The generator's stages (rh_dataset.generate): seeding by a real hash, the import rule between the stages and the
backends, and the one frame function shared by the backends and the bench."""
from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np

from rh_dataset.generate import rng_for
from rh_dataset.generate.seeding import LEGACY_KEY_CODES, hashed_keys, key_word

ROOT = Path(__file__).resolve().parents[1]


def test_legacy_codes_are_what_the_old_rule_gave_so_shipped_protocols_keep_their_streams():
    assert LEGACY_KEY_CODES["train"] == 1 and LEGACY_KEY_CODES["test"] == 2
    for k in ("a", "b", "protocol_a", "protocol_b"):
        assert LEGACY_KEY_CODES[k] == sum(k.encode()) + 1000
    a = rng_for(0, "light", 3, "a", "test", 5).random(4)
    b = np.random.default_rng(np.random.SeedSequence([0, 3, 3, 1097, 2, 5])).random(4)
    np.testing.assert_array_equal(a, b)


def test_string_keys_with_the_same_byte_sum_get_different_streams():
    assert sum(b"val") == sum(b"lav")
    assert key_word("val") != key_word("lav")
    assert not np.array_equal(rng_for(0, "pose", 0, "val", 1).random(4), rng_for(0, "pose", 0, "lav", 1).random(4))
    assert key_word("val") == key_word("val") >= 1 << 63  # stable, and never a small integer key


def test_a_protocol_with_other_split_names_records_the_key_hash():
    from rh_dataset.generate.folder import dataset_record
    from rh_dataset.generate.plan import DatasetPlan
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.spec import load_protocol

    spec = load_protocol("a")
    plan = DatasetPlan(out=Path("x"), spec=spec, settings=RenderSettings())
    assert hashed_keys(spec) == [] and "key_hash" not in dataset_record(plan)
    train, test = spec.splits
    renamed = dataclasses.replace(spec, splits=(train, dataclasses.replace(test, name="val")))
    plan = dataclasses.replace(plan, spec=renamed)
    assert hashed_keys(renamed) == ["val"] and dataset_record(plan)["key_hash"] == "blake2b-64"


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def test_the_stages_never_import_a_backend_and_stay_small():
    for path in sorted((ROOT / "rh_dataset" / "generate").glob("*.py")):
        assert not any(n.startswith("rh_dataset.backends") for n in _imports(path)), path
        text = path.read_text()
        assert len(text.splitlines()) <= 400, path
        assert ast.get_docstring(ast.parse(text)), f"{path}: first lines must say what comes in and goes out"


def test_backends_and_bench_render_through_the_one_frame_function():
    assert "run_subject" in (ROOT / "rh_dataset" / "backends" / "local.py").read_text()
    assert "run_subject" in (ROOT / "rh_dataset" / "backends" / "ray_backend.py").read_text()
    bench = (ROOT / "bench" / "bench_generate.py").read_text()
    assert "render_frame_to_disk" in bench and "render_frame(" not in bench and "frame_body" not in bench
    frames = (ROOT / "rh_dataset" / "generate" / "frames.py").read_text()
    run_subject = frames[frames.index("def run_subject"):]
    assert "render_frame_to_disk(" in run_subject


def test_the_ray_crash_hook_is_not_on_the_frame_path_unless_armed(monkeypatch, tmp_path):
    from rh_dataset.backends import ray_backend
    from rh_dataset.generate import FrameTask

    seen = []
    report = ray_backend._crash_after_first_render(lambda t, s: seen.append((t, s)), str(tmp_path / "absent"))
    report(FrameTask(0, "test", 0), False)  # the file is gone: no crash, the frame is still reported
    assert seen == [(FrameTask(0, "test", 0), False)]
    source = (ROOT / "rh_dataset" / "backends" / "ray_backend.py").read_text()
    assert source.count("os.environ.get(CRASH_HOOK_ENV)") == 1


def test_a_frame_scene_pickled_and_rendered_again_is_the_frame_rh_generate_wrote(tmp_path):
    """The render stage's whole input is the FrameScene: pickled (as bench_render_stage ships it to a GPU machine)
    and rendered by `render_scene`, it gives the written frame's float layers bit for bit, and its mask within
    8-bit rounding of the written PNG."""
    import pickle

    from rh_common.imageio import read_exr, read_png
    from rh_dataset.generate import (DatasetPlan, frame_scenes, render_frame_to_disk, render_scene, resolve_plan,
                                     subject_source)
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.spec import load_protocol

    spec = load_protocol("a").with_overrides(subjects=1, resolution=(24, 24))
    plan = resolve_plan(DatasetPlan(out=tmp_path / "ds", spec=spec, seed=3,
                                    settings=RenderSettings(spp=4, aov_spp=2, max_depth=3, drape="coarse")))
    source = subject_source(plan)
    subject, split = source.subject(0), spec.split("test")
    written = render_frame_to_disk(plan, source, subject, split, 1)
    [scene] = frame_scenes(plan, source, subject, split, 1)
    assert scene.light is not None and scene.settings == plan.settings.for_split(split)
    layers = render_scene(pickle.loads(pickle.dumps(scene))).layers
    stem = written.json_path.stem
    for name in ("image", "albedo", "normal", "depth"):
        on_disk = read_exr(written.json_path.with_name(f"{stem}_{name}.exr"))
        np.testing.assert_array_equal(layers[name], on_disk.reshape(layers[name].shape))
    mask = read_png(written.json_path.with_name(f"{stem}_mask.png")).astype(np.float64)
    assert np.max(np.abs(layers["mask"] * 255.0 - mask)) <= 0.5 + 1e-6


def test_a_split_is_not_resumed_on_another_mitsuba_variant_and_a_worker_error_is_one_line(tmp_path):
    """Frames of cuda_ad_rgb and llvm_ad_rgb are not the same benchmark (docs/ARCHITECTURE.md, "Content identity"):
    a resumed split whose frames another variant rendered is refused with one line naming the variant to resume
    with, also from a worker process (whose exit, terminated by the parent, used to print a traceback)."""
    import json
    import subprocess
    import sys

    out = tmp_path / "ds"
    args = [sys.executable, "-m", "rh_dataset.cli", "--protocol", "a", "--subjects", "1", "--frames", "2",
            "--resolution", "16", "--spp", "2", "--aov-spp", "1", "--max-depth", "2", "--drape", "coarse",
            "--no-progress", "--variant", "llvm_ad_rgb", "--out", str(out)]
    subprocess.run(args, check=True, capture_output=True, cwd=ROOT)
    split = out / "subject_000" / "protocol_a" / "test"
    first = split / "frame_000000.json"
    record = json.loads(first.read_text())
    assert record["render"]["variant"] == "llvm_ad_rgb"
    record["render"]["variant"] = "cuda_ad_rgb"  # as if a GPU machine had begun the dataset
    first.write_text(json.dumps(record))
    (split / "frame_000001.json").unlink()
    for workers in ("1", "2"):
        proc = subprocess.run(args + ["--workers", workers], capture_output=True, text=True, cwd=ROOT)
        assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
        lines = [line for line in proc.stderr.splitlines() if line.startswith("rh-generate: ")]
        assert len(lines) == 1 and "rendered with Mitsuba's cuda_ad_rgb" in lines[0]
        assert "resume with --variant cuda_ad_rgb" in lines[0]
    assert not (split / "frame_000001.json").exists()
