"""`rh-export`: write a finished dataset (one protocol) in another layout."""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections import defaultdict
from pathlib import Path

from rh_common import layout
from rh_common.cli_help import HelpFormatter
from rh_common.imageio import read_json, write_json
from rh_common.interrupt import add_debug_flag, checkpoint, command, on_stop

from .common import ExportError, check_dataset, iter_frames

__all__ = ["FORMATS", "export_dataset", "main"]

FORMATS = ("relighting-humans", "zju-mocap", "usd")
EXPORT_FORMAT = "rh-export/1"
FIT_CACHES = ("smpl_fit", "smplx_fit")  # export/smpl.py CACHE_DIRS


def _prepare_out(out: Path, fmt: str, dataset: Path, protocol: str, smpl: dict | None = None,
                 smplx: dict | None = None) -> None:
    rec_path = out / "export.json"
    if rec_path.is_file():
        rec = read_json(rec_path)
        if rec.get("format") != fmt:
            raise ExportError(f"{out} holds a {rec.get('format')!r} export; choose another --out for {fmt!r}")
        if fmt == "relighting-humans" and rec.get("protocol") not in (None, protocol):
            # The published layout has one test/ for every protocol: two protocols in one folder would mix.
            raise ExportError(f"{out} holds protocol {rec.get('protocol')!r}; the Relighting Humans layout shares "
                              f"test/ between protocols, so export protocol {protocol!r} to another --out")
    # A fit cache copied from another export of the same dataset may be there already (export/smpl.py reuses it).
    elif out.is_dir() and any(p for p in out.iterdir() if not p.name.startswith(".") and p.name not in FIT_CACHES):
        raise ExportError(f"{out} is not empty and holds no export.json; choose an empty or new --out folder")
    manifest = layout.read_manifest(dataset)
    from rh_dataset import __version__

    write_json(rec_path, {
        "export": EXPORT_FORMAT, "format": fmt, "protocol": protocol, "source": str(dataset.resolve()),
        "source_dataset_json": read_json(dataset / layout.DATASET_JSON),
        "source_files": len(manifest), "generator_version": __version__,
        **({"smpl": smpl} if smpl else {}), **({"smplx": smplx} if smplx else {}),
    })


def _model_record(model) -> dict | None:
    return None if model is None else {"model_file": Path(model.path).name, "model_sha256": model.sha256,
                                       "gender": model.gender, "standin": bool(model.extra.get("rh_standin"))}


