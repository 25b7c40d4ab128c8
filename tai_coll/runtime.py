"""Taichi start-up: which arch, which float precision, how many CPU threads.

`init()` is the only place that calls `ti.init`. Every other module asks `ensure_init()`
first, so using the API before `init()` starts the default arch ("auto"). Calling `init()`
again with the same arguments does nothing; different arguments restart Taichi, and
scenes built before then refuse to run (their fields belong to the old runtime).
"""

from __future__ import annotations

import ctypes
import numbers
import platform
from dataclasses import dataclass

import numpy as np
import taichi as ti

ARCHS = ("auto", "cpu", "gpu", "cuda", "vulkan", "metal")
PRECISIONS = ("f32", "f64")


@dataclass(frozen=True)
class RuntimeInfo:
    """What `init()` settled on. `arch` is the arch Taichi actually runs on."""

    requested_arch: str
    arch: str
    precision: str
    threads: int | None
    seed: int
    generation: int

    @property
    def float_dtype(self):
        return np.float64 if self.precision == "f64" else np.float32


_info: RuntimeInfo | None = None
_generation = 0


def _check_init_args(arch, precision, threads, seed):
    if not isinstance(arch, str):
        raise TypeError(f"arch must be a string, one of {ARCHS}; got {type(arch).__name__}")
    if arch not in ARCHS:
        raise ValueError(f"arch must be one of {ARCHS}; got {arch!r}")
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be 'f32' or 'f64'; got {precision!r}")
    if threads is not None:
        if isinstance(threads, bool) or not isinstance(threads, numbers.Integral):
            raise TypeError(f"threads must be an integer or None; got {threads!r}")
        if threads < 1:
            raise ValueError(f"threads must be >= 1; got {threads}")
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer; got {seed!r}")
    if precision == "f64" and arch in ("vulkan", "metal"):
        raise ValueError(f"precision='f64' is not supported on arch={arch!r}; use 'f32'")


def _cuda_driver_present() -> bool:
    """Whether the CUDA driver library loads, checked without Taichi's fallback warnings."""
    names = {"Linux": ["libcuda.so.1", "libcuda.so"], "Windows": ["nvcuda.dll"]}.get(platform.system(), [])
    for name in names:
        try:
            ctypes.CDLL(name)
            return True
        except OSError:
            continue
    return False


def _arch_name(arch) -> str:
    return {ti.x64: "cpu", ti.arm64: "cpu", ti.cuda: "cuda", ti.vulkan: "vulkan",
            ti.metal: "metal", ti.opengl: "opengl"}.get(arch, str(arch))


def _start(arch: str, precision: str, threads: int | None, seed: int) -> str:
    fp = ti.f64 if precision == "f64" else ti.f32
    common = dict(default_fp=fp, default_ip=ti.i32, random_seed=seed, log_level=ti.WARN)
    cpu = dict(arch=ti.cpu, **common)
    if threads is not None:
        cpu["cpu_max_num_threads"] = threads
    if arch == "cpu":
        ti.init(**cpu)
    elif arch == "auto":
        # A GPU when one is usable: CUDA, or Metal on a Mac. Vulkan is not tried here, since
        # on a machine without a GPU it would pick a software rasteriser (lavapipe), slower
        # than Taichi's own CPU backend and without f64.
        candidates = [ti.cuda] if _cuda_driver_present() else []
        if platform.system() == "Darwin" and precision == "f32":
            candidates.append(ti.metal)
        if candidates:
            ti.init(arch=candidates, **common)
        if not candidates or (_arch_name(ti.lang.impl.current_cfg().arch) == "cpu" and threads is not None):
            if candidates:
                ti.reset()
            ti.init(**cpu)
    else:
        target = {"gpu": ti.gpu, "cuda": ti.cuda, "vulkan": ti.vulkan, "metal": ti.metal}[arch]
        ti.init(arch=target, **common)
    return _arch_name(ti.lang.impl.current_cfg().arch)


def init(arch: str = "auto", *, precision: str = "f32", threads: int | None = None,
         seed: int = 0) -> RuntimeInfo:
    """Start Taichi for tai_coll.

    arch: "cpu" | "gpu" | "cuda" | "vulkan" | "metal" | "auto" ("auto": CUDA or Metal when
        usable, else the CPU). A GPU arch that is not available falls back to the CPU, as
        Taichi does; `RuntimeInfo.arch` says where it landed.
    precision: "f32" (fast, the default) or "f64" (for tests and accuracy studies).
    threads: CPU worker threads (None: all cores). Ignored on GPUs.
    seed: Taichi's random seed.
    """
    global _info, _generation
    _check_init_args(arch, precision, threads, seed)
    if _info is not None and (_info.requested_arch, _info.precision, _info.threads, _info.seed) == (
            arch, precision, threads, seed):
        return _info
    if _info is not None:
        ti.reset()
    actual = _start(arch, precision, threads, seed)
    _generation += 1
    _info = RuntimeInfo(arch, actual, precision, threads, seed, _generation)
    return _info


def ensure_init() -> RuntimeInfo:
    """The current runtime, starting the default one ("auto", f32) if none is running."""
    return _info if _info is not None else init()


def info() -> RuntimeInfo | None:
    """The running runtime, or None before the first `init()`."""
    return _info


def float_dtype():
    """The numpy dtype matching Taichi's default float."""
    return ensure_init().float_dtype


def check_generation(generation: int, what: str = "this object") -> None:
    """Raise if `generation` belongs to a Taichi runtime that `init()` has since replaced."""
    if _info is None or generation != _info.generation:
        raise RuntimeError(
            f"{what} was built before tai_coll.init() restarted Taichi with other arguments; "
            "its fields are gone. Build it again after the last init().")
