"""Turn npm's `@pmndrs/assets` HDRIs into a `--hdri-folder`: decode, measure the ringing, repair or reject.

In: the package (`npm pack @pmndrs/assets@1.7.0` gives pmndrs-assets-1.7.0.tgz, or its extracted folder); with
`--originals`, the folder of the package's own sources (`src/hdri/*.hdr` of the pmndrs/assets git repository,
1024x512 RGBE) to measure each repaired map against. Out, in `--out`: `pmndrs_<name>.exr` (float32, 512x256) for
each accepted map, `pmndrs_hdris.json` (per map: licence, origin, sha256 of the module, ringing figures, the
decision and its reason), and with `--with-bundled` the 8 bundled Blender maps as well, so that one
`rh-generate --hdri-folder <out>` draws from all of them. Prints one line per map.

Decisions: a map whose embedded EXR does not decode, holds NaN/Inf or negative light beyond ringing is rejected
(the reason is `rh_dataset.lights.ringing`'s one-line error); a map whose repaired SH or power differs from its
source by more than MAX_SOURCE_ERROR is rejected (measured with `--originals`, otherwise read from the committed
tools/pmndrs_hdris.json for modules with the same sha256); every other map is repaired
(`ringing.repair_ringing`) and written.

  python tools/pmndrs_hdris.py --package pmndrs-assets-1.7.0.tgz --out data/hdri --with-bundled
  python tools/pmndrs_hdris.py --package pkg/ --out /tmp/h --originals assets/src/hdri --record tools/pmndrs_hdris.json
"""
from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

from rh_common import sh
from rh_common.colourspace import luminance
from rh_common.imageio import atomic_path, write_exr, write_json
from rh_dataset.lights import HdriError, bundled_hdris, downsample_equirect, load_hdri
from rh_dataset.lights.ringing import check_ringing, decode_exr_module, repair_ringing

PACKAGE = "@pmndrs/assets@1.7.0"
RECORD = Path(__file__).with_name("pmndrs_hdris.json")
MAX_SOURCE_ERROR = 0.02  # repaired vs source: max |ΔSH| / max |SH|, and |Δpower| / power
LICENCE = "CC0-1.0 (the package's licence field and LICENSE; Poly Haven publishes its HDRIs as CC0)"
# The package's first ten maps are drei's `Environment` presets ("fix: add all standard drei hdris"); drei names
# the Poly Haven map of each. The package does not say which Poly Haven maps the later eight are.
POLYHAVEN_IDS = {"apartment": "lebombo", "city": "potsdamer_platz", "dawn": "kiara_1_dawn", "forest": "forest_slope",
                 "lobby": "st_fagans_interior", "night": "dikhololo_night", "park": "rooitou_park",
                 "studio": "studio_small_03", "sunset": "venice_sunset", "warehouse": "empty_warehouse_01"}


def _modules(package: Path, tmp: Path) -> list[Path]:
    if package.is_file():
        try:
            with tarfile.open(package) as tar:
                members = [m for m in tar.getmembers() if m.isfile() and m.name.startswith("package/hdri/")
                           and m.name.endswith(".exr.js")]
                tar.extractall(tmp, members=members, filter="data")
        except tarfile.TarError as exc:
            raise SystemExit(f"{package}: not a readable npm tarball ({exc}); run `npm pack {PACKAGE}`") from None
        package = tmp / "package"
    found = sorted((package / "hdri").glob("*.exr.js"))
    if not found:
        raise SystemExit(f"{package}: no hdri/*.exr.js modules; pass the tarball of `npm pack {PACKAGE}`")
    return found


def _power(m: np.ndarray) -> float:
    H, W = m.shape[:2]
    return float(np.sum(luminance(m).astype(np.float64) * sh.pixel_solid_angles(H, W)))


def _against_source(repaired: np.ndarray, source: Path) -> dict:
    ref, _ = load_hdri(source)
    f = ref.shape[0] // repaired.shape[0]
    ref = downsample_equirect(ref, f) if f > 1 else ref.astype(np.float64)
    c_ref, c_rep = sh.project_equirect(ref), sh.project_equirect(repaired)
    return {"source_size": [int(ref.shape[1] * f), int(ref.shape[0] * f)], "source_max": float(load_hdri(source)[0].max()),
            "sh_error": float(np.abs(c_rep - c_ref).max() / np.abs(c_ref).max()),
            "power_error": _power(repaired) / _power(ref) - 1.0}


