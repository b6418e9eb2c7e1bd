"""`rana`: train (coarse stage + personalization), predict (RANA or SMPL+D), pretrain, plot, synth.

    rana train   --dataset D --protocol a --subject subject_000 --runs runs/ --preset cpu [--pretrained P]
    rana train   --dataset D --protocol a --subject all --runs runs/          # every subject, one after another
    rana predict --dataset D --protocol a --runs runs/ --out preds/rana
    rana smpld   --dataset D --protocol a --runs runs/ --out preds/smpld       # the SMPL+D baseline
    rana smpld   ... --split olat --out preds/smpld_olat                      # another split (default test)
    rana pretrain --dataset P --out pre/ --preset cpu                          # = rana-pretrain
    rana plot    runs/subject_000 --out losses.png
    rana synth   --out /tmp/syn --subjects 1 --resolution 64                   # a tiny synthetic dataset

A run folder is `<runs>/<subject>/` with config.json, coarse.pt, checkpoints/step-%09d.pt, losses.jsonl.
Rerunning `rana train` with the same flags resumes from the newest checkpoint; other flags are refused
unless --force (which restarts the subject).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rh_common.interrupt import add_debug_flag, checkpoint, command, on_stop

from .config import PRESETS, get_preset
from .config_flags import add_config_flags, apply_config_flags

__all__ = ["main", "build_parser", "plot_losses"]


def plot_losses(run_dir: str | Path, out: str | Path, keys: list[str] | None = None) -> Path:
    """PNG of every logged loss term against the step (log scale where all values are positive)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .runs import RunDir

    recs = [r for r in RunDir(run_dir).read_log() if r.get("step", -1) >= 0]
    if not recs:
        raise ValueError(f"{run_dir}: no loss log (losses.jsonl) to plot")
    skip = {"step", "seconds", "phase", "lr_net", "stage"}
    names = keys or sorted({k for r in recs for k, v in r.items() if k not in skip and isinstance(v, (int, float))})
    n = len(names)
    cols = min(4, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3 * rows), squeeze=False)
    for ax, k in zip(axes.flat, names):
        xs = [r["step"] for r in recs if k in r]
        ys = [r[k] for r in recs if k in r]
        ax.plot(xs, ys, lw=1)
        if ys and min(ys) > 0:
            ax.set_yscale("log")
        ax.set_title(k)
        ax.set_xlabel("step")
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.suptitle(str(run_dir))
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="rana", description=__doc__.strip().splitlines()[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)

    t = sub.add_parser("train", help="coarse stage + personalization of one subject (or all)")
    t.add_argument("--dataset", required=True, type=Path, help="dataset folder written by rh-generate")
    t.add_argument("--protocol", default="a", help="protocol letter (a or b)")
    t.add_argument("--subject", default="all", help="subject_NNN, a comma-separated list, or 'all'")
    t.add_argument("--runs", required=True, type=Path, help="folder of run folders, one per subject")
    t.add_argument("--preset", default="cpu", choices=sorted(PRESETS),
                   help="starting config (docs/RANA.md, 'Presets'); the --<section>.<field> flags override it")
    t.add_argument("--pretrained", type=Path, default=None, help="pretrained.pt from rana-pretrain")
    t.add_argument("--force", action="store_true", help="restart the subject's run instead of resuming")
    t.add_argument("--no-progress", action="store_true", help="no progress bars (for logs)")
    add_config_flags(t)

    for name, helptext in (("predict", "RANA predictions for rh-eval"), ("smpld", "SMPL+D baseline predictions")):
        q = sub.add_parser(name, help=helptext)
        q.add_argument("--dataset", required=True, type=Path, help="dataset folder written by rh-generate")
        q.add_argument("--protocol", default="a", help="protocol letter (a or b)")
        q.add_argument("--runs", required=True, type=Path,
                       help="folder of run folders, one per subject (what `rana train --runs` wrote)")
        q.add_argument("--out", required=True, type=Path, help="predictions folder")
        q.add_argument("--split", default="test",
                       help="the split to predict (default: test; e.g. olat): written to <out>/<subject>/"
                            "protocol_<p>/<split>/, what rh-eval --split reads")
        q.add_argument("--subject", default="all", help="subject_NNN, comma-separated list, or 'all'")
        q.add_argument("--background", default="sh", choices=["sh", "black"],
                       help="outside the person: the target light's SH environment (default) or black")
        q.add_argument("--name", default=None,
                       help="method name in method.json (what rh-leaderboard shows; default 'RANA' / 'SMPL+D')")
        q.add_argument("--no-progress", action="store_true", help="no progress bars (for logs)")
        if name == "predict":
            q.add_argument("--mask-composite", default="threshold", choices=["threshold", "probability"],
                           help="how the person meets the background: the person wherever AlbedoNet's mask is "
                                "> 0.5 (default), or a blend weighted by that mask, which is a probability rather "
                                "than a coverage (docs/RANA.md, 'Compositing RANA's image')")
        if name == "smpld":
            q.add_argument("--preset", default="cpu", choices=sorted(PRESETS),
                           help="config for subjects whose coarse stage is missing (it is run first)")
            add_config_flags(q, sections=("geometry", "texture", "model"))
            q.add_argument("--pretrained", type=Path, default=None, help="pretrained.pt (for TextureNet)")

    pr = sub.add_parser("pretrain", help="same as rana-pretrain", add_help=False)
    pr.add_argument("rest", nargs=argparse.REMAINDER, help="arguments for rana-pretrain (see rana-pretrain --help)")

    pl = sub.add_parser("plot", help="plot a run's losses.jsonl to PNG")
    pl.add_argument("run", type=Path, help="a subject's run folder (holding losses.jsonl)")
    pl.add_argument("--out", type=Path, default=None, help="PNG path (default <run>/losses.png)")
    pl.add_argument("--keys", default=None, help="comma-separated loss names (default all)")

    sy = sub.add_parser("synth", help="write a tiny synthetic dataset (our rasteriser, Lambertian SH)")
    sy.add_argument("--out", required=True, type=Path, help="dataset folder to write")
    sy.add_argument("--subjects", type=int, default=1, help="number of subjects")
    sy.add_argument("--train-frames", type=int, default=12, help="train frames per subject")
    sy.add_argument("--test-frames", type=int, default=4, help="test frames per subject")
    sy.add_argument("--resolution", type=int, default=128, help="image size in pixels (square)")
    sy.add_argument("--seed", type=int, default=0, help="seed of shapes, poses and lights")
    sy.add_argument("--aov-only-train", action="store_true", help="pretraining-style train split")
    for sp in (t, *[sub.choices[n] for n in ("predict", "smpld", "plot", "synth")]):
        add_debug_flag(sp)
    return p


