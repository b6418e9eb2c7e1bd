"""From the second frame on no kernel compiles: the scene's buffers reach drjit 64-byte aligned (`jit_array`), so a
rebuilt scene gives the same kernels, found in drjit's caches. Kernel counts do not depend on the machine's load."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from analytic_scenes import uv_sphere
from rh_common.camera import Camera
from rh_dataset.characters.hair_fibre import HairFibre
from rh_dataset.render.passes import render_frame
from rh_dataset.render.scene import RenderSettings
from rh_dataset.variant import JIT_ALIGN, jit_array, load_mitsuba, select_variant


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant("llvm_ad_rgb")


@dataclasses.dataclass(frozen=True)
class _Strands:
    name: str
    points: np.ndarray
    radius: np.ndarray
    fibre: HairFibre


def _at_offset(a: np.ndarray, offset: int) -> np.ndarray:
    """A copy of `a` whose data starts `offset` bytes past a 64-byte boundary."""
    raw = np.empty(a.nbytes + 2 * JIT_ALIGN, np.uint8)
    start = (-raw.ctypes.data % JIT_ALIGN) + offset
    out = raw[start:start + a.nbytes].view(a.dtype).reshape(a.shape)
    out[...] = a
    return out


def test_jit_array_is_an_aligned_copy():
    mi = load_mitsuba()
    for offset in (0, 4, 16, 36):
        src = _at_offset(np.arange(50, dtype=np.float32), offset)
        x = jit_array(mi.Float, src)
        assert np.from_dlpack(x).ctypes.data % JIT_ALIGN == 0
        src[0] = 99.0  # a copy: the scene does not see later writes
        assert np.array_equal(np.array(x), np.arange(50, dtype=np.float32))
    assert np.array_equal(np.array(jit_array(mi.UInt32, np.array([[1, 2], [3, 4]]))), [1, 2, 3, 4])


def test_a_rebuilt_frame_with_hair_compiles_no_kernel():
    import drjit as dr

    cam = Camera(16, 16, 40.0, (0.0, -4.0, 0.2), (0.0, 0.0, 0.2))
    x = np.linspace(-0.8, 0.8, 6)
    pts = np.stack([np.stack([x, 0 * x - 1.2, 0 * x + 0.1 * k], 1) for k in range(5)]).astype(np.float32)
    strands = _Strands("s", pts, np.full(pts.shape[:2], 0.03, np.float32), HairFibre(0.6, 0.2))
    sphere = uv_sphere(radius=0.7, albedo=(0.6, 0.5, 0.4), n_lat=8, n_lon=16)
    env = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}
    st = RenderSettings(spp=9, aov_spp=4, max_depth=3, sampler="multijitter", env_spp=1)
    layers = ["image", "mask", "albedo"]
    flag = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        first = render_frame([sphere, strands], env, cam, st, layers, 5)  # compiles, or loads from the disk cache
        dr.kernel_history()
        for offset in (0, 4, 16, 48):  # the same frame from buffers aligned and not (numpy's allocator gives either)
            mesh = dataclasses.replace(sphere, vertices=_at_offset(sphere.vertices, offset),
                                       uvs=_at_offset(sphere.uvs, offset))
            hair = dataclasses.replace(strands, points=_at_offset(pts, offset))
            again = render_frame([mesh, hair], env, cam, st, layers, 5)
            compiled = [k for k in dr.kernel_history() if k.get("type") == dr.KernelType.JIT and not k.get("cache_hit")]
            assert compiled == [], f"offset {offset}: {len(compiled)} kernels compiled again"
            assert all(np.array_equal(first.layers[k], again.layers[k]) for k in layers)
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, flag)
