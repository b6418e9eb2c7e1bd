"""Hair as shells over the scalp plus, for longer styles, curtains hanging from the back of the head.

- Scalp shell: head vertices above an azimuth-dependent hairline (high on the forehead, around the ears, down to
  the nape at the back), minus anny's face and ear masks; offset 0.3-2 cm, more volume on top, tapered to the
  hairline. Buns and ponytail ties are a smooth bump in that offset.
- Curtain (bob, long, ponytail): rows interpolated between a ring of head vertices behind the ears and the
  shoulder/upper-back vertices below them. Each curtain vertex is a blend of posed body vertices, so the top
  follows the head and the bottom the back when the character turns its head or bends.
- Long hair also covers the upper back with a shell below the curtain.
"""
from __future__ import annotations

import numpy as np

from .body import ANNY_TOPOLOGY
from .garments import PartGeometry, _metres_per_uv, _select_faces, _smoothstep
from .geometry import BodyFeatures, boundary_distance, hull_anchors, split_faces

__all__ = ["build_hair", "scalp_mask", "SHELL_OFFSET"]

SHELL_OFFSET = {"buzz": 0.003, "short": 0.011, "bob": 0.015, "long": 0.015, "bun": 0.010, "ponytail": 0.008}


def _head_frame(feats: BodyFeatures) -> tuple[np.ndarray, float, np.ndarray]:
    hb = feats.bone_heads["head"]
    z_eye = 0.5 * float(feats.bone_heads["eye.L"][2] + feats.bone_heads["eye.R"][2])
    v = feats.rest_vertices
    # Azimuth about the head's vertical axis: 0 = front (-Y), +90 deg = character's left (+X), 180 = back.
    phi = np.degrees(np.arctan2(v[:, 0] - hb[0], -(v[:, 1] - hb[1])))
    return hb, z_eye, np.abs(phi)


def scalp_mask(style: str, feats: BodyFeatures) -> np.ndarray:
    """Body vertices under the scalp shell."""
    hb, z_eye, aphi = _head_frame(feats)
    z = feats.rest_vertices[:, 2]
    nape = {"buzz": -0.03, "short": -0.04, "bob": -0.05, "long": -0.05, "bun": -0.035, "ponytail": -0.035}[style]
    # Hairline height (metres) as a function of |azimuth|: forehead, temples, in front of/over the ear, nape.
    knots = np.array([0.0, 45.0, 75.0, 100.0, 130.0, 180.0])
    heights = np.array([z_eye + 0.04, z_eye + 0.034, z_eye + 0.005, z_eye + 0.0, hb[2] - 0.0, hb[2] + nape])
    line = np.interp(aphi, knots, heights)
    head = feats.in_groups("head", "neck")
    keep_out = (feats.masks["face"] > 0.35) | (feats.masks["ears"] > 0.2) | (feats.masks["eyelids"] > 0.2)
    return head & (z > line) & ~keep_out


def _bump(feats: BodyFeatures, centre: np.ndarray, radius: float, height: float) -> np.ndarray:
    d = np.linalg.norm(feats.rest_vertices - centre, axis=1)
    return height * np.sqrt(np.clip(1.0 - (d / radius) ** 2, 0.0, 1.0))


def _nearest_on_scalp(feats: BodyFeatures, mask: np.ndarray, target: np.ndarray) -> np.ndarray:
    idx = np.flatnonzero(mask)
    return feats.rest_vertices[idx[np.argmin(np.linalg.norm(feats.rest_vertices[idx] - target, axis=1))]]


def _curtain(
    name: str,
    feats: BodyFeatures,
    angles_deg: np.ndarray,
    z_top: float,
    top_offset: np.ndarray,
    z_bottom: float,
    bottom_offset: float,
    reach: float,
    under: np.ndarray,
    n_rows: int = 10,
) -> PartGeometry:
    """A sheet from a ring of head vertices at height z_top (over `angles_deg`, 0 = front) down towards the
    trunk vertices nearest to the points below them at z_bottom; `reach` in (0, 1] is how far along it goes."""
    v = feats.rest_vertices
    hb = feats.bone_heads["head"]
    head = feats.in_groups("head") & (feats.masks["ears"] < 0.2)
    band = np.flatnonzero(head & (np.abs(v[:, 2] - z_top) < 0.008))
    ang = np.radians(angles_deg)
    top_idx, top_w = hull_anchors(v, band, hb, ang)
    top_pos = (v[top_idx] * top_w[..., None]).sum(1)
    trunk = np.flatnonzero(feats.in_groups("torso", "shoulder", "neck"))
    bot_idx = np.zeros(len(ang), dtype=np.int64)
    for k, p in enumerate(top_pos):
        outward = np.array([np.sin(ang[k]), -np.cos(ang[k]), 0.0])
        target = np.array([p[0], p[1], z_bottom]) + 0.02 * outward
        bot_idx[k] = trunk[np.argmin(np.linalg.norm(v[trunk] - target, axis=1))]
    ss = np.linspace(0.0, reach, n_rows)
    ncol = len(ang)
    widths = np.linalg.norm(np.diff(top_pos, axis=0), axis=1)
    u_cum = np.concatenate([[0.0], np.cumsum(widths)])
    length = float(np.linalg.norm(top_pos.mean(0) - v[bot_idx].mean(0))) * reach
    scale = max(float(u_cum[-1]), length, 1e-3)
    bv, bw, uvs, off = [], [], [], []
    for s in ss:
        for k in range(ncol):
            bv.append([top_idx[k, 0], top_idx[k, 1], bot_idx[k], bot_idx[k]])
            bw.append([(1 - s) * top_w[k, 0], (1 - s) * top_w[k, 1], s, 0.0])
            uvs.append((u_cum[k] / scale, 1.0 - s / max(reach, 1e-6) * length / scale))
            # The bottom end lies on the clothes, not the skin: keep it outside the outermost garment there.
            bottom = max(bottom_offset, float(under[bot_idx[k]]) + 0.004)
            off.append((1 - s) * top_offset[k] + s * bottom)
    faces = []
    for r in range(n_rows - 1):
        for c in range(ncol - 1):
            a, b = r * ncol + c, r * ncol + c + 1
            d, e = a + ncol, b + ncol
            # Columns run round the back from the character's left, rows go down: (a, d, b) faces away from the head.
            faces += [(a, d, b), (b, d, e)]
    bv = np.array(bv, dtype=np.int64)
    bw = np.array(bw, dtype=np.float32)
    return PartGeometry(
        name=name,
        faces=np.array(faces, dtype=np.int32),
        uvs=np.clip(np.array(uvs, dtype=np.float32), 0.0, 1.0),
        body_vertex=bv[np.arange(len(bv)), np.argmax(bw, axis=1)],
        offset=np.array(off, dtype=np.float32),
        uv_layout="own",
        metres_per_uv=scale,
        blend_vertices=bv,
        blend_weights=bw,
    )


