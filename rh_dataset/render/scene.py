"""Turn posed meshes and hair strands, a light and a camera into a Mitsuba 3 scene dict. Nothing here renders.

One plain function builds the dict (as Mitsuba's own `cornell_box()` does), so tests derive variants by editing it.
Strands become one `bsplinecurve` shape per fibre (`rh_dataset.characters.strand_shape`) with Mitsuba's `hair`
BSDF, wrapped so that the AOV pass reads the fibre's albedo from it.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Protocol, Sequence

import numpy as np

from rh_common.camera import Camera

from .camera import mitsuba_sensor
from .sampler import SAMPLERS
from ..variant import jit_array, load_mitsuba, require_variant

__all__ = ["MeshLike", "StrandsLike", "RenderSettings", "scene_dict", "mitsuba_mesh", "mitsuba_bsdf", "is_strands"]


class MaterialLike(Protocol):
    albedo: np.ndarray  # (H, W, 3) float32 linear, row 0 = top of the texture image (v = 1)
    roughness: float
    specular: float
    # optional: sheen, sheen_tint (the principled sheen lobe), clearcoat, clearcoat_gloss (its clear coat; absent = 0)


class MeshLike(Protocol):
    name: str
    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray  # OpenGL convention: v = 0 at the bottom row of the texture
    material: MaterialLike


class FibreLike(Protocol):
    eumelanin: float
    pheomelanin: float
    longitudinal_roughness: float
    azimuthal_roughness: float
    albedo: np.ndarray  # (3,) linear RGB, the stand-in's reflectance


class StrandsLike(Protocol):
    name: str
    points: np.ndarray  # (S, K, 3) cubic B-spline control points, metres
    radius: np.ndarray  # (S, K) metres
    fibre: FibreLike


def is_strands(shape) -> bool:
    """Hair strands rather than a triangle mesh."""
    return getattr(shape, "fibre", None) is not None


@dataclass(frozen=True)
class RenderSettings:
    """How hard the renderer works. Presets live in rh_dataset/scenes/presets.json."""

    spp: int = 64
    """Samples per pixel of the path-traced beauty pass."""
    aov_spp: int = 16
    """Samples per pixel of the AOV pass (albedo, normal, mask, depth): these converge far faster."""
    max_depth: int | None = 6
    """Longest path (Mitsuba `max_depth`): 2 = direct light only; each extra unit adds one bounce. None: the split's
    scene class decides (`for_split`); a path-traced pass refuses an unresolved None."""
    rr_depth: int | None = None
    """Path depth from which Mitsuba's path tracer ends paths by Russian roulette (survival probability = the path's
    throughput, at most 0.95, the survivors reweighted: unbiased, so paths may run deep at the cost of a little
    noise). None: Mitsuba's default (5), which changes nothing at max_depth <= 5."""
    preset: str = "custom"
    sampler: str = "independent"
    """Mitsuba's sample generator for both passes (`rh_dataset.render.sampler.SAMPLERS`); the presets choose theirs
    by measurement (bench/bench_sampler.py). Some round their sample count: a count they would round is refused."""
    env_spp: int | None = None
    """Samples per pixel where the AOV pass sees no person (the environment seen directly); the person's pixels get
    `spp` (`rh_dataset.render.focus`: unbiased either way). None: every pixel gets `spp`. Needs an AOV layer in the
    frame (the coverage comes from that pass); a frame without one renders every pixel at `spp`."""
    adaptive_tiers: tuple[int, ...] | None = None
    """Sample counts a person's pixel may get (`rh_dataset.render.adaptive`): each gets the one nearest its share in
    proportion to its display-space noise, measured on the env_spp pass, and `spp` is then the mean over the person's
    pixels. Needs env_spp >= 2 and the frame's exposure (`render_frame(exposure=...)`). None: every person pixel
    gets `spp`. Unbiased either way; whether it saves time is measured (docs/TRADEOFFS.md, "Samples by noise")."""
    denoise: bool = False
    """Opt-in: run Intel Open Image Denoise (pyoidn, HDR mode, guided by the albedo and normal AOVs) on the beauty
    image. Biased (docs/TRADEOFFS.md measures it); recorded in the frame JSON as `render.denoise`/`render.denoised`."""
    cull: bool = True
    """Leave out geometry the camera cannot see (skin hidden under clothes; for AOV-only frames also triangles outside
    the view frustum): `rh_dataset.render.cull`. Changes the beauty image by far less than its noise (measured,
    docs/TRADEOFFS.md); the frame JSON records what was left out. False renders every triangle."""
    cloth: str = "skinned"
    """How draped garments reach each frame's pose (`rh_dataset.characters.cloth_pose.CLOTH_MODES`): "skinned"
    (linear-blend skinning, then pushed out of the skin) or "simulated" (newton's cloth solver while the body moves
    from the rest pose into the frame's). Which preset takes which: bench/bench_cloth_pose.py, docs/TRADEOFFS.md."""
    drape: str = "full"
    """How finely draped garments (loose skirts and dresses) are simulated onto each subject's rest-pose body
    (`rh_dataset.characters.drape.DRAPE_LEVELS`): "full" (the benchmark's), "coarse" (half the particles around and
    along, half the steps: ~1/8 of the drape's time; the draft preset's). A per-dataset choice: every subject is
    built with it."""

    def __post_init__(self) -> None:
        for name in ("denoise", "cull"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"render setting {name} must be a bool, got {getattr(self, name)!r}")
        for name in ("spp", "aov_spp"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ValueError(f"render setting {name} must be a positive integer, got {v!r}")
        if self.sampler not in SAMPLERS:
            raise ValueError(f"render setting sampler must be one of {', '.join(SAMPLERS)}, got {self.sampler!r}")
        if self.env_spp is not None and (not isinstance(self.env_spp, int) or not 1 <= self.env_spp <= self.spp):
            raise ValueError(f"render setting env_spp must be None or an integer in [1, spp={self.spp}], "
                             f"got {self.env_spp!r}")
        if self.adaptive_tiers is not None:
            from .adaptive import check_tiers

            object.__setattr__(self, "adaptive_tiers", check_tiers(self.adaptive_tiers, self.spp, self.env_spp))
        if self.rr_depth is not None and (not isinstance(self.rr_depth, int) or self.rr_depth < 1):
            raise ValueError(f"render setting rr_depth must be None or an integer >= 1, got {self.rr_depth!r}")
        if self.max_depth is not None and (not isinstance(self.max_depth, int) or self.max_depth < 2):
            raise ValueError(f"render setting max_depth must be an integer >= 2 or None, got {self.max_depth!r}")
        from rh_dataset.characters.cloth_pose import CLOTH_MODES

        if self.cloth not in CLOTH_MODES:
            raise ValueError(f"render setting cloth must be one of {', '.join(CLOTH_MODES)}, got {self.cloth!r}")
        from rh_dataset.characters.drape import DRAPE_LEVELS

        if self.drape not in DRAPE_LEVELS:
            raise ValueError(f"render setting drape must be one of {', '.join(DRAPE_LEVELS)}, got {self.drape!r}")

    def for_split(self, split) -> "RenderSettings":
        """These settings for one split of a scene description: an unset max_depth becomes the depth of the split's
        scene class (`SplitSpec.max_depth`), with its Russian-roulette depth unless rr_depth is set; a split that
        does not path-trace keeps None (it has no depth)."""
        if self.max_depth is not None or not split.path_traced:
            return self
        rr = self.rr_depth if self.rr_depth is not None else getattr(split, "rr_depth", None)
        return dataclasses.replace(self, max_depth=int(split.max_depth), rr_depth=rr)


def mitsuba_bsdf(material: MaterialLike) -> Any:
    mi = load_mitsuba()
    require_variant()
    # Mitsuba looks textures up with v = 0 on the bitmap's first row; our UVs follow OpenGL (v = 0 at the
    # bottom), so the texture is flipped once here rather than every UV set being rewritten.
    tex = np.ascontiguousarray(np.flipud(np.asarray(material.albedo, dtype=np.float32)))
    reflectance = {"type": "bitmap", "bitmap": mi.Bitmap(tex), "raw": True, "filter_type": "bilinear"}
    # Disney principled: a diffuse base whose reflected radiance stays close to albedo x irradiance / pi (+6 to 13%
    # from the specular lobe under uniform light, measured), so the albedo layer (its base_color, exactly the
    # texture) and the image agree as a Lambertian reading expects. `roughplastic` was tried first: its 1/eta^2
    # internal-refraction factor darkened the diffuse part to ~0.54 x albedo, breaking that agreement.
    if material.specular <= 0.0:
        bsdf = {"type": "diffuse", "reflectance": reflectance}
    else:
        bsdf = {"type": "principled", "base_color": reflectance,
                "roughness": float(np.clip(material.roughness, 0.02, 1.0)),
                "specular": float(np.clip(material.specular, 0.0, 1.0))}
        # Cloth sheen: a lobe added on top of the base; the `aov` integrator's albedo (eval_diffuse_reflectance) is
        # still base_color, i.e. the texture (tests/test_surface_detail.py renders it).
        sheen = float(getattr(material, "sheen", 0.0))
        if sheen > 0.0:
            bsdf["sheen"] = sheen
            bsdf["sheen_tint"] = float(getattr(material, "sheen_tint", 0.5))
        # A clear coat (the eyes' tear film): a second specular lobe; the albedo AOV is still base_color.
        coat = float(getattr(material, "clearcoat", 0.0))
        if coat > 0.0:
            bsdf["clearcoat"] = coat
            bsdf["clearcoat_gloss"] = float(getattr(material, "clearcoat_gloss", 0.0))
    # Hems, skirts and hair sheets are seen from inside: shade both faces alike.
    if getattr(material, "two_sided", False):
        bsdf = {"type": "twosided", "material": bsdf}
    return mi.load_dict(bsdf)


def mitsuba_mesh(mesh: MeshLike) -> Any:
    """A Mitsuba mesh built in memory from arrays (no temporary files)."""
    mi = load_mitsuba()
    require_variant()
    V = np.asarray(mesh.vertices, dtype=np.float32)
    F = np.asarray(mesh.faces, dtype=np.uint32)
    N = np.asarray(mesh.normals, dtype=np.float32)
    UV = np.asarray(mesh.uvs, dtype=np.float32)
    if not (V.ndim == 2 and V.shape[1] == 3 and N.shape == V.shape and UV.shape == (len(V), 2)):
        raise ValueError(f"mesh {mesh.name}: inconsistent shapes V{V.shape} N{N.shape} UV{UV.shape}")
    if F.size and F.max() >= len(V):
        raise ValueError(f"mesh {mesh.name}: face index {int(F.max())} out of range for {len(V)} vertices")
    if not (np.all(np.isfinite(V)) and np.all(np.isfinite(N))):
        raise ValueError(f"mesh {mesh.name}: non-finite vertex positions or normals")
    props = mi.Properties()
    props["bsdf"] = mitsuba_bsdf(mesh.material)
    m = mi.Mesh(mesh.name, len(V), len(F), props, has_vertex_normals=True, has_vertex_texcoords=True)
    params = mi.traverse(m)
    # Aligned copies (`jit_array`): a buffer's alignment decides the kernel drjit compiles for reading it.
    params["vertex_positions"] = jit_array(mi.Float, V)
    params["vertex_normals"] = jit_array(mi.Float, N)
    params["vertex_texcoords"] = jit_array(mi.Float, UV)
    params["faces"] = jit_array(mi.UInt32, F)
    params.update()
    return m


def scene_dict(meshes: Sequence[MeshLike | StrandsLike], emitter: dict | None, camera: Camera, integrator: dict,
               spp: int, *, pixel_format: str, sampler: str = "independent") -> dict:
    """The whole Mitsuba scene: one sensor, the environment emitter (None: no light at all, for passes that read
    only primary hits), the character's meshes and hair strands."""
    d: dict[str, Any] = {
        "type": "scene",
        "integrator": integrator,
        "sensor": mitsuba_sensor(camera, spp, pixel_format=pixel_format, sampler=sampler),
    }
    if emitter is not None:
        d["environment"] = emitter
    for i, mesh in enumerate(meshes):
        if is_strands(mesh):
            from rh_dataset.characters.strand_shape import mitsuba_curves

            d[f"curves_{i:02d}_{mesh.name}"] = mitsuba_curves(mesh)
        else:
            d[f"mesh_{i:02d}_{mesh.name}"] = mitsuba_mesh(mesh)
    return d