def _subjects(arg: str, dataset: Path, protocol: str, split: str) -> list[str]:
    from .data import subjects_of

    if arg == "all":
        subs = subjects_of(dataset, protocol, split)
        if not subs:
            raise FileNotFoundError(f"{dataset}: no subject has protocol_{protocol}/{split}")
        return subs
    return [s.strip() for s in arg.split(",") if s.strip()]


@command("rana", not_on_resume=("--force",))
def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["pretrain"]:
        from .pretrain import main as pretrain_main

        return pretrain_main(argv[1:])
    args = build_parser().parse_args(argv)
    if args.cmd in ("predict", "smpld", "synth"):
        on_stop(lambda: f"the files already in {args.out} are whole; a rerun writes them again")
    try:
        if args.cmd == "train":
            from rh_common.threads import torch_threads

            from .train import personalize

            cfg = apply_config_flags(get_preset(args.preset), args)
            subjects = _subjects(args.subject, args.dataset, args.protocol, "train")
            trained: list[str] = []
            # Checkpoints are written atomically; a rerun with the same flags resumes from each subject's newest.
            on_stop(lambda: f"{len(trained)} of {len(subjects)} subjects trained, the others' newest checkpoints "
                            f"kept in {args.runs}")
            with torch_threads(cfg.threads):  # the command's own count, restored when it returns
                for s in subjects:
                    run = personalize(args.dataset, s, args.protocol, args.runs / s, cfg, pretrained=args.pretrained,
                                      progress=not args.no_progress, force=args.force)
                    trained.append(s)
                    print(f"rana train: {s} done → {run.path}")
        elif args.cmd == "predict":
            from .predict import predict_rana

            subs = None if args.subject == "all" else _subjects(args.subject, args.dataset, args.protocol,
                                                                 args.split)
            n = predict_rana(args.dataset, args.protocol, args.runs, args.out, subjects=subs,
                             background=args.background, progress=not args.no_progress, name=args.name,
                             mask_composite=args.mask_composite, split=args.split)
            print(f"rana predict: {n} frames written to {args.out}")
        elif args.cmd == "smpld":
            from rh_common.threads import torch_threads

            from .predict import predict_smpld
            from .train import ensure_coarse

            cfg = apply_config_flags(get_preset(args.preset), args)
            subs = _subjects(args.subject, args.dataset, args.protocol, args.split)
            with torch_threads(cfg.threads):  # the command's own count, restored when it returns
                for s in subs:
                    if (args.runs / s / "coarse.pt").is_file():
                        continue  # an existing run's own coarse stage is the one to use
                    ensure_coarse(args.dataset, s, args.protocol, args.runs / s, cfg, pretrained=args.pretrained,
                                  progress=not args.no_progress)
                n = predict_smpld(args.dataset, args.protocol, args.runs, args.out, subjects=subs,
                                  background=args.background, progress=not args.no_progress, name=args.name,
                                  split=args.split)
            print(f"rana smpld: {n} frames written to {args.out}")
        elif args.cmd == "plot":
            out = plot_losses(args.run, args.out or args.run / "losses.png",
                              args.keys.split(",") if args.keys else None)
            print(f"rana plot: wrote {out}")
        elif args.cmd == "synth":
            from .synthetic import make_dataset

            root = make_dataset(args.out, subjects=args.subjects, train_frames=args.train_frames,
                                test_frames=args.test_frames, resolution=args.resolution, seed=args.seed,
                                aov_only_train=args.aov_only_train)
            print(f"rana synth: wrote {root}")
    except (FileNotFoundError, ValueError) as exc:
        checkpoint()  # an error that follows a stop lost in a C callback is that stop (rh_common.interrupt)
        print(f"rana {args.cmd}: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
