"""`rh-generate` with Dr.Jit's LLVM backend compiling for another CPU target and vector width: the cross-machine
difference measured on one machine (docs/ARCHITECTURE.md, "Content identity").

    python bench/llvm_target.py --show                                   # this CPU's native target
    python bench/llvm_target.py --target haswell --width 8 -- --protocol a --out /tmp/w8 --subjects 1 ...
    rh-verify /tmp/native --against /tmp/w8

In: a target CPU name, LLVM feature string and vector width, then rh-generate's own arguments after `--`.
Out: the dataset rh-generate writes, every kernel compiled for that target; it prints the target used.
Dr.Jit 1.5 has no Python call for this: `jit_llvm_set_target` is called through ctypes from libdrjit-core.so (the
C++ symbol of drjit-core's public `jit_llvm_set_target(cpu, features, width)`), after the LLVM backend starts and
before any kernel is compiled. Kernels are cached on disk by their IR, which names the target and vector width, so a
cached kernel of another target is never reused. Only `--workers 1` (one process) applies the target.
"""
from __future__ import annotations

import argparse
import ctypes
import os
import sys

# Feature strings of the x86-64 levels this machine's LLVM knows as CPU names (a target may not use more than the
# host has: --features defaults to these).
FEATURES = {
    "nehalem": "+sse4.2,+popcnt,-avx,-avx2,-fma,-avx512f",                   # 4 lanes (SSE4.2)
    "haswell": "+avx,+avx2,+fma,+f16c,+bmi,+bmi2,+popcnt,-avx512f",          # 8 lanes (AVX2)
}


def _lib():
    import drjit

    return ctypes.CDLL(os.path.join(os.path.dirname(drjit.__file__), "libdrjit-core.so"))


def current() -> tuple[str, str, int]:
    lib = _lib()
    cpu, feat, width = lib._Z19jit_llvm_target_cpuv, lib._Z24jit_llvm_target_featuresv, lib._Z21jit_llvm_vector_widthv
    cpu.restype = feat.restype = ctypes.c_char_p
    width.restype = ctypes.c_uint32
    return cpu().decode(), feat().decode(), int(width())


def set_target(cpu: str, features: str, width: int) -> None:
    fn = _lib()._Z19jit_llvm_set_targetPKcS0_j
    fn.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint32]
    fn.restype = None
    fn(cpu.encode(), features.encode(), width)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ours, gen = (argv[:argv.index("--")], argv[argv.index("--") + 1:]) if "--" in argv else (argv, [])
    p = argparse.ArgumentParser(prog="bench/llvm_target.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--show", action="store_true", help="print the native target and exit")
    p.add_argument("--target", help="LLVM CPU name, e.g. haswell (AVX2) or nehalem (SSE4.2); default: native")
    p.add_argument("--features", help="LLVM feature string (default: the table above for --target)")
    p.add_argument("--width", type=int, help="vector width in lanes (default: 8 for haswell, 4 for nehalem)")
    args = p.parse_args(ours)
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")  # starts the LLVM backend, so its native target is known
    if args.target:
        feats = args.features if args.features is not None else FEATURES.get(args.target)
        if feats is None:
            p.error(f"no default features for {args.target!r}: give --features")
        set_target(args.target, feats, args.width or {"nehalem": 4}.get(args.target, 8))
    cpu, feat, width = current()
    print(f"llvm target: cpu {cpu}, vector width {width}, features {feat[:60]}...", flush=True)
    if args.show or not gen:
        return 0
    if any(a.startswith("--workers") for a in gen):
        p.error("the target is set in this process only: leave --workers at 1")
    from rh_dataset.cli import main as generate

    return generate(gen)


if __name__ == "__main__":
    sys.exit(main())
