"""Mitsuba's variant, chosen by explicit calls; the one place that prepares the process for drjit.

In: a variant name, or None (choose: `cuda_ad_rgb` where a GPU works, else `llvm_ad_rgb`). Out: the variant
set, its name; `ensure_variant` and `load_mitsuba` return the `mitsuba` module.
Mitsuba's variant is process-global (drjit keeps per-variant JIT state) and cannot be unset once chosen. So the
command picks it (rh-generate's --variant -> `select_variant`) and passes the name down as an argument; code that
needs only *a* vectorised variant asks `ensure_variant()`, which keeps whatever is set and sets the project
default only when nothing is. No module sets a variant by itself, and nothing passes the choice through the
environment. Every part of the generator imports Mitsuba through here (a leaf module: lights, characters, poses
and render all use it), so the LLVM pin below always comes first.
"""
from __future__ import annotations

import os

import numpy as np

__all__ = ["select_variant", "require_variant", "ensure_variant", "load_mitsuba", "jit_array", "VariantError",
           "DEFAULT_VARIANT", "MIN_RENDER_THREADS", "set_render_threads"]

DEFAULT_VARIANT = "llvm_ad_rgb"  # the project's default where no command chose: CPU, bit-identical everywhere
_LLVM19 = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"


class VariantError(RuntimeError):
    pass


def load_mitsuba():
    """The `mitsuba` module, imported after pinning the LLVM library drjit loads (no variant is set here).

    drjit reads DRJIT_LIBLLVM_PATH from the environment (its only channel) when it first loads libLLVM, and the
    LLVM backend aborts the process (uncatchably) with LLVM 15/16; so Debian's libLLVM 19 is named, when present,
    before drjit can load. `setdefault`: a path the user set wins. This is the only environment variable the
    package sets.
    """
    if os.path.exists(_LLVM19):
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", _LLVM19)
    import mitsuba as mi

    return mi


def select_variant(requested: str | None = None) -> str:
    """Set and return Mitsuba's variant. `requested=None` keeps the current one, or picks cuda_ad_rgb if it
    initialises, else llvm_ad_rgb. Switching a variant already set is refused."""
    mi = load_mitsuba()
    current = mi.variant()
    if requested is None and current is not None:
        return current
    if requested is not None:
        if requested not in mi.variants():
            raise VariantError(f"Mitsuba variant {requested!r} is not available; choose one of {mi.variants()}")
        if current not in (None, requested):
            # drjit keeps per-variant JIT state; switching mid-run would mix two renderers in one dataset.
            raise VariantError(f"Mitsuba variant already set to {current!r} in this process; cannot switch to {requested!r}")
        mi.set_variant(requested)
        return requested
    for candidate in ("cuda_ad_rgb", "llvm_ad_rgb"):
        if candidate not in mi.variants():
            continue
        try:
            mi.set_variant(candidate)
            if candidate == "cuda_ad_rgb":
                import drjit as dr

                dr.eval(mi.Float(1.0) + 1.0)  # fails here when no CUDA driver/GPU is usable
            return candidate
        except Exception:
            continue
    raise VariantError("neither cuda_ad_rgb nor llvm_ad_rgb works; run `bash setup.sh` (installs libllvm19)")


def require_variant() -> str:
    """The variant in use; if none is set yet, the one `select_variant(None)` picks."""
    return load_mitsuba().variant() or select_variant(None)


def ensure_variant(default: str = DEFAULT_VARIANT):
    """The `mitsuba` module with a variant set: the current one, or `default` when none is set yet (it then
    stays set: Mitsuba 3.9 cannot return to "no variant"). For tools and helpers that render or evaluate
    emitters under whatever variant the command chose, and never switch it."""
    mi = load_mitsuba()
    if mi.variant() is None:
        select_variant(default)
    return mi


MIN_RENDER_THREADS = 2
"""The fewest threads drjit's LLVM backend renders with. One thread gives strand hair other last bits than any pool
of two or more (2, 3, 4 and 8 gave the same bits; a pixel's curve hit moves by ~1e-7, and a path through the hair
can then take another course): `rh-generate --workers 2` on 2 cores, one thread a process, wrote another content
identity than `--workers 1` (docs/TRADEOFFS.md, "Two processes on two cores"). Never fewer than two, a dataset's bits
do not depend on --workers or, as far as measured (2, 3, 4 and 8 threads), on the core count."""


def set_render_threads(n: int | None = None) -> int:
    """Give drjit's LLVM backend `n` render threads (None: as many as it has, by default one per core), never fewer
    than MIN_RENDER_THREADS (more threads than cores take turns: on 2 cores `--workers 2` with two threads a process
    was faster than with one, docs/TRADEOFFS.md). Returns the count set. Called by the backends that render
    (process-wide, like the variant)."""
    import drjit as dr

    count = max(MIN_RENDER_THREADS, int(n if n is not None else dr.thread_count()))
    if dr.thread_count() != count:
        dr.set_thread_count(count)
    return count


JIT_ALIGN = 64
"""Bytes: the alignment drjit's LLVM backend asks of a mapped buffer before it reads it in packets (the vector width
times the element size, at most 64)."""


def jit_array(array_type, values):
    """`array_type` (e.g. `mi.Float`, `mi.UInt32`) holding a flat copy of `values` in JIT_ALIGN-byte-aligned memory.

    On the LLVM backend drjit maps a numpy buffer instead of copying it, and compiles a gather from it as one packet
    load when the buffer is 64-byte aligned but as separate loads when it is not. numpy's allocator aligns to 16
    bytes only, so the same scene built twice could give two kernels, and a frame recompiled (~0.5 s a kernel) what
    the previous frame had cached (bench/bench_generate.py, the "compiled / frame" column). Aligned here, every
    frame builds the same kernel; the copy also stops a later write to `values` from reaching the scene.
    """
    import drjit as dr

    dtype = np.dtype(str(dr.type_v(array_type)).split(".")[-1].lower())  # VarType.Float32 -> float32
    flat = np.asarray(values, dtype=dtype).ravel()
    step = JIT_ALIGN // flat.itemsize
    buf = np.empty(flat.size + step, dtype)
    start = (-buf.ctypes.data % JIT_ALIGN) // flat.itemsize
    out = buf[start:start + flat.size]
    out[...] = flat
    return array_type(out)