def build_hair(
    style: str, feats: BodyFeatures, topology: str = ANNY_TOPOLOGY, under: np.ndarray | None = None
) -> list[PartGeometry]:
    """Hair parts for a style: always a scalp shell ("hair"), plus "hair_curtain" / "hair_back" for longer styles.

    `under` (V,) is the outermost garment offset per body vertex (see `build_garments`); hair stays outside it.
    """
    if under is None:
        under = np.zeros(len(feats.rest_vertices))
    gap = 0.004
    v = feats.rest_vertices
    hb, z_eye, aphi = _head_frame(feats)
    z_top = float(v[feats.in_groups("head"), 2].max())
    mask = scalp_mask(style, feats)
    face_ids = _select_faces(mask, topology)
    split = split_faces(face_ids, topology)
    dist = boundary_distance(face_ids, v, topology)
    base = SHELL_OFFSET[style]
    volume = 1.0 + 0.6 * _smoothstep((v[:, 2] - z_eye) / 0.08)  # fuller on the crown than at the temples
    off = base * volume * (0.2 + 0.8 * _smoothstep(dist / 0.02))
    back = np.array([hb[0], hb[1] + 0.2, 0.0])
    if style == "bun":
        centre = _nearest_on_scalp(feats, mask, np.array([hb[0], back[1], z_top - 0.03]))
        off = off + _bump(feats, centre, 0.055, 0.05)
    if style == "ponytail":
        tie = _nearest_on_scalp(feats, mask, np.array([hb[0], back[1], z_eye + 0.01]))
        off = off + _bump(feats, tie, 0.03, 0.018)
    parts = [
        PartGeometry(
            name="hair",
            faces=split.faces,
            uvs=split.uvs,
            body_vertex=split.body_vertex,
            offset=off[split.body_vertex].astype(np.float32),
            uv_layout="body",
            metres_per_uv=_metres_per_uv(face_ids, feats, topology),
        )
    ]
    z_shoulder = 0.5 * float(feats.bone_heads["shoulder01.L"][2] + feats.bone_heads["shoulder01.R"][2])
    if style in ("bob", "long"):
        angles = np.linspace(98.0, 262.0, 29)  # behind the ears, round the back
        # Start above the shell's lower edge and slightly inside it, so the curtain emerges from under the shell.
        zt = z_eye + 0.015
        top_off = np.full(len(angles), base * 0.7)
        reach = 0.55 if style == "bob" else 1.0
        parts.append(_curtain("hair_curtain", feats, angles, zt, top_off, z_shoulder - 0.01, 0.02, reach, under))
    if style == "long":
        trunk = feats.in_groups("torso", "shoulder", "neck")
        z_end = float(feats.bone_heads["spine02"][2])
        width = 0.13
        n = feats.rest_normals
        m = trunk & (n[:, 1] > 0.25) & (np.abs(v[:, 0]) < width) & (v[:, 2] > z_end) & (v[:, 2] < z_shoulder + 0.04)
        fid = _select_faces(m, topology)
        sp = split_faces(fid, topology)
        d = boundary_distance(fid, v, topology)
        off_b = 0.02 * (0.3 + 0.7 * _smoothstep(d / 0.03))
        off_b = np.maximum(off_b, np.where(under > 0, under + gap, 0.0))
        parts.append(PartGeometry("hair_back", sp.faces, sp.uvs, sp.body_vertex,
                                  off_b[sp.body_vertex].astype(np.float32), "body",
                                  _metres_per_uv(fid, feats, topology)))
    if style == "ponytail":
        angles = np.linspace(163.0, 197.0, 7)
        zt = z_eye + 0.01
        top_off = np.full(len(angles), base + 0.014)
        parts.append(
            _curtain("hair_curtain", feats, angles, zt, top_off, z_shoulder - 0.08, 0.015, 1.0, under, n_rows=12)
        )
    return parts
