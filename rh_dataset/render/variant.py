"""Choosing Mitsuba's variant once per process: `cuda_ad_rgb` where a GPU works, else `llvm_ad_rgb`."""
from __future__ import annotations

import os

__all__ = ["select_variant", "require_variant", "VariantError"]

_LLVM19 = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"


class VariantError(RuntimeError):
    pass


def select_variant(requested: str | None = None) -> str:
    """Set and return Mitsuba's variant. `requested=None` picks cuda_ad_rgb if it initialises, else llvm_ad_rgb.

    The LLVM backend aborts the process (uncatchably) with LLVM 15/16, so the LLVM library is pinned to
    Debian's libLLVM 19 when it is present, before drjit first loads it.
    """
    if os.path.exists(_LLVM19):
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", _LLVM19)
    import mitsuba as mi

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
    import mitsuba as mi

    return mi.variant() or select_variant(None)