def export_dataset(dataset: str | Path, protocol: str, fmt: str, out: str | Path, *, subjects: int | None = None,
                   splits: tuple[str, ...] | None = None, usd_ext: str = "usdc", zju_vertices: bool = True,
                   progress: bool = False, smpl_model: str | Path | None = None, smpl_gender: str = "neutral",
                   smpl_settings=None, smplx_model: str | Path | None = None) -> dict:
    """Export every frame of `protocol` (optionally the first `subjects`, some `splits`); returns counts.
    `smpl_model`: the folder of the user's SMPL files; every frame then carries SMPL fitted to its anny body
    (export/smpl.py), one betas per subject fitted over all its frames of the protocol. `smplx_model`: the same
    with the user's SMPL-X files (`skeleton_0.smplx_data`, ZJU-MoCap `params_smplx/`; not in USD stages)."""
    dataset, out = Path(dataset), Path(out)
    if fmt not in FORMATS:
        raise ExportError(f"unknown --format {fmt!r}; choose one of {', '.join(FORMATS)}")
    ds = check_dataset(dataset, protocol)
    model = None
    if smpl_model is not None:
        from .smpl import load_model

        model = load_model(smpl_model, smpl_gender)  # before anything is written: a bad file stops here
    model_x = None
    if smplx_model is not None:
        if fmt == "usd":
            raise ExportError("--smplx-model: the USD stage carries the SMPL mesh only; export SMPL-X with --format "
                              "relighting-humans or zju-mocap")
        from .smpl import load_model

        model_x = load_model(smplx_model, smpl_gender, kind="smplx")
    out.mkdir(parents=True, exist_ok=True)
    _prepare_out(out, fmt, dataset, protocol, _model_record(model), _model_record(model_x))
    hdri_folder = ds["protocols"][layout.protocol_dir(protocol)]["spec"].get("hdri_folder")
    frames = list(iter_frames(dataset, protocol, splits, subjects))
    if not frames:
        raise ExportError(f"{dataset}: no frames of protocol {protocol!r} to export")
    if fmt != "zju-mocap" and any(f.view is not None for f in frames):
        raise ExportError(f"{dataset}: protocol {protocol} is multi-view (cameras cam_NN per split): --format {fmt} "
                          f"has one camera per sequence; export it with --format zju-mocap")
    # A multi-view frame's body is the same from every camera: fitted and written once, for its first camera.
    first_view: dict[tuple[str, str, int], object] = {}
    for f in frames:
        first_view.setdefault((f.subject, f.split, f.index), f)
    fits = fits_x = None
    if model is not None or model_x is not None:
        from .smpl import SmplFits

        # Every split of the exported subjects: the betas must not depend on --split.
        every, fitted = [], set()
        for f in iter_frames(dataset, protocol, None, subjects):  # one camera per multi-view frame
            if (f.subject, f.split, f.index) not in fitted:
                fitted.add((f.subject, f.split, f.index))
                every.append(f)
        log = lambda line: print(f"rh-export: {line}", flush=True)  # noqa: E731
        fits = None if model is None else SmplFits(model, out, every, smpl_settings, log=log)
        fits_x = None if model_x is None else SmplFits(model_x, out, every, smpl_settings, log=log)
    from tqdm import tqdm

    t0 = time.perf_counter()
    files = 0
    sequences: dict[tuple[str, str], list] = defaultdict(list)
    baked: dict[str, dict] = {}  # relighting-humans: each distinct light is baked once per export
    limits: list[str] = []
    for f in tqdm(frames, disable=not progress, unit="frame", desc=f"export {fmt}"):
        if fmt == "relighting-humans":
            from .relighting_humans import export_frame

            files += len(export_frame(f, out, layout.protocol_dir(protocol)[len("protocol_"):],
                                      hdri_folder=hdri_folder, baked=baked,
                                      smpl=None if fits is None else fits.rh_block(f),
                                      smplx=None if fits_x is None else fits_x.rh_block(f)))
        elif fmt == "zju-mocap":
            from .zju_mocap import export_frame

            body = first_view[(f.subject, f.split, f.index)]
            files += len(export_frame(f, out, protocol, vertices=zju_vertices, body=body is f,
                                      smpl=None if fits is None or body is not f else fits.zju_params(f),
                                      smplx=None if fits_x is None or body is not f else fits_x.zju_params(f)))
            sequences[(f.subject, f.split)].append(f)
        else:
            from .usd import export_frame

            files += len(export_frame(f, out, protocol, dataset=dataset, hdri_folder=hdri_folder, ext=usd_ext,
                                      smpl=None if fits is None else fits.usd_mesh(f)))
    if fmt == "zju-mocap":
        from .zju_mocap import CAPTURE, camera_name, capture_splits, export_frame, sequence_dir, write_annots

        together = capture_splits(ds["protocols"][layout.protocol_dir(protocol)]["spec"])
        if together and {f.split for f in frames} >= set(together):
            # train + novel_view as one sequence of every camera (NeuralBody's training_view picks the train ones)
            for f in (f for f in frames if f.split in together):
                g = dataclasses.replace(f, split=CAPTURE)
                body = first_view[(f.subject, together[0], f.index)]
                files += len(export_frame(g, out, protocol, vertices=zju_vertices, body=body is f,
                                          smpl=None if fits is None or body is not f else fits.zju_params(f),
                                          smplx=None if fits_x is None or body is not f else fits_x.zju_params(f)))
                sequences[(f.subject, CAPTURE)].append(g)
        for (subject, split), seq in sequences.items():
            training = sorted({camera_name(f) for f in frames if f.subject == subject and f.split == together[0]}) \
                if split == CAPTURE else None
            write_annots(sequence_dir(out, seq[0]), seq, training)
            files += 1
    if fmt == "relighting-humans":
        from .relighting_humans import write_readme

        limits = write_readme(out, layout.protocol_dir(protocol)[len("protocol_"):], frames, baked, smpl=model,
                              smplx=model_x)
        files += 1 + 2 * len(baked)
    counts = {"frames": len(frames), "files": files, "seconds": time.perf_counter() - t0, "limits": limits}
    for key, fit in (("smpl", fits), ("smplx", fits_x)):
        if fit is not None:
            counts[f"{key}_fit_seconds"], counts[f"{key}_fitted_frames"] = fit.seconds, fit.fitted_frames
    return counts


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="rh-export",
        description="Write a finished Relighting Humans dataset (one protocol) in another layout: the published "
                    "Relighting Humans folders, ZJU-MoCap (NeuralBody family), or one USD stage per frame. "
                    "docs/INTEROP.md lists what each holds and how it differs from the original.",
        formatter_class=HelpFormatter)
    # --dataset, --format and --out are required unless --write-test-smpl(x) is given (checked in main).
    p.add_argument("--dataset", type=Path, help="dataset folder made by rh-generate (required)")
    p.add_argument("--protocol", default="a", help="protocol to export: a, b or c (c: zju-mocap only)")
    p.add_argument("--format", choices=FORMATS, help="output layout (required)")
    p.add_argument("--out", type=Path, help="output folder (required; empty, new, or an earlier export of "
                                            "the same format, whose files are replaced)")
    p.add_argument("--subjects", type=int, default=None, help="export only the first N subjects")
    p.add_argument("--split", action="append", default=None, help="export only this split (repeatable)")
    p.add_argument("--usd-ext", default="usdc", choices=["usda", "usdc", "usd"],
                   help="USD file type: usda (text) or usdc (binary crate, ~4x smaller)")
    p.add_argument("--no-vertices", action="store_true", help="zju-mocap: skip vertices/<i>.npy (posed body)")
    p.add_argument("--smpl-model", type=Path, default=None, metavar="DIR",
                   help="folder holding your own SMPL_NEUTRAL.pkl / SMPL_MALE.pkl / SMPL_FEMALE.pkl (SMPL's licence: "
                        "never bundled or downloaded): fit SMPL to every frame's unclothed anny body and write its "
                        "numbers (relighting-humans, zju-mocap; usd adds the SMPL mesh); the fit is cached in "
                        "OUT/smpl_fit/")
    p.add_argument("--smplx-model", type=Path, default=None, metavar="DIR",
                   help="folder holding your own SMPLX_NEUTRAL.npz / SMPLX_MALE.npz / SMPLX_FEMALE.npz (or .pkl; "
                        "also DIR/smplx/): fit SMPL-X to every frame as well and write it as skeleton_0.smplx_data "
                        "(relighting-humans) and params_smplx/ + vertices_smplx/ (zju-mocap); cached in OUT/smplx_fit/")
    p.add_argument("--smpl-gender", default="neutral", choices=["neutral", "male", "female"],
                   help="which SMPL (and SMPL-X) file to fit (the clients name it in `gender`; Gaussian Shadow "
                        "Casting always loads the neutral one)")
    p.add_argument("--smpl-max-mean-mm", type=float, default=None,
                   help="refuse a frame whose mean SMPL-to-anny distance (either way) is above this (default 15)")
    p.add_argument("--smpl-max-peak-mm", type=float, default=None,
                   help="refuse a frame whose largest SMPL-to-anny distance (either way) is above this (default 100)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--write-test-smpl", type=Path, metavar="DIR",
                   help="write a stand-in model built from anny as SMPL_NEUTRAL.pkl, SMPL_MALE.pkl and "
                        "SMPL_FEMALE.pkl into DIR, then exit (no dataset needed): it lets the SMPL path be tried "
                        "without SMPL's own files. It is NOT SMPL: results with it are not SMPL results")
    p.add_argument("--write-test-smplx", type=Path, metavar="DIR",
                   help="the same in SMPL-X's layout: SMPLX_NEUTRAL.npz, SMPLX_MALE.npz, SMPLX_FEMALE.npz (10,475 "
                        "vertices, 55 joints), then exit. It is NOT SMPL-X")
    add_debug_flag(p)
    return p


