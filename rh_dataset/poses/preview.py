"""Contact sheet of sampled poses: `python -m rh_dataset.poses.preview --n 12 --out /tmp/poses.png`.

Each pose is rendered as a grey diffuse mesh under a constant environment (Mitsuba, llvm_ad_rgb), from the front
(camera at -Y, as the generator's default camera) and, with `--side`, also from the character's left (+X) so that
knees and hips can be checked.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from .pose import BodyPose

__all__ = ["render_pose", "contact_sheet", "main"]


def _posed_vertices(pose: BodyPose, model) -> np.ndarray:
    import torch

    with torch.no_grad():
        out = model(pose_parameters=pose.as_anny_tensor(model))
    return pose.apply_root_transform(out["vertices"][0].cpu().numpy())


def render_pose(vertices: np.ndarray, faces: np.ndarray, *, azimuth_deg: float = 0.0, size: int = 256,
                spp: int = 16) -> np.ndarray:
    """(size, size, 3) linear RGB render; the camera orbits +Z, azimuth 0 = at -Y looking at the body's front."""
    from ..variant import ensure_variant

    mi = ensure_variant()
    mesh = mi.Mesh("body", len(vertices), len(faces), has_vertex_normals=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(np.ascontiguousarray(vertices, dtype=np.float32).ravel())
    params["faces"] = mi.UInt32(np.ascontiguousarray(faces, dtype=np.uint32).ravel())
    params.update()
    lo, hi = vertices.min(0), vertices.max(0)
    centre = (lo + hi) / 2
    extent = float(np.max(hi - lo))
    fov = 30.0
    distance = 0.6 * extent / np.tan(np.radians(fov / 2)) + 0.5
    a = np.radians(azimuth_deg)
    origin = centre + distance * np.array([np.sin(a), -np.cos(a), 0.0])
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": {"type": "perspective", "fov": fov,
                   "to_world": mi.ScalarTransform4f().look_at(origin=origin.tolist(), target=centre.tolist(),
                                                              up=[0, 0, 1]),
                   "film": {"type": "hdrfilm", "width": size, "height": size, "pixel_format": "rgb"},
                   "sampler": {"type": "independent", "sample_count": spp}},
        "emitter": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
        "body": mesh,
    })
    return np.asarray(mi.render(scene, seed=0))[..., :3]


def contact_sheet(poses: list[BodyPose], model, out: str, *, side: bool = True, size: int = 256) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    faces = model.faces.cpu().numpy()
    cols = min(4 if side else 6, len(poses))
    rows = -(-len(poses) // cols)
    views = (0.0, 90.0) if side else (0.0,)
    fig, axes = plt.subplots(rows, cols, figsize=(2.2 * cols * len(views), 2.5 * rows), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for i, pose in enumerate(poses):
        vertices = _posed_vertices(pose, model)
        images = [render_pose(vertices, faces, azimuth_deg=az, size=size) for az in views]
        image = np.clip(np.concatenate(images, axis=1), 0, 1) ** (1 / 2.2)
        ax = axes.ravel()[i]
        ax.imshow(image)
        yaw = np.degrees(np.arctan2(pose.bones["root"][1, 0], pose.bones["root"][0, 0])) if "root" in pose.bones \
            else 0.0
        ax.set_title(f"{i}: {pose.label} (yaw {yaw:+.0f}°)", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    from rh_common.body_model import load_anny
    from .prior import sample_poses

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=12, help="number of poses")
    parser.add_argument("--seed", type=int, default=0, help="seed of the one generator")
    parser.add_argument("--out", default="/tmp/poses.png", help="output PNG")
    parser.add_argument("--no-side", action="store_true", help="front view only")
    parser.add_argument("--size", type=int, default=256, help="pixels per view")
    args = parser.parse_args(argv)
    model = load_anny()
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    poses = sample_poses(rng, model, args.n)
    print(f"sampled {args.n} poses in {time.perf_counter() - t0:.2f} s")
    contact_sheet(poses, model, args.out, side=not args.no_side, size=args.size)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
