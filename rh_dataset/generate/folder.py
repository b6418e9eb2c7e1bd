"""The dataset folder's bookkeeping: a `DatasetPlan` in; dataset.json and each subject's character.json out.

`prepare_out` refuses to mix datasets (a folder must be empty, hold this protocol made with the same settings, or
`--overwrite` be given) and records the protocol's description, seed and render settings in dataset.json before any
frame is written. `keep_character_record` writes a subject's character.json, or checks that a resumed run makes the
same character.
"""
from __future__ import annotations

import dataclasses
import json
import shutil

from rh_common import layout
from rh_common.imageio import dumps_json, read_json, write_json
from rh_dataset import __version__
from rh_dataset.generate.plan import DATASET_FORMAT, DatasetPlan, GenerateError
from rh_dataset.generate.seeding import KEY_HASH, hashed_keys

__all__ = ["prepare_out", "keep_character_record", "dataset_record", "json_roundtrip"]


def json_roundtrip(obj: dict) -> dict:
    """`obj` as it reads back from our JSON (tuples become lists), for comparing with a file."""
    return json.loads(dumps_json(obj))


def dataset_record(plan: DatasetPlan) -> dict:
    record = {
        "spec": plan.spec.to_json(),
        "spec_digest": plan.spec.digest(),
        "seed": plan.seed,
        "render": dataclasses.asdict(plan.settings),
    }
    if hashed_keys(plan.spec):
        # Split names outside the legacy table drew from other streams before; this makes an old dataset of such
        # a protocol "made with other settings" instead of silently resumed with mixed streams.
        record["key_hash"] = KEY_HASH
    return record


def prepare_out(plan: DatasetPlan) -> None:
    """Refuse to mix datasets: a folder must be empty, ours with the same settings, or `--overwrite` given."""
    out = plan.out
    if out.exists() and not out.is_dir():
        raise GenerateError(f"--out {out} is a file; pass a folder")
    ds_path = out / "dataset.json"
    key = layout.protocol_dir(plan.spec.protocol)
    record = json_roundtrip(dataset_record(plan))
    if ds_path.is_file():
        ds = read_json(ds_path)
        if ds.get("format") != DATASET_FORMAT:
            raise GenerateError(f"{ds_path} is not an rh dataset ({ds.get('format')!r}); choose another --out")
        old = ds.get("protocols", {}).get(key)
        if old is not None and old != record and not plan.overwrite:
            raise GenerateError(
                f"{out} already holds {key} made with other settings (spec {old.get('spec_digest')}, seed "
                f"{old.get('seed')}, render {old.get('render')}); rerun with the same flags to resume, choose another "
                f"--out, or pass --overwrite to replace it")
    elif out.is_dir() and any(p for p in out.iterdir() if not p.name.startswith(".")):
        raise GenerateError(f"{out} is not empty and holds no dataset.json: it is not an rh dataset; "
                            "choose an empty or new --out folder")
    else:
        ds = {"format": DATASET_FORMAT, "protocols": {}}
    if plan.overwrite and key in ds.get("protocols", {}) and ds["protocols"][key] != record:
        for d in out.glob(f"subject_*/{key}"):
            shutil.rmtree(d)
    ds["generator_version"] = __version__
    ds.setdefault("protocols", {})[key] = record
    write_json(ds_path, ds)


def keep_character_record(plan: DatasetPlan, s: int, record: dict) -> None:
    """Write the subject's character.json, or check that the one already there describes this character (a resumed
    run must not mix characters)."""
    path = plan.out / layout.subject_name(s) / layout.CHARACTER_JSON
    if path.is_file() and not plan.overwrite:
        if read_json(path) != json_roundtrip(record):
            raise GenerateError(f"{path} describes another character than this run would make; "
                                "use another --out or --overwrite")
    else:
        write_json(path, record)
