"""Per-vertex body features of anny's rest pose, the quantities garment, hair and texture cut-offs are expressed in.

In: a phenotype (dict of anny's phenotype parameters) and a topology name; anny's own data files (bone skinning,
mpfb2 region masks, the UV body-part segmentation). Out: `BodyFeatures` (rest vertices and normals, each vertex's
bone group out of GROUPS, positions along arms and legs, region masks, the edge list) from `body_features`; one mpfb2
mask image from `mask_image`.

Everything here is a pure function of (phenotype, topology) or of the topology alone; the expensive
phenotype-independent parts are cached.
"""
from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import numpy as np
from PIL import Image

from rh_common.body_model import ANNY_TOPOLOGY

from rh_dataset.mesh import vertex_normals

from .body import BodyTopology, body_topology, run_anny

__all__ = ["BodyFeatures", "body_features", "group_mask", "mask_image", "anny_data_dir", "GROUPS"]

# Bone groups: each body vertex is labelled with the group that holds most of its skinning weight. Garment regions
# are cut from these labels, so a sleeve is made of exactly the vertices the arm bones move.
GROUPS = ("head", "neck", "torso", "shoulder", "upperarm", "lowerarm", "hand", "upperleg", "lowerleg", "foot")


def _bone_group(label: str) -> str:
    base = label.split(".")[0]
    if base in ("head", "eye"):
        return "head"
    if base.startswith("neck"):
        return "neck"
    if base in ("root", "pelvis") or base.startswith("spine"):
        return "torso"
    if base in ("clavicle", "shoulder01"):
        return "shoulder"
    if base.startswith("upperarm"):
        return "upperarm"
    if base.startswith("lowerarm"):
        return "lowerarm"
    if base in ("wrist",) or base.startswith(("finger", "metacarpal")):
        return "hand"
    if base.startswith("upperleg"):
        return "upperleg"
    if base.startswith("lowerleg"):
        return "lowerleg"
    if base in ("foot",) or base.startswith("toe"):
        return "foot"
    raise ValueError(f"unknown anny bone {label!r}")


def anny_data_dir() -> Path:
    import anny

    return Path(anny.__file__).parent / "data"


@functools.lru_cache(maxsize=8)
def mask_image(name: str) -> np.ndarray:
    """An mpfb2 region mask (face, lips, ears, eyelids, fingernails, toenails) as float32 (H, W) in [0, 1]."""
    path = anny_data_dir() / "mpfb2" / "textures" / f"mpfb_{name}.jpg"
    with Image.open(path) as im:
        arr = np.asarray(im.convert("L"), dtype=np.float32) / 255.0
    arr.setflags(write=False)
    return arr


@functools.lru_cache(maxsize=1)
def _segmentation() -> tuple[np.ndarray, dict[str, tuple[int, int, int]]]:
    import yaml

    seg_dir = anny_data_dir() / "segmentation"
    with Image.open(seg_dir / "body_parts_segmentation.png") as im:
        rgb = np.asarray(im.convert("RGB"), dtype=np.uint8)
    with open(seg_dir / "body_parts_segmentation.yaml") as f:
        colours = {k: tuple(v) for k, v in yaml.safe_load(f)["colors"].items()}
    return rgb, colours


