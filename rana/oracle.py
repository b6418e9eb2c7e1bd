"""The Lambertian-SH oracle bound: ground-truth albedo times the order-2 SH shading of ground-truth normals.

This is what any method that models the person as Lambertian under order-2 SH light (RANA and the SMPL+D baseline
included) would score with perfect albedo and normals. The gap between it and the path-traced ground truth is the
lighting model's error (cast shadows, interreflection, specular, SH truncation), not a learning error. It reads
the scored split's ground truth (`test`, or `--split olat`: one small light, which order-2 SH cannot represent), so
it is a bound, never a method: its method.json says "kind": "bound".
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from rh_common import sh
from rh_common.imageio import read_exr
from rh_common.interrupt import add_debug_flag, checkpoint, command, on_stop

from .predictions import PredictionWriter, iter_test_frames

__all__ = ["oracle_image", "predict_oracle", "main"]


def oracle_image(albedo: np.ndarray, normal: np.ndarray, sh_camera: np.ndarray, background: np.ndarray) -> np.ndarray:
    """albedo * max(0, S(n)) inside the person, the given background (radiance) elsewhere.

    Order-2 SH shading can ring negative under strongly directional light; radiance cannot, so it is clamped.
    """
    inside = np.any(normal != 0.0, axis=-1)
    shade = np.maximum(sh.shading(np.asarray(sh_camera, np.float64), normal.astype(np.float64)), 0.0)
    return np.where(inside[..., None], albedo * shade, background).astype(np.float32)


def predict_oracle(dataset: str | Path, protocol: str, out: str | Path, split: str = "test") -> int:
    writer = PredictionWriter(out, {"name": "Oracle (GT albedo x SH2 shading of GT normals)", "kind": "bound",
                                    "description": __doc__.strip().splitlines()[0]})
    n = 0
    for fr in iter_test_frames(dataset, protocol, split):
        albedo = read_exr(fr.layer_path("albedo"))
        normal = read_exr(fr.layer_path("normal"))
        # Outside the person the bound copies the ground truth: it bounds the person, not the environment.
        background = read_exr(fr.layer_path("image"))
        img = oracle_image(albedo, normal, np.asarray(fr.meta["light"]["sh_camera"]), background)
        writer.write(fr, image=img, albedo=albedo, normal=normal)
        n += 1
    return n


@command("rana-oracle")
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="rana-oracle", description=__doc__.strip().splitlines()[0])
    p.add_argument("--dataset", required=True, type=Path, help="dataset folder made by rh-generate")
    p.add_argument("--protocol", default="a", choices=["a", "b", "c"],
                   help="which protocol's test split (c: multi-view, every held-out camera)")
    p.add_argument("--split", default="test",
                   help="the split to predict (default: test; e.g. olat): predictions go to <out>/<subject>/"
                        "protocol_<p>/<split>/, what rh-eval --split reads")
    p.add_argument("--out", required=True, type=Path, help="predictions folder to write")
    add_debug_flag(p)
    args = p.parse_args(argv)
    on_stop(lambda: f"the predictions already in {args.out} are whole; a rerun writes them all again")
    try:
        n = predict_oracle(args.dataset, args.protocol, args.out, args.split)
    except (FileNotFoundError, ValueError) as exc:
        checkpoint()  # an error that follows a stop lost in a C callback is that stop (rh_common.interrupt)
        print(f"rana-oracle: error: {exc}", file=sys.stderr)
        return 2
    print(f"rana-oracle: {n} frames written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