@command("rh-export")
def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.write_test_smpl is not None or args.write_test_smplx is not None:
        from rh_dataset.smpl.standin import write_test_models

        for kind, folder in (("smpl", args.write_test_smpl), ("smplx", args.write_test_smplx)):
            if folder is None:
                continue
            try:
                paths = write_test_models(folder, kind)
            except OSError as exc:
                print(f"rh-export: error: {folder}: cannot write the stand-in model files "
                      f"({exc.strerror or exc}); pass a folder you can write to", file=sys.stderr)
                return 2
            for path in paths:
                name = "SMPL" if kind == "smpl" else "SMPL-X"
                print(f"rh-export: wrote {path} (a stand-in built from anny, not {name})")
        return 0
    missing = [f"--{k}" for k in ("dataset", "format", "out") if getattr(args, k) is None]
    if missing:
        parser.error(f"the following arguments are required: {', '.join(missing)}")
    # Every export file is written atomically, and a rerun into the same --out replaces them all.
    on_stop(lambda: f"the files already in {args.out} are whole; a rerun rewrites the export")
    try:
        settings = None
        if args.smpl_max_mean_mm is not None or args.smpl_max_peak_mm is not None:
            import dataclasses

            from rh_dataset.smpl.fit import FitSettings

            d = FitSettings()
            settings = dataclasses.replace(
                d, max_mean_mm=d.max_mean_mm if args.smpl_max_mean_mm is None else args.smpl_max_mean_mm,
                max_max_mm=d.max_max_mm if args.smpl_max_peak_mm is None else args.smpl_max_peak_mm)
        counts = export_dataset(args.dataset, args.protocol, args.format, args.out, subjects=args.subjects,
                                splits=tuple(args.split) if args.split else None, usd_ext=args.usd_ext,
                                zju_vertices=not args.no_vertices, progress=not args.no_progress,
                                smpl_model=args.smpl_model, smpl_gender=args.smpl_gender, smpl_settings=settings,
                                smplx_model=args.smplx_model)
    except (ExportError, ValueError, FileNotFoundError) as exc:
        checkpoint()  # an error that follows a stop lost in a C callback is that stop (rh_common.interrupt)
        print(f"rh-export: error: {exc}", file=sys.stderr)
        return 2
    print(f"rh-export: {counts['frames']} frames, {counts['files']} files written in {counts['seconds']:.1f} s; "
          f"{args.format} export in {args.out}")
    for key, name in (("smpl", "SMPL"), ("smplx", "SMPL-X")):
        if counts.get(f"{key}_fitted_frames"):
            n, sec = counts[f"{key}_fitted_frames"], counts[f"{key}_fit_seconds"]
            print(f"rh-export: {name} fit {n} frames in {sec:.1f} s ({sec / n:.2f} s per frame)")
    for line in counts["limits"]:
        print(f"rh-export: note: {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