def _sample_uv(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Nearest-texel lookup of an image (row 0 = top) at v-up UVs."""
    h, w = image.shape[:2]
    col = np.clip((uv[:, 0] * w).astype(np.int64), 0, w - 1)
    row = np.clip(((1.0 - uv[:, 1]) * h).astype(np.int64), 0, h - 1)
    return image[row, col]


def _per_vertex_max(topo: BodyTopology, corner_values: np.ndarray) -> np.ndarray:
    """Reduce per-face-corner values (F, 3) to per-vertex values by max (a vertex on a UV seam has several)."""
    out = np.full(topo.n_vertices, -np.inf)
    np.maximum.at(out, topo.faces.ravel(), corner_values.ravel())
    return out


@functools.lru_cache(maxsize=1)
def _static_features(topology: str) -> dict[str, np.ndarray]:
    """Phenotype-independent per-vertex labels: bone group, UV segmentation part, mpfb2 region masks."""
    topo = body_topology(topology)
    group_of_bone = np.array([GROUPS.index(_bone_group(b)) for b in topo.bone_labels])
    gw = np.zeros((topo.n_vertices, len(GROUPS)))
    np.add.at(gw, (np.arange(topo.n_vertices)[:, None], group_of_bone[topo.bone_indices]), topo.bone_weights)
    corner_uv = topo.texcoords[topo.face_texcoords]  # (F, 3, 2)
    flat_uv = corner_uv.reshape(-1, 2)
    out = {"group": np.argmax(gw, axis=1), "group_weights": gw}
    for name in ("face", "lips", "ears", "eyelids", "fingernails", "toenails"):
        vals = _sample_uv(mask_image(name), flat_uv).reshape(-1, 3)
        out[f"mask_{name}"] = _per_vertex_max(topo, vals)
    seg, colours = _segmentation()
    seg_corner = _sample_uv(seg, flat_uv).reshape(-1, 3, 3)
    for part in ("head", "foot.L", "foot.R", "hand.L", "hand.R"):
        hit = np.all(seg_corner == np.array(colours[part], dtype=np.uint8), axis=-1).astype(np.float64)
        out[f"seg_{part}"] = _per_vertex_max(topo, hit) > 0.5
    # Edge graph (for geodesic-like distances along the surface).
    f = topo.faces
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    out["edges"] = np.unique(np.sort(edges, axis=1), axis=0)
    for v in out.values():
        v.setflags(write=False)
    return out


@dataclasses.dataclass(frozen=True)
class BodyFeatures:
    """Per-vertex quantities of one phenotype's rest pose that garment and hair cut-offs are expressed in."""

    rest_vertices: np.ndarray  # (V, 3) float64
    rest_normals: np.ndarray  # (V, 3) float64
    group: np.ndarray  # (V,) int index into GROUPS
    bone_heads: dict[str, np.ndarray]  # label -> (3,) rest position
    arm_t: np.ndarray  # (V,) 0 at the shoulder joint, 1 at the wrist (nan off the arms)
    leg_t: np.ndarray  # (V,) 0 at the hip joint, 1 at the ankle (nan off the legs)
    masks: dict[str, np.ndarray]  # mpfb2 region masks and segmentation parts, per vertex
    edges: np.ndarray  # (E, 2) unique undirected edges

    def in_groups(self, *names: str) -> np.ndarray:
        return np.isin(self.group, [GROUPS.index(n) for n in names])


def _segment_t(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    return (points - a) @ d / float(d @ d)


def group_mask(topology: str, *names: str) -> np.ndarray:
    """(V,) bool: the body vertices whose bone group is one of `names` (GROUPS; the same labels for every
    phenotype, `BodyFeatures.in_groups` without building the features)."""
    return np.isin(_static_features(topology)["group"], [GROUPS.index(n) for n in names])


@functools.lru_cache(maxsize=16)
def _body_features_cached(pheno_items: tuple[tuple[str, float], ...], topology: str) -> BodyFeatures:
    topo = body_topology(topology)
    st = _static_features(topology)
    out = run_anny(dict(pheno_items), None, topology)
    rest = out["rest_vertices"]
    heads = {label: out["rest_bone_heads"][i] for i, label in enumerate(topo.bone_labels)}
    group = st["group"]
    x = rest[:, 0]
    arm_t = np.full(len(rest), np.nan)
    leg_t = np.full(len(rest), np.nan)
    arm_groups = np.isin(group, [GROUPS.index(g) for g in ("shoulder", "upperarm", "lowerarm", "hand")])
    leg_groups = np.isin(group, [GROUPS.index(g) for g in ("upperleg", "lowerleg", "foot")])
    for side, sel in (("L", x > 0), ("R", x <= 0)):
        m = arm_groups & sel
        arm_t[m] = _segment_t(rest[m], heads[f"upperarm01.{side}"], heads[f"wrist.{side}"])
        m = leg_groups & sel
        leg_t[m] = _segment_t(rest[m], heads[f"upperleg01.{side}"], heads[f"foot.{side}"])
    masks = {k[5:]: v for k, v in st.items() if k.startswith("mask_")}
    masks.update({k[4:]: v for k, v in st.items() if k.startswith("seg_")})
    feats = BodyFeatures(
        rest_vertices=rest,
        rest_normals=vertex_normals(rest, topo.faces),
        group=group,
        bone_heads=heads,
        arm_t=arm_t,
        leg_t=leg_t,
        masks=masks,
        edges=st["edges"],
    )
    for a in (feats.rest_vertices, feats.rest_normals, feats.arm_t, feats.leg_t):
        a.setflags(write=False)
    return feats


def body_features(phenotype: dict[str, float], topology: str = ANNY_TOPOLOGY) -> BodyFeatures:
    """Rest-pose features for a phenotype (cached: garments, hair and textures all ask for the same one)."""
    return _body_features_cached(tuple(sorted((k, float(v)) for k, v in phenotype.items())), topology)