def convert(module: Path, shown: str, out: Path, originals: Path | None, record: dict) -> dict:
    """Decide one map (`shown`: how messages name it); write it when accepted. Returns its record entry."""
    name = module.name[: -len(".exr.js")]
    digest = hashlib.sha256(module.read_bytes()).hexdigest()
    entry = {"name": name, "file": f"pmndrs_{name}.exr", "package": PACKAGE, "module": f"hdri/{module.name}",
             "sha256": digest, "licence": LICENCE,
             "origin": (f"Poly Haven '{POLYHAVEN_IDS[name]}' (1k)" if name in POLYHAVEN_IDS else
                        "a Poly Haven map (the package README); which one the package does not say")
             + "; the package converted it with ImageMagick: -compress DWAB -resize 512x512 (to 512x256)"}
    try:
        img = decode_exr_module(module)
        stats = check_ringing(img, module)
    except HdriError as exc:
        return {**entry, "decision": "rejected", "reason": str(exc).replace(str(module), shown)}
    entry["ringing"] = stats.as_dict()
    repaired = repair_ringing(img)
    if originals is not None:
        entry["against_source"] = _against_source(repaired, originals / f"{name}.hdr")
    elif record.get(name, {}).get("sha256") == digest and "against_source" in record[name]:
        entry["against_source"] = record[name]["against_source"]
    src = entry.get("against_source")
    if src and (src["sh_error"] > MAX_SOURCE_ERROR or abs(src["power_error"]) > MAX_SOURCE_ERROR):
        return {**entry, "decision": "rejected",
                "reason": (f"{shown}: after repair {100 * src['sh_error']:.1f}% SH error and "
                           f"{100 * src['power_error']:+.1f}% power against the package's source map"
                           + (f" (its brightest pixel, {src['source_max']:.0f}, is beyond half-float range, "
                              f"65504: the package's half EXR lost that light)" if src["source_max"] > 65504 else
                              ""))}
    write_exr(out / entry["file"], repaired)
    how = f"repaired at {stats.repair_block}x{stats.repair_block} blocks" if stats.repair_block else "no ringing"
    return {**entry, "decision": "repaired" if stats.repair_block else "accepted",
            "reason": how + ("" if src else "; not compared with a source map")}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--package", type=Path, required=True, help="pmndrs-assets-1.7.0.tgz or its extracted folder")
    ap.add_argument("--out", type=Path, required=True, help="folder to write the maps and pmndrs_hdris.json into")
    ap.add_argument("--originals", type=Path, help="the package's source .hdr maps, to measure against")
    ap.add_argument("--with-bundled", action="store_true", help="also copy the 8 bundled Blender maps into --out")
    ap.add_argument("--record", type=Path, help="also write the report here (tools/pmndrs_hdris.json)")
    args = ap.parse_args(argv)
    record = {e["name"]: e for e in json.loads(RECORD.read_text())["maps"]} if RECORD.is_file() else {}
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        entries = [convert(m, f"{args.package.name}:hdri/{m.name}", args.out, args.originals, record)
                   for m in _modules(args.package, Path(tmp))]
    for e in entries:
        r = e.get("ringing", {})
        src = e.get("against_source")
        print(f"{e['name']:10s} {e['decision']:9s} min {r.get('minimum', float('nan')):9.1f} "
              f"clamp would add {100 * r.get('clamp_power_gain', float('nan')):6.2f}% "
              f"{'SH vs source %5.2f%%' % (100 * src['sh_error']) if src else '':20s} {e['reason']}")
    if args.with_bundled:
        for path in bundled_hdris().values():
            with atomic_path(args.out / path.name) as tmp_file:
                shutil.copyfile(path, tmp_file)
    report = {"package": PACKAGE, "max_source_error": MAX_SOURCE_ERROR, "maps": entries}
    write_json(args.out / "pmndrs_hdris.json", report)
    if args.record:
        write_json(args.record, report)
    kept = sum(e["decision"] != "rejected" for e in entries)
    print(f"pmndrs_hdris: {kept} of {len(entries)} maps written to {args.out}"
          f"{' with the bundled maps' if args.with_bundled else ''}; use rh-generate --hdri-folder {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
