"""`rh-generate`: path-trace a Relighting Humans dataset (protocol a, b or c) into a folder, resumably."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rh_common.cli_help import HelpFormatter
from rh_common.interrupt import add_debug_flag, checkpoint, command, on_stop

__all__ = ["main", "build_parser", "options_from_args", "render_settings", "backend_from_args"]


def _resolution(text: str) -> tuple[int, int]:
    try:
        parts = [int(x) for x in text.lower().split("x")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"resolution {text!r}: expected N or WxH, e.g. 512 or 512x384") from None
    if len(parts) == 1:
        parts = parts * 2
    if len(parts) != 2 or min(parts) < 8:
        raise argparse.ArgumentTypeError(f"resolution {text!r}: expected N or WxH with each side >= 8")
    return parts[0], parts[1]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="rh-generate",
        description="Path-trace the Relighting Humans benchmark: posed, clothed anny characters under HDRI "
                    "environment light, with ground-truth albedo, normal, mask and depth, the pose, camera and "
                    "light (HDRI id and SH coefficients) of every frame. Reruns resume: finished frames whose "
                    "checksums match are skipped.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("--protocol", default="a",
                   help="'a' (train: A-pose turntable under one light; test: random poses and lights), 'b' (train: "
                        "random poses under one light; test: the same poses under other lights), 'c' (multi-view: "
                        "train: 10 cameras under one light; novel_view, test: 6 held-out cameras under that light "
                        "and under other lights), a scene name in "
                        "rh_dataset/scenes/ (e.g. 'demo'), or the path of a scene JSON file")
    p.add_argument("--out", required=True, type=Path,
                   help="dataset folder; several protocols may share one folder")
    p.add_argument("--subjects", type=int, default=None,
                   help="number of subjects (default: the protocol's, 49 for a and b, 10 for c)")
    p.add_argument("--frames", type=int, default=None,
                   help="cap on frames per split, for small runs (default: the protocol's, e.g. 100 train / 150 test)")
    p.add_argument("--resolution", type=_resolution, default=None,
                   help="image size N or WxH (default: the protocol's, 512x512)")
    p.add_argument("--preset", default="standard",
                   help="render preset from rh_dataset/scenes/presets.json: draft, standard or reference")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel of the beauty pass (overrides the preset)")
    p.add_argument("--aov-spp", type=int, default=None,
                   help="samples per pixel of the albedo/normal/mask/depth pass (overrides the preset)")
    p.add_argument("--sampler", default=None,
                   help="Mitsuba sampler of both passes (overrides the preset): independent, stratified, multijitter, "
                        "orthogonal or ldsampler; some take only certain sample counts (docs/TRADEOFFS.md)")
    p.add_argument("--env-spp", type=int, default=None,
                   help="samples per pixel where the AOV pass sees no person (overrides the preset; 0 = every pixel "
                        "at --spp): the person's pixels get the full count, unbiased either way (docs/TRADEOFFS.md)")
    p.add_argument("--max-depth", type=int, default=None,
                   help="longest light path; 2 = direct light only (overrides the preset; by default the draft and "
                        "standard presets take each split's scene_class depth from rh_dataset/scenes/presets.json)")
    p.add_argument("--denoise", action="store_true",
                   help="denoise the beauty image with Intel Open Image Denoise guided by the albedo and normal AOVs; "
                        "biased (docs/TRADEOFFS.md), recorded in every frame's JSON, off for benchmark ground truth")
    p.add_argument("--no-cull", action="store_true",
                   help="load every triangle: by default skin hidden under clothes (and, in AOV-only frames, "
                        "triangles outside the view) is left out, which changes the image by far less than its noise "
                        "(docs/TRADEOFFS.md); each frame's JSON records what was left out")
    p.add_argument("--cloth", default=None,
                   help="how draped garments reach each frame's pose (overrides the preset): 'skinned' follows the "
                        "body's skinning and is pushed out of the skin (cheap), 'simulated' runs newton's cloth solver "
                        "while the body moves from the rest pose into the frame's (tens of seconds a posed frame), "
                        "'auto' skins and simulates only the frames whose skinned cloth lets skin through or pulls a "
                        "skirt or dress taut; the frame JSON records it under render.cloth, and under "
                        "render.cloth_posed what an 'auto' frame took (docs/TRADEOFFS.md, 'Skinned or simulated "
                        "cloth')")
    p.add_argument("--drape", default=None,
                   help="how finely loose garments (draped skirts, dresses, wide trousers, loose shorts, coats, "
                        "open jackets, loose tops, hoods) are simulated onto each subject's body (overrides the "
                        "preset): 'full' (the benchmark's, 1-3 min a subject on 2 cores, cached) or 'coarse' (the draft preset's, ~1/8 of "
                        "that); recorded under render.drape")
    p.add_argument("--seed", type=int, default=0, help="dataset seed: characters, poses, lights and sampler seeds")
    p.add_argument("--variant", default=None, choices=["llvm_ad_rgb", "cuda_ad_rgb"],
                   help="Mitsuba variant (default: cuda_ad_rgb if a GPU works, else llvm_ad_rgb); a split "
                        "begun on one variant is not resumed on the other (their frames are not the same benchmark)")
    p.add_argument("--workers", type=int, default=1,
                   help="processes rendering subjects in parallel (each renders with cores/workers threads, at "
                        "least 2)")
    p.add_argument("--backend", default="local", choices=["local", "ray"],
                   help="where frames render: 'local' (this machine, --workers processes) or 'ray' (tasks on a Ray "
                        "cluster; same files, bit-identical on the same machine kind and variant)")
    p.add_argument("--ray-address", default=None,
                   help="Ray cluster to join, e.g. 'auto' or 'ray://head:10001' (default: start a local one); every "
                        "node must see --out at the same path")
    p.add_argument("--ray-frames-per-task", type=int, default=8,
                   help="frames of one subject and split per Ray task (the unit of retry)")
    p.add_argument("--ray-cpus-per-task", type=float, default=1.0,
                   help="CPUs Ray reserves per task (also the task's render threads)")
    p.add_argument("--ray-gpus-per-task", type=float, default=0.0,
                   help="GPUs Ray reserves per task; use with --variant cuda_ad_rgb on GPU nodes")
    p.add_argument("--hdri-folder", default=None,
                   help="folder of .exr/.hdr environment maps to light with instead of the bundled Poly Haven set")
    p.add_argument("--motion", type=Path, default=None,
                   help="a .bvh (or .fbx/.glb/.gltf) motion file whose frames, retargeted onto each subject's body "
                        "(anny's, or the --character rig), replace the pose prior: protocol a's test poses, "
                        "protocol b's train poses (which its test split reuses). Read through Blender (bash "
                        "setup.sh installs it); the frame JSON records the file's name, sha256 and frame "
                        "(docs/INTEROP.md)")
    p.add_argument("--motion-start", type=int, default=0, help="first motion frame used (0-based)")
    p.add_argument("--motion-stride", type=int, default=None,
                   help="motion frames between consecutive dataset frames (default: spread the split over the clip)")
    p.add_argument("--motion-heading", default="file", choices=["file", "front"],
                   help="'file': the body faces where the actor faced; 'front': every frame turned to face the "
                        "camera")
    p.add_argument("--character", type=Path, default=None,
                   help="a rigged character (.glb, .gltf or .fbx, read through Blender) rendered for every subject "
                        "instead of anny characters: train = turntable of its rest pose, test = frames of its own "
                        "animation (the rest pose if it has none); --subjects defaults to 1. docs/INTEROP.md")
    p.add_argument("--character-scale", type=float, default=None,
                   help="multiply the imported character's metres by this (default: detect metres or centimetres "
                        "from its height)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace this protocol's frames in --out if they were made with other settings")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (for logs)")
    p.add_argument("--no-space-check", action="store_true",
                   help="start even if the estimated size of the frames still to render (rh_dataset/space.py, "
                        "measured per layer by bench/bench_sizes.py) exceeds the free space of --out")
    add_debug_flag(p)
    return p


def options_from_args(args: argparse.Namespace):
    """(the dataset plan, the backend) that the command line asks for."""
    from rh_dataset.generate import DatasetPlan
    from rh_dataset.spec import MotionSpec, SpecError, load_protocol

    motion = None
    if args.motion is not None:
        motion = MotionSpec.from_file(args.motion, start=args.motion_start, stride=args.motion_stride,
                                      heading=args.motion_heading)
    elif args.motion_stride is not None or args.motion_start != 0 or args.motion_heading != "file":
        raise SpecError("--motion-start, --motion-stride and --motion-heading need --motion FILE")
    character = None
    subjects = args.subjects
    if args.character is not None:
        from rh_dataset.characters.imported_model import CharacterImportError
        from rh_dataset.characters.imported_reader import character_digest
        from rh_dataset.spec import CharacterSource

        if not args.character.is_file():
            raise CharacterImportError(f"--character {args.character}: no such file")
        character = CharacterSource(file=args.character.name, sha256=character_digest(args.character),
                                    scale=args.character_scale)
        # One imported character is the same person in every subject: one subject unless asked for more.
        subjects = 1 if subjects is None else subjects
    elif args.character_scale is not None:
        raise SpecError("--character-scale needs --character")
    spec = load_protocol(args.protocol).with_overrides(
        subjects=subjects, frames=args.frames, resolution=args.resolution, hdri_folder=args.hdri_folder,
        motion=motion, character=character)
    settings = render_settings(args.preset, spp=args.spp, aov_spp=args.aov_spp, max_depth=args.max_depth,
                               sampler=args.sampler, env_spp=args.env_spp, denoise=bool(args.denoise),
                               cull=not args.no_cull, cloth=args.cloth, drape=args.drape)
    plan = DatasetPlan(out=args.out, spec=spec, settings=settings, seed=args.seed, variant=args.variant,
                       overwrite=args.overwrite, character_path=args.character)
    return plan, backend_from_args(args)


def render_settings(preset: str, *, spp: int | None = None, aov_spp: int | None = None, max_depth: int | None = None,
                    sampler: str | None = None, env_spp: int | None = None, denoise: bool = False,
                    cull: bool = True, cloth: str | None = None, adaptive_tiers: tuple[int, ...] | None = None,
                    drape: str | None = None):
    """RenderSettings of a preset of scenes/presets.json, with the given fields overridden (None: the preset's;
    adaptive_tiers (): off)."""
    from rh_dataset.render.sampler import SAMPLERS
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.spec import SpecError
    from rh_dataset.presets import load_presets

    presets = load_presets()
    if preset not in presets:
        raise SpecError(f"unknown --preset {preset!r}; choose one of {sorted(presets)}")
    pr = presets[preset]
    overridden = any(v is not None for v in (spp, aov_spp, max_depth, sampler, env_spp, cloth, adaptive_tiers, drape))
    if sampler is not None and sampler not in SAMPLERS:
        raise SpecError(f"unknown --sampler {sampler!r}; choose one of {', '.join(SAMPLERS)}")
    from rh_dataset.characters.cloth_pose import CLOTH_MODES

    if cloth is not None and cloth not in CLOTH_MODES:
        raise SpecError(f"unknown --cloth {cloth!r}; choose one of {', '.join(CLOTH_MODES)}")
    from rh_dataset.characters.drape import DRAPE_LEVELS

    if drape is not None and drape not in DRAPE_LEVELS:
        raise SpecError(f"unknown --drape {drape!r}; choose one of {', '.join(DRAPE_LEVELS)}")
    return RenderSettings(
        spp=spp if spp is not None else pr.spp,
        aov_spp=aov_spp if aov_spp is not None else pr.aov_spp,
        max_depth=max_depth if max_depth is not None else pr.max_depth,
        sampler=sampler if sampler is not None else pr.sampler,
        env_spp=(env_spp or None) if env_spp is not None else _preset_env_spp(pr.env_spp, spp),
        adaptive_tiers=(tuple(adaptive_tiers) or None) if adaptive_tiers is not None else
        (pr.adaptive_tiers if spp is None and env_spp is None else None),
        preset=f"{pr.name}+overrides" if overridden else pr.name,
        denoise=denoise,
        cull=cull,
        cloth=cloth if cloth is not None else pr.cloth,
        drape=drape if drape is not None else pr.drape,
    )


def _preset_env_spp(env_spp: int | None, spp: int | None) -> int | None:
    """The preset's env_spp under a --spp override: never above the override (at or above it, focusing saves nothing:
    None)."""
    if env_spp is None or spp is None:
        return env_spp
    return env_spp if env_spp < spp else None


def backend_from_args(args: argparse.Namespace):
    """The backend --backend names, with its own flags; a flag of the other backend is refused."""
    from rh_dataset.backends import LocalBackend, RayBackend
    from rh_dataset.generate import GenerateError

    if args.backend == "ray":
        if args.workers != 1:
            raise GenerateError("--workers applies to the local backend; with --backend ray the cluster's CPUs are "
                                "used (size tasks with --ray-cpus-per-task)")
        return RayBackend(address=args.ray_address, frames_per_task=args.ray_frames_per_task,
                          cpus_per_task=args.ray_cpus_per_task, gpus_per_task=args.ray_gpus_per_task)
    return LocalBackend(workers=args.workers)


@command("rh-generate")
def main(argv: list[str] | None = None) -> int:
    from rh_dataset.generate import GenerateError, generate
    from rh_common.blender import BlenderError
    from rh_dataset import space
    from rh_dataset.variant import VariantError

    args = build_parser().parse_args(argv)
    try:
        plan, backend = options_from_args(args)
        # What a stop says: the frames on disk (a frame's JSON is written last), and the bytes still to write.
        on_stop(lambda: "{} of {} frames finished and kept".format(*space.frames_finished(plan)),
                lambda: space.remaining_bytes(plan))
        if not args.no_space_check:
            space.check_space(plan)
        counts = generate(plan, backend, progress=not args.no_progress)
    except (ValueError, GenerateError, VariantError, FileNotFoundError, BlenderError, space.SpaceError) as exc:
        checkpoint()  # an error that follows a stop lost in a C callback is that stop (rh_common.interrupt)
        print(f"rh-generate: error: {exc}", file=sys.stderr)
        return 2
    print(f"rh-generate: {counts['rendered']} frames rendered, {counts['skipped']} already complete, "
          f"{counts['seconds']:.1f} s; dataset in {plan.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
